//! Cancellation, deadlines and progress for heavy work (voxelizations, fills, morphology, CSG,
//! statistics).
//!
//! A [`Control`] is handed to the work; the work calls [`Control::check`] at natural points (a
//! band of x-rows, a GPU slab, a block of winding voxels, a morphology plane) and returns
//! [`Canceled`] when it says so, and reports how far it got there. Whoever started the work keeps
//! a clone: [`Control::cancel`] stops it at the next check point, a deadline
//! ([`Control::with_deadline`]) stops it once passed, and [`Control::progress`] reads the
//! fraction done (0..=1, never decreasing) from any thread.
//!
//! Progress is additive, so stages that run at the same time add up: a stage
//! ([`Control::stage`]) is a view that owns the share `lo..hi` of its parent and reports its own
//! 0..1 into it; [`Control::counter`] reports `n` of a known number of units, from any number of
//! threads; [`Control::set`] and [`Control::complete`] move a stage to a fraction or to its end.
//! A stage never reports more than its share. Everything is a few atomic operations: cheap enough
//! for every band, slab or block. [`Control::none`] is for callers that don't care.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, OnceLock};
use std::time::Instant;

/// Why work stopped before it was done.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, thiserror::Error)]
pub enum Canceled {
    /// [`Control::cancel`] was called.
    #[error("the work was canceled")]
    Canceled,
    /// The deadline of [`Control::with_deadline`] passed.
    #[error("the work ran past its deadline")]
    DeadlinePassed,
}

/// The whole, in fixed-point units of progress (exact in an f64).
const ONE: u64 = 1 << 40;
const NO_DEADLINE: u64 = u64::MAX;

/// What every view of one piece of work shares.
struct Shared {
    canceled: AtomicBool,
    /// Nanoseconds after [`epoch`], or [`NO_DEADLINE`].
    deadline: AtomicU64,
    root: Arc<Stage>,
}

/// A share of the progress: `width` units of the whole, `done` of them reported so far (its
/// own and its sub-stages'), which also count in its parent.
struct Stage {
    width: u64,
    done: AtomicU64,
    parent: Option<Arc<Stage>>,
}

impl Stage {
    /// Adds up to `delta` units (no more than the stage has left), and what was added to every
    /// ancestor.
    fn advance(&self, delta: u64) {
        let mut stage = Some(self);
        let mut d = delta;
        while let Some(s) = stage {
            if d == 0 {
                return;
            }
            let prev = s
                .done
                .fetch_update(Ordering::AcqRel, Ordering::Acquire, |x| {
                    Some(x.saturating_add(d).min(s.width))
                })
                .expect("the update always returns Some");
            d = prev.saturating_add(d).min(s.width) - prev;
            stage = s.parent.as_deref();
        }
    }

    /// Raises `done` to `target` units (clamped to the width) if it is below.
    fn raise_to(&self, target: u64) {
        let target = target.min(self.width);
        let prev = self.done.fetch_max(target, Ordering::AcqRel);
        if let (true, Some(p)) = (target > prev, &self.parent) {
            p.advance(target - prev);
        }
    }
}

/// Instants are kept as nanoseconds after this one (the first use of a control).
fn epoch() -> Instant {
    static EPOCH: OnceLock<Instant> = OnceLock::new();
    *EPOCH.get_or_init(Instant::now)
}

fn nanos(t: Instant) -> u64 {
    u64::try_from(t.saturating_duration_since(epoch()).as_nanos()).unwrap_or(NO_DEADLINE - 1)
}

/// Cancellation, an optional deadline and progress of one piece of work; clones (and stages)
/// share them.
#[derive(Clone)]
pub struct Control {
    shared: Arc<Shared>,
    stage: Arc<Stage>,
}

impl std::fmt::Debug for Control {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Control")
            .field("canceled", &self.shared.canceled.load(Ordering::Relaxed))
            .field("deadline", &self.deadline())
            .field("progress", &self.progress())
            .finish()
    }
}

impl Default for Control {
    fn default() -> Control {
        Control::new()
    }
}

impl Control {
    /// A fresh control: not canceled, no deadline, nothing done.
    pub fn new() -> Control {
        let root = Arc::new(Stage {
            width: ONE,
            done: AtomicU64::new(0),
            parent: None,
        });
        Control {
            shared: Arc::new(Shared {
                canceled: AtomicBool::new(false),
                deadline: AtomicU64::new(NO_DEADLINE),
                root: root.clone(),
            }),
            stage: root,
        }
    }

    /// For callers that neither cancel nor watch: never stops the work.
    pub fn none() -> Control {
        Control::new()
    }

    /// This control (and every clone and stage of it) with a deadline at `at`.
    pub fn with_deadline(self, at: Instant) -> Control {
        self.set_deadline(at);
        self
    }

    /// Sets the deadline of this control and every clone and stage of it.
    pub fn set_deadline(&self, at: Instant) {
        self.shared.deadline.store(nanos(at), Ordering::Release);
    }

    /// The deadline, if any (to the nanosecond).
    pub fn deadline(&self) -> Option<Instant> {
        match self.shared.deadline.load(Ordering::Acquire) {
            NO_DEADLINE => None,
            n => Some(epoch() + std::time::Duration::from_nanos(n)),
        }
    }

    /// Asks the work to stop at its next check point.
    pub fn cancel(&self) {
        self.shared.canceled.store(true, Ordering::Release);
    }

    /// Whether [`Control::cancel`] was called (a passed deadline does not count here).
    pub fn is_canceled(&self) -> bool {
        self.shared.canceled.load(Ordering::Acquire)
    }

    /// `Err` once canceled or past the deadline (a cancel wins when both hold).
    #[inline]
    pub fn check(&self) -> Result<(), Canceled> {
        if self.shared.canceled.load(Ordering::Relaxed) {
            return Err(Canceled::Canceled);
        }
        let d = self.shared.deadline.load(Ordering::Relaxed);
        if d != NO_DEADLINE && nanos(Instant::now()) >= d {
            return Err(Canceled::DeadlinePassed);
        }
        Ok(())
    }

    /// Fraction of the whole work done, 0..=1; never decreases.
    pub fn progress(&self) -> f64 {
        self.shared.root.done.load(Ordering::Acquire) as f64 / ONE as f64
    }

    /// Fraction of this stage done, 0..=1.
    pub fn stage_progress(&self) -> f64 {
        if self.stage.width == 0 {
            return 1.0;
        }
        self.stage.done.load(Ordering::Acquire) as f64 / self.stage.width as f64
    }

    /// A view for a sub-step that owns `lo..hi` (fractions of this stage, clamped to 0..=1): its
    /// progress 0..1 moves this stage's from `lo` to `hi`. Sharing cancellation and deadline.
    /// Sub-stages that tile 0..1 add up to exactly this stage's share.
    pub fn stage(&self, lo: f64, hi: f64) -> Control {
        let at = |f: f64| {
            let f = if f.is_nan() { 0.0 } else { f.clamp(0.0, 1.0) };
            (f * self.stage.width as f64).floor() as u64
        };
        let (a, b) = (at(lo), at(hi));
        Control {
            shared: self.shared.clone(),
            stage: Arc::new(Stage {
                width: b.saturating_sub(a),
                done: AtomicU64::new(0),
                parent: Some(self.stage.clone()),
            }),
        }
    }

    /// Part `i` of `n` equal parts of this stage.
    pub fn part(&self, i: usize, n: usize) -> Control {
        let n = n.max(1) as f64;
        self.stage(i as f64 / n, (i as f64 + 1.0) / n)
    }

    /// Moves this stage to `fraction` (0..=1) of its share, if it is not further already.
    pub fn set(&self, fraction: f64) {
        let f = if fraction.is_nan() {
            0.0
        } else {
            fraction.clamp(0.0, 1.0)
        };
        self.stage
            .raise_to((f * self.stage.width as f64).floor() as u64);
    }

    /// Marks this stage done (whatever its sub-steps reported).
    pub fn complete(&self) {
        self.stage.raise_to(self.stage.width);
    }

    /// A counter of `total` units of this stage: adding all of them (from any threads) completes
    /// the stage exactly.
    pub fn counter(&self, total: u64) -> Counter {
        Counter {
            control: self.clone(),
            total,
            units: AtomicU64::new(0),
        }
    }

    /// A guard that cancels this control when dropped unless [`CancelOnDrop::disarm`]ed: for
    /// work on behalf of a future that may be dropped (a client that disconnects).
    pub fn cancel_on_drop(&self) -> CancelOnDrop {
        CancelOnDrop(Some(self.clone()))
    }
}

/// Progress by units of a known total; see [`Control::counter`].
pub struct Counter {
    control: Control,
    total: u64,
    units: AtomicU64,
}

impl Counter {
    /// `n` more units are done.
    pub fn add(&self, n: u64) {
        if self.total == 0 || n == 0 {
            return;
        }
        let before = self.units.fetch_add(n, Ordering::AcqRel);
        let width = self.control.stage.width as u128;
        let at = |u: u64| (u.min(self.total) as u128 * width / self.total as u128) as u64;
        let delta = at(before.saturating_add(n)) - at(before);
        self.control.stage.advance(delta);
    }

    /// The control's [`Control::check`].
    #[inline]
    pub fn check(&self) -> Result<(), Canceled> {
        self.control.check()
    }

    pub fn control(&self) -> &Control {
        &self.control
    }
}

/// Cancels its control when dropped; see [`Control::cancel_on_drop`].
pub struct CancelOnDrop(Option<Control>);

impl CancelOnDrop {
    /// The work is over: dropping the guard no longer cancels.
    pub fn disarm(mut self) {
        self.0 = None;
    }
}

impl Drop for CancelOnDrop {
    fn drop(&mut self) {
        if let Some(c) = self.0.take() {
            c.cancel();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn cancel_and_deadline() {
        let c = Control::new();
        assert_eq!(c.check(), Ok(()));
        let view = c.stage(0.2, 0.4);
        c.clone().cancel();
        assert_eq!(view.check(), Err(Canceled::Canceled));
        let d = Control::new().with_deadline(Instant::now() - Duration::from_secs(1));
        assert_eq!(d.check(), Err(Canceled::DeadlinePassed));
        assert!(d.deadline().is_some());
        let later = Control::new().with_deadline(Instant::now() + Duration::from_secs(3600));
        assert_eq!(later.check(), Ok(()));
        assert_eq!(Control::none().deadline(), None);
        // A cancel wins over a passed deadline.
        d.cancel();
        assert_eq!(d.check(), Err(Canceled::Canceled));
    }

    #[test]
    fn stages_add_up_exactly_and_never_exceed_their_share() {
        let c = Control::new();
        let parts: Vec<Control> = (0..3).map(|i| c.part(i, 3)).collect();
        let counter = parts[0].counter(7);
        for _ in 0..7 {
            counter.add(1);
        }
        assert!((c.progress() - 1.0 / 3.0).abs() < 1e-9, "{}", c.progress());
        counter.add(100); // beyond the total: nothing more
        assert!((c.progress() - 1.0 / 3.0).abs() < 1e-9);
        parts[1].set(0.5);
        parts[1].set(0.25); // never backwards
        assert!((c.progress() - 0.5).abs() < 1e-9);
        let inner = parts[2].stage(0.0, 0.5);
        inner.complete();
        inner.complete();
        assert!((parts[2].stage_progress() - 0.5).abs() < 1e-9);
        parts[1].complete();
        parts[2].complete();
        assert_eq!(c.progress(), 1.0);
    }

    #[test]
    fn counters_from_many_threads_reach_one() {
        let c = Control::new();
        let counter = c.counter(1000);
        std::thread::scope(|s| {
            for _ in 0..4 {
                s.spawn(|| {
                    for _ in 0..250 {
                        counter.add(1);
                    }
                });
            }
        });
        assert_eq!(c.progress(), 1.0);
    }

    #[test]
    fn guard_cancels_unless_disarmed() {
        let c = Control::new();
        drop(c.cancel_on_drop());
        assert!(c.is_canceled());
        let c = Control::new();
        c.cancel_on_drop().disarm();
        assert!(!c.is_canceled());
    }
}
