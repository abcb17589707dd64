//! Error responses that whole classes of operations share, declared once in the OpenAPI
//! document instead of on every handler: the bearer token on `/v1` (401, and 403 for a
//! read-only token on writes), unreadable paths, queries, headers and bodies (400), invalid
//! fields (422) and bodies that are too large or of a type the operation does not take
//! (413, 415). The probes outside `/v1` are declared as needing no token.

use utoipa::openapi::path::{Operation, ParameterIn};
use utoipa::openapi::{Content, OpenApi, Ref, RefOr, ResponseBuilder};

/// Declares the shared error responses on every operation of `spec` that can give them,
/// keeping any response a handler already documents.
pub fn declare_common_responses(spec: &mut OpenApi) {
    for (path, item) in spec.paths.paths.iter_mut() {
        let versioned = path.starts_with("/v1/");
        let operations = [
            (&mut item.get, false),
            (&mut item.put, true),
            (&mut item.post, true),
            (&mut item.delete, true),
            (&mut item.patch, true),
        ];
        for (operation, writes) in operations {
            if let Some(operation) = operation.as_mut() {
                declare_in_operation(operation, versioned, writes);
            }
        }
    }
}

fn declare_in_operation(operation: &mut Operation, versioned: bool, writes: bool) {
    if !versioned {
        // The probes answer without a token, whatever the document's default security.
        operation.security = Some(Vec::new());
        return;
    }
    add(
        operation,
        "401",
        "No bearer token, or an unknown one (`auth.missing_token`, `auth.invalid_token`)",
    );
    if writes {
        add(
            operation,
            "403",
            "The token may only read (`auth.read_only`)",
        );
    }
    let parameters: Vec<ParameterIn> = operation
        .parameters
        .iter()
        .flatten()
        .filter_map(|p| match p {
            RefOr::T(p) => Some(p.parameter_in.clone()),
            RefOr::Ref(_) => None,
        })
        .collect();
    let takes_mesh_format = operation.parameters.iter().flatten().any(|p| {
        matches!(p, RefOr::T(p) if p.name == "format"
            && serde_json::to_string(&p.schema)
                .is_ok_and(|s| s.contains(r#"["obj","stl","ply","vtk"]"#)))
    });
    if takes_mesh_format {
        add(
            operation,
            "415",
            "`format` is not a mesh format (`mesh.unsupported_format`)",
        );
    }
    let has_body = operation.request_body.is_some();
    if has_body || !parameters.is_empty() {
        add(
            operation,
            "400",
            "The path, query, headers or body could not be read (`request.invalid_path`, \
             `request.invalid_query`, `request.invalid_header`, `request.malformed_json`, \
             `request.unreadable_body`, …)",
        );
    }
    let has_query = parameters.iter().any(|p| matches!(p, ParameterIn::Query));
    if has_body || has_query {
        add(
            operation,
            "422",
            "A field is missing, out of range or inconsistent (`request.invalid_field`, …)",
        );
    }
    if has_body {
        add(
            operation,
            "413",
            "The body is larger than the service accepts (`request.body_too_large`)",
        );
        add(
            operation,
            "415",
            "The body's Content-Type is not one this operation takes \
             (`request.unsupported_media_type`, …)",
        );
    }
}

/// Adds a problem+json response for `status` unless the operation documents one already.
fn add(operation: &mut Operation, status: &str, description: &str) {
    operation
        .responses
        .responses
        .entry(status.to_owned())
        .or_insert_with(|| {
            RefOr::T(
                ResponseBuilder::new()
                    .description(description)
                    .content(
                        "application/problem+json",
                        Content::new(Some(Ref::from_schema_name("Problem"))),
                    )
                    .build(),
            )
        });
}

#[cfg(test)]
mod tests {
    fn statuses(spec: &serde_json::Value, path: &str, method: &str) -> Vec<String> {
        let mut s: Vec<String> = spec["paths"][path][method]["responses"]
            .as_object()
            .unwrap_or_else(|| panic!("{method} {path} has responses"))
            .keys()
            .cloned()
            .collect();
        s.sort();
        s
    }

    #[test]
    fn every_operation_documents_the_errors_it_can_give() {
        let spec = serde_json::to_value(crate::api::openapi()).unwrap();
        // A write with a body: token, read-only, unreadable, invalid, too large, wrong type.
        let jobs = statuses(&spec, "/v1/jobs", "post");
        for status in ["400", "401", "403", "413", "415", "422"] {
            assert!(jobs.contains(&status.to_owned()), "POST /v1/jobs: {jobs:?}");
        }
        // A read with a query: no 403 and no body errors.
        let list = statuses(&spec, "/v1/models", "get");
        assert!(list.contains(&"401".to_owned()) && list.contains(&"400".to_owned()));
        assert!(!list.contains(&"403".to_owned()) && !list.contains(&"413".to_owned()));
        // Probes need no token.
        assert_eq!(
            spec["paths"]["/healthz"]["get"]["security"],
            serde_json::json!([])
        );
        assert!(!statuses(&spec, "/healthz", "get").contains(&"401".to_owned()));
    }
}
