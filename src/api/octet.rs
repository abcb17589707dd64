//! Binary bodies as `application/octet-stream`, for generated clients that know no mesh or
//! image media types: a download answers in that type when the request's `Accept` prefers it,
//! and the OpenAPI document declares it beside every binary type of a download or an upload.

use axum::extract::Request;
use axum::http::{HeaderMap, HeaderValue, header};
use axum::middleware::Next;
use axum::response::Response;
use utoipa::openapi::path::Operation;
use utoipa::openapi::{OpenApi, RefOr};

/// The generic binary media type.
pub const OCTET_STREAM: &str = "application/octet-stream";

/// Media types of the files the service sends and receives.
const BINARY_TYPES: [&str; 9] = [
    "model/obj",
    "model/stl",
    "application/x-ply",
    "application/vnd.vtk",
    "application/x-nifti",
    "application/gzip",
    "application/zip",
    "image/png",
    "image/svg+xml",
];

fn is_binary(content_type: &str) -> bool {
    let essence = content_type.split(';').next().unwrap_or("").trim();
    BINARY_TYPES.iter().any(|t| t.eq_ignore_ascii_case(essence))
}

/// The quality an `Accept` header gives `media_type` (its most specific matching range;
/// 0 when none matches). No header accepts everything.
fn quality(headers: &HeaderMap, media_type: &str) -> f32 {
    let ranges: Vec<&str> = headers
        .get_all(header::ACCEPT)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .flat_map(|v| v.split(','))
        .collect();
    if ranges.is_empty() {
        return 1.0;
    }
    let (kind, _) = media_type.split_once('/').unwrap_or((media_type, ""));
    let mut best: Option<(u8, f32)> = None;
    for range in ranges {
        let mut parts = range.split(';');
        let name = parts.next().unwrap_or("").trim().to_ascii_lowercase();
        let q = parts
            .filter_map(|p| p.trim().strip_prefix("q="))
            .find_map(|q| q.trim().parse::<f32>().ok())
            .unwrap_or(1.0);
        let specificity = if name.eq_ignore_ascii_case(media_type) {
            3
        } else if name == format!("{kind}/*") {
            2
        } else if name == "*/*" {
            1
        } else {
            continue;
        };
        if best.is_none_or(|(s, _)| specificity > s) {
            best = Some((specificity, q));
        }
    }
    best.map_or(0.0, |(_, q)| q)
}

/// Middleware: a successful binary response is sent as `application/octet-stream` when the
/// request's `Accept` header ranks that type above the response's own.
pub async fn octet_stream_when_preferred(request: Request, next: Next) -> Response {
    let accept = request.headers().clone();
    let mut response = next.run(request).await;
    let native = response
        .headers()
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .filter(|c| is_binary(c))
        .map(str::to_owned);
    if let Some(native) = native
        && response.status().is_success()
        && quality(&accept, OCTET_STREAM) > quality(&accept, &native)
    {
        response
            .headers_mut()
            .insert(header::CONTENT_TYPE, HeaderValue::from_static(OCTET_STREAM));
    }
    response
}

/// Declares `application/octet-stream` beside every binary type of the document's request
/// bodies and successful responses.
pub fn declare_octet_stream(spec: &mut OpenApi) {
    for item in spec.paths.paths.values_mut() {
        let operations = [
            &mut item.get,
            &mut item.put,
            &mut item.post,
            &mut item.delete,
            &mut item.patch,
        ];
        for operation in operations.into_iter().flatten() {
            declare_in_operation(operation);
        }
    }
}

fn declare_in_operation(operation: &mut Operation) {
    if let Some(RefOr::T(body)) = &mut operation.request_body
        && let Some(content) = body
            .content
            .iter()
            .find(|(media, _)| is_binary(media))
            .map(|(_, c)| c.clone())
    {
        body.content.insert(OCTET_STREAM.to_owned(), content);
    }
    for (status, response) in &mut operation.responses.responses {
        if !status.starts_with('2') {
            continue;
        }
        let RefOr::T(response) = response else {
            continue;
        };
        if let Some(content) = response
            .content
            .iter()
            .find(|(media, _)| is_binary(media))
            .map(|(_, c)| c.clone())
        {
            response.content.insert(OCTET_STREAM.to_owned(), content);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn accept(value: &str) -> HeaderMap {
        let mut headers = HeaderMap::new();
        headers.insert(header::ACCEPT, HeaderValue::from_str(value).unwrap());
        headers
    }

    #[test]
    fn octet_stream_wins_only_when_ranked_higher() {
        let only = accept("application/octet-stream");
        assert!(quality(&only, OCTET_STREAM) > quality(&only, "model/obj"));
        let both = accept("model/obj, application/octet-stream");
        assert!(quality(&both, OCTET_STREAM) <= quality(&both, "model/obj"));
        let browser = accept("text/html,application/xhtml+xml,*/*;q=0.8");
        assert!(quality(&browser, OCTET_STREAM) <= quality(&browser, "image/png"));
        let lower = accept("image/*;q=0.5, application/octet-stream");
        assert!(quality(&lower, OCTET_STREAM) > quality(&lower, "image/png"));
        assert_eq!(quality(&HeaderMap::new(), "model/stl"), 1.0);
    }

    #[test]
    fn binary_types_ignore_parameters_and_case() {
        assert!(is_binary("Model/OBJ"));
        assert!(is_binary("image/png; charset=binary"));
        assert!(!is_binary("application/json"));
        assert!(!is_binary("text/csv"));
    }
}
