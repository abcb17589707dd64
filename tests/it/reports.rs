//! Report pages rendered in a real headless Chromium: the page loads, is self-contained and
//! shows the expected number of plots; each plot alone, as SVG and PNG.

use std::process::Command;

use cohortforge::report::svg::{HEIGHT, WIDTH};
use reqwest::StatusCode;

use crate::support::{TestServer, expect_problem};

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

/// The page at `path` as Chromium rendered it (as served when the browser is skipped).
pub async fn rendered_page(s: &TestServer, path: &str) -> String {
    let response = s.client.get(s.url(path)).send().await.unwrap();
    assert_eq!(response.status(), StatusCode::OK, "{path}");
    let served = response.text().await.unwrap();
    let Some(browser) = browser() else {
        return served;
    };
    let url = s.url(path);
    tokio::task::spawn_blocking(move || rendered_dom(&browser, &url))
        .await
        .unwrap()
}

/// GETs `path`, asserts a 200 with `content_type`, returns the body.
async fn fetch(s: &TestServer, path: &str, content_type: &str) -> Vec<u8> {
    let response = s.client.get(s.url(path)).send().await.unwrap();
    let status = response.status();
    let got = response.headers()["content-type"]
        .to_str()
        .unwrap()
        .to_owned();
    let body = response.bytes().await.unwrap().to_vec();
    assert_eq!(
        status,
        StatusCode::OK,
        "{path}: {}",
        String::from_utf8_lossy(&body)
    );
    assert_eq!(got, content_type, "{path}");
    body
}

/// The single-plot URL of `name` beside the report page `page`.
fn plot_path(page: &str, name: &str) -> String {
    format!("{}plots/{name}", page.trim_end_matches("report.html"))
}

/// The plot `name` of the report page `page`, alone: as SVG it is the very plot the page
/// shows (and links to), as PNG a PNG of the plot's size.
pub async fn check_single_plot(s: &TestServer, page: &str, name: &str) {
    let path = plot_path(page, name);
    let svg = String::from_utf8(fetch(s, &path, "image/svg+xml").await).unwrap();
    assert!(svg.starts_with("<svg class=\"plot\" xmlns=") && svg.ends_with("</svg>"));
    let html = s.client.get(s.url(page)).send().await.unwrap();
    let html = html.text().await.unwrap();
    assert!(html.contains(&svg), "{path} is not the plot on {page}");
    assert!(html.contains(&format!("href=\"plots/{name}?format=png\"")));
    for format in ["png", "PNG"] {
        let png = fetch(s, &format!("{path}?format={format}"), "image/png").await;
        assert_eq!(
            png[..8],
            [0x89, b'P', b'N', b'G', b'\r', b'\n', 0x1a, b'\n']
        );
        let be = |at: usize| u32::from_be_bytes(png[at..at + 4].try_into().unwrap());
        assert_eq!(
            (&png[12..16], be(16), be(20)),
            (&b"IHDR"[..], WIDTH as u32, HEIGHT as u32)
        );
    }
}

/// The errors of the single plots beside `page`: an unknown name is a 404 listing the
/// names (among them `available`), a bad format a 400, and `absent` (a plot of a kind this
/// model lacks) a 404 saying so.
pub async fn check_plot_errors(s: &TestServer, page: &str, available: &str, absent: Option<&str>) {
    let get = |path: String| async move { s.client.get(s.url(&path)).send().await.unwrap() };
    let unknown = get(plot_path(page, "no_such_plot")).await;
    let problem = expect_problem(unknown, StatusCode::NOT_FOUND, "plot.not_found").await;
    let names = problem["available"].as_array().unwrap();
    assert!(names.iter().any(|n| n == available), "{problem}");
    assert!(problem["detail"].as_str().unwrap().contains(available));
    let bad = get(format!("{}?format=gif", plot_path(page, available))).await;
    let problem = expect_problem(bad, StatusCode::BAD_REQUEST, "plot.unsupported_format").await;
    assert_eq!(problem["field"], "format");
    if let Some(absent) = absent {
        let missing = get(plot_path(page, absent)).await;
        let problem = expect_problem(missing, StatusCode::NOT_FOUND, "plot.not_available").await;
        assert!(!names.iter().any(|n| n == absent), "{problem}");
    }
}
