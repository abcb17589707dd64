//! Bearer-token authorisation: an admin token may do everything, a read token only reads.

use axum::extract::{Request, State};
use axum::http::{Method, StatusCode, header};
use axum::middleware::Next;
use axum::response::Response;

use super::AppState;
use super::error::ApiError;

/// What a request's token allows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scope {
    /// Everything.
    Admin,
    /// GET and HEAD only.
    Read,
}

/// Configured tokens.
#[derive(Debug, Clone, Default)]
pub struct Tokens {
    /// Token with the admin scope.
    pub admin: Option<String>,
    /// Token with the read scope.
    pub read: Option<String>,
}

impl Tokens {
    /// Whether any token is configured (otherwise the API is open).
    pub fn enabled(&self) -> bool {
        self.admin.is_some() || self.read.is_some()
    }

    fn scope_of(&self, presented: &str) -> Option<Scope> {
        let matches = |t: &Option<String>| {
            t.as_deref()
                .is_some_and(|t| equal_in_constant_time(t, presented))
        };
        if matches(&self.admin) {
            Some(Scope::Admin)
        } else if matches(&self.read) {
            Some(Scope::Read)
        } else {
            None
        }
    }
}

/// Compares two strings without an early exit that would leak the matching prefix length.
fn equal_in_constant_time(a: &str, b: &str) -> bool {
    let (a, b) = (a.as_bytes(), b.as_bytes());
    let mut diff = (a.len() ^ b.len()) as u8 | u8::from(a.len() != b.len());
    for (i, x) in a.iter().enumerate() {
        diff |= x ^ b.get(i).copied().unwrap_or(0);
    }
    diff == 0
}

/// Middleware for `/v1`: checks the bearer token when tokens are configured.
pub async fn require_token(
    State(state): State<AppState>,
    request: Request,
    next: Next,
) -> Result<Response, ApiError> {
    if !state.tokens.enabled() {
        return Ok(next.run(request).await);
    }
    let presented = request
        .headers()
        .get(header::AUTHORIZATION)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| {
            v.strip_prefix("Bearer ")
                .or_else(|| v.strip_prefix("bearer "))
        });
    let Some(presented) = presented else {
        return Err(ApiError::new(
            StatusCode::UNAUTHORIZED,
            "auth.missing_token",
            "this endpoint needs the header Authorization: Bearer <token>",
        ));
    };
    match state.tokens.scope_of(presented.trim()) {
        None => Err(ApiError::new(
            StatusCode::UNAUTHORIZED,
            "auth.invalid_token",
            "the bearer token is not valid for this service; check the token you were given",
        )),
        Some(Scope::Read) if !matches!(*request.method(), Method::GET | Method::HEAD) => {
            Err(ApiError::new(
                StatusCode::FORBIDDEN,
                "auth.read_only",
                "the read token may only read (GET); use the admin token to change data",
            ))
        }
        Some(_) => Ok(next.run(request).await),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constant_time_comparison_is_still_equality() {
        assert!(equal_in_constant_time("abcdef", "abcdef"));
        assert!(!equal_in_constant_time("abcdef", "abcdeg"));
        assert!(!equal_in_constant_time("abcdef", "abcde"));
        assert!(!equal_in_constant_time("", "a"));
        assert!(equal_in_constant_time("", ""));
    }

    #[test]
    fn scopes_follow_tokens() {
        let tokens = Tokens {
            admin: Some("admin-token-0123456".into()),
            read: Some("read-token-01234567".into()),
        };
        assert_eq!(tokens.scope_of("admin-token-0123456"), Some(Scope::Admin));
        assert_eq!(tokens.scope_of("read-token-01234567"), Some(Scope::Read));
        assert_eq!(tokens.scope_of("nope"), None);
    }
}
