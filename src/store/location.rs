//! Where the database is: a SQLite file or a PostgreSQL server, from a `--database` value.

use std::fmt;
use std::path::PathBuf;

/// A database named by `--database`.
#[derive(Clone, PartialEq, Eq)]
pub enum Location {
    /// A SQLite file, created with its tables when missing.
    Sqlite(PathBuf),
    /// A PostgreSQL connection URL (`postgres://user:password@host:port/database`).
    Postgres(String),
}

impl Location {
    /// Reads `sqlite://FILE` (`sqlite:///abs/path` for an absolute path), `sqlite:FILE`, a
    /// bare path, or `postgres://…` / `postgresql://…`.
    pub fn parse(value: &str) -> Result<Self, String> {
        let scheme = value.split_once("://").map(|(s, _)| s.to_ascii_lowercase());
        if let Some("postgres" | "postgresql") = scheme.as_deref() {
            return Ok(Self::Postgres(value.to_owned()));
        }
        let path = value
            .strip_prefix("sqlite://")
            .or_else(|| value.strip_prefix("sqlite:"))
            .unwrap_or(value);
        if let Some(other) = scheme.filter(|s| s != "sqlite") {
            return Err(format!(
                "unknown database scheme {other}://; give sqlite://FILE, a file path or \
                 postgres://USER:PASSWORD@HOST:PORT/DATABASE"
            ));
        }
        if path.is_empty() || path.contains('?') {
            return Err(format!(
                "{value:?} names no database file; give sqlite://FILE or a file path \
                 (options after '?' are not supported)"
            ));
        }
        Ok(Self::Sqlite(PathBuf::from(path)))
    }

    /// The SQLite file, if this is one.
    pub fn sqlite_file(&self) -> Option<&std::path::Path> {
        match self {
            Self::Sqlite(path) => Some(path),
            Self::Postgres(_) => None,
        }
    }
}

impl From<PathBuf> for Location {
    fn from(path: PathBuf) -> Self {
        Self::Sqlite(path)
    }
}

/// Shows the location without a password, for logs and error messages.
impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Sqlite(path) => write!(f, "sqlite://{}", path.display()),
            Self::Postgres(url) => f.write_str(&redact_password(url)),
        }
    }
}

impl fmt::Debug for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(self, f)
    }
}

/// `scheme://user:secret@host/db` → `scheme://user:***@host/db`.
fn redact_password(url: &str) -> String {
    let Some((scheme, rest)) = url.split_once("://") else {
        return url.to_owned();
    };
    let (authority, tail) = match rest.find(['/', '?']) {
        Some(i) => rest.split_at(i),
        None => (rest, ""),
    };
    match authority.rsplit_once('@') {
        Some((user_info, host)) => match user_info.split_once(':') {
            Some((user, _)) => format!("{scheme}://{user}:***@{host}{tail}"),
            None => url.to_owned(),
        },
        None => url.to_owned(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn file(value: &str) -> Result<String, String> {
        match Location::parse(value)? {
            Location::Sqlite(p) => Ok(p.display().to_string()),
            Location::Postgres(url) => Ok(url),
        }
    }

    #[test]
    fn urls_and_bare_paths_name_a_sqlite_file() {
        assert_eq!(file("sqlite://cohortforge.db").unwrap(), "cohortforge.db");
        assert_eq!(file("sqlite:///srv/data/c.db").unwrap(), "/srv/data/c.db");
        assert_eq!(file("sqlite:c.db").unwrap(), "c.db");
        assert_eq!(file("data/c.db").unwrap(), "data/c.db");
        assert!(file("mysql://h/db").unwrap_err().contains("postgres://"));
        assert!(file("sqlite://").is_err());
        assert!(file("sqlite://c.db?mode=ro").is_err());
    }

    #[test]
    fn postgres_urls_are_kept_whole_and_shown_without_password() {
        let url = "postgres://cf:s3cret@db.internal:5432/cohortforge?sslmode=require";
        let location = Location::parse(url).unwrap();
        assert_eq!(location, Location::Postgres(url.to_owned()));
        assert_eq!(
            location.to_string(),
            "postgres://cf:***@db.internal:5432/cohortforge?sslmode=require"
        );
        assert!(matches!(
            Location::parse("postgresql://localhost/x"),
            Ok(Location::Postgres(_))
        ));
        assert_eq!(
            Location::parse("postgres://localhost/x")
                .unwrap()
                .to_string(),
            "postgres://localhost/x"
        );
    }
}
