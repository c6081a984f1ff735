//! Request input with every bound checked: [`Query`] (a typed query string; the types deny
//! unknown parameters), [`read_body`] (a body within the size limit, the connection's time
//! limits and the in-flight byte budget) and [`Json`] (a JSON body read that way). Rejections
//! are problem documents.

use std::sync::Arc;

use axum::body::Body;
use axum::extract::{FromRequest, FromRequestParts, Request};
use axum::http::request::Parts;
use axum::http::{HeaderMap, header};
use bytes::Bytes;
use futures_util::StreamExt;
use serde::de::DeserializeOwned;

use super::App;
use super::problem::Problem;
use crate::app::memory::MemoryPermit;
use crate::app::{Error, ErrorKind, Result};

/// A query string deserialized into `T` (`#[serde(deny_unknown_fields)]` types refuse unknown
/// parameters); a malformed one is an `invalid-parameter` problem naming the parameter, the
/// value given and what is accepted ([`parse_query`]).
pub struct Query<T>(pub T);

impl<T: DeserializeOwned, S: Send + Sync> FromRequestParts<S> for Query<T> {
    type Rejection = Problem;

    async fn from_request_parts(parts: &mut Parts, _: &S) -> Result<Self, Problem> {
        parse_query(parts.uri.query().unwrap_or(""))
            .map(Query)
            .map_err(Problem::from)
    }
}

/// Deserializes a query string into `T`; an error names the parameter it is in, with the value
/// given, and says what is accepted.
pub fn parse_query<T: DeserializeOwned>(q: &str) -> Result<T> {
    let de = serde_urlencoded::Deserializer::new(form_urlencoded::parse(q.as_bytes()));
    serde_path_to_error::deserialize(de).map_err(|e| {
        let param = e.path().to_string();
        Error::invalid(query_error(q, &param, &e.into_inner().to_string()))
    })
}

/// The detail of a query parse error `inner` in parameter `param` (`.` when the error is not in
/// one parameter: an unknown or missing one, which serde's message names).
fn query_error(q: &str, param: &str, inner: &str) -> String {
    let given = form_urlencoded::parse(q.as_bytes())
        .filter(|(k, _)| k == param)
        .last()
        .map(|(_, v)| v.into_owned());
    let Some(given) = given else {
        return format!("query string: {inner}");
    };
    // serde_urlencoded parses numbers with `FromStr`: its messages say neither the parameter
    // nor what is expected.
    let expected = match inner {
        "invalid digit found in string"
        | "cannot parse integer from empty string"
        | "number too large to fit in target type"
        | "number too small to fit in target type" => {
            format!("expected a whole number of at least 0 ({inner})")
        }
        "invalid float literal" | "cannot parse float from empty string" => {
            "expected a number".to_string()
        }
        other => other.to_string(),
    };
    format!("query parameter {param}={given:?}: {expected}")
}
/// A request body in memory, with its share of the process-wide memory budget (released on
/// drop).
pub struct BodyBytes {
    pub bytes: Bytes,
    _permits: Vec<MemoryPermit>,
}

/// Bytes a body of unknown length (chunked) holds of the budget before its first chunk; it
/// asks for more in doubling steps as it grows.
const FIRST_CHUNKED_HOLD: u64 = 64 << 10;

/// Reads a body within `limit` bytes and the connection limits. Its memory is held of the
/// process-wide budget before it is read: a declared `Content-Length` at once, a chunked body in
/// doubling steps. Waiting for the budget is at most the body timeout and then `busy` (503,
/// `Retry-After`), never charged to the client: the body's rate clock starts once the budget is
/// held, and stops while a chunked body waits for its next step. Each chunk must come within
/// the idle timeout, and the average rate after the grace period must be at least the minimum.
/// A declared `Content-Length` over the limit is refused before anything is read.
pub async fn read_body(
    app: &App,
    headers: &HeaderMap,
    body: Body,
    limit: usize,
) -> Result<BodyBytes> {
    read_body_as(app, headers, body, limit, "request body").await
}

/// [`read_body`], with `what` the body is named in a refusal ("JSON body").
async fn read_body_as(
    app: &App,
    headers: &HeaderMap,
    body: Body,
    limit: usize,
    what: &str,
) -> Result<BodyBytes> {
    let http = &app.http;
    let too_large = || {
        Error::new(
            ErrorKind::BodyTooLarge,
            format!("the {what} is larger than {limit} bytes"),
        )
    };
    let declared = headers
        .get(header::CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.parse::<u64>().ok());
    if declared.is_some_and(|n| n > limit as u64) {
        return Err(too_large());
    }
    let what = format!("this {what}");
    let wait = http.body_idle_timeout;
    let first = declared.unwrap_or(FIRST_CHUNKED_HOLD.min(limit as u64));
    let mut permits = vec![app.memory.admit(first, &what, wait).await?];
    let mut held = first;
    // The rate clock starts now that the budget is held.
    let mut start = tokio::time::Instant::now();
    let mut body = body.into_data_stream();
    let mut buf = Vec::with_capacity(declared.unwrap_or(0).min(limit as u64) as usize);
    loop {
        let next = tokio::time::timeout(http.body_idle_timeout, body.next())
            .await
            .map_err(|_| {
                Error::new(
                    ErrorKind::Timeout,
                    format!(
                        "the request body paused for more than {} s",
                        http.body_idle_timeout.as_secs_f64()
                    ),
                )
            })?;
        let Some(chunk) = next else { break };
        let chunk = chunk.map_err(|e| Error::invalid(format!("reading the request body: {e}")))?;
        let want = (buf.len() + chunk.len()) as u64;
        if want > limit as u64 {
            return Err(too_large());
        }
        if want > held {
            // A declared length that was too short, or a chunked body: double what is held.
            let more = want.max(held.saturating_mul(2)).min(limit as u64) - held;
            let waited = tokio::time::Instant::now();
            permits.push(app.memory.admit(more, &what, wait).await?);
            held += more;
            start += waited.elapsed();
        }
        buf.extend_from_slice(&chunk);
        let t = start.elapsed();
        if t > http.body_grace {
            let due = http.min_body_rate as f64 * (t - http.body_grace).as_secs_f64();
            if (buf.len() as f64) < due {
                return Err(Error::new(
                    ErrorKind::Timeout,
                    format!(
                        "the request body arrives slower than {} bytes/s",
                        http.min_body_rate
                    ),
                ));
            }
        }
    }
    Ok(BodyBytes {
        bytes: Bytes::from(buf),
        _permits: permits,
    })
}

/// Refuses a `Content-Encoding` the handler cannot decode: only `identity`, and `gzip` where
/// `gzip_ok` (mesh uploads, which are inflated by the loader).
pub fn check_content_encoding(headers: &HeaderMap, gzip_ok: bool) -> Result<bool> {
    let Some(v) = headers.get(header::CONTENT_ENCODING) else {
        return Ok(false);
    };
    let v = v.to_str().unwrap_or("").trim().to_ascii_lowercase();
    match v.as_str() {
        "" | "identity" => Ok(false),
        "gzip" | "x-gzip" if gzip_ok => Ok(true),
        other => Err(Error::new(
            ErrorKind::UnsupportedMediaType,
            format!(
                "Content-Encoding {other:?} is not accepted here; send {}",
                if gzip_ok {
                    "identity or gzip"
                } else {
                    "identity"
                }
            ),
        )),
    }
}

/// A JSON body deserialized into `T`, read within its own small limit (`--max-json-bytes`,
/// checked while reading: a larger body is refused before any of it is parsed) and the
/// connection limits. Parsing holds [`JSON_TREE_FACTOR`] times the body of the memory budget.
pub struct Json<T>(pub T);

impl<T: DeserializeOwned> FromRequest<Arc<App>> for Json<T> {
    type Rejection = Problem;

    async fn from_request(req: Request, app: &Arc<App>) -> Result<Self, Problem> {
        let (parts, body) = req.into_parts();
        check_content_encoding(&parts.headers, false)?;
        let limit = app.limits.max_json_bytes;
        let body = read_body_as(app, &parts.headers, body, limit, "JSON body")
            .await
            .map_err(|e| match e.kind {
                ErrorKind::BodyTooLarge => Error::new(
                    e.kind,
                    format!("{} (--max-json-bytes); it was not parsed", e.detail),
                ),
                _ => e,
            })?;
        let _tree = app
            .admit(
                JSON_TREE_FACTOR * body.bytes.len() as u64,
                "parsing this JSON body",
            )
            .await?;
        let mut de = serde_json::Deserializer::from_slice(&body.bytes);
        serde_path_to_error::deserialize(&mut de)
            .map(Json)
            .map_err(|e| {
                let at = match e.path().to_string() {
                    p if p == "." => String::new(),
                    p => format!(" (at {p})"),
                };
                Problem::invalid(format!(
                    "the body is not the JSON expected{at}: {}",
                    e.into_inner()
                ))
            })
    }
}

/// Bytes a parsed JSON document may take per byte of its text, at most (a generic tree of
/// small values: ~17× measured for a CSG expression).
pub const JSON_TREE_FACTOR: u64 = 20;

/// Deserializes `X,Y,Z` query values.
pub mod triple {
    use serde::{Deserialize, Deserializer};

    pub fn deserialize<'de, D, T>(d: D) -> Result<Option<[T; 3]>, D::Error>
    where
        D: Deserializer<'de>,
        T: std::str::FromStr,
    {
        let s = Option::<String>::deserialize(d)?;
        s.map(|s| crate::names::parse_triple(&s).map_err(serde::de::Error::custom))
            .transpose()
    }
}

/// Deserializes a boolean query value: `true`, `false`, `1` or `0` in any case (Python's
/// requests sends `True`). Use with `#[serde(default, deserialize_with = "flag::deserialize")]`.
pub mod flag {
    use serde::{Deserialize, Deserializer};

    /// What a boolean query value may be.
    pub const ACCEPTED: &str = "expected true, false, 1 or 0 (in any case)";

    pub fn parse(s: &str) -> Option<bool> {
        match s.trim().to_ascii_lowercase().as_str() {
            "true" | "1" => Some(true),
            "false" | "0" => Some(false),
            _ => None,
        }
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<bool, D::Error> {
        let s = <std::borrow::Cow<'de, str>>::deserialize(d)?;
        parse(&s).ok_or_else(|| serde::de::Error::custom(ACCEPTED))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct Q {
        #[serde(default, deserialize_with = "flag::deserialize")]
        cubic: bool,
        n: Option<u32>,
        x: Option<f64>,
    }

    fn detail(q: &str) -> String {
        parse_query::<Q>(q).unwrap_err().detail
    }

    #[test]
    fn booleans_take_true_false_1_0_in_any_case() {
        for (s, want) in [
            ("True", true),
            ("TRUE", true),
            ("1", true),
            ("fAlse", false),
            ("0", false),
        ] {
            assert_eq!(
                parse_query::<Q>(&format!("cubic={s}")).unwrap().cubic,
                want,
                "{s}"
            );
        }
        assert!(!parse_query::<Q>("").unwrap().cubic);
        assert_eq!(
            detail("cubic=yes"),
            "query parameter cubic=\"yes\": expected true, false, 1 or 0 (in any case)"
        );
    }

    #[test]
    fn parse_errors_name_the_parameter_and_the_value() {
        assert_eq!(
            detail("n=4&x=big"),
            "query parameter x=\"big\": expected a number"
        );
        assert_eq!(
            detail("n=-1"),
            "query parameter n=\"-1\": expected a whole number of at least 0 (invalid digit found in string)"
        );
        let d = detail("m=1");
        assert!(
            d.contains("unknown field `m`") && d.contains("`cubic`"),
            "{d}"
        );
    }
}
