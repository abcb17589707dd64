//! End-to-end tests: one binary, a real server on an ephemeral port.
