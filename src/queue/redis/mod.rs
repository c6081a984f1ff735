//! The queue shared by replicas: Redis Streams with one consumer group (`voxd serve --queue
//! redis://HOST:PORT[/DB]`). Any replica accepts a job, any replica with a free worker takes
//! the next one; the job's record lives in Redis, so every replica answers for every job.
//!
//! - **Submit**: the prepared job (its mesh in binary form, [`NewJob::into_shared`]) goes to
//!   the store first ([`VolumeStore::put_upload`]), then the job (its request as data, a
//!   `JobSpec`) enters the stream of its size class, in one script that also checks the shared
//!   capacity (`429` when full). The request was prepared (validated) before, so a bad mesh is
//!   refused at once, and the mesh is parsed once per job, whichever replica runs it.
//! - **Classes**: one stream per size class by estimated cost (small ≤ a 256³ job, medium ≤
//!   512³, large beyond). A worker takes, of the classes' next jobs, the one with the lowest
//!   `cost − 256³ × seconds waited`, the in-process queue's rule: small jobs overtake large
//!   ones, and a large one that has waited long enough is not overtaken again.
//! - **Running**: the worker that took a job (XREADGROUP) is handed its stored request
//!   ([`Work::Stored`]), which the application's worker decodes from the stored upload (a job
//!   submitted to this very replica is handed its prepared mesh instead), and renews its lease
//!   every `min(lease/3, 1 s)` while it runs: the renewal resets the entry's idle time (XCLAIM
//!   by its own consumer), reports progress and hears a cancel.
//! - **Dead workers**: an entry idle for a lease (`--lease-seconds`) belongs to a worker that
//!   stopped: the next replica looking for work takes it over (XAUTOCLAIM) and runs it again, at
//!   most `--max-attempts` starts in all; then the job fails with a problem saying why.
//! - **One result**: a job's volume id is derived from the job's ([`volume_id_for`]), so two
//!   runs of one job (a worker thought dead that was not) write one volume, not two; the finish
//!   is a compare-and-set on the run's token, and a run that lost its job never records it.
//!   Whatever is left of a job that did not succeed (its upload, a volume a lost run stored) is
//!   removed by whoever records its end.
//! - **Cancel** from any replica: a queued job's entry is deleted (never delivered); a running
//!   one is marked canceled, its worker stops at its next renewal and its result is discarded.
//! - **Records** are Redis hashes; finished ones expire after [`RedisOptions::record_ttl`].
//!   `wait` polls with bounded backoff and wakes early on the `done` events of a pub/sub
//!   channel; idle workers wake on its `new` events (and poll twice a second regardless, which
//!   is also how they notice expired leases).
//! - **Redis down**: calls fail with `queue-unavailable` (503, `Retry-After`), the connection
//!   manager reconnects, workers back off and retry; a job whose worker could not renew for a
//!   lease is run again once Redis is back. With `appendonly yes` (and `appendfsync always`)
//!   an accepted job survives a Redis restart.
//!
//! Every state change is one Lua script (scripts.rs), atomic in Redis; times are Redis's clock.

mod events;
mod lease;
mod scripts;

use std::collections::{HashMap, VecDeque};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use async_trait::async_trait;
use redis::aio::{ConnectionManager, ConnectionManagerConfig};
use tokio::sync::{Notify, broadcast, watch};

use crate::app::queue::{
    AGE_CREDIT_PER_SEC, Claim, Error, ErrorKind, JobQueue, JobRecord, NewJob, Owner, QueueStats,
    Result, State, Timings, Work,
};
use crate::app::store::{VolumeStore, sha256_hex};
use crate::cancel::Control;
use crate::limits::Limits;
use events::listen;
use lease::{Guard, renew};
use scripts::{Cancel, Claimed, Finished, Redis, Run, Submitted};

/// The size classes, each a stream, in the order their names sort jobs (small first).
pub const CLASSES: [&str; 3] = ["small", "medium", "large"];

/// How often an idle worker looks for work (and expired leases) without being woken.
const IDLE_POLL: Duration = Duration::from_millis(500);

/// Lease of a running job (`--lease-seconds`): a default `voxd serve` and [`RedisOptions::new`]
/// share.
pub const DEFAULT_LEASE_S: f64 = crate::limits::serve::LEASE_S;

/// Starts of one job at most (`--max-attempts`).
pub const DEFAULT_MAX_ATTEMPTS: u32 = crate::limits::serve::MAX_ATTEMPTS;

/// Prepared meshes of jobs submitted here, kept for when this replica runs them.
const PREPARED_KEPT: usize = 8;

/// How long a worker keeps trying to record a job's end while Redis is unreachable.
const FINISH_RETRY: Duration = Duration::from_secs(120);

/// The size class of a job of estimated `cost` ([`NewJob::cost`]).
pub fn class_of(cost: f64) -> &'static str {
    if cost <= 256f64.powi(3) {
        "small"
    } else if cost <= 512f64.powi(3) {
        "medium"
    } else {
        "large"
    }
}

/// The id of job `job`'s volume: 16 hex digits of sha256("voxd-volume:" + job), the same on
/// every replica and every attempt.
pub fn volume_id_for(job: &str) -> String {
    sha256_hex(format!("voxd-volume:{job}").as_bytes())[..16].to_string()
}

/// How a [`RedisQueue`] behaves.
#[derive(Clone, Debug)]
pub struct RedisOptions {
    /// Jobs that may wait, over all replicas (`--queue-capacity`); more get 429.
    pub capacity: usize,
    /// A running job's worker renews its lease within this; an entry idle this long is taken
    /// over by another replica (`--lease-seconds`).
    pub lease: Duration,
    /// Starts of one job at most (`--max-attempts`).
    pub max_attempts: u32,
    /// How long one run may take (`--job-timeout`).
    pub job_timeout: Option<Duration>,
    /// Prefix of every key and of the channel: replicas with one prefix share one queue.
    pub prefix: String,
    /// How long the records of finished jobs are kept.
    pub record_ttl: Duration,
    /// This process's limits: a job its worker prepares again here is held to them too.
    pub limits: Limits,
}

impl RedisOptions {
    pub fn new(capacity: usize) -> RedisOptions {
        RedisOptions {
            capacity,
            lease: Duration::from_secs_f64(DEFAULT_LEASE_S),
            max_attempts: DEFAULT_MAX_ATTEMPTS,
            job_timeout: None,
            prefix: "voxd".into(),
            record_ttl: Duration::from_secs(7 * 24 * 3600),
            limits: Limits::SERVICE,
        }
    }

    fn ttl_s(&self) -> u64 {
        self.record_ttl.as_secs().max(1)
    }
}

/// A job this process runs.
struct Running {
    token: String,
    control: Control,
    renewal: tokio::task::JoinHandle<()>,
}

struct Inner {
    redis: Redis,
    store: Arc<dyn VolumeStore>,
    opts: RedisOptions,
    /// This process's name in the consumer group.
    consumer: String,
    /// Where Redis is (without a password), for messages.
    target: String,
    /// Woken by `new` events (and on reconnects).
    ready: Notify,
    /// Ids of jobs that finished (`""`: everyone look again).
    done: broadcast::Sender<String>,
    closed: watch::Sender<bool>,
    running: Mutex<HashMap<String, Running>>,
    prepared: Mutex<VecDeque<(String, Work)>>,
}

pub struct RedisQueue {
    inner: Arc<Inner>,
    events: tokio::task::JoinHandle<()>,
}

impl Drop for RedisQueue {
    fn drop(&mut self) {
        self.events.abort();
        for (_, r) in self.inner.lock_running().drain() {
            r.renewal.abort();
        }
    }
}

/// Six hex digits that differ between processes (and between queues of one process): a
/// consumer name's tail.
fn nonce() -> String {
    crate::app::store::random_hex::<3>()
}

/// `url` without its password.
fn redact(url: &str) -> String {
    match (url.find("://"), url.rfind('@')) {
        (Some(s), Some(at)) if at > s => format!("{}***{}", &url[..s + 3], &url[at..]),
        _ => url.to_string(),
    }
}

/// The `major.minor` of an `INFO server` reply.
fn redis_version(info: &str) -> Option<(u32, u32)> {
    let v = info
        .lines()
        .find_map(|l| l.strip_prefix("redis_version:"))?
        .trim();
    let mut it = v.split('.').map(|p| p.parse::<u32>().ok());
    Some((it.next()??, it.next()??))
}

impl RedisQueue {
    /// Connects to the Redis at `url` (refusing a server older than 6.2, which lacks
    /// XAUTOCLAIM), creates the consumer groups and starts listening for events. An unreachable
    /// server is an error naming it: `voxd serve` refuses to start.
    pub async fn open(
        url: &str,
        opts: RedisOptions,
        store: Arc<dyn VolumeStore>,
    ) -> std::result::Result<RedisQueue, String> {
        let mut opts = opts;
        // Renewals come every third of the lease: not a busy loop.
        opts.lease = opts.lease.max(Duration::from_millis(100));
        let target = redact(url);
        let client = redis::Client::open(url).map_err(|e| {
            format!("--queue {target} is not a Redis URL (redis://HOST:PORT[/DB]): {e}")
        })?;
        let config = ConnectionManagerConfig::new()
            .set_connection_timeout(Some(Duration::from_secs(2)))
            .set_response_timeout(Some(Duration::from_secs(10)))
            .set_number_of_retries(2)
            .set_max_delay(Duration::from_secs(1));
        let unreachable = |e: &dyn std::fmt::Display| {
            format!(
                "cannot reach the job queue at {target}: {e}; start Redis there or correct --queue (VOXD_QUEUE)"
            )
        };
        let conn = tokio::time::timeout(
            Duration::from_secs(15),
            ConnectionManager::new_with_config(client.clone(), config),
        )
        .await
        .map_err(|_| unreachable(&"no answer within 15 s"))?
        .map_err(|e| unreachable(&e))?;
        let info: String = redis::cmd("INFO")
            .arg("server")
            .query_async(&mut conn.clone())
            .await
            .map_err(|e| unreachable(&e))?;
        match redis_version(&info) {
            Some(v) if v >= (6, 2) => {}
            v => {
                return Err(format!(
                    "the Redis at {target} is version {v:?}; the job queue needs 6.2 or later (XAUTOCLAIM)"
                ));
            }
        }
        let redis = Redis::new(conn, &opts.prefix);
        redis.ensure_groups().await.map_err(|e| unreachable(&e))?;
        let host = std::fs::read_to_string("/proc/sys/kernel/hostname")
            .ok()
            .map(|h| h.trim().to_string())
            .filter(|h| !h.is_empty())
            .unwrap_or_else(|| "voxd".into());
        let consumer = format!("{host}-{}-{}", std::process::id(), nonce());
        tracing::info!(queue = %target, %consumer, "shared job queue ready");
        let (done, _) = broadcast::channel(256);
        let inner = Arc::new(Inner {
            redis,
            store,
            opts,
            consumer,
            target,
            ready: Notify::new(),
            done,
            closed: watch::channel(false).0,
            running: Mutex::new(HashMap::new()),
            prepared: Mutex::new(VecDeque::new()),
        });
        let events = tokio::spawn(listen(client, Arc::downgrade(&inner)));
        Ok(RedisQueue { inner, events })
    }

    /// This process's consumer name (in logs and in the problem of a job whose runs all died).
    pub fn consumer(&self) -> &str {
        &self.inner.consumer
    }
}

impl Inner {
    fn lock_running(&self) -> std::sync::MutexGuard<'_, HashMap<String, Running>> {
        self.running.lock().unwrap_or_else(|p| p.into_inner())
    }

    fn lock_prepared(&self) -> std::sync::MutexGuard<'_, VecDeque<(String, Work)>> {
        self.prepared.lock().unwrap_or_else(|p| p.into_inner())
    }

    fn forget_prepared(&self, id: &str) {
        self.lock_prepared().retain(|(j, _)| j != id);
    }

    fn unavailable(&self, e: &redis::RedisError) -> Error {
        Error::new(
            ErrorKind::QueueUnavailable,
            format!(
                "the job queue (Redis at {}) cannot be reached: {e}; retry shortly",
                self.target
            ),
        )
        .retry_after(5)
    }

    fn is_closed(&self) -> bool {
        *self.closed.borrow()
    }

    /// `shutting-down` once this replica is closed.
    fn open_for_jobs(&self) -> Result<()> {
        if self.is_closed() {
            return Err(Error::new(
                ErrorKind::ShuttingDown,
                "this replica is shutting down; retry on another",
            ));
        }
        Ok(())
    }

    /// Removes what is left of a job that has ended: its upload, and its volume unless the
    /// job succeeded with it (a run that lost its job may have stored one).
    async fn clean_up(&self, id: &str, keep_volume: bool) {
        self.forget_prepared(id);
        if let Err(e) = self.store.delete_upload(id).await {
            tracing::warn!(job = %id, "cannot remove the job's upload: {e}");
        }
        if !keep_volume {
            let volume = volume_id_for(id);
            if let Ok(Some(meta)) = self.store.get(&volume).await {
                tracing::info!(job = %id, %volume, "removing the volume of a run whose result is discarded");
                let deleted =
                    crate::app::sources::delete_volume(&*self.store, &volume, Some(meta)).await;
                if let Err(e) = deleted {
                    tracing::warn!(job = %id, "cannot remove a discarded volume: {e}");
                }
            }
        }
    }

    /// A run's work: the prepared voxelization kept from its submit here, else its stored
    /// request, which the worker prepares from the stored prepared job (decoded: the mesh was
    /// parsed once, by the replica it was submitted to).
    fn work(&self, run: &Run) -> Work {
        let mut kept = self.lock_prepared();
        if let Some(i) = kept.iter().position(|(j, _)| *j == run.id) {
            return kept.remove(i).expect("present").1;
        }
        Work::Stored {
            spec: run.spec.clone(),
            limits: self.opts.limits,
        }
    }

    /// Takes the next job, if any: expired leases first, then new jobs; clears what it meets.
    async fn claim(&self) -> std::result::Result<Option<Claim>, redis::RedisError> {
        let o = &self.opts;
        // Every answer but `Run` and none cleared an entry: bounded, for a stream full of them.
        for _ in 0..1000 {
            let claimed = self
                .redis
                .claim(
                    &self.consumer,
                    o.lease.as_millis() as u64,
                    o.max_attempts.max(1),
                    AGE_CREDIT_PER_SEC,
                    o.ttl_s(),
                    o.lease.as_secs_f64(),
                )
                .await?;
            match claimed {
                None => return Ok(None),
                Some(Claimed::Dropped) => {}
                Some(Claimed::Failed { id }) => {
                    tracing::warn!(job = %id, "the job's last attempt's replica died too; failed");
                    self.clean_up(&id, false).await;
                }
                Some(Claimed::Cleaned { id, state, .. }) => {
                    self.clean_up(&id, state == "succeeded").await;
                }
                Some(Claimed::Run(run)) => {
                    if run.attempt > 1 {
                        tracing::warn!(job = %run.id, attempt = run.attempt, "taking over a job whose replica stopped renewing its lease");
                    }
                    if let Some(claim) = self.start(run).await {
                        return Ok(Some(claim));
                    }
                }
            }
        }
        Ok(None)
    }

    /// Starts a run: its lease renewal, its deadline, and its claim (the worker prepares its
    /// work when it was not submitted here).
    async fn start(&self, run: Run) -> Option<Claim> {
        let control = Control::new();
        let every = (self.opts.lease / 3).min(Duration::from_secs(1));
        let renewal = tokio::spawn(renew(
            self.redis.clone(),
            self.consumer.clone(),
            run.id.clone(),
            run.token.clone(),
            control.clone(),
            every,
        ));
        self.lock_running().insert(
            run.id.clone(),
            Running {
                token: run.token.clone(),
                control: control.clone(),
                renewal,
            },
        );
        let work = self.work(&run);
        if let Some(at) = self
            .opts
            .job_timeout
            .and_then(|t| Instant::now().checked_add(t))
        {
            control.set_deadline(at);
        }
        let (name, owner, request_id) = serde_json::from_str::<JobRecord>(&run.record)
            .ok()
            .map_or((None, None, None), |r| (r.name, r.owner, r.request_id));
        Some(Claim {
            id: run.id.clone(),
            work,
            name,
            owner,
            request_id,
            control: control.clone(),
            timeout: self.opts.job_timeout,
            volume_id: Some(volume_id_for(&run.id)),
            guard: Some(Arc::new(Guard {
                redis: self.redis.clone(),
                consumer: self.consumer.clone(),
                id: run.id,
                token: run.token,
                control,
            })),
        })
    }

    async fn finish(&self, id: &str, result: Result<String>) {
        let Some(run) = self.lock_running().remove(id) else {
            return;
        };
        run.renewal.abort();
        let (state, volume, error, progress) = match &result {
            Ok(v) => ("succeeded", v.as_str(), String::new(), 1.0),
            Err(e) => (
                "failed",
                "",
                serde_json::to_string(e).expect("an error serialises"),
                run.control.progress(),
            ),
        };
        let give_up = Instant::now() + FINISH_RETRY;
        let mut backoff = Duration::from_millis(100);
        let finished = loop {
            match self
                .redis
                .finish(
                    id,
                    &run.token,
                    state,
                    volume,
                    &error,
                    progress,
                    self.opts.ttl_s(),
                )
                .await
            {
                Ok(f) => break f,
                Err(e) if Instant::now() < give_up => {
                    tracing::warn!(job = %id, "cannot record the job's end yet: {e}");
                    tokio::time::sleep(backoff).await;
                    backoff = (backoff * 2).min(Duration::from_secs(5));
                }
                Err(e) => {
                    // The entry stays pending: once its lease has run out, a replica takes the
                    // job over and runs it again, into the same volume id.
                    tracing::error!(job = %id, "gave up recording the job's end: {e}");
                    return;
                }
            }
        };
        match finished {
            Finished::Done => self.clean_up(id, result.is_ok()).await,
            // Ended otherwise meanwhile (canceled, or failed or succeeded by another run): what
            // is left goes, but a volume the job succeeded with (its id is this run's too).
            Finished::Other { state, .. }
                if ["succeeded", "failed", "canceled"].contains(&state.as_str()) =>
            {
                self.clean_up(id, state == "succeeded").await
            }
            // Another run has it now, and writes the same volume id.
            Finished::Other { .. } => {}
            Finished::Gone => self.clean_up(id, false).await,
        }
    }

    fn record(&self, v: scripts::View) -> Option<JobRecord> {
        let f = v.fields;
        let mut r: JobRecord = serde_json::from_str(f.get("record")?).ok()?;
        r.state =
            serde_json::from_value(serde_json::Value::String(f.get("state")?.clone())).ok()?;
        let ms = |k: &str| f.get(k).and_then(|x| x.parse::<i64>().ok());
        let secs = |a: i64, b: i64| ((b - a).max(0) as f64).round() / 1000.0;
        r.progress = match r.state {
            State::Succeeded => 1.0,
            _ => f
                .get("progress")
                .and_then(|p| p.parse().ok())
                .unwrap_or(0.0),
        };
        r.position = (r.state == State::Queued)
            .then(|| v.rank.map(|p| p + 1))
            .flatten();
        r.volume_id = f.get("volume").cloned().filter(|v| !v.is_empty());
        r.error = f.get("error").and_then(|e| serde_json::from_str(e).ok());
        r.attempts = f
            .get("attempts")
            .and_then(|a| a.parse().ok())
            .filter(|a| *a > 0);
        let (enq, start, end) = (ms("enq"), ms("start"), ms("end"));
        if let Some(enq) = enq {
            r.timings = Timings {
                queued_s: Some(secs(enq, start.or(end).unwrap_or(v.now_ms))),
                running_s: start.map(|s| secs(s, end.unwrap_or(v.now_ms))),
            };
        }
        Some(r)
    }
}

/// The refusal of a job when `waiting` jobs wait over all replicas, the shared capacity.
fn full(waiting: usize) -> Error {
    Error::new(
        ErrorKind::QueueFull,
        format!("{waiting} jobs are already waiting (over all replicas); retry later"),
    )
    .retry_after(5)
}

#[async_trait]
impl JobQueue for RedisQueue {
    /// The shared capacity only (one round trip); the owner's limit is the submit script's.
    async fn admission(&self, _owner: Option<&Owner>) -> Result<()> {
        let q = &*self.inner;
        q.open_for_jobs()?;
        let waiting = q.redis.waiting().await.map_err(|e| q.unavailable(&e))?;
        if waiting >= q.opts.capacity {
            return Err(full(waiting));
        }
        Ok(())
    }

    async fn submit(&self, job: NewJob) -> Result<JobRecord> {
        let q = &*self.inner;
        // The shared capacity was looked at by `admission` before the upload was read (the
        // route asks it); the submit script decides, atomically.
        q.open_for_jobs()?;
        let record = job.queued_record();
        let cost = job.cost();
        let (class, method) = (class_of(cost), job.method());
        let spec = serde_json::to_string(&job.spec).expect("a spec serialises");
        let (id, owner) = (job.id.clone(), job.owner.clone());
        // The prepared job, not the uploaded file: whichever replica runs it decodes the mesh
        // rather than parse it again.
        let (work, stored) = job.into_shared().await?;
        q.store
            .put_upload(&id, stored)
            .await
            .map_err(|e| Error::from(e).context("cannot store the upload"))?;
        {
            // Kept before the job is visible, for when a worker here takes it at once.
            let mut kept = q.lock_prepared();
            if kept.len() >= PREPARED_KEPT {
                kept.pop_front();
            }
            kept.push_back((id.clone(), work));
        }
        let submitted = q
            .redis
            .submit(
                &id,
                q.opts.capacity,
                class,
                cost,
                method,
                &serde_json::to_string(&record).expect("a record serialises"),
                &spec,
                owner.as_ref(),
            )
            .await;
        let position = match submitted {
            Ok(Submitted::Queued(p)) => p,
            other => {
                // Not queued (or not known to be: then a replica that runs it finds no upload
                // and fails it, saying so).
                q.forget_prepared(&id);
                let _ = q.store.delete_upload(&id).await;
                return Err(match other {
                    Ok(Submitted::Full(n)) => full(n),
                    Ok(Submitted::OwnerBusy(n)) => owner.as_ref().map_or_else(
                        || Error::internal("an owner limit without an owner"),
                        |o| o.too_many(n),
                    ),
                    Err(e) => q.unavailable(&e),
                    _ => Error::internal(format!("job id {id} is taken")),
                });
            }
        };
        Ok(JobRecord {
            position: Some(position),
            timings: Timings {
                queued_s: Some(0.0),
                running_s: None,
            },
            ..record
        })
    }

    async fn get(&self, id: &str) -> Result<Option<JobRecord>> {
        let q = &*self.inner;
        let v = q.redis.view(id).await.map_err(|e| q.unavailable(&e))?;
        Ok(q.record(v))
    }

    async fn wait(&self, id: &str, timeout: Duration) -> Result<Option<JobRecord>> {
        let deadline = tokio::time::Instant::now() + timeout;
        let mut done = self.inner.done.subscribe();
        let mut backoff = Duration::from_millis(50);
        loop {
            let r = self.get(id).await?;
            let now = tokio::time::Instant::now();
            match r {
                Some(r) if !r.state.is_final() && now < deadline => {}
                other => return Ok(other),
            }
            let heard = async {
                loop {
                    match done.recv().await {
                        Ok(d) if d == id || d.is_empty() => return,
                        Ok(_) => {}
                        Err(broadcast::error::RecvError::Lagged(_)) => return,
                        Err(broadcast::error::RecvError::Closed) => std::future::pending().await,
                    }
                }
            };
            tokio::select! {
                _ = tokio::time::sleep(backoff.min(deadline - now)) => {
                    backoff = (backoff * 2).min(Duration::from_secs(1));
                }
                _ = heard => {}
            }
        }
    }

    async fn cancel(&self, id: &str) -> Result<Option<JobRecord>> {
        let q = &*self.inner;
        match q
            .redis
            .cancel(id, q.opts.ttl_s())
            .await
            .map_err(|e| q.unavailable(&e))?
        {
            Cancel::None => return Ok(None),
            Cancel::Final(state) => {
                return Err(Error::new(
                    ErrorKind::NotCancelable,
                    format!("job {id} has already {state}"),
                ));
            }
            Cancel::Canceled { was_running: true } => {
                // Running here: stop now rather than at the next renewal.
                if let Some(r) = q.lock_running().get(id) {
                    r.control.cancel();
                }
            }
            Cancel::Canceled { was_running: false } => q.clean_up(id, true).await,
        }
        self.get(id).await
    }

    async fn next(&self) -> Option<Claim> {
        let q = &*self.inner;
        let mut closed = q.closed.subscribe();
        let mut backoff = Duration::from_millis(100);
        let mut failing = false;
        loop {
            if q.is_closed() {
                return None;
            }
            // Registered before looking, so that a `new` event meanwhile still wakes.
            let ready = q.ready.notified();
            tokio::pin!(ready);
            ready.as_mut().enable();
            let wait = match q.claim().await {
                Ok(Some(claim)) => return Some(claim),
                Ok(None) => {
                    if failing {
                        tracing::info!(queue = %q.target, "the job queue answers again");
                    }
                    failing = false;
                    backoff = Duration::from_millis(100);
                    IDLE_POLL
                }
                Err(e) => {
                    if !failing {
                        tracing::warn!(queue = %q.target, "cannot take jobs from the queue: {e}; retrying");
                    }
                    failing = true;
                    backoff = (backoff * 2).min(Duration::from_secs(5));
                    backoff
                }
            };
            tokio::select! {
                _ = &mut ready, if !failing => {}
                _ = tokio::time::sleep(wait) => {}
                _ = closed.wait_for(|c| *c) => return None,
            }
        }
    }

    async fn finish(&self, id: &str, result: Result<String>) {
        self.inner.finish(id, result).await
    }

    /// Stops this replica taking and accepting jobs. The queued ones stay queued, for the
    /// other replicas: none is failed here.
    async fn close(&self, _why: Error) -> usize {
        self.inner.closed.send_replace(true);
        self.inner.ready.notify_waiters();
        0
    }

    async fn stats(&self) -> QueueStats {
        let q = &*self.inner;
        match q.redis.stats().await {
            Ok(s) => {
                let mut by_state: Vec<(State, String, u64)> = s
                    .counts
                    .into_iter()
                    .filter(|(_, n)| *n > 0)
                    .filter_map(|(k, n)| {
                        let (state, method) = k.split_once('|')?;
                        let state =
                            serde_json::from_value(serde_json::Value::String(state.into())).ok()?;
                        Some((state, method.to_string(), n as u64))
                    })
                    .collect();
                by_state.sort_by(|a, b| (a.0.name(), &a.1).cmp(&(b.0.name(), &b.1)));
                QueueStats {
                    depth: s.waiting,
                    running: s.running,
                    by_state,
                    oldest_queued_s: s.oldest_ms.map_or(0.0, |ms| ms as f64 / 1000.0),
                    classes: CLASSES.iter().copied().zip(s.classes).collect(),
                    unavailable: None,
                }
            }
            Err(e) => QueueStats {
                unavailable: Some(q.unavailable(&e).detail),
                ..QueueStats::default()
            },
        }
    }
}

#[cfg(test)]
mod tests;
