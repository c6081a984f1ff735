//! The queue's side of the application layer: the [`JobQueue`] trait that every queue adapter
//! (`crate::queue::local`, `crate::queue::redis`) implements, what goes in ([`NewJob`]) and
//! comes out ([`Claim`], with its [`Work`]), the [`JobRecord`] every state change writes, and
//! the scheduling rule both queues follow ([`priority`]). The application owns the contract (as
//! in axum's dependency-injection example); the adapters import it from here, and never run the
//! application's pipeline themselves: a job's work is prepared by the front that submits it
//! (its mesh parsed there, once), and a shared queue stores it in the form the application
//! hands it ([`NewJob::into_shared`]), which the worker of another process decodes
//! ([`crate::app::jobs`]). Not here: how a queue keeps its jobs.

use std::sync::Arc;
use std::time::Duration;

use async_trait::async_trait;
use bytes::Bytes;
use serde::{Deserialize, Serialize};

use super::request::JobSpec;
use super::voxelize::Prepared;
use crate::cancel::Control;
use crate::grid::Grid;
use crate::limits::Limits;

// The errors a queue answers with: the application's, which the queues make and pass on.
pub use super::error::{Error, ErrorKind, Result};

/// Cost credit per second of waiting: the work of a 256³ job.
pub const AGE_CREDIT_PER_SEC: f64 = 256.0 * 256.0 * 256.0;

/// The scheduling rule of every queue: of the waiting jobs, the one with the lowest
/// `cost − AGE_CREDIT_PER_SEC × seconds waited` runs next, where the cost is the job's
/// classified voxels plus 64 per triangle ([`Prepared::cost`], [`NewJob::cost`]). Small jobs
/// therefore overtake a huge one, but a huge one that has waited long enough runs before newer
/// small ones: nothing waits forever. (The Redis queue computes the same in its claim script,
/// with [`AGE_CREDIT_PER_SEC`] passed in.)
pub fn priority(cost: f64, waited_s: f64) -> f64 {
    cost - AGE_CREDIT_PER_SEC * waited_s
}

crate::named_enum! {
    /// Where a job is in its life. Its names (records, the API, metrics) are this one table.
    pub enum State: "job state" {
        Queued = "queued",
        Running = "running",
        Succeeded = "succeeded",
        Failed = "failed",
        Canceled = "canceled",
    }
}

impl State {
    pub fn is_final(self) -> bool {
        matches!(self, State::Succeeded | State::Failed | State::Canceled)
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
    /// The name of the API key that submitted the job (never the key).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub key_name: Option<String>,
    /// The tenant that owns the job, and the volume it makes (the key's tenant).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub owner: Option<String>,
    /// The id of the request that submitted the job (its `X-Request-Id`): what ties the job's
    /// log lines to the request's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub request_id: Option<String>,
    pub created: String,
    pub timings: Timings,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub volume_id: Option<String>,
    /// Times the job was started (more than one when its process or replica died during a
    /// start and it was run again); not shown for a job never started, nor by the in-process
    /// queue for a job whose answer was still awaited (it is not kept through a crash).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub attempts: Option<u32>,
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
    /// The same request as data: what a queue shared by replicas keeps with the job, beside
    /// the bytes of [`NewJob::into_shared`], so that any of them can run it. The in-process
    /// queue runs `work` and ignores it.
    pub spec: JobSpec,
    pub name: Option<String>,
    /// The API key that submitted it, and how many jobs that key may have queued or running
    /// at once (`None`: the service needs no keys).
    pub owner: Option<Owner>,
    /// The request that submitted it (for its record and log lines).
    pub request_id: Option<String>,
    /// RFC 3339.
    pub created: String,
}

/// Whose job it is (an API key's name) and that key's limit of jobs queued or running at once
/// (0: none). A queue refuses a job past the limit with `too-many-jobs`, counted over every
/// replica that shares the queue.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Owner {
    pub name: String,
    pub max_jobs: usize,
    /// The tenant whose volumes and jobs the key works with (the key's name unless its line
    /// says `tenant=`): what the volumes and jobs it makes are owned by.
    pub tenant: String,
    pub role: Role,
}

/// What a key may do (`role=` in the keys file).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Role {
    /// Reads and writes its tenant's volumes and jobs.
    #[default]
    User,
    /// Reads its tenant's volumes and jobs; every write is `403 forbidden`.
    ReadOnly,
    /// Reads and writes every tenant's volumes and jobs (and those owned by none).
    Admin,
}

impl Role {
    pub fn parse(s: &str) -> Option<Role> {
        match s {
            "user" => Some(Role::User),
            "read-only" => Some(Role::ReadOnly),
            "admin" => Some(Role::Admin),
            _ => None,
        }
    }
}

impl Owner {
    /// Whether this key may see a volume or job owned by `owner` (`None`: made without keys,
    /// or before volumes had owners): its tenant's, and every one for an admin.
    pub fn sees(&self, owner: Option<&str>) -> bool {
        self.role == Role::Admin || owner == Some(self.tenant.as_str())
    }

    /// The refusal of a job past the key's limit.
    pub fn too_many(&self, active: usize) -> Error {
        Error::new(
            ErrorKind::TooManyJobs,
            format!(
                "key {} has {active} jobs queued or running, and may have at most {}; retry once one has finished",
                self.name, self.max_jobs
            ),
        )
        .retry_after(5)
    }
}

impl NewJob {
    /// The job's estimated cost, what [`priority`] orders it by ([`Prepared::cost`]).
    pub fn cost(&self) -> f64 {
        self.work.cost()
    }

    /// The method's name (what records and metrics show).
    pub fn method(&self) -> &'static str {
        self.work.method.name()
    }

    /// The prepared work, for the queue to hand to the worker that takes the job.
    pub fn into_work(self) -> Work {
        Work::Prepared(Arc::new(self.work))
    }

    /// For a queue shared by replicas: the prepared work, for the queue to hand to a worker of
    /// this process, and the bytes to store under the job's id
    /// ([`VolumeStore::put_upload`](super::store::VolumeStore::put_upload)) for a worker of any
    /// process, which turns them back into the same work without parsing the mesh again
    /// ([`crate::app::jobs::stored`]). Encoding copies the mesh: done on a blocking thread.
    pub async fn into_shared(self) -> Result<(Work, Bytes)> {
        let work = Arc::new(self.work);
        let p = work.clone();
        let bytes = super::ops::blocking(move || Ok(super::jobs::stored::encode(&p))).await?;
        Ok((Work::Prepared(work), Bytes::from(bytes)))
    }

    /// The record of this job as it enters a queue.
    pub fn queued_record(&self) -> JobRecord {
        JobRecord {
            id: self.id.clone(),
            state: State::Queued,
            position: None,
            progress: 0.0,
            method: self.work.method.name().into(),
            grid: self.work.grid,
            name: self.name.clone(),
            key_name: self.owner.as_ref().map(|o| o.name.clone()),
            owner: self.owner.as_ref().map(|o| o.tenant.clone()),
            request_id: self.request_id.clone(),
            created: self.created.clone(),
            timings: Timings::default(),
            volume_id: None,
            attempts: None,
            error: None,
        }
    }
}

/// What a worker runs.
#[derive(Clone, Debug)]
pub enum Work {
    /// Prepared by the front that submitted the job, in this process: run as it is.
    Prepared(Arc<Prepared>),
    /// Submitted elsewhere (another replica, or an earlier process): the worker prepares it
    /// from the job's stored request (`spec`, the [`JobSpec`] as JSON) and its stored upload
    /// (in the store, under the job's id: the prepared job of [`NewJob::into_shared`], decoded
    /// rather than parsed), held to this process's `limits`.
    Stored { spec: String, limits: Limits },
}

/// A job a worker took.
pub struct Claim {
    pub id: String,
    pub work: Work,
    pub name: Option<String>,
    /// The tenant that owns the job: its volume's owner.
    pub owner: Option<String>,
    /// The request that submitted it (its record's), for the job's log lines.
    pub request_id: Option<String>,
    /// The job's control: canceled when the job is canceled while it runs (the work stops at
    /// its next check point and its result is discarded), with the job's deadline when the
    /// queue has a job timeout; the job's record shows its progress while it runs.
    pub control: Control,
    /// The job timeout the deadline came from, for the problem of a job that outlives it.
    pub timeout: Option<Duration>,
    /// The id the job's volume gets: a shared queue derives it from the job's, so that a job
    /// run twice (its replica was thought dead, another ran it too) writes one volume, not two.
    /// `None`: a fresh id.
    pub volume_id: Option<String>,
    /// Asked just before the volume is stored (`None`: nothing to ask).
    pub guard: Option<Arc<dyn CommitGuard>>,
}

/// The last word before a worker stores a job's volume: a shared queue checks that the job is
/// still this worker's (not canceled from another replica, not taken over by one).
#[async_trait]
pub trait CommitGuard: Send + Sync {
    /// `Err` (the job's result is discarded) when the volume must not be stored.
    async fn confirm(&self) -> Result<()>;
}

/// What `/metrics` and `/readyz` report.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct QueueStats {
    pub depth: usize,
    pub running: usize,
    /// Jobs known, by state and method.
    pub by_state: Vec<(State, String, u64)>,
    /// Seconds the oldest waiting job has waited (0 when none waits).
    pub oldest_queued_s: f64,
    /// Waiting jobs by size class, for a queue that keeps classes apart (empty otherwise).
    pub classes: Vec<(&'static str, usize)>,
    /// Why the queue cannot be answered for now (a shared queue whose server is unreachable):
    /// `/readyz` is then 503 and the numbers above are zero.
    pub unavailable: Option<String>,
}

#[async_trait]
pub trait JobQueue: Send + Sync {
    /// Queues a job; refused with `queue-full` (with a retry delay) or `shutting-down`. The job's
    /// record is durable when this returns.
    async fn submit(&self, job: NewJob) -> Result<JobRecord>;
    /// [`JobQueue::submit`] for a caller that waits for the job before it answers (`wait`): the
    /// record need be durable only once the job is final or [`JobQueue::persist`] returns,
    /// which a caller that answers before the job is final calls first. A job that finishes
    /// meanwhile has one record written instead of two. By default: `submit`.
    async fn submit_deferred(&self, job: NewJob) -> Result<JobRecord> {
        self.submit(job).await
    }
    /// Makes job `id`'s record as it is now durable (after [`JobQueue::submit_deferred`]). By
    /// default there is nothing to do: records are durable when a change returns.
    async fn persist(&self, _id: &str) -> Result<()> {
        Ok(())
    }
    /// A cheap look, before an upload is read and parsed, at whether a job would be refused
    /// now (`queue-full`, `shutting-down`, `too-many-jobs`): what [`JobQueue::submit`] would
    /// say. Not a promise either way; `submit` decides. By default: nothing to say.
    async fn admission(&self, _owner: Option<&Owner>) -> Result<()> {
        Ok(())
    }
    async fn get(&self, id: &str) -> Result<Option<JobRecord>>;
    /// Waits up to `timeout` for the job to finish; its record then.
    async fn wait(&self, id: &str, timeout: Duration) -> Result<Option<JobRecord>>;
    /// Cancels a queued or running job; `not-cancelable` when it has already finished.
    async fn cancel(&self, id: &str) -> Result<Option<JobRecord>>;
    /// The next job by the scheduling policy; `None` once the queue is closed and drained.
    async fn next(&self) -> Option<Claim>;
    /// Says that the worker of job `id` is about to store its volume as `volume_id`, so that
    /// the queue may write the job's final record while the volume is written rather than after
    /// it (as the in-process queue does). Writes nothing the job's state depends on before
    /// [`JobQueue::finish`]. By default: nothing.
    fn storing(&self, _id: &str, _volume_id: &str) {}
    /// Records the end of a job a worker took: its volume's id, or why it failed.
    async fn finish(&self, id: &str, result: Result<String>);
    /// Stops accepting jobs and fails the queued ones that would not survive the process with
    /// `why` (kept jobs stay queued for the next start); running jobs finish. The number of
    /// queued jobs failed.
    async fn close(&self, why: Error) -> usize;
    async fn stats(&self) -> QueueStats;
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The states' names are the ones records, the API and metrics have always used, both ways.
    #[test]
    fn states_are_named_once_and_read_back() {
        let names: Vec<&str> = State::ALL.iter().map(|s| s.name()).collect();
        assert_eq!(
            names,
            ["queued", "running", "succeeded", "failed", "canceled"]
        );
        for s in State::ALL {
            let json = serde_json::to_string(&s).unwrap();
            assert_eq!(json, format!("\"{}\"", s.name()));
            assert_eq!(serde_json::from_str::<State>(&json).unwrap(), s);
            assert_eq!(s.to_string().parse::<State>(), Ok(s));
        }
        assert!(serde_json::from_str::<State>("\"paused\"").is_err());
        assert_eq!(
            State::ALL.iter().filter(|s| s.is_final()).count(),
            3,
            "succeeded, failed and canceled are final"
        );
    }

    /// A large job that has waited long enough goes before a new small one, and not before.
    #[test]
    fn the_age_credit_lets_a_waiting_large_job_overtake() {
        let (small, large) = (64f64.powi(3), 512f64.powi(3));
        assert!(priority(small, 0.0) < priority(large, 0.0));
        // 512³ = 8 × 256³: after 8 s of waiting it scores as a fresh job of cost 0.
        assert!(priority(large, 8.0) < priority(small, 0.0));
        assert!(priority(large, 7.0) > priority(small, 0.0));
    }
}
