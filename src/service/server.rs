//! The HTTP/1.1 server loop: hyper over tokio with the bounds axum's `serve` does not set. Every
//! connection has a header-read timeout (which also closes idle keep-alive connections: the
//! timer runs whenever the connection waits for a request's head), a cap on header bytes, and a
//! place under a cap on open connections (beyond it, new connections wait in the kernel's
//! backlog until one closes, so file descriptors are never exhausted). Shutdown stops
//! accepting, lets connections finish their requests for at most the shutdown timeout, then
//! drops them.

use std::future::Future;
use std::sync::Arc;
use std::time::Duration;

use axum::Router;
use axum::body::Body;
use hyper::body::Incoming;
use hyper_util::rt::{TokioIo, TokioTimer};
use hyper_util::server::graceful::GracefulShutdown;
use hyper_util::service::TowerToHyperService;
use tokio::net::TcpListener;
use tokio::sync::Semaphore;
use tower::ServiceExt;

/// Bounds on connections.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ConnectionLimits {
    /// Time a connection may take to send a request's head, and may sit idle between requests.
    pub header_read_timeout: Duration,
    /// Open connections at most.
    pub max_connections: usize,
    /// Bytes of a request's head (request line and headers) at most; more gets 431.
    pub max_header_bytes: usize,
    /// A body may pause this long between chunks at most.
    pub body_idle_timeout: Duration,
    /// After `body_grace`, a body must have arrived at this many bytes per second on average.
    pub min_body_rate: u64,
    pub body_grace: Duration,
    /// Bytes of request bodies held in memory at once, over all requests; more wait (and fail
    /// with `busy` after `body_idle_timeout`).
    pub max_inflight_bytes: u64,
}

impl Default for ConnectionLimits {
    fn default() -> Self {
        ConnectionLimits {
            header_read_timeout: Duration::from_secs(20),
            max_connections: 512,
            max_header_bytes: 64 << 10,
            body_idle_timeout: Duration::from_secs(20),
            min_body_rate: 16 << 10,
            body_grace: Duration::from_secs(10),
            max_inflight_bytes: 1 << 30,
        }
    }
}

/// Serves `router` on `listener` until `shutdown` resolves, then drains connections for at most
/// `drain` and returns.
pub async fn run(
    listener: TcpListener,
    router: Router,
    limits: ConnectionLimits,
    shutdown: impl Future<Output = ()>,
    drain: Duration,
) {
    let slots = Arc::new(Semaphore::new(limits.max_connections.max(1)));
    let graceful = GracefulShutdown::new();
    let mut shutdown = std::pin::pin!(shutdown);
    loop {
        let slot = tokio::select! {
            s = slots.clone().acquire_owned() => s.expect("the semaphore is never closed"),
            _ = &mut shutdown => break,
        };
        let stream = tokio::select! {
            r = listener.accept() => match r {
                Ok((s, _)) => s,
                Err(e) => {
                    // Out of file descriptors or a connection reset before accept: back off a
                    // little instead of spinning.
                    tracing::warn!("accept failed: {e}");
                    tokio::time::sleep(Duration::from_millis(50)).await;
                    continue;
                }
            },
            _ = &mut shutdown => break,
        };
        let _ = stream.set_nodelay(true);
        let service = TowerToHyperService::new(
            router
                .clone()
                .map_request(|r: hyper::Request<Incoming>| r.map(Body::new)),
        );
        let conn = hyper::server::conn::http1::Builder::new()
            .timer(TokioTimer::new())
            .header_read_timeout(limits.header_read_timeout)
            .max_header_size(limits.max_header_bytes)
            .serve_connection(TokioIo::new(stream), service);
        let conn = graceful.watch(conn);
        tokio::spawn(async move {
            if let Err(e) = conn.await {
                tracing::debug!("connection ended: {e}");
            }
            drop(slot);
        });
    }
    drop(listener);
    tracing::info!(
        connections = graceful.count(),
        "stopped accepting; draining connections"
    );
    if tokio::time::timeout(drain, graceful.shutdown())
        .await
        .is_err()
    {
        tracing::warn!(
            "connections still open after the shutdown timeout ({} s); closing them",
            drain.as_secs()
        );
    }
}
