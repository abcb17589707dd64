//! Service configuration: one struct, filled from flags or `COHORTFORGE_*` environment
//! variables, validated once at start.

use std::net::SocketAddr;
use std::path::PathBuf;

/// Configuration of the HTTP service. Each flag also reads an environment variable.
#[derive(clap::Args, Debug, Clone)]
pub struct Config {
    /// Address and port to listen on.
    #[arg(long, env = "COHORTFORGE_BIND", default_value = "127.0.0.1:8080")]
    pub bind: SocketAddr,

    /// Database: `sqlite://FILE` or a bare file path (SQLite; created with its tables when
    /// missing).
    #[arg(long, env = "COHORTFORGE_DATABASE", default_value = "sqlite://cohortforge.db",
        value_parser = parse_database)]
    pub database: PathBuf,

    /// Largest accepted request body in bytes (uploads included).
    #[arg(long, env = "COHORTFORGE_MAX_BODY_BYTES", default_value_t = 256 * 1024 * 1024)]
    pub max_body_bytes: usize,

    /// Largest accepted mesh, in vertices (after parsing, before welding).
    #[arg(long, env = "COHORTFORGE_MAX_VERTICES", default_value_t = 1_000_000)]
    pub max_vertices: usize,

    /// Number of worker threads that run training jobs (0: serve the API only, and let
    /// workers of another process sharing the database run the jobs).
    #[arg(long, env = "COHORTFORGE_WORKERS", default_value_t = 1)]
    pub workers: usize,

    /// Seconds a job's lease lasts: a job whose worker is silent this long (crashed, killed,
    /// cut off) is taken over by another worker.
    #[arg(long, env = "COHORTFORGE_LEASE_SECONDS", default_value_t = 30)]
    pub lease_seconds: u64,

    /// Largest cohort drawn inside its request (answered 201); larger ones, and any sent
    /// with `Prefer: respond-async`, are queued for the workers (answered 202). Also the
    /// largest cohort whose members are listed inline in `GET /v1/cohorts/{id}`.
    #[arg(long, env = "COHORTFORGE_SYNC_COHORT_MAX", default_value_t = 1_000)]
    pub sync_cohort_max: usize,

    /// Bearer token that may do everything. With no token configured, /v1 is open.
    #[arg(long, env = "COHORTFORGE_ADMIN_TOKEN", hide_env_values = true)]
    pub admin_token: Option<String>,

    /// Bearer token that may only read (GET and HEAD requests).
    #[arg(long, env = "COHORTFORGE_READ_TOKEN", hide_env_values = true)]
    pub read_token: Option<String>,

    /// Allow binding to a non-loopback address without any token configured.
    #[arg(long, env = "COHORTFORGE_INSECURE")]
    pub insecure: bool,
}

/// Configuration of a worker process (`cohortforge worker`): workers only, sharing the
/// database of the API processes, with a small listener for probes and metrics.
#[derive(clap::Args, Debug, Clone)]
pub struct WorkerConfig {
    /// Address of the probes and metrics listener (`/healthz`, `/readyz`, `/metrics`).
    #[arg(
        long,
        env = "COHORTFORGE_WORKER_BIND",
        default_value = "127.0.0.1:9464"
    )]
    pub bind: SocketAddr,

    /// Database of the API processes: `sqlite://FILE` or a bare file path.
    #[arg(long, env = "COHORTFORGE_DATABASE", default_value = "sqlite://cohortforge.db",
        value_parser = parse_database)]
    pub database: PathBuf,

    /// Number of worker threads that run jobs.
    #[arg(long, env = "COHORTFORGE_WORKERS", default_value_t = 1)]
    pub workers: usize,

    /// Seconds a job's lease lasts: a job whose worker is silent this long is taken over.
    #[arg(long, env = "COHORTFORGE_LEASE_SECONDS", default_value_t = 30)]
    pub lease_seconds: u64,
}

impl WorkerConfig {
    /// Checks that the configuration can run jobs.
    pub fn validate(&self) -> Result<(), ConfigError> {
        if self.workers == 0 {
            return Err(ConfigError::ZeroLimit("--workers"));
        }
        if self.lease_seconds == 0 {
            return Err(ConfigError::ZeroLimit("--lease-seconds"));
        }
        Ok(())
    }
}

/// The SQLite file of a `--database` value: `sqlite://FILE` (`sqlite:///abs/path` for an
/// absolute path), `sqlite:FILE`, or a bare path.
pub fn parse_database(value: &str) -> Result<PathBuf, String> {
    let scheme = value.split_once("://").map(|(s, _)| s.to_ascii_lowercase());
    if let Some("postgres" | "postgresql") = scheme.as_deref() {
        return Err(
            "PostgreSQL is not supported by this version yet; give a SQLite file \
             (sqlite://FILE or a path)"
                .into(),
        );
    }
    let path = value
        .strip_prefix("sqlite://")
        .or_else(|| value.strip_prefix("sqlite:"))
        .unwrap_or(value);
    if let Some(other) = scheme.filter(|s| s != "sqlite") {
        return Err(format!(
            "unknown database scheme {other}://; give sqlite://FILE or a file path"
        ));
    }
    if path.is_empty() || path.contains('?') {
        return Err(format!(
            "{value:?} names no database file; give sqlite://FILE or a file path \
             (options after '?' are not supported)"
        ));
    }
    Ok(PathBuf::from(path))
}

/// A configuration that cannot start the service.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// Serving an open API to the network needs an explicit opt-in.
    #[error(
        "refusing to listen on {0} without a token: set --admin-token (COHORTFORGE_ADMIN_TOKEN) \
         or pass --insecure to serve an open API on a non-loopback address"
    )]
    OpenNonLoopback(SocketAddr),
    /// A read token alone would lock every client out of writes.
    #[error("--read-token needs --admin-token as well, otherwise nobody could write")]
    ReadTokenWithoutAdmin,
    /// Tokens must be long enough to resist guessing.
    #[error("{0} must be at least {MIN_TOKEN_CHARS} characters long")]
    TokenTooShort(&'static str),
    /// Zero is not a usable limit.
    #[error("{0} must be greater than zero")]
    ZeroLimit(&'static str),
}

/// Shortest accepted bearer token.
pub const MIN_TOKEN_CHARS: usize = 16;

impl Config {
    /// A configuration for tests and embedding: loopback, given database, no tokens.
    pub fn local(database: PathBuf) -> Self {
        Self {
            bind: SocketAddr::from(([127, 0, 0, 1], 0)),
            database,
            max_body_bytes: 256 * 1024 * 1024,
            max_vertices: 1_000_000,
            workers: 1,
            lease_seconds: 30,
            sync_cohort_max: 1_000,
            admin_token: None,
            read_token: None,
            insecure: false,
        }
    }

    /// Checks that the configuration is safe and usable.
    pub fn validate(&self) -> Result<(), ConfigError> {
        if self.max_body_bytes == 0 {
            return Err(ConfigError::ZeroLimit("--max-body-bytes"));
        }
        if self.max_vertices == 0 {
            return Err(ConfigError::ZeroLimit("--max-vertices"));
        }
        if self.lease_seconds == 0 {
            return Err(ConfigError::ZeroLimit("--lease-seconds"));
        }
        for (flag, token) in [
            ("--admin-token", &self.admin_token),
            ("--read-token", &self.read_token),
        ] {
            if token
                .as_ref()
                .is_some_and(|t| t.chars().count() < MIN_TOKEN_CHARS)
            {
                return Err(ConfigError::TokenTooShort(flag));
            }
        }
        if self.read_token.is_some() && self.admin_token.is_none() {
            return Err(ConfigError::ReadTokenWithoutAdmin);
        }
        if self.admin_token.is_none() && !self.bind.ip().is_loopback() && !self.insecure {
            return Err(ConfigError::OpenNonLoopback(self.bind));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn open_service_only_on_loopback() {
        let mut c = Config::local("x.db".into());
        assert!(c.validate().is_ok());
        c.bind = "0.0.0.0:8080".parse().unwrap();
        assert!(matches!(c.validate(), Err(ConfigError::OpenNonLoopback(_))));
        c.insecure = true;
        assert!(c.validate().is_ok());
        c.insecure = false;
        c.admin_token = Some("0123456789abcdef".into());
        assert!(c.validate().is_ok());
    }

    #[test]
    fn database_urls_and_bare_paths_name_a_sqlite_file() {
        let file = |v: &str| parse_database(v).map(|p| p.display().to_string());
        assert_eq!(file("sqlite://cohortforge.db").unwrap(), "cohortforge.db");
        assert_eq!(file("sqlite:///srv/data/c.db").unwrap(), "/srv/data/c.db");
        assert_eq!(file("sqlite:c.db").unwrap(), "c.db");
        assert_eq!(file("data/c.db").unwrap(), "data/c.db");
        assert!(
            file("postgres://u@h/db")
                .unwrap_err()
                .contains("PostgreSQL")
        );
        assert!(file("mysql://h/db").unwrap_err().contains("mysql://"));
        assert!(file("sqlite://").is_err());
        assert!(file("sqlite://c.db?mode=ro").is_err());
    }

    #[test]
    fn short_or_lonely_tokens_are_refused() {
        let mut c = Config::local("x.db".into());
        c.admin_token = Some("short".into());
        assert!(matches!(c.validate(), Err(ConfigError::TokenTooShort(_))));
        c.admin_token = None;
        c.read_token = Some("0123456789abcdef".into());
        assert!(matches!(
            c.validate(),
            Err(ConfigError::ReadTokenWithoutAdmin)
        ));
    }
}
