//! The job queue in front of the engine: the [`JobQueue`] trait and its first implementation,
//! in-process ([`local::LocalQueue`], the default). A front submits a [`NewJob`] (a prepared
//! voxelization); workers take jobs with [`JobQueue::next`], run them through the application
//! layer and report with [`JobQueue::finish`]. Every state change is recorded as a
//! [`JobRecord`] in the store, so a job outlives the process that accepted it as a record.

pub mod local;

use std::sync::Arc;
use std::time::Duration;

use async_trait::async_trait;
use serde::{Deserialize, Serialize};

use crate::app::{Error, Prepared, Result};
use crate::cancel::Control;
use crate::grid::Grid;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum State {
    Queued,
    Running,
    Succeeded,
    Failed,
    Canceled,
}

impl State {
    pub fn is_final(self) -> bool {
        matches!(self, State::Succeeded | State::Failed | State::Canceled)
    }
    pub fn name(self) -> &'static str {
        match self {
            State::Queued => "queued",
            State::Running => "running",
            State::Succeeded => "succeeded",
            State::Failed => "failed",
            State::Canceled => "canceled",
        }
    }
}

/// A job as it is recorded and shown.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct JobRecord {
    pub id: String,
    pub state: State,
    /// 1-based position in the queue while queued.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub position: Option<usize>,
    pub progress: f64,
    pub method: String,
    pub grid: Grid,
    pub name: Option<String>,
    pub created: String,
    pub timings: Timings,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub volume_id: Option<String>,
    /// Why the job failed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<Error>,
}

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Timings {
    /// Seconds spent queued and running (so far, while unfinished).
    pub queued_s: Option<f64>,
    pub running_s: Option<f64>,
}

/// A job to queue.
pub struct NewJob {
    pub id: String,
    pub work: Prepared,
    pub name: Option<String>,
    /// RFC 3339.
    pub created: String,
}

/// A job a worker took.
pub struct Claim {
    pub id: String,
    pub work: Arc<Prepared>,
    pub name: Option<String>,
    /// The job's control: canceled when the job is canceled while it runs (the work stops at
    /// its next check point and its result is discarded), with the job's deadline when the
    /// queue has a job timeout; the job's record shows its progress while it runs.
    pub control: Control,
    /// The job timeout the deadline came from, for the problem of a job that outlives it.
    pub timeout: Option<Duration>,
}

/// What `/metrics` and `/readyz` report.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct QueueStats {
    pub depth: usize,
    pub running: usize,
    /// Jobs known, by state and method.
    pub by_state: Vec<(State, String, u64)>,
}

#[async_trait]
pub trait JobQueue: Send + Sync {
    /// Queues a job; refused with `queue-full` (with a retry delay) or `shutting-down`. The job's
    /// record is durable when this returns.
    async fn submit(&self, job: NewJob) -> Result<JobRecord>;
    async fn get(&self, id: &str) -> Result<Option<JobRecord>>;
    /// Waits up to `timeout` for the job to finish; its record then.
    async fn wait(&self, id: &str, timeout: Duration) -> Result<Option<JobRecord>>;
    /// Cancels a queued or running job; `not-cancelable` when it has already finished.
    async fn cancel(&self, id: &str) -> Result<Option<JobRecord>>;
    /// The next job by the scheduling policy; `None` once the queue is closed and drained.
    async fn next(&self) -> Option<Claim>;
    /// Records the end of a job a worker took: its volume's id, or why it failed.
    async fn finish(&self, id: &str, result: Result<String>);
    /// Stops accepting jobs and fails the queued ones with `why`; running jobs finish. The
    /// number of queued jobs failed.
    async fn close(&self, why: Error) -> usize;
    async fn stats(&self) -> QueueStats;
}
