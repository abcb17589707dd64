//! Service configuration: one struct, filled from flags or `COHORTFORGE_*` environment
//! variables, validated once at start.

use crate::store::Location;
use std::net::SocketAddr;

/// Configuration of the HTTP service. Each flag also reads an environment variable.
#[derive(clap::Args, Debug, Clone)]
pub struct Config {
    /// Address and port to listen on.
    #[arg(long, env = "COHORTFORGE_BIND", default_value = "127.0.0.1:8080")]
    pub bind: SocketAddr,

    /// Database: `sqlite://FILE` or a bare file path (SQLite; created with its tables when
    /// missing), or `postgres://USER:PASSWORD@HOST:PORT/DATABASE` (PostgreSQL, shared by
    /// API replicas and worker processes on several machines).
    #[arg(long, env = "COHORTFORGE_DATABASE", default_value = "sqlite://cohortforge.db",
        value_parser = parse_database)]
    pub database: Location,

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

    /// Database of the API processes: `sqlite://FILE`, a bare file path or
    /// `postgres://USER:PASSWORD@HOST:PORT/DATABASE`.
    #[arg(long, env = "COHORTFORGE_DATABASE", default_value = "sqlite://cohortforge.db",
        value_parser = parse_database)]
    pub database: Location,

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

/// A `--database` value: `sqlite://FILE` (`sqlite:///abs/path` for an absolute path),
/// `sqlite:FILE`, a bare path, or `postgres://…`.
pub fn parse_database(value: &str) -> Result<Location, String> {
    Location::parse(value)
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
    pub fn local(database: impl Into<Location>) -> Self {
        Self {
            bind: SocketAddr::from(([127, 0, 0, 1], 0)),
            database: database.into(),
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

    /// The configuration with empty tokens taken as no token: `COHORTFORGE_READ_TOKEN=` (as a
    /// compose file's `${COHORTFORGE_READ_TOKEN:-}` sets it) means no read token, not a
    /// token too short to accept.
    pub fn without_empty_tokens(mut self) -> Self {
        for token in [&mut self.admin_token, &mut self.read_token] {
            if token.as_deref().is_some_and(str::is_empty) {
                *token = None;
            }
        }
        self
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
    use std::path::PathBuf;

    #[test]
    fn open_service_only_on_loopback() {
        let mut c = Config::local(PathBuf::from("x.db"));
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
    fn empty_tokens_are_no_tokens() {
        let mut c = Config::local(PathBuf::from("x.db"));
        c.admin_token = Some("0123456789abcdef".into());
        c.read_token = Some(String::new());
        let c = c.without_empty_tokens();
        assert_eq!(c.read_token, None);
        assert!(c.validate().is_ok());
        // An empty admin token is no token: off loopback that still needs --insecure.
        let mut open = Config::local(PathBuf::from("x.db"));
        open.bind = "0.0.0.0:8080".parse().unwrap();
        open.admin_token = Some(String::new());
        let open = open.without_empty_tokens();
        assert!(matches!(
            open.validate(),
            Err(ConfigError::OpenNonLoopback(_))
        ));
    }

    #[test]
    fn short_or_lonely_tokens_are_refused() {
        let mut c = Config::local(PathBuf::from("x.db"));
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
