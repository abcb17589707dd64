//! Extractors whose rejections are problem+json.

use axum::extract::{FromRequest, FromRequestParts, Request};
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use utoipa::{IntoParams, ToSchema};

use super::error::ApiError;
use crate::store::Page;

/// JSON body; a malformed one becomes a 400/422 problem. A number with a zero fraction
/// (`768.0`) is read as the whole number it is wherever an integer is expected, as JSON
/// Schema counts it an integer.
pub struct Json<T>(pub T);

impl<S: Send + Sync, T: DeserializeOwned> FromRequest<S> for Json<T> {
    type Rejection = ApiError;

    async fn from_request(request: Request, state: &S) -> Result<Self, ApiError> {
        let axum::Json(value) =
            axum::Json::<serde_json::Value>::from_request(request, state).await?;
        serde_path_to_error::deserialize(whole_numbers_as_integers(value))
            .map(Json)
            .map_err(|e| {
                let path = e.path().to_string();
                let field = if path == "." { "body" } else { path.as_str() };
                ApiError::invalid_field(
                    field,
                    format!("the JSON body does not match the expected fields: {e}"),
                )
            })
    }
}

/// `value` with every finite number that has no fraction and fits an `i64` or `u64` stored as
/// an integer.
fn whole_numbers_as_integers(value: serde_json::Value) -> serde_json::Value {
    use serde_json::Value;
    match value {
        Value::Number(n) if n.is_f64() => {
            let x = n.as_f64().unwrap_or(f64::NAN);
            let whole = x.is_finite() && x.fract() == 0.0;
            if whole && x >= i64::MIN as f64 && x < i64::MAX as f64 {
                Value::from(x as i64)
            } else if whole && x >= 0.0 && x < u64::MAX as f64 {
                Value::from(x as u64)
            } else {
                Value::Number(n)
            }
        }
        Value::Array(items) => {
            Value::Array(items.into_iter().map(whole_numbers_as_integers).collect())
        }
        Value::Object(fields) => Value::Object(
            fields
                .into_iter()
                .map(|(k, v)| (k, whole_numbers_as_integers(v)))
                .collect(),
        ),
        other => other,
    }
}

impl<T: Serialize> axum::response::IntoResponse for Json<T> {
    fn into_response(self) -> axum::response::Response {
        axum::Json(self.0).into_response()
    }
}

/// Query string; an invalid one becomes a 400 problem.
#[derive(FromRequestParts)]
#[from_request(via(axum::extract::Query), rejection(ApiError))]
pub struct Query<T>(pub T);

/// Path parameters; invalid ones become a 400 problem.
#[derive(FromRequestParts)]
#[from_request(via(axum::extract::Path), rejection(ApiError))]
pub struct Path<T>(pub T);

/// Default page size of listings.
pub const DEFAULT_LIMIT: i64 = 50;
/// Largest page size of listings.
pub const MAX_LIMIT: i64 = 500;

/// Paging of a listing.
#[derive(Debug, Deserialize, IntoParams)]
#[into_params(parameter_in = Query)]
#[serde(deny_unknown_fields)]
pub struct PageQuery {
    /// Items per page (1–500, default 50).
    #[param(minimum = 1, maximum = 500)]
    pub limit: Option<i64>,
    /// Items to skip (default 0).
    #[param(minimum = 0)]
    pub offset: Option<i64>,
}

impl PageQuery {
    /// Checks the bounds and fills defaults.
    pub fn page(&self) -> Result<Page, ApiError> {
        let limit = self.limit.unwrap_or(DEFAULT_LIMIT);
        if !(1..=MAX_LIMIT).contains(&limit) {
            return Err(ApiError::invalid_field(
                "limit",
                format!("limit must be between 1 and {MAX_LIMIT}, got {limit}"),
            ));
        }
        let offset = self.offset.unwrap_or(0);
        if offset < 0 {
            return Err(ApiError::invalid_field(
                "offset",
                "offset must not be negative",
            ));
        }
        Ok(Page { limit, offset })
    }
}

/// One page of a listing.
#[derive(Debug, Serialize, ToSchema)]
pub struct Paginated<T> {
    /// The items of this page.
    pub items: Vec<T>,
    /// Items in the whole listing.
    pub total: i64,
    /// Page size used.
    pub limit: i64,
    /// Items skipped.
    pub offset: i64,
}

impl<T> Paginated<T> {
    /// Wraps a page of items.
    pub fn new(items: Vec<T>, total: i64, page: Page) -> Self {
        Self {
            items,
            total,
            limit: page.limit,
            offset: page.offset,
        }
    }
}

#[cfg(test)]
mod tests {
    use serde_json::json;

    use super::whole_numbers_as_integers;

    #[test]
    fn whole_valued_numbers_become_integers_and_fractions_stay() {
        let read = whole_numbers_as_integers(json!({
            "target_vertices": 768.0, "holdout_fraction": 0.25, "seed": 1.8e19,
            "huge": 1e300, "nested": [{"size": 3.0}]
        }));
        assert!(read["target_vertices"].is_i64());
        assert_eq!(read["target_vertices"], json!(768));
        assert_eq!(read["holdout_fraction"], json!(0.25));
        assert!(read["seed"].is_u64());
        assert!(read["huge"].is_f64());
        assert_eq!(read["nested"][0]["size"], json!(3));
        let cohort: crate::jobs::cohort::CohortRequest = serde_json::from_value(
            whole_numbers_as_integers(json!({"size": 10.0, "seed": 7.0})),
        )
        .unwrap();
        assert_eq!((cohort.size, cohort.seed), (10, 7));
    }
}
