//! The HTTP/1.1 server loop: hyper over tokio with the bounds axum's `serve` does not set. Every
//! connection has a header-read timeout (which also closes idle keep-alive connections: the
//! timer runs whenever the connection waits for a request's head), a cap on header bytes, and a
//! place under a cap on open connections (by default derived from the file-descriptor limit,
//! whose soft value is raised to the hard one at start). Connections are registered
//! (`registry`): one client address may hold a bounded number of them, and under pressure the
//! cheapest go first: at the cap, the connection idle longest is closed to make room for a new
//! one (one waits in the kernel's backlog only while every place serves a request), and above
//! 80 % of the cap idle connections are closed after 2 s instead of the header timeout.
//! Shutdown stops accepting, lets connections finish their requests for at most the shutdown
//! timeout, then drops them.

mod registry;
mod send_timeout;

use std::future::Future;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use axum::Router;
use axum::body::Body;
use http_body_util::BodyExt;
use hyper::body::Incoming;
use hyper_util::rt::{TokioIo, TokioTimer};
use hyper_util::server::graceful::GracefulShutdown;
use hyper_util::service::TowerToHyperService;
use tokio::net::{TcpListener, TcpSocket};
use tokio::sync::Semaphore;
use tower::ServiceExt;

use registry::Registry;
use send_timeout::SendTimeout;

use crate::limits::serve;

/// Connection places of the admin listener (`--admin-addr`): probes and scrapes, a few at a
/// time, each answered at once.
pub const ADMIN_CONNECTIONS: usize = 64;

/// Bounds on connections.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ConnectionLimits {
    /// Time a connection may take to send a request's head, and may sit idle between requests.
    pub header_read_timeout: Duration,
    /// Open connections at most; 0: derived from the file-descriptor limit
    /// ([`connection_cap`]).
    pub max_connections: usize,
    /// Connections one client address may hold at once (0: no limit); more are closed at once.
    pub max_connections_per_client: usize,
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
}

/// The defaults of `voxd serve`'s connection flags (`crate::limits::serve`), and the bounds no
/// flag sets.
impl Default for ConnectionLimits {
    fn default() -> Self {
        ConnectionLimits {
            header_read_timeout: Duration::from_secs_f64(serve::HEADER_TIMEOUT_S),
            max_connections: serve::MAX_CONNECTIONS,
            max_connections_per_client: serve::MAX_CONNECTIONS_PER_CLIENT,
            max_header_bytes: 64 << 10,
            max_headers: 100,
            max_uri_bytes: 8 << 10,
            send_timeout: Duration::from_secs_f64(serve::SEND_TIMEOUT_S),
            body_idle_timeout: Duration::from_secs_f64(serve::BODY_TIMEOUT_S),
            min_body_rate: serve::MIN_BODY_RATE,
            body_grace: Duration::from_secs(10),
        }
    }
}

/// Pending connections the kernel queues for a listener (its `listen` backlog; Linux clamps it
/// to `net.core.somaxconn`).
const BACKLOG: u32 = 4096;
/// Above this share of the cap (in fifths), idle connections are closed after [`PRESSURE_IDLE`].
const PRESSURE_FIFTHS: usize = 4;
/// The header and idle timeout under pressure.
const PRESSURE_IDLE: Duration = Duration::from_secs(2);

/// A listener on `addr` with a large backlog ([`BACKLOG`]) and `SO_REUSEADDR`.
pub fn bind(addr: SocketAddr) -> std::io::Result<TcpListener> {
    let socket = match addr {
        SocketAddr::V4(_) => TcpSocket::new_v4()?,
        SocketAddr::V6(_) => TcpSocket::new_v6()?,
    };
    socket.set_reuseaddr(true)?;
    socket.bind(addr)?;
    socket.listen(BACKLOG)
}

/// The limits on open files (soft and hard), or `None` where they cannot be read.
#[cfg(unix)]
fn nofile() -> Option<libc::rlimit> {
    let mut lim = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: `lim` is a valid, writable rlimit for the call's duration.
    (unsafe { libc::getrlimit(libc::RLIMIT_NOFILE, &mut lim) } == 0).then_some(lim)
}

/// The soft limit on open files now in force (`None`: unlimited, or it cannot be read).
pub fn fd_limit() -> Option<u64> {
    #[cfg(unix)]
    {
        nofile()
            .map(|l| l.rlim_cur)
            .filter(|n| *n != libc::RLIM_INFINITY)
    }
    #[cfg(not(unix))]
    {
        None
    }
}

/// Raises the soft limit on open files to the hard one (once; later calls only read it);
/// returns the soft limit now in force, or `None` where it cannot be read.
pub fn raise_fd_limit() -> Option<u64> {
    #[cfg(unix)]
    {
        let mut lim = nofile()?;
        if lim.rlim_cur < lim.rlim_max {
            let raised = libc::rlimit {
                rlim_cur: lim.rlim_max,
                rlim_max: lim.rlim_max,
            };
            // SAFETY: `raised` is a valid rlimit; raising the soft limit up to the hard one
            // needs no privilege.
            if unsafe { libc::setrlimit(libc::RLIMIT_NOFILE, &raised) } == 0 {
                lim = raised;
            }
        }
        Some(lim.rlim_cur)
    }
    #[cfg(not(unix))]
    {
        None
    }
}

/// The cap on open connections: `configured`, or with 0 the file-descriptor limit less a
/// reserve for the store, logs and the admin listener (an eighth of it, at least 256), within
/// 64..=32768.
pub fn connection_cap(configured: usize) -> usize {
    if configured > 0 {
        return configured;
    }
    let fds = raise_fd_limit().unwrap_or(1024).min(1 << 30) as usize;
    fds.saturating_sub((fds / 8).max(256)).clamp(64, 32768)
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
    let cap = connection_cap(limits.max_connections);
    tracing::info!(
        max_connections = cap,
        per_client = limits.max_connections_per_client,
        addr = ?listener.local_addr().ok(),
        "accepting connections"
    );
    let slots = Arc::new(Semaphore::new(cap));
    let registry = Registry::new(limits.max_connections_per_client);
    let pressure = move |open: usize| open * 5 > cap * PRESSURE_FIFTHS;
    // Under pressure, idle connections are closed after PRESSURE_IDLE (checked twice a second).
    let sweeper = tokio::spawn({
        let registry = registry.clone();
        async move {
            let mut tick = tokio::time::interval(Duration::from_millis(500));
            loop {
                tick.tick().await;
                if pressure(registry.open()) {
                    let n = registry.sweep(PRESSURE_IDLE);
                    if n > 0 {
                        tracing::debug!(closed = n, "connections near the cap: closed idle ones");
                    }
                }
            }
        }
    });
    let graceful = GracefulShutdown::new();
    let mut shutdown = std::pin::pin!(shutdown);
    'accept: loop {
        let (stream, peer) = tokio::select! {
            r = listener.accept() => match r {
                Ok(s) => s,
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
        let Some(handle) = registry.admit(peer.ip()) else {
            tracing::debug!(peer = %peer.ip(), "client over its connection cap: closed");
            drop(stream);
            continue;
        };
        // A place: free, or made by closing the connection idle longest; while every place
        // serves a request, wait (retrying as connections go idle).
        let slot = loop {
            if let Ok(s) = slots.clone().try_acquire_owned() {
                break s;
            }
            registry.shed_idle();
            tokio::select! {
                s = slots.clone().acquire_owned() => break s.expect("the semaphore is never closed"),
                _ = tokio::time::sleep(Duration::from_millis(100)) => {}
                _ = &mut shutdown => break 'accept,
            }
        };
        handle.placed();
        let _ = stream.set_nodelay(true);
        let service = {
            let (router, handle) = (router.clone(), handle.tracker());
            tower::service_fn(move |req: hyper::Request<Incoming>| {
                let busy = handle.busy();
                let call = router.clone().oneshot(req.map(Body::new));
                async move {
                    let res = call.await?;
                    // The request counts as served until its response's body is sent (or
                    // dropped): the connection is not idle meanwhile.
                    Ok::<_, std::convert::Infallible>(res.map(|b| {
                        Body::new(b.map_frame(move |f| {
                            busy.sending();
                            f
                        }))
                    }))
                }
            })
        };
        let service = TowerToHyperService::new(service);
        let header_timeout = if pressure(registry.open()) {
            limits.header_read_timeout.min(PRESSURE_IDLE)
        } else {
            limits.header_read_timeout
        };
        // The parser's own bounds are twice the service's: a head between the two reaches the
        // router, which refuses it with a problem document (`check_head`); only a head beyond
        // twice the limit, or one that is not HTTP, gets the parser's bare status.
        let conn = hyper::server::conn::http1::Builder::new()
            .timer(TokioTimer::new())
            .header_read_timeout(header_timeout)
            .max_header_size(limits.max_header_bytes.saturating_mul(2).max(8192))
            .max_headers(limits.max_headers.saturating_mul(2))
            .serve_connection(
                TokioIo::new(SendTimeout::new(stream, limits.send_timeout)),
                service,
            );
        let conn = graceful.watch(conn);
        tokio::spawn(async move {
            let mut conn = std::pin::pin!(conn);
            loop {
                tokio::select! {
                    r = &mut conn => {
                        if let Err(e) = r {
                            tracing::debug!("connection ended: {e}");
                        }
                        break;
                    }
                    // Shed while idle: dropped (closed) at once. One that started a request
                    // meanwhile is kept.
                    _ = handle.closing() => if !handle.keep_if_busy() { break },
                }
            }
            drop(handle);
            drop(slot);
        });
    }
    sweeper.abort();
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
