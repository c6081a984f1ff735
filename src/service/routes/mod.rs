//! The v1 routes, one file per resource. [`ROUTES`] is the route table `openapi.yaml` is checked
//! against; a test over the router in-process checks that the router answers exactly it.

mod conditional;
mod disposition;
mod distance;
mod download;
mod health;
mod hermite;
mod jobs;
mod mesh;
mod viewer;
mod volumes;
mod voxelize;

use std::sync::Arc;

use axum::Router;
use axum::body::Body;
use axum::extract::{DefaultBodyLimit, Request, State};
use axum::http::{HeaderValue, StatusCode, header};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use tower_http::compression::CompressionLayer;
use tower_http::compression::predicate::{NotForContentType, Predicate, SizeAbove};
use tracing::Instrument;

use super::App;
use super::problem::Problem;
use crate::app::ErrorKind;
use crate::app::queue::Role;

/// The `.vxl` media type (its row of `codec::FORMATS`): already compressed, so not again.
pub const VXL_MEDIA_TYPE: &str = crate::codec::VolumeFormat::Vxl.media_type();

/// Every path and the methods it answers.
pub const ROUTES: &[(&str, &[&str])] = &[
    ("/v1/voxelize", &["POST"]),
    ("/v1/jobs/{id}", &["GET", "DELETE"]),
    ("/v1/volumes", &["GET"]),
    ("/v1/volumes/csg", &["POST"]),
    ("/v1/volumes/intersect", &["POST"]),
    ("/v1/volumes/{id}", &["GET", "DELETE"]),
    ("/v1/volumes/{id}/data", &["GET"]),
    ("/v1/volumes/{id}/morphology", &["POST"]),
    ("/v1/volumes/{id}/stats", &["GET"]),
    ("/v1/volumes/{id}/threshold", &["POST"]),
    ("/v1/volumes/{id}/sdf", &["POST"]),
    ("/v1/volumes/{id}/query", &["POST"]),
    ("/v1/volumes/{id}/normals", &["GET"]),
    ("/v1/volumes/{id}/preview.png", &["GET"]),
    ("/v1/volumes/{id}/mesh", &["GET"]),
    ("/v1/volumes/{id}/hermite", &["GET"]),
    ("/v1/volumes/{id}/view", &["GET"]),
    ("/v1/viewer/{file}", &["GET"]),
    ("/healthz", &["GET"]),
    ("/readyz", &["GET"]),
    ("/metrics", &["GET"]),
    ("/openapi.yaml", &["GET"]),
];

pub fn router(app: Arc<App>) -> Router {
    let compress = CompressionLayer::new().gzip(true).zstd(true).compress_when(
        SizeAbove::new(256)
            .and(NotForContentType::const_new(VXL_MEDIA_TYPE))
            .and(NotForContentType::const_new("application/problem+json"))
            // Volume metadata and downloads: the handler chose their coding (`conditional`).
            .and(|_, _, _: &_, x: &axum::http::Extensions| {
                x.get::<conditional::Negotiated>().is_none()
            }),
    );
    Router::new()
        .route(
            "/v1/voxelize",
            // The body limit is the handler's own (a problem document, not axum's text).
            post(voxelize::submit).layer(DefaultBodyLimit::disable()),
        )
        .route("/v1/jobs/{id}", get(jobs::get).delete(jobs::cancel))
        .route("/v1/volumes", get(volumes::list))
        .route("/v1/volumes/csg", post(volumes::csg))
        .route("/v1/volumes/intersect", post(volumes::intersect))
        .route(
            "/v1/volumes/{id}",
            get(volumes::get).delete(volumes::delete),
        )
        .route("/v1/volumes/{id}/data", get(download::data))
        .route("/v1/volumes/{id}/morphology", post(volumes::morphology))
        .route("/v1/volumes/{id}/stats", get(volumes::stats))
        .route("/v1/volumes/{id}/threshold", post(distance::threshold))
        .route("/v1/volumes/{id}/sdf", post(distance::sdf))
        .route("/v1/volumes/{id}/query", post(volumes::query))
        .route("/v1/volumes/{id}/normals", get(volumes::normals))
        .route("/v1/volumes/{id}/preview.png", get(volumes::preview))
        .route("/v1/volumes/{id}/mesh", get(mesh::mesh))
        .route("/v1/volumes/{id}/hermite", get(hermite::hermite))
        .route("/v1/volumes/{id}/view", get(viewer::page))
        .route("/v1/viewer/{file}", get(viewer::file))
        .merge(probes())
        .route("/openapi.yaml", get(health::openapi))
        .fallback(|| async {
            Problem::new(ErrorKind::NotFound, "no such route; see /openapi.yaml")
        })
        .method_not_allowed_fallback(method_not_allowed)
        .layer(compress)
        .layer(middleware::from_fn_with_state(app.clone(), request_context))
        .with_state(app)
}

/// The admin listener's router (`--admin-addr`): the probes and the metrics only, with the
/// same request handling (request ids, `--protect-metrics`) as on the service's listener.
pub fn admin_router(app: Arc<App>) -> Router {
    probes()
        .fallback(|| async {
            Problem::new(
                ErrorKind::NotFound,
                "the admin listener answers /healthz, /readyz and /metrics only",
            )
        })
        .method_not_allowed_fallback(method_not_allowed)
        .layer(CompressionLayer::new().gzip(true).zstd(true))
        .layer(middleware::from_fn_with_state(app.clone(), request_context))
        .with_state(app)
}

/// The probes and the metrics: on the service's listener and on the admin one.
fn probes() -> Router<Arc<App>> {
    Router::new()
        .route("/healthz", get(health::healthz))
        .route("/readyz", get(health::readyz))
        .route("/metrics", get(health::metrics))
}

async fn method_not_allowed() -> Problem {
    Problem::new(
        ErrorKind::MethodNotAllowed,
        "this route does not answer that method; see /openapi.yaml",
    )
}

/// Refuses a volume name that is too long (in characters, as openapi.yaml's `maxLength`
/// counts) or holds control characters.
fn check_name(name: &str, limits: &crate::app::Limits) -> crate::app::Result<()> {
    if name.chars().count() > limits.max_name_chars || name.chars().any(char::is_control) {
        return Err(crate::app::Error::invalid(format!(
            "name must be at most {} characters without control characters",
            limits.max_name_chars
        )));
    }
    Ok(())
}

/// `201 Created` with `Location` and the volume's metadata.
fn created(meta: &crate::app::store::VolumeMeta) -> Response {
    let mut r = (StatusCode::CREATED, axum::Json(meta)).into_response();
    set_location(&mut r, &format!("/v1/volumes/{}", meta.id));
    r
}

fn set_location(r: &mut Response, path: &str) {
    if let Ok(v) = HeaderValue::from_str(path) {
        r.headers_mut().insert(header::LOCATION, v);
    }
}

/// Gives every request an id (the caller's `x-request-id` or a new one), a tracing span, the
/// id in the response header, and the id and path in every problem document.
/// The request's head within the service's bounds (`http.max_uri_bytes`, `max_headers`,
/// `max_header_bytes`), or the problem (414, 431) that refuses it. The HTTP parser lets heads
/// up to twice these bounds through so that this check, not the parser, answers them.
fn check_head(req: &Request, http: &super::server::ConnectionLimits) -> Option<Problem> {
    let uri = req.uri().path_and_query().map_or(0, |p| p.as_str().len());
    if uri > http.max_uri_bytes {
        return Some(Problem::new(
            ErrorKind::UriTooLong,
            format!(
                "the request target is {uri} bytes; at most {} are allowed (send large inputs in the body)",
                http.max_uri_bytes
            ),
        ));
    }
    let (n, bytes) = (req.headers().len(), super::server::head_bytes(req));
    if n > http.max_headers || bytes > http.max_header_bytes {
        return Some(Problem::new(
            ErrorKind::HeadersTooLarge,
            format!(
                "the request's head is {bytes} bytes in {n} header fields; at most {} bytes and {} fields are allowed",
                http.max_header_bytes, http.max_headers
            ),
        ));
    }
    // HTTP/1.1 defines one expectation; any other cannot be met (RFC 9110 §10.1.1).
    if let Some(v) = req.headers().get(header::EXPECT)
        && !v.as_bytes().eq_ignore_ascii_case(b"100-continue")
    {
        return Some(Problem::new(
            ErrorKind::ExpectationFailed,
            format!(
                "the request expects {:?}; only `Expect: 100-continue` is understood",
                String::from_utf8_lossy(v.as_bytes())
            ),
        ));
    }
    None
}

/// Paths probed often (health checks, scrapes): not in the access log.
fn is_probe(path: &str) -> bool {
    matches!(path, "/healthz" | "/readyz" | "/metrics")
}

/// A request's id, in its extensions for the handlers (a job records the request that made it).
#[derive(Clone, Debug)]
pub struct RequestId(pub String);

/// The job a request made, in its response's extensions for the access log.
#[derive(Clone, Debug)]
pub struct JobId(pub String);

/// Whether a caller's `X-Request-Id` is used as it is: 1 to 128 characters of
/// `A-Z a-z 0-9 . _ : -`. Any other is replaced by a fresh id (the response's `X-Request-Id`
/// says which id the request has), so an id can never carry a space, a quote, `=` or a line
/// break into a log line.
pub fn valid_request_id(v: &str) -> bool {
    (1..=128).contains(&v.len())
        && v.bytes()
            .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'.' | b'_' | b':' | b'-'))
}

/// The route label of a request (metrics, the access log): the route's template
/// (`/v1/volumes/{id}`), never the path a caller sent, so that labels stay few.
fn route_of(req: &Request) -> String {
    req.extensions()
        .get::<axum::extract::MatchedPath>()
        .map_or_else(|| "unmatched".to_string(), |m| m.as_str().to_string())
}

async fn request_context(State(app): AppState, mut req: Request, next: Next) -> Response {
    let rid = req
        .headers()
        .get("x-request-id")
        .and_then(|v| v.to_str().ok())
        .filter(|v| valid_request_id(v))
        .map(str::to_string)
        .unwrap_or_else(crate::app::new_id);
    req.extensions_mut().insert(RequestId(rid.clone()));
    let path = req.uri().path().to_string();
    let route = route_of(&req);
    let method = req.method().clone();
    // `key`: the API key's name (never the key), once the request is authenticated. Strings
    // (the path a caller sent) are recorded as strings: quoted and escaped in a text line,
    // JSON strings in a JSON one, so that they cannot forge a field. The request id is
    // checked above; the route is a template of ours.
    let span = tracing::info_span!(
        "request",
        request_id = %rid,
        method = %method,
        route = %route,
        path = path.as_str(),
        key = tracing::field::Empty,
        job = tracing::field::Empty,
    );
    let mut key_name = None;
    let started = std::time::Instant::now();
    // A request with a body: refused, its body may be left unread, after which hyper cannot
    // reuse the connection and closes it. Say so (`Connection: close`), so that a client does
    // not send its next request into a closed connection.
    let has_body = req.headers().contains_key(header::TRANSFER_ENCODING)
        || req
            .headers()
            .get(header::CONTENT_LENGTH)
            .is_some_and(|v| v.as_bytes() != b"0");
    let refused = check_head(&req, &app.http)
        .map(IntoResponse::into_response)
        .or_else(|| {
            let keys = app.keys.as_ref().filter(|k| k.guards(&path))?;
            match keys.authenticate(req.headers()) {
                Ok(owner) => {
                    span.record("key", owner.name.as_str());
                    key_name = Some(owner.name.clone());
                    if owner.role == Role::ReadOnly && writes(req.method(), &path) {
                        let e = crate::app::Error::new(
                            ErrorKind::Forbidden,
                            format!(
                                "key {} is read-only: it may read its tenant's volumes and jobs, not {} {path}",
                                owner.name,
                                req.method()
                            ),
                        );
                        return Some(Problem::from(e).into_response());
                    }
                    req.extensions_mut().insert(owner);
                    None
                }
                Err(refusal) => {
                    let mut r = Problem::from(refusal.error).into_response();
                    if let Some(c) = refusal.challenge {
                        r.headers_mut().insert(header::WWW_AUTHENTICATE, c);
                    }
                    Some(r)
                }
            }
        });
    let mut res = match refused {
        Some(r) => r,
        None => next.run(req).instrument(span.clone()).await,
    };
    let is_problem = res
        .headers()
        .get(header::CONTENT_TYPE)
        .is_some_and(|v| v == "application/problem+json");
    if is_problem {
        let (mut parts, body) = res.into_parts();
        let bytes = axum::body::to_bytes(body, 1 << 20)
            .await
            .unwrap_or_default();
        let body = match serde_json::from_slice::<Problem>(&bytes) {
            Ok(mut p) => {
                p.request_id = Some(rid.clone());
                p.instance.get_or_insert(path.clone());
                serde_json::to_vec(&p).unwrap_or_default()
            }
            Err(_) => bytes.to_vec(),
        };
        parts.headers.remove(header::CONTENT_LENGTH);
        res = Response::from_parts(parts, Body::from(body));
    }
    if let Ok(v) = HeaderValue::from_str(&rid) {
        res.headers_mut().insert("x-request-id", v);
    }
    if has_body && (res.status().is_client_error() || res.status().is_server_error()) {
        res.headers_mut()
            .insert(header::CONNECTION, HeaderValue::from_static("close"));
    }
    let secs = started.elapsed().as_secs_f64();
    let status = res.status().as_u16();
    app.metrics.http_request(&route, &method, status, secs);
    if !is_probe(&path) {
        // The body's size where it is known before it is sent (a streamed or compressed body's
        // is not: then its Content-Length if it has one, else no `bytes`).
        let bytes = axum::body::HttpBody::size_hint(res.body())
            .exact()
            .or_else(|| {
                res.headers()
                    .get(header::CONTENT_LENGTH)?
                    .to_str()
                    .ok()?
                    .parse()
                    .ok()
            });
        let job = res.extensions().get::<JobId>().map(|j| j.0.clone());
        // Every field on the line itself (a log shipper needs no span to read it).
        tracing::info!(
            target: "voxd::access",
            parent: None,
            method = %method,
            route = %route,
            path = path.as_str(),
            status,
            bytes,
            duration_ms = (secs * 1e3 * 1e3).round() / 1e3,
            request_id = %rid,
            key = key_name.as_deref(),
            job = job.as_deref(),
            "request"
        );
    }
    res
}

/// The state extractor every handler uses.
type AppState = State<Arc<App>>;

#[cfg(test)]
mod tests;

/// Whether a `/v1` request writes (makes, changes or deletes a volume or job): what a
/// `read-only` key may not do. The POSTs that only read (a query, an overlap) are not writes.
fn writes(method: &axum::http::Method, path: &str) -> bool {
    use axum::http::Method;
    match *method {
        Method::GET | Method::HEAD | Method::OPTIONS => false,
        Method::POST => !(path.ends_with("/query") || path == "/v1/volumes/intersect"),
        _ => true,
    }
}
