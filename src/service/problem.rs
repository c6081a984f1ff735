//! Errors as RFC 9457 problem documents (`application/problem+json`): a problem's `type` is
//! [`TYPE_BASE`] + the kind's code, its status and title the kind's own (all from the one table
//! of kinds in `app/error.rs`; the list is also in `openapi.yaml`, components/schemas/Problem,
//! checked by `tests/openapi_enums.rs`). Handlers return `Result<_, Problem>` and use `?` on
//! application errors, which convert by `From`. Not here: which error is which kind.

use axum::http::{HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde::{Deserialize, Serialize};

use crate::app::{Error, ErrorKind};

/// Base of every problem `type`.
pub const TYPE_BASE: &str = "https://voxd.dev/problems/";

/// A problem document.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Problem {
    #[serde(rename = "type")]
    pub type_: String,
    pub title: String,
    pub status: u16,
    pub detail: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub instance: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub request_id: Option<String>,
    /// Seconds to wait before retrying (queue-full), sent as `Retry-After`.
    #[serde(skip)]
    pub retry_after: Option<u64>,
}

impl Problem {
    pub fn new(kind: ErrorKind, detail: impl Into<String>) -> Problem {
        Problem {
            type_: format!("{TYPE_BASE}{}", kind.code()),
            title: kind.title().into(),
            status: kind.status(),
            detail: detail.into(),
            instance: None,
            request_id: None,
            retry_after: None,
        }
    }

    pub fn invalid(detail: impl Into<String>) -> Problem {
        Problem::new(ErrorKind::InvalidParameter, detail)
    }
}

impl From<Error> for Problem {
    fn from(e: Error) -> Problem {
        let mut p = Problem::new(e.kind, e.detail);
        p.retry_after = e.retry_after;
        p
    }
}

impl IntoResponse for Problem {
    fn into_response(self) -> Response {
        let status = StatusCode::from_u16(self.status).unwrap_or(StatusCode::INTERNAL_SERVER_ERROR);
        let retry = self.retry_after;
        let mut r = (status, serde_json::to_vec(&self).unwrap_or_default()).into_response();
        r.headers_mut().insert(
            header::CONTENT_TYPE,
            HeaderValue::from_static("application/problem+json"),
        );
        if let Some(s) = retry {
            r.headers_mut()
                .insert(header::RETRY_AFTER, HeaderValue::from(s));
        }
        r
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every kind's status is one HTTP knows, so no problem goes out as a bare 500 by accident.
    #[test]
    fn every_status_is_a_valid_http_status() {
        for k in ErrorKind::ALL {
            let p = Problem::new(k, "d");
            assert_eq!(p.type_, format!("https://voxd.dev/problems/{}", k.code()));
            let r = p.into_response();
            assert_eq!(r.status().as_u16(), k.status(), "{k:?}");
            assert!(r.status().is_client_error() || r.status().is_server_error());
        }
    }
}
