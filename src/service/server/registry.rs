//! The open connections of one listener: which client each belongs to, whether it is serving a
//! request or idle (waiting for a head: a keep-alive connection between requests, or one that
//! has not sent a full head yet) and since when, and a way to close it. Under pressure the
//! cheapest connections go first: the one idle longest when a new one needs its place
//! ([`Registry::shed_idle`]), and every one idle longer than a short time once the open count
//! nears the cap ([`Registry::sweep`]), as Envoy's overload manager and nginx do. A connection
//! that is serving a request is never closed here.

use std::collections::HashMap;
use std::net::IpAddr;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use tokio::sync::Notify;

pub(super) struct Registry {
    inner: Mutex<Inner>,
    /// Connections one client address may hold at once (0: no limit).
    per_client: usize,
}

#[derive(Default)]
struct Inner {
    next: u64,
    conns: HashMap<u64, Entry>,
    per_ip: HashMap<IpAddr, usize>,
}

struct Entry {
    ip: IpAddr,
    /// Requests being served (0: idle).
    busy: u32,
    /// When the connection last became idle (accepted, or its last response sent).
    idle_since: Instant,
    /// Holds one of the listener's places (a connection accepted while every place is taken
    /// waits for one, and is not shed to make room for itself meanwhile).
    placed: bool,
    /// Told to close, not yet gone.
    closing: bool,
    close: Arc<Notify>,
}

impl Registry {
    pub(super) fn new(per_client: usize) -> Arc<Registry> {
        Arc::new(Registry {
            inner: Mutex::default(),
            per_client,
        })
    }

    fn lock(&self) -> MutexGuard<'_, Inner> {
        self.inner.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Open connections.
    pub(super) fn open(&self) -> usize {
        self.lock().conns.len()
    }

    /// Registers a new connection from `ip`, idle; `None` when that client already holds its
    /// most connections (the caller closes the new one at once).
    pub(super) fn admit(self: &Arc<Self>, ip: IpAddr) -> Option<Handle> {
        let mut g = self.lock();
        let held = g.per_ip.get(&ip).copied().unwrap_or(0);
        if self.per_client > 0 && held >= self.per_client {
            return None;
        }
        g.next += 1;
        let id = g.next;
        let close = Arc::new(Notify::new());
        g.conns.insert(
            id,
            Entry {
                ip,
                busy: 0,
                idle_since: Instant::now(),
                placed: false,
                closing: false,
                close: close.clone(),
            },
        );
        *g.per_ip.entry(ip).or_default() += 1;
        Some(Handle {
            reg: self.clone(),
            id,
            close,
        })
    }

    /// Tells the connection idle longest to close; false when none is idle.
    pub(super) fn shed_idle(&self) -> bool {
        let mut g = self.lock();
        let oldest = g
            .conns
            .values_mut()
            .filter(|e| e.placed && e.busy == 0 && !e.closing)
            .min_by_key(|e| e.idle_since);
        let Some(e) = oldest else { return false };
        e.closing = true;
        e.close.notify_one();
        tracing::debug!(ip = %e.ip, "connections at the cap: closing the one idle longest");
        true
    }

    /// Tells every connection idle for longer than `idle` to close; how many.
    pub(super) fn sweep(&self, idle: Duration) -> usize {
        let now = Instant::now();
        let mut g = self.lock();
        let mut n = 0;
        for e in g.conns.values_mut() {
            if e.placed && e.busy == 0 && !e.closing && now.duration_since(e.idle_since) >= idle {
                e.closing = true;
                e.close.notify_one();
                n += 1;
            }
        }
        n
    }
}

/// One registered connection; dropping it unregisters the connection.
pub(super) struct Handle {
    reg: Arc<Registry>,
    id: u64,
    close: Arc<Notify>,
}

impl Handle {
    /// Resolves when the connection is told to close.
    pub(super) async fn closing(&self) {
        self.close.notified().await
    }

    /// The connection has its place: from now on it is idle (since now) until it serves a
    /// request, and may be shed while it is.
    pub(super) fn placed(&self) {
        if let Some(e) = self.reg.lock().conns.get_mut(&self.id) {
            e.placed = true;
            e.idle_since = Instant::now();
        }
    }

    /// Whether a request is being served now. A connection told to close while it started one
    /// is kept (the flag is cleared): only idle connections are shed.
    pub(super) fn keep_if_busy(&self) -> bool {
        let mut g = self.reg.lock();
        match g.conns.get_mut(&self.id) {
            Some(e) if e.busy > 0 => {
                e.closing = false;
                true
            }
            _ => false,
        }
    }

    /// Marks a request as being served until the returned guard drops (its response sent).
    #[cfg(test)]
    fn busy(&self) -> Busy {
        self.tracker().busy()
    }

    /// What the connection's service keeps to mark its requests.
    pub(super) fn tracker(&self) -> Tracker {
        Tracker {
            reg: self.reg.clone(),
            id: self.id,
        }
    }
}

/// Marks a connection's requests as being served ([`Tracker::busy`]).
#[derive(Clone)]
pub(super) struct Tracker {
    reg: Arc<Registry>,
    id: u64,
}

impl Tracker {
    /// Marks a request as being served until the returned guard drops (its response sent).
    pub(super) fn busy(&self) -> Busy {
        if let Some(e) = self.reg.lock().conns.get_mut(&self.id) {
            e.busy += 1;
        }
        Busy {
            reg: self.reg.clone(),
            id: self.id,
        }
    }
}

impl Drop for Handle {
    fn drop(&mut self) {
        let mut g = self.reg.lock();
        if let Some(e) = g.conns.remove(&self.id)
            && let Some(n) = g.per_ip.get_mut(&e.ip)
        {
            *n -= 1;
            if *n == 0 {
                g.per_ip.remove(&e.ip);
            }
        }
    }
}

/// A request being served: held by the request and then by its response's body.
pub(super) struct Busy {
    reg: Arc<Registry>,
    id: u64,
}

impl Busy {
    /// Called as the response's body is sent (keeps the guard alive with the body).
    pub(super) fn sending(&self) {}
}

impl Drop for Busy {
    fn drop(&mut self) {
        if let Some(e) = self.reg.lock().conns.get_mut(&self.id) {
            e.busy = e.busy.saturating_sub(1);
            if e.busy == 0 {
                e.idle_since = Instant::now();
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const A: IpAddr = IpAddr::V4(std::net::Ipv4Addr::new(10, 0, 0, 1));
    const B: IpAddr = IpAddr::V4(std::net::Ipv4Addr::new(10, 0, 0, 2));

    #[test]
    fn a_client_over_its_cap_is_refused_and_others_are_not() {
        let reg = Registry::new(2);
        let a1 = reg.admit(A).unwrap();
        let _a2 = reg.admit(A).unwrap();
        assert!(reg.admit(A).is_none());
        assert!(reg.admit(B).is_some());
        drop(a1);
        assert!(reg.admit(A).is_some());
    }

    #[test]
    fn the_connection_idle_longest_is_shed_and_busy_ones_never() {
        let reg = Registry::new(0);
        let placed = |ip| {
            let h = reg.admit(ip).unwrap();
            h.placed();
            h
        };
        // Waiting for a place since before the others: never shed to make room for itself.
        let waiting = reg.admit(B).unwrap();
        std::thread::sleep(Duration::from_millis(5));
        let old = placed(A);
        std::thread::sleep(Duration::from_millis(5));
        let busy = placed(A);
        let serving = busy.busy();
        let young = placed(B);
        // The oldest idle one is told; the busy one and the younger idle one are not.
        assert!(reg.shed_idle());
        assert!(!old.keep_if_busy());
        let (o, y) = (old.close.clone(), young.close.clone());
        assert!(reg.lock().conns[&old.id].closing);
        assert!(!reg.lock().conns[&young.id].closing);
        assert!(!reg.lock().conns[&busy.id].closing);
        drop((o, y));
        // The next shed takes the young one, then none is left idle.
        assert!(reg.shed_idle());
        assert!(!reg.shed_idle());
        drop(serving);
        assert!(reg.shed_idle());
        assert_eq!(reg.open(), 4);
        assert_eq!(reg.sweep(Duration::ZERO), 0);
        assert!(!reg.lock().conns[&waiting.id].closing);
    }
}
