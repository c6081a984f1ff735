//! The queue adapters: in-process ([`local::LocalQueue`], the default) and shared by replicas
//! over Redis Streams ([`redis::RedisQueue`], `--queue redis://…`). Each implements the
//! application's [`JobQueue`] trait (declared in [`crate::app::queue`], with [`NewJob`],
//! [`Claim`], [`JobRecord`] and the scheduling rule). A front submits a [`NewJob`]; workers take
//! jobs with [`JobQueue::next`], run them through the application layer and report with
//! [`JobQueue::finish`]. Every state change is recorded as a [`JobRecord`] (in the store, or in
//! Redis), so a job outlives the process that accepted it. Not here: running a job (the
//! application's worker, [`crate::app::jobs`]).

pub mod local;
#[cfg(feature = "redis")]
pub mod redis;

// The contract's names where older callers look for them.
pub use crate::app::queue::{
    Claim, CommitGuard, JobQueue, JobRecord, NewJob, Owner, QueueStats, State, Timings, Work,
};
