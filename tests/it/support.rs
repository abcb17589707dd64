//! A real server on 127.0.0.1:0 with a temporary database, and a small client.
//!
//! The database is a temporary SQLite file, or, when `COHORTFORGE_TEST_POSTGRES` names a
//! PostgreSQL server (`postgres://USER@HOST:PORT`, no database), a new database on it for
//! every server: the whole suite then runs against PostgreSQL.

use std::path::PathBuf;

use cohortforge::config::Config;
use cohortforge::store::{Location, Store};
use reqwest::{Response, StatusCode};
use serde_json::Value;
use tokio_util::sync::CancellationToken;

/// A running service and a client for it.
pub struct TestServer {
    /// `http://127.0.0.1:<port>`.
    pub base: String,
    /// HTTP client.
    pub client: reqwest::Client,
    /// The store the server uses, for checks behind the API.
    pub store: Store,
    shutdown: CancellationToken,
    database: Location,
    _dir: tempfile::TempDir,
}

/// The PostgreSQL server the suite runs against, if any (`COHORTFORGE_TEST_POSTGRES`).
pub fn test_postgres() -> Option<String> {
    std::env::var("COHORTFORGE_TEST_POSTGRES")
        .ok()
        .filter(|url| !url.is_empty())
        .map(|url| url.trim_end_matches('/').to_owned())
}

/// A new empty database: a PostgreSQL database when the suite runs against PostgreSQL, a
/// SQLite file in `dir` otherwise.
pub async fn fresh_database(dir: &std::path::Path) -> Location {
    let Some(server) = test_postgres() else {
        return Location::Sqlite(dir.join("test.db"));
    };
    let name = format!("cf_test_{}", uuid::Uuid::new_v4().simple());
    let admin = format!("{server}/postgres");
    sqlx::any::install_default_drivers();
    let mut conn = <sqlx::AnyConnection as sqlx::Connection>::connect(&admin)
        .await
        .unwrap_or_else(|e| panic!("COHORTFORGE_TEST_POSTGRES={server} does not answer: {e}"));
    sqlx::query(sqlx::AssertSqlSafe(format!("CREATE DATABASE {name}")))
        .execute(&mut conn)
        .await
        .expect("a test database is created");
    Location::Postgres(format!("{server}/{name}"))
}

impl TestServer {
    /// Starts a server with the default local configuration.
    pub async fn start() -> Self {
        Self::start_with(|_| {}).await
    }

    /// Starts a server after adjusting the configuration.
    pub async fn start_with(adjust: impl FnOnce(&mut Config)) -> Self {
        Self::start_on(None, adjust).await
    }

    /// A second server on `other`'s database file, as an API replica in another process
    /// would be: its own connections, the same data.
    pub async fn sharing(other: &TestServer) -> Self {
        Self::start_on(Some(other.database.clone()), |_| {}).await
    }

    async fn start_on(database: Option<Location>, adjust: impl FnOnce(&mut Config)) -> Self {
        let dir = tempfile::tempdir().expect("temporary directory");
        let database = match database {
            Some(database) => database,
            None => fresh_database(dir.path()).await,
        };
        let mut config = Config::local(database);
        adjust(&mut config);
        config.validate().expect("valid test configuration");
        let config_database = config.database.clone();
        let store = Store::connect(&config.database)
            .await
            .expect("database opens");
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0")
            .await
            .expect("bind");
        let base = format!("http://{}", listener.local_addr().expect("address"));
        let shutdown = CancellationToken::new();
        let (server_store, server_shutdown) = (store.clone(), shutdown.clone());
        tokio::spawn(async move {
            cohortforge::api::run(listener, &config, server_store, server_shutdown)
                .await
                .expect("server runs");
        });
        Self {
            base,
            client: reqwest::Client::new(),
            store,
            shutdown,
            database: config_database,
            _dir: dir,
        }
    }

    /// The server's database as a `--database` value (for other processes, and for tests
    /// that tamper with what is stored).
    pub fn database_url(&self) -> String {
        match &self.database {
            Location::Sqlite(path) => format!("sqlite://{}", path.display()),
            Location::Postgres(url) => url.clone(),
        }
    }

    /// A connection to the server's database through sqlx's `Any` driver (`$N`
    /// placeholders work on both databases).
    pub async fn database_pool(&self) -> sqlx::AnyPool {
        sqlx::any::install_default_drivers();
        sqlx::AnyPool::connect(&self.database_url())
            .await
            .expect("the test database opens")
    }

    /// Absolute URL of a path.
    /// The body of a successful GET of `url` (a full URL, as [`Self::url`] makes).
    pub async fn get_bytes(&self, url: String) -> bytes::Bytes {
        let response = self.client.get(url).send().await.expect("request");
        assert!(response.status().is_success(), "{}", response.status());
        response.bytes().await.expect("body")
    }

    pub fn url(&self, path: &str) -> String {
        format!("{}{}", self.base, path)
    }

    /// Creates a dataset and returns its id.
    pub async fn dataset(&self, name: &str, organ: &str) -> String {
        let response = self
            .client
            .post(self.url("/v1/datasets"))
            .json(&serde_json::json!({"name": name, "organ": organ}))
            .send()
            .await
            .expect("request");
        let body = expect_json(response, StatusCode::CREATED).await;
        body["id"].as_str().expect("id").to_owned()
    }

    /// Uploads one raw mesh file with `?format=` and returns the response.
    pub async fn upload(&self, dataset: &str, format: &str, bytes: Vec<u8>) -> Response {
        self.client
            .post(self.url(&format!("/v1/datasets/{dataset}/meshes?format={format}")))
            .body(bytes)
            .send()
            .await
            .expect("request")
    }

    /// Number of meshes in a dataset, read through the API.
    pub async fn mesh_count(&self, dataset: &str) -> i64 {
        let response = self
            .client
            .get(self.url(&format!("/v1/datasets/{dataset}")))
            .send()
            .await
            .expect("request");
        expect_json(response, StatusCode::OK).await["mesh_count"]
            .as_i64()
            .expect("mesh_count")
    }
}

impl Drop for TestServer {
    fn drop(&mut self) {
        self.shutdown.cancel();
    }
}

/// Asserts the status and returns the JSON body.
pub async fn expect_json(response: Response, status: StatusCode) -> Value {
    let got = response.status();
    let text = response.text().await.expect("body");
    assert_eq!(got, status, "unexpected status; body: {text}");
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("body is not JSON ({e}): {text}"))
}

/// Asserts a problem+json response with the given status and code; returns the body.
pub async fn expect_problem(response: Response, status: StatusCode, code: &str) -> Value {
    let content_type = response
        .headers()
        .get("content-type")
        .and_then(|v| v.to_str().ok())
        .unwrap_or_default()
        .to_owned();
    let body = expect_json(response, status).await;
    assert_eq!(content_type, "application/problem+json", "body: {body}");
    assert_eq!(body["code"], code, "body: {body}");
    assert_eq!(body["status"], status.as_u16(), "body: {body}");
    for field in ["type", "title", "detail"] {
        assert!(
            body[field].as_str().is_some_and(|s| !s.is_empty()),
            "no {field}: {body}"
        );
    }
    body
}

/// The crate's root directory.
pub fn crate_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}
