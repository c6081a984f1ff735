//! One process-wide memory budget (`voxd serve --max-memory`) that admits every request, volume
//! operation and job by an estimate of the memory it will use, before the work starts.
//!
//! Each piece of work asks for a [`MemoryPermit`] of its estimated peak bytes and holds it until
//! its memory is freed. Work that could never fit (more than the whole budget) is refused at
//! once with `too-much-memory` (422, the numbers in the detail); work that does not fit now waits
//! at most the given time and then gets `busy` (503, `Retry-After`): the wait is never charged to
//! the client as slowness. The budget is counted in KiB (a semaphore's permits are `u32`).
//!
//! Not here: the estimates themselves (beside the work they estimate: mesh loading, volume
//! operations, the engine), and where each front waits.

use std::sync::Arc;
use std::time::Duration;

use tokio::sync::{OwnedSemaphorePermit, Semaphore};

use super::error::{Error, ErrorKind, Result};

/// Seconds a client is told to wait before retrying work refused as `busy`.
pub const RETRY_AFTER_S: u64 = 5;

/// The fraction of the machine's (or the cgroup's) memory `--max-memory` defaults to.
pub const DEFAULT_FRACTION: f64 = 0.5;

/// The process-wide memory budget. Cheap to clone (shared).
#[derive(Clone, Debug)]
pub struct MemoryBudget {
    total: u64,
    kib: Arc<Semaphore>,
}

/// Bytes of the budget held until dropped.
#[derive(Debug)]
pub struct MemoryPermit {
    bytes: u64,
    _permit: Option<OwnedSemaphorePermit>,
}

impl MemoryPermit {
    /// Bytes this permit holds.
    pub fn bytes(&self) -> u64 {
        self.bytes
    }
    /// A permit that holds nothing (work too small to count, or a front without a budget).
    pub fn none() -> MemoryPermit {
        MemoryPermit {
            bytes: 0,
            _permit: None,
        }
    }
}

fn units(bytes: u64) -> u64 {
    bytes.div_ceil(1024).max(1)
}

impl MemoryBudget {
    /// A budget of `total` bytes (at least 1 KiB, at most what one acquisition can count in KiB:
    /// `u32::MAX`, so that every admitted request's KiB fit the `u32` it is acquired with).
    pub fn new(total: u64) -> MemoryBudget {
        let kib = units(total)
            .min(Semaphore::MAX_PERMITS as u64)
            .min(u32::MAX as u64);
        MemoryBudget {
            total: kib * 1024,
            kib: Arc::new(Semaphore::new(kib as usize)),
        }
    }

    /// `--max-memory`'s default: [`DEFAULT_FRACTION`] of the memory this process may use (the
    /// cgroup's limit where there is one, else the machine's).
    pub fn default_total() -> u64 {
        let mem = available_memory().unwrap_or(4 << 30);
        (mem as f64 * DEFAULT_FRACTION) as u64
    }

    /// Bytes of the whole budget.
    pub fn total(&self) -> u64 {
        self.total
    }

    /// Bytes held now.
    pub fn in_use(&self) -> u64 {
        self.total - self.kib.available_permits() as u64 * 1024
    }

    /// `too-much-memory` when `bytes` exceed the whole budget: work that could never run.
    pub fn check_fits(&self, bytes: u64, what: &str) -> Result<()> {
        self.never_fits(bytes, what).map_or(Ok(()), Err)
    }

    fn never_fits(&self, bytes: u64, what: &str) -> Option<Error> {
        (bytes > self.total).then(|| {
            Error::new(
                ErrorKind::TooMuchMemory,
                format!(
                    "{what} would need about {bytes} bytes of memory, more than the server's whole budget of {} bytes (--max-memory); ask for less (a smaller grid, a smaller mesh)",
                    self.total
                ),
            )
        })
    }

    fn busy(&self, bytes: u64, what: &str) -> Error {
        Error::new(
            ErrorKind::Busy,
            format!(
                "{what} would need about {bytes} bytes of memory, and other work holds {} of the {} allowed; retry later",
                self.in_use(),
                self.total
            ),
        )
        .retry_after(RETRY_AFTER_S)
    }

    /// Holds `bytes` now: `too-much-memory` when it exceeds the whole budget, `busy` when it does
    /// not fit at the moment.
    pub fn try_admit(&self, bytes: u64, what: &str) -> Result<MemoryPermit> {
        if let Some(e) = self.never_fits(bytes, what) {
            return Err(e);
        }
        let n = units(bytes) as u32;
        match self.kib.clone().try_acquire_many_owned(n) {
            Ok(p) => Ok(MemoryPermit {
                bytes,
                _permit: Some(p),
            }),
            Err(_) => Err(self.busy(bytes, what)),
        }
    }

    /// Holds `bytes`, waiting at most `wait` for them to free up: `too-much-memory` at once when
    /// it exceeds the whole budget, `busy` (503 with `Retry-After`) when the wait runs out.
    pub async fn admit(&self, bytes: u64, what: &str, wait: Duration) -> Result<MemoryPermit> {
        if let Some(e) = self.never_fits(bytes, what) {
            return Err(e);
        }
        let n = units(bytes) as u32;
        match tokio::time::timeout(wait, self.kib.clone().acquire_many_owned(n)).await {
            Ok(p) => Ok(MemoryPermit {
                bytes,
                _permit: Some(p.expect("the semaphore is never closed")),
            }),
            Err(_) => Err(self.busy(bytes, what)),
        }
    }
}

/// Bytes of memory this process may use: the cgroup's limit (v2 `memory.max`, v1
/// `memory.limit_in_bytes`) when it sets one below the machine's, else the machine's
/// `MemTotal`. `None` where neither can be read (not Linux).
pub fn available_memory() -> Option<u64> {
    let machine = std::fs::read_to_string("/proc/meminfo").ok().and_then(|s| {
        s.lines()
            .find_map(|l| l.strip_prefix("MemTotal:"))
            .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<u64>().ok())
            .map(|kib| kib * 1024)
    });
    let cgroup = [
        "/sys/fs/cgroup/memory.max",
        "/sys/fs/cgroup/memory/memory.limit_in_bytes",
    ]
    .iter()
    .filter_map(|p| std::fs::read_to_string(p).ok())
    .filter_map(|s| s.trim().parse::<u64>().ok())
    .min();
    match (machine, cgroup) {
        (Some(m), Some(c)) => Some(m.min(c)),
        (m, c) => m.or(c),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn work_over_the_whole_budget_is_refused_with_its_numbers_and_work_that_waits_is_busy() {
        let b = MemoryBudget::new(10 << 20);
        let e = b.try_admit(11 << 20, "this stats request").unwrap_err();
        assert_eq!(e.kind, ErrorKind::TooMuchMemory);
        assert!(
            e.detail.contains(&(11u64 << 20).to_string()),
            "{}",
            e.detail
        );
        assert!(
            e.detail.contains(&(10u64 << 20).to_string()),
            "{}",
            e.detail
        );
        let held = b.try_admit(8 << 20, "one").unwrap();
        assert_eq!(b.in_use(), 8 << 20);
        let e = b
            .admit(4 << 20, "two", Duration::from_millis(20))
            .await
            .unwrap_err();
        assert_eq!(e.kind, ErrorKind::Busy);
        assert_eq!(e.retry_after, Some(RETRY_AFTER_S));
        drop(held);
        assert_eq!(b.in_use(), 0);
        let p = b.admit(4 << 20, "two", Duration::from_millis(20)).await;
        assert_eq!(p.unwrap().bytes(), 4 << 20);
    }

    #[test]
    fn a_budget_beyond_what_one_acquisition_counts_is_capped_so_no_request_wraps() {
        let b = MemoryBudget::new(u64::MAX);
        assert_eq!(b.total(), u32::MAX as u64 * 1024);
        let e = b
            .try_admit((u32::MAX as u64 + 1) * 1024, "a huge request")
            .unwrap_err();
        assert_eq!(e.kind, ErrorKind::TooMuchMemory);
    }

    #[test]
    fn the_machine_has_memory() {
        let m = available_memory().expect("Linux reports its memory");
        assert!(m > 64 << 20, "{m}");
        assert!(MemoryBudget::default_total() <= m);
    }
}
