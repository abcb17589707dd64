//! SQLite repositories.
