//! `/healthz` (the process answers), `/readyz` (the store takes writes and the job queue
//! answers; engine and queue state), `/metrics` (Prometheus text) and `/openapi.yaml` (the
//! contract).

use axum::http::{HeaderValue, header};
use axum::response::{IntoResponse, Response};
use serde_json::json;

use super::super::problem::Problem;
use super::AppState;
use crate::app::{Error, ErrorKind};

/// How long `/readyz` waits for each of its probes (store, queue, usage) before answering 503.
pub const PROBE_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(2);

const OPENAPI: &str = include_str!("../../../openapi.yaml");

pub async fn healthz() -> Response {
    axum::Json(json!({ "status": "ok" })).into_response()
}

pub async fn readyz(axum::extract::State(app): AppState) -> Result<Response, Problem> {
    // Draining: no new work here (answered on the admin listener, which outlives the service's).
    if app.shutting_down() {
        return Err(Error::new(
            ErrorKind::ShuttingDown,
            "the server is shutting down: finishing its running jobs, taking no new ones",
        )
        .into());
    }
    // Each probe is bounded: a store or queue that hangs (an S3 endpoint paused, a Redis that
    // takes connections but never answers) makes the replica unready at once, not a probe
    // that hangs until the balancer gives up on it.
    let unready = |kind, what: &str| {
        Error::new(
            kind,
            format!(
                "{what} did not answer within {} s",
                PROBE_TIMEOUT.as_secs_f64()
            ),
        )
        .retry_after(5)
    };
    tokio::time::timeout(PROBE_TIMEOUT, app.store.health())
        .await
        .map_err(|_| unready(ErrorKind::StorageUnavailable, "the store's probe"))?
        .map_err(|e| {
            Error::new(
                ErrorKind::StorageUnavailable,
                format!("the store is not writable: {e}"),
            )
            .retry_after(5)
        })?;
    let q = tokio::time::timeout(PROBE_TIMEOUT, app.queue.stats())
        .await
        .map_err(|_| unready(ErrorKind::QueueUnavailable, "the job queue"))?;
    if let Some(why) = q.unavailable {
        return Err(Error::new(ErrorKind::QueueUnavailable, why)
            .retry_after(5)
            .into());
    }
    let usage = tokio::time::timeout(PROBE_TIMEOUT, app.store.usage())
        .await
        .map_err(|_| unready(ErrorKind::StorageUnavailable, "the store's usage"))?
        .map_err(Error::from)?;
    Ok(axum::Json(json!({
        "status": "ready",
        "engine": app.engine.describe(),
        "queue_depth": q.depth,
        "running": q.running,
        "stored_bytes": usage.bytes,
    }))
    .into_response())
}

pub async fn metrics(axum::extract::State(app): AppState) -> Response {
    let q = app.queue.stats().await;
    // The store's usage as the quota counts it; left out when the store does not answer in
    // time (a scrape must not hang on it).
    let usage = tokio::time::timeout(PROBE_TIMEOUT, app.store.usage())
        .await
        .ok()
        .and_then(Result::ok);
    let mut text = app
        .metrics
        .render(&q, usage.as_ref(), app.engine.gpu_stats());
    if let Some(keys) = &app.keys {
        keys.render_metrics(&mut text);
    }
    let mut r = text.into_response();
    r.headers_mut().insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("text/plain; version=0.0.4"),
    );
    r
}

pub async fn openapi() -> Response {
    let mut r = OPENAPI.into_response();
    r.headers_mut().insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("application/yaml"),
    );
    r
}
