//! A real server on 127.0.0.1:0 with a temporary SQLite file, and a small client.

use std::path::PathBuf;

use cohortforge::config::Config;
use cohortforge::store::Store;
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
    database: PathBuf,
    _dir: tempfile::TempDir,
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
        Self::start_on(Some(other.database_path()), |_| {}).await
    }

    async fn start_on(database: Option<PathBuf>, adjust: impl FnOnce(&mut Config)) -> Self {
        let dir = tempfile::tempdir().expect("temporary directory");
        let mut config = Config::local(database.unwrap_or_else(|| dir.path().join("test.db")));
        adjust(&mut config);
        config.validate().expect("valid test configuration");
        let config_database = config.database.clone();
        let store = Store::open(&config.database).await.expect("database opens");
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

    /// The server's SQLite file (for tests that tamper with what is stored).
    pub fn database_path(&self) -> PathBuf {
        self.database.clone()
    }

    /// Absolute URL of a path.
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
