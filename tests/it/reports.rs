//! Report pages rendered in a real headless Chromium: the page loads, is self-contained and
//! shows the expected number of plots.

use std::process::Command;

use reqwest::StatusCode;

use crate::support::TestServer;

/// The browser binary: `COHORTFORGE_BROWSER`, else Debian's `chromium`.
fn browser() -> Option<String> {
    if std::env::var_os("COHORTFORGE_SKIP_BROWSER").is_some() {
        return None;
    }
    Some(std::env::var("COHORTFORGE_BROWSER").unwrap_or_else(|_| "chromium".to_owned()))
}

/// The DOM of `url` after Chromium has loaded it.
fn rendered_dom(browser: &str, url: &str) -> String {
    let output = Command::new(browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-dev-shm-usage",
            "--dump-dom",
            url,
        ])
        .output()
        .unwrap_or_else(|e| {
            panic!("cannot run {browser} ({e}): install Debian's chromium, set COHORTFORGE_BROWSER, or set COHORTFORGE_SKIP_BROWSER=1")
        });
    assert!(
        output.status.success(),
        "{browser} failed: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    String::from_utf8_lossy(&output.stdout).into_owned()
}

/// Fetches the page over HTTP, checks it is self-contained HTML, and renders it in Chromium
/// (unless skipped): returns the number of plots in the rendered page.
pub async fn plots_on_page(s: &TestServer, path: &str) -> usize {
    let response = s.client.get(s.url(path)).send().await.unwrap();
    assert_eq!(response.status(), StatusCode::OK, "{path}");
    let content_type = response.headers()["content-type"]
        .to_str()
        .unwrap()
        .to_owned();
    assert!(content_type.starts_with("text/html"), "{content_type}");
    let html = response.text().await.unwrap();
    for external in ["<script", "src=\"http", "href=\"http", "@import"] {
        assert!(!html.contains(external), "{path} loads {external}");
    }
    let served = html.matches("<svg class=\"plot\"").count();
    let Some(browser) = browser() else {
        return served;
    };
    let url = s.url(path);
    let dom = tokio::task::spawn_blocking(move || rendered_dom(&browser, &url))
        .await
        .unwrap();
    assert!(dom.contains("</html>"), "no document rendered: {dom}");
    let rendered = dom.matches("<svg class=\"plot\"").count();
    assert_eq!(rendered, served, "the browser dropped plots of {path}");
    rendered
}
