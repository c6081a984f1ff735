//! Group submission: jobs that reach the device while it is busy go to it together, in one
//! submission, as a store's group commit gathers the writes that arrive during a sync.
//!
//! A job records its command buffer on its own thread (building work items and writing its
//! triangles overlap whatever the device is running), then hands it to [`Batcher::run`]. If no
//! batch is being run, the caller becomes the leader: it takes every item waiting (its own among
//! them), runs them as one batch and wakes the others. Items that arrive meanwhile wait for the
//! next leader, one of their own threads, so the device is given the next batch as soon as it
//! finishes the last. No thread waits for a batch that does not hold its item, and none leads
//! more than once per call.
//!
//! This module knows nothing of wgpu: what a batch is run by is the caller's closure, which is
//! how the tests drive it.

use std::collections::HashMap;
use std::sync::{Condvar, Mutex, MutexGuard};

use super::BatchStats;

/// Items that have reached the batcher and results not yet taken, by ticket.
struct State<T, R> {
    waiting: Vec<(u64, T)>,
    /// A leader is running a batch.
    leading: bool,
    next: u64,
    /// Results by ticket; `None` for the items of a batch whose leader panicked.
    done: HashMap<u64, Option<R>>,
    stats: BatchStats,
}

pub(super) struct Batcher<T, R> {
    state: Mutex<State<T, R>>,
    finished: Condvar,
}

impl<T, R> Batcher<T, R> {
    pub fn new() -> Batcher<T, R> {
        Batcher {
            state: Mutex::new(State {
                waiting: Vec::new(),
                leading: false,
                next: 0,
                done: HashMap::new(),
                stats: BatchStats::default(),
            }),
            finished: Condvar::new(),
        }
    }

    fn lock(&self) -> MutexGuard<'_, State<T, R>> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The batches run so far.
    pub fn stats(&self) -> BatchStats {
        self.lock().stats
    }

    /// Runs `item` in a batch with whatever else is waiting, and returns its result: `lead`
    /// gets the batch's items in the order they came and must return one result per item, in
    /// the same order. `None` when the batch's leader panicked (its items were not all run).
    pub fn run(&self, item: T, lead: impl FnOnce(Vec<T>) -> Vec<R>) -> Option<R> {
        let mut state = self.lock();
        let ticket = state.next;
        state.next += 1;
        state.waiting.push((ticket, item));
        loop {
            if let Some(result) = state.done.remove(&ticket) {
                return result;
            }
            if !state.leading {
                break;
            }
            state = self.finished.wait(state).unwrap_or_else(|e| e.into_inner());
        }
        // Lead: the batch is everything waiting, this item included (it cannot have been taken
        // by another leader, or its result would be there).
        state.leading = true;
        let (tickets, items): (Vec<u64>, Vec<T>) =
            std::mem::take(&mut state.waiting).into_iter().unzip();
        let s = &mut state.stats;
        s.batches += 1;
        s.items += items.len() as u64;
        s.largest = s.largest.max(items.len() as u64);
        drop(state);
        // If `lead` panics, the guard ends the batch: its items get `None`, and another thread
        // may lead the next one.
        let mut guard = EndBatch {
            batcher: self,
            own: ticket,
            tickets,
            results: None,
        };
        let results = lead(items);
        assert_eq!(
            results.len(),
            guard.tickets.len(),
            "a batch must give one result per item"
        );
        guard.results = Some(results);
        drop(guard);
        self.lock().done.remove(&ticket).flatten()
    }
}

/// Ends a batch, also when its leader unwinds: files its results (or `None` for each item) and
/// wakes the waiting threads.
struct EndBatch<'a, T, R> {
    batcher: &'a Batcher<T, R>,
    /// The leader's own item: not filed when the leader unwinds (nobody would take it).
    own: u64,
    tickets: Vec<u64>,
    results: Option<Vec<R>>,
}

impl<T, R> Drop for EndBatch<'_, T, R> {
    fn drop(&mut self) {
        let mut state = self.batcher.lock();
        match self.results.take() {
            Some(results) => {
                for (t, r) in self.tickets.drain(..).zip(results) {
                    state.done.insert(t, Some(r));
                }
            }
            None => {
                for t in self.tickets.drain(..).filter(|&t| t != self.own) {
                    state.done.insert(t, None);
                }
            }
        }
        state.leading = false;
        drop(state);
        self.batcher.finished.notify_all();
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;
    use std::sync::mpsc;
    use std::thread::JoinHandle;
    use std::time::Duration;

    use super::*;

    /// A batcher whose first batch, `[0]`, stays on the "device" until released, and whose
    /// other batches give each item times ten, or panic (quietly) when `panic_at` items come
    /// together.
    struct Rig {
        batcher: Arc<Batcher<u32, u32>>,
        batches: Arc<Mutex<Vec<Vec<u32>>>>,
        entered: mpsc::Sender<()>,
        hold: Arc<Mutex<mpsc::Receiver<()>>>,
        panic_at: usize,
    }

    impl Rig {
        /// The rig, a receiver told when batch `[0]` runs, and the sender that releases it.
        fn new(panic_at: usize) -> (Rig, mpsc::Receiver<()>, mpsc::Sender<()>) {
            let (entered, leader_in) = mpsc::channel();
            let (release, hold) = mpsc::channel();
            let rig = Rig {
                batcher: Arc::new(Batcher::new()),
                batches: Arc::default(),
                entered,
                hold: Arc::new(Mutex::new(hold)),
                panic_at,
            };
            (rig, leader_in, release)
        }

        fn call(&self, item: u32) -> JoinHandle<Option<u32>> {
            let (batcher, batches) = (self.batcher.clone(), self.batches.clone());
            let (entered, hold, panic_at) =
                (self.entered.clone(), self.hold.clone(), self.panic_at);
            std::thread::spawn(move || {
                batcher.run(item, |items| {
                    batches.lock().unwrap().push(items.clone());
                    if items == [0] {
                        entered.send(()).unwrap();
                        hold.lock().unwrap().recv().unwrap();
                    }
                    if items.len() == panic_at {
                        // A panic, as a lost device raises, without the panic hook's message
                        // and backtrace note in a passing run's output: resume_unwind unwinds
                        // without calling the hook.
                        std::panic::resume_unwind(Box::new("the device is gone"));
                    }
                    items.iter().map(|i| i * 10).collect()
                })
            })
        }

        /// Waits (bounded) until `n` items wait behind the running batch.
        fn await_waiting(&self, n: usize) {
            for _ in 0..2_000 {
                if self.batcher.lock().waiting.len() == n {
                    break;
                }
                std::thread::sleep(Duration::from_millis(1));
            }
            assert_eq!(self.batcher.lock().waiting.len(), n);
        }
    }

    /// While a leader runs a batch, items that arrive wait and go together in the next batch,
    /// led by one of their threads; every caller gets its own item's result.
    #[test]
    fn items_that_arrive_during_a_batch_go_together_in_the_next() {
        let (rig, leader_in, release) = Rig::new(usize::MAX);
        let first = rig.call(0);
        leader_in.recv().unwrap();
        let others: Vec<_> = (1..=5).map(|i| rig.call(i)).collect();
        rig.await_waiting(5);
        release.send(()).unwrap();
        assert_eq!(first.join().unwrap(), Some(0));
        for (i, t) in others.into_iter().enumerate() {
            assert_eq!(t.join().unwrap(), Some(10 * (i as u32 + 1)));
        }
        let mut seen = rig.batches.lock().unwrap().clone();
        assert_eq!(seen.len(), 2, "{seen:?}");
        seen[1].sort();
        assert_eq!(seen, [vec![0], vec![1, 2, 3, 4, 5]]);
        assert_eq!(
            rig.batcher.stats(),
            BatchStats {
                batches: 2,
                items: 6,
                largest: 5
            }
        );
        let state = rig.batcher.lock();
        assert!(state.done.is_empty() && !state.leading);
    }

    /// A leader that panics ends its batch: the batch's other items get `None`, nothing is
    /// left behind, and later items still run.
    #[test]
    fn a_panicking_leader_fails_its_batch_and_frees_the_batcher() {
        let (rig, leader_in, release) = Rig::new(2);
        let first = rig.call(0);
        leader_in.recv().unwrap();
        let (a, b) = (rig.call(1), rig.call(2));
        rig.await_waiting(2);
        release.send(()).unwrap();
        assert_eq!(first.join().unwrap(), Some(0));
        // One of the two led the batch and panicked; the other got `None`.
        let mut ends: Vec<String> = [a.join(), b.join()]
            .into_iter()
            .map(|r| match r {
                Ok(v) => format!("{v:?}"),
                Err(_) => "panicked".into(),
            })
            .collect();
        ends.sort();
        assert_eq!(ends, ["None", "panicked"]);
        {
            let state = rig.batcher.lock();
            assert!(state.done.is_empty() && !state.leading && state.waiting.is_empty());
        }
        assert_eq!(rig.call(3).join().unwrap(), Some(30));
    }
}
