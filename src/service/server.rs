//! The HTTP/1.1 server loop: hyper over tokio with the bounds axum's `serve` does not set. Every
//! connection has a header-read timeout (which also closes idle keep-alive connections: the
//! timer runs whenever the connection waits for a request's head), a cap on header bytes, and a
//! place under a cap on open connections (beyond it, new connections wait in the kernel's
//! backlog until one closes, so file descriptors are never exhausted). Shutdown stops
//! accepting, lets connections finish their requests for at most the shutdown timeout, then
//! drops them.

use std::future::Future;
use std::pin::Pin;
use std::sync::Arc;
use std::task::{Context, Poll};
use std::time::Duration;

use axum::Router;
use axum::body::Body;
use hyper::body::Incoming;
use hyper_util::rt::{TokioIo, TokioTimer};
use hyper_util::server::graceful::GracefulShutdown;
use hyper_util::service::TowerToHyperService;
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::net::TcpListener;
use tokio::sync::Semaphore;
use tower::ServiceExt;

use crate::limits::serve;

/// Connection places of the admin listener (`--admin-addr`): probes and scrapes, a few at a
/// time, each answered at once.
pub const ADMIN_CONNECTIONS: usize = 64;

/// Bounds on connections.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ConnectionLimits {
    /// Time a connection may take to send a request's head, and may sit idle between requests.
    pub header_read_timeout: Duration,
    /// Open connections at most.
    pub max_connections: usize,
    /// Bytes of a request's head (request line and headers) at most; more gets 431.
    pub max_header_bytes: usize,
    /// Header fields of a request at most; more gets 431.
    pub max_headers: usize,
    /// Bytes of a request's target (path and query) at most; more gets 414.
    pub max_uri_bytes: usize,
    /// A response may wait this long for the client to take more of it (a client that stops
    /// reading is disconnected, and the work producing the response stops).
    pub send_timeout: Duration,
    /// A body may pause this long between chunks at most.
    pub body_idle_timeout: Duration,
    /// After `body_grace`, a body must have arrived at this many bytes per second on average.
    pub min_body_rate: u64,
    pub body_grace: Duration,
    /// Bytes of request bodies held in memory at once, over all requests; more wait (and fail
    /// with `busy` after `body_idle_timeout`).
    pub max_inflight_bytes: u64,
}

/// The defaults of `voxd serve`'s connection flags (`crate::limits::serve`), and the bounds no
/// flag sets.
impl Default for ConnectionLimits {
    fn default() -> Self {
        ConnectionLimits {
            header_read_timeout: Duration::from_secs_f64(serve::HEADER_TIMEOUT_S),
            max_connections: serve::MAX_CONNECTIONS,
            max_header_bytes: 64 << 10,
            max_headers: 100,
            max_uri_bytes: 8 << 10,
            send_timeout: Duration::from_secs_f64(serve::SEND_TIMEOUT_S),
            body_idle_timeout: Duration::from_secs_f64(serve::BODY_TIMEOUT_S),
            min_body_rate: serve::MIN_BODY_RATE,
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
        // The parser's own bounds are twice the service's: a head between the two reaches the
        // router, which refuses it with a problem document (`check_head`); only a head beyond
        // twice the limit, or one that is not HTTP, gets the parser's bare status.
        let conn = hyper::server::conn::http1::Builder::new()
            .timer(TokioTimer::new())
            .header_read_timeout(limits.header_read_timeout)
            .max_header_size(limits.max_header_bytes.saturating_mul(2).max(8192))
            .max_headers(limits.max_headers.saturating_mul(2))
            .serve_connection(
                TokioIo::new(SendTimeout::new(stream, limits.send_timeout)),
                service,
            );
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

/// Size of a request's head as sent: the request line and the header lines.
pub fn head_bytes<B>(req: &hyper::Request<B>) -> usize {
    let line = req.method().as_str().len() + 1 + req.uri().to_string().len() + 11;
    req.headers()
        .iter()
        .map(|(k, v)| k.as_str().len() + 2 + v.len() + 2)
        .sum::<usize>()
        + line
}

/// A connection whose writes fail with `TimedOut` once the peer has taken nothing for `limit`
/// (its receive window full: a client that stopped reading). Reads are bounded elsewhere (the
/// header-read timeout, the body rate).
struct SendTimeout<S> {
    io: S,
    limit: Duration,
    /// Armed while a write waits.
    stalled: Option<Pin<Box<tokio::time::Sleep>>>,
}

impl<S> SendTimeout<S> {
    fn new(io: S, limit: Duration) -> Self {
        SendTimeout {
            io,
            limit,
            stalled: None,
        }
    }

    /// After a write returned `Pending`: `TimedOut` once the stall has lasted `limit`.
    fn check_stall<T>(&mut self, cx: &mut Context<'_>) -> Poll<std::io::Result<T>> {
        let limit = self.limit;
        let sleep = self
            .stalled
            .get_or_insert_with(|| Box::pin(tokio::time::sleep(limit)));
        match sleep.as_mut().poll(cx) {
            Poll::Ready(()) => Poll::Ready(Err(std::io::Error::new(
                std::io::ErrorKind::TimedOut,
                format!(
                    "the client took nothing of the response for {} s",
                    limit.as_secs_f64()
                ),
            ))),
            Poll::Pending => Poll::Pending,
        }
    }

    fn track<T>(
        &mut self,
        cx: &mut Context<'_>,
        r: Poll<std::io::Result<T>>,
    ) -> Poll<std::io::Result<T>> {
        match r {
            Poll::Pending => self.check_stall(cx),
            done => {
                self.stalled = None;
                done
            }
        }
    }
}

impl<S: AsyncRead + Unpin> AsyncRead for SendTimeout<S> {
    fn poll_read(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<std::io::Result<()>> {
        Pin::new(&mut self.io).poll_read(cx, buf)
    }
}

impl<S: AsyncWrite + Unpin> AsyncWrite for SendTimeout<S> {
    fn poll_write(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<std::io::Result<usize>> {
        let r = Pin::new(&mut self.io).poll_write(cx, buf);
        self.track(cx, r)
    }

    fn poll_write_vectored(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bufs: &[std::io::IoSlice<'_>],
    ) -> Poll<std::io::Result<usize>> {
        let r = Pin::new(&mut self.io).poll_write_vectored(cx, bufs);
        self.track(cx, r)
    }

    fn is_write_vectored(&self) -> bool {
        self.io.is_write_vectored()
    }

    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<std::io::Result<()>> {
        let r = Pin::new(&mut self.io).poll_flush(cx);
        self.track(cx, r)
    }

    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<std::io::Result<()>> {
        let r = Pin::new(&mut self.io).poll_shutdown(cx);
        self.track(cx, r)
    }
}
