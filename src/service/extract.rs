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
use tokio::sync::OwnedSemaphorePermit;

use super::App;
use super::problem::Problem;
use crate::app::{Error, ErrorKind, Result};

/// A query string deserialized into `T` (`#[serde(deny_unknown_fields)]` types refuse unknown
/// parameters); a malformed one is an `invalid-parameter` problem naming the parameter.
pub struct Query<T>(pub T);

impl<T: DeserializeOwned, S: Send + Sync> FromRequestParts<S> for Query<T> {
    type Rejection = Problem;

    async fn from_request_parts(parts: &mut Parts, _: &S) -> Result<Self, Problem> {
        let q = parts.uri.query().unwrap_or("");
        serde_urlencoded::from_str(q)
            .map(Query)
            .map_err(|e| Problem::invalid(format!("query string: {e}")))
    }
}

/// A request body in memory, with its share of the in-flight byte budget (released on drop).
pub struct BodyBytes {
    pub bytes: Bytes,
    _permits: Vec<OwnedSemaphorePermit>,
}

/// Reads a body within `limit` bytes and the connection limits: each chunk must come within
/// the idle timeout, the average rate after the grace period must be at least the minimum, and
/// the bytes count against the budget of bodies in flight over all requests. A declared
/// `Content-Length` over the limit is refused before anything is read.
pub async fn read_body(
    app: &App,
    headers: &HeaderMap,
    body: Body,
    limit: usize,
) -> Result<BodyBytes> {
    let http = &app.http;
    let too_large = || {
        Error::new(
            ErrorKind::BodyTooLarge,
            format!("the request body is larger than {limit} bytes"),
        )
    };
    let declared = headers
        .get(header::CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.parse::<u64>().ok());
    if declared.is_some_and(|n| n > limit as u64) {
        return Err(too_large());
    }
    let start = tokio::time::Instant::now();
    let mut body = body.into_data_stream();
    let mut buf = Vec::with_capacity(declared.unwrap_or(0).min(limit as u64) as usize);
    let mut permits = vec![];
    let mut held_kib: u64 = 0;
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
        if buf.len() + chunk.len() > limit {
            return Err(too_large());
        }
        let want_kib = (buf.len() + chunk.len()).div_ceil(1024) as u64;
        if want_kib > held_kib {
            let more = (want_kib - held_kib) as u32;
            let p = tokio::time::timeout(
                http.body_idle_timeout,
                app.inflight.clone().acquire_many_owned(more),
            )
            .await
            .map_err(|_| {
                Error::new(
                    ErrorKind::Busy,
                    format!(
                        "uploads already hold {} bytes in memory; retry later",
                        http.max_inflight_bytes
                    ),
                )
                .retry_after(5)
            })?
            .expect("the semaphore is never closed");
            permits.push(p);
            held_kib = want_kib;
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

/// A JSON body deserialized into `T`, read within the service's body limit and connection
/// limits.
pub struct Json<T>(pub T);

impl<T: DeserializeOwned> FromRequest<Arc<App>> for Json<T> {
    type Rejection = Problem;

    async fn from_request(req: Request, app: &Arc<App>) -> Result<Self, Problem> {
        let (parts, body) = req.into_parts();
        check_content_encoding(&parts.headers, false)?;
        let body = read_body(app, &parts.headers, body, app.limits.max_body_bytes).await?;
        serde_json::from_slice(&body.bytes)
            .map(Json)
            .map_err(|e| Problem::invalid(format!("the body is not the JSON expected: {e}")))
    }
}

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
