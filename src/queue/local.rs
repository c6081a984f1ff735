//! The in-process queue.
//!
//! Jobs wait in a bounded queue; workers take them one at a time. Scheduling policy: the queued
//! job with the lowest `estimated cost − age credit` runs next, the application's rule
//! ([`crate::app::queue::priority`]): the cost is its classified voxels plus 64 per triangle and
//! every second of waiting earns the credit of a 256³ job. Small jobs therefore overtake a huge one, but a huge one that has waited long
//! enough runs before newer small ones: nothing waits forever. A full queue refuses new jobs
//! (429) and never drops accepted ones.
//!
//! Cancelling a queued job removes it; cancelling a running one marks it canceled and cancels
//! its [`Control`]: the engine stops at its next check point and nothing is stored. With a job
//! timeout ([`LocalQueue::with_job_timeout`]) a job's control gets a deadline when it starts
//! running; past it the job stops the same way and fails. A running job's record shows its
//! control's progress.
//!
//! State lives under a plain mutex that is never held across an await or any I/O. Records are
//! written by one writer task, in the order the changes happened, through the store; the call
//! that made a change waits until its record is durable.
//!
//! A job's success is written ahead: when its worker starts storing the volume
//! ([`JobQueue::storing`]), the job's final record goes to the writer marked
//! `"unconfirmed_volume": true`, so that it is made durable while the volume is, not after it
//! (on a disk, the job's answer waits for one sync instead of two in a row). The job is shown
//! succeeded only once both are durable ([`JobQueue::finish`]); the record then written without
//! the mark is not waited for. At start, the newest record of a job that carries the mark
//! counts as succeeded only if its volume is in the store; otherwise the job failed
//! (interrupted), as one that was running does. A job seen succeeded therefore stays succeeded
//! through a crash, and a succeeded job's volume always exists.

use std::collections::{BTreeSet, HashMap};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use async_trait::async_trait;
use bytes::Bytes;
use tokio::sync::{Notify, mpsc, oneshot, watch};

use crate::app::queue::{
    Claim, Error, ErrorKind, JobQueue, JobRecord, NewJob, Owner, QueueStats, Result, State,
    Timings, Work, priority,
};
use crate::app::store::VolumeStore;
use crate::cancel::Control;

struct Job {
    record: JobRecord,
    /// A record of an earlier process: shown as stored.
    loaded: bool,
    work: Option<Work>,
    cost: f64,
    enqueued: Instant,
    started: Option<Instant>,
    finished: Option<Instant>,
    /// Canceled with the job; its progress is the record's while running.
    control: Control,
    done: watch::Sender<State>,
    /// The success written ahead by [`JobQueue::storing`]: the volume it names, and when that
    /// record is durable.
    ahead: Option<(String, oneshot::Receiver<()>)>,
}

struct Inner {
    jobs: HashMap<String, Job>,
    /// Ids of queued jobs, in arrival order.
    queue: Vec<String>,
    closed: bool,
    /// The finished jobs, oldest first (creation time, then id): what [`LocalQueue::prune`]
    /// forgets, without walking or sorting every job under the lock.
    finished: BTreeSet<(String, String)>,
    /// Jobs queued or running per API key: what [`Inner::admits`] checks a key's limit against,
    /// without walking every job remembered.
    active: HashMap<String, usize>,
}

/// A record to write (`None`: to remove), and who waits for it.
type Write = (String, Option<Bytes>, oneshot::Sender<()>);

/// Finished jobs remembered at most (their records in memory and in the store); past it the
/// oldest are forgotten, in batches of a tenth, so a long-running server's job records stay
/// bounded (a soak of 10 minutes left 15,746 of them).
pub const KEEP_FINISHED: usize = 10_000;

pub struct LocalQueue {
    inner: Mutex<Inner>,
    ready: Notify,
    capacity: usize,
    /// How long a job may run (its control's deadline from when it starts).
    job_timeout: Option<Duration>,
    writes: mpsc::UnboundedSender<Write>,
    /// Finished jobs remembered at most ([`KEEP_FINISHED`]).
    keep_finished: usize,
}

impl LocalQueue {
    /// A queue of `capacity` waiting jobs whose records live in `store`. Records of earlier
    /// processes are loaded; a job that was queued or running when that process died is marked
    /// failed (interrupted), since its mesh was only in memory, and so is one whose success was
    /// written ahead of a volume the store does not have. Spawns the record writer.
    pub async fn open(capacity: usize, store: Arc<dyn VolumeStore>) -> Result<LocalQueue> {
        let (writes, rx) = mpsc::unbounded_channel();
        tokio::spawn(write_records(store.clone(), rx));
        let mut jobs = HashMap::new();
        // Records written again: those of interrupted jobs, and confirmed successes.
        let mut rewrite = vec![];
        for bytes in store.job_records().await? {
            let Some((mut record, unconfirmed)) = parse_record(&bytes) else {
                tracing::warn!("ignoring an unreadable job record");
                continue;
            };
            // A success written ahead of its volume: it stands if the volume was stored (and
            // is written again without the mark), else the job was interrupted.
            if unconfirmed && record.state == State::Succeeded {
                let stored = match &record.volume_id {
                    Some(v) => store.get(v).await?.is_some(),
                    None => false,
                };
                if stored {
                    rewrite.push(record.clone());
                } else {
                    record.state = State::Running;
                    record.volume_id = None;
                }
            }
            if !record.state.is_final() {
                record.state = State::Failed;
                record.position = None;
                record.error = Some(Error::new(
                    ErrorKind::ShuttingDown,
                    "interrupted: the server stopped before this job finished; submit it again",
                ));
                rewrite.push(record.clone());
            }
            let (done, _) = watch::channel(record.state);
            let now = Instant::now();
            jobs.insert(
                record.id.clone(),
                Job {
                    record,
                    loaded: true,
                    work: None,
                    cost: 0.0,
                    enqueued: now,
                    started: None,
                    finished: Some(now),
                    control: Control::new(),
                    done,
                    ahead: None,
                },
            );
        }
        tracing::info!(jobs = jobs.len(), "job records loaded");
        // Every loaded job is final (those that were not are failed above).
        let finished = jobs
            .values()
            .map(|j| (j.record.created.clone(), j.record.id.clone()))
            .collect();
        let q = LocalQueue {
            inner: Mutex::new(Inner {
                jobs,
                queue: vec![],
                closed: false,
                finished,
                active: HashMap::new(),
            }),
            ready: Notify::new(),
            capacity,
            job_timeout: None,
            writes,
            keep_finished: KEEP_FINISHED,
        };
        let acks: Vec<_> = rewrite.iter().map(|r| q.record(r)).collect();
        for a in acks {
            let _ = a.await;
        }
        q.prune(q.keep_finished);
        Ok(q)
    }

    /// Jobs may run for `timeout` at most (none: as long as they take): past it a job stops at
    /// its engine's next check point and fails.
    /// Remembers at most `keep` finished jobs (default [`KEEP_FINISHED`]).
    pub fn with_keep_finished(mut self, keep: usize) -> LocalQueue {
        self.keep_finished = keep;
        self
    }

    pub fn with_job_timeout(mut self, timeout: Option<Duration>) -> LocalQueue {
        self.job_timeout = timeout;
        self
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Inner> {
        self.inner.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Hands a record to the writer (call it while holding the lock, so records are written in
    /// the order of the changes); the receiver resolves once it is durable.
    fn record(&self, r: &JobRecord) -> oneshot::Receiver<()> {
        self.write(r, false)
    }

    /// [`LocalQueue::record`], marked [`UNCONFIRMED`] when `unconfirmed`.
    fn write(&self, r: &JobRecord, unconfirmed: bool) -> oneshot::Receiver<()> {
        let (tx, rx) = oneshot::channel();
        let bytes = if unconfirmed {
            let mut v = serde_json::to_value(r).expect("job record serialises");
            v[UNCONFIRMED] = true.into();
            serde_json::to_vec(&v)
        } else {
            serde_json::to_vec(r)
        };
        let bytes = Bytes::from(bytes.expect("job record serialises"));
        let _ = self.writes.send((r.id.clone(), Some(bytes), tx));
        rx
    }

    /// Forgets the oldest finished jobs once more than `keep` (+ a tenth) are known, down to
    /// `keep`: their records leave memory and the store.
    fn prune(&self, keep: usize) {
        let mut inner = self.lock();
        if inner.finished.len() <= keep + keep / 10 {
            return;
        }
        while inner.finished.len() > keep {
            let Some((_, id)) = inner.finished.pop_first() else {
                break;
            };
            inner.jobs.remove(&id);
            let (tx, _) = oneshot::channel();
            let _ = self.writes.send((id, None, tx));
        }
    }
}

/// Reads a record, and whether it is a success written ahead of its volume ([`UNCONFIRMED`]);
/// records of earlier versions carried a problem document instead of `error`.
fn parse_record(bytes: &[u8]) -> Option<(JobRecord, bool)> {
    let mut v: serde_json::Value = serde_json::from_slice(bytes).ok()?;
    let unconfirmed = v
        .as_object_mut()
        .and_then(|o| o.remove(UNCONFIRMED))
        .is_some_and(|b| b == serde_json::Value::Bool(true));
    if let Some(p) = v.as_object_mut().and_then(|o| o.remove("problem")) {
        let kind = p
            .get("type")
            .and_then(|t| t.as_str())
            .and_then(|t| t.rsplit('/').next())
            .and_then(|slug| slug.parse::<ErrorKind>().ok())
            .unwrap_or(ErrorKind::Internal);
        let detail = p.get("detail").and_then(|d| d.as_str()).unwrap_or("");
        v["error"] = serde_json::to_value(Error::new(kind, detail)).ok()?;
    }
    Some((serde_json::from_value(v).ok()?, unconfirmed))
}

/// The mark of a success written ahead of its volume (see the module's documentation).
const UNCONFIRMED: &str = "unconfirmed_volume";

/// Records waiting to be written at most per group commit.
const GROUP_MAX: usize = 256;

/// The one writer of job records, in order, each acknowledged once durable: a group commit.
/// Whatever has queued up while the last batch was being written goes in the next one, each
/// job's newest record only (a job that was queued, started and finished meanwhile is written
/// once, in its last state), and every change in a batch is acknowledged once the whole batch
/// is durable. Order per job is kept: a batch holds the
/// newest change of each of its jobs, and batches are written one after the other.
async fn write_records(store: Arc<dyn VolumeStore>, mut rx: mpsc::UnboundedReceiver<Write>) {
    while let Some(first) = rx.recv().await {
        let mut pending = vec![first];
        while pending.len() < GROUP_MAX {
            match rx.try_recv() {
                Ok(w) => pending.push(w),
                Err(_) => break,
            }
        }
        // The newest change per job, in the order of the jobs' last changes.
        let mut newest: HashMap<String, usize> = HashMap::new();
        for (i, (id, _, _)) in pending.iter().enumerate() {
            newest.insert(id.clone(), i);
        }
        let mut acks = Vec::with_capacity(pending.len());
        let mut batch = Vec::with_capacity(newest.len());
        for (i, (id, bytes, ack)) in pending.into_iter().enumerate() {
            if newest.get(&id) == Some(&i) {
                batch.push((id, bytes));
            }
            acks.push(ack);
        }
        // A batch whose every change nobody waits for (the record after a success written
        // ahead, removals of forgotten jobs) need not be synced now: the next batch's sync
        // covers it, and a crash of this process loses nothing written.
        let durable = acks.iter().any(|a| !a.is_closed());
        let ids: Vec<String> = batch.iter().map(|(id, _)| id.clone()).collect();
        for (id, r) in ids.iter().zip(store.put_job_records(batch, durable).await) {
            if let Err(e) = r {
                tracing::error!(job = %id, "cannot write the job record: {e}");
            }
        }
        for ack in acks {
            let _ = ack.send(());
        }
    }
}

impl Inner {
    /// Whether a job of `owner` may be queued now: not closed, room in the queue, the owner
    /// under its limit of jobs queued or running.
    fn admits(&self, capacity: usize, owner: Option<&Owner>) -> Result<()> {
        if self.closed {
            return Err(Error::new(
                ErrorKind::ShuttingDown,
                "the server is shutting down; retry on another replica",
            ));
        }
        if self.queue.len() >= capacity {
            return Err(Error::new(
                ErrorKind::QueueFull,
                format!("{capacity} jobs are already waiting; retry later"),
            )
            .retry_after(5));
        }
        if let Some(owner) = owner.filter(|o| o.max_jobs > 0) {
            let active = self.active.get(&owner.name).copied().unwrap_or(0);
            if active >= owner.max_jobs {
                return Err(owner.too_many(active));
            }
        }
        Ok(())
    }

    /// Indexes a job just queued: one more active job of its key.
    fn queued(&mut self, id: &str) {
        if let Some(key) = self.jobs.get(id).and_then(|j| j.record.key_name.clone()) {
            *self.active.entry(key).or_insert(0) += 1;
        }
    }

    /// Indexes a job whose record just became final: finished (to be forgotten in its turn),
    /// and one active job fewer for its key. Called once per job, at the change.
    fn ended(&mut self, id: &str) {
        let Some(j) = self.jobs.get(id) else {
            return;
        };
        debug_assert!(j.record.state.is_final());
        self.finished
            .insert((j.record.created.clone(), j.record.id.clone()));
        if let Some(key) = &j.record.key_name
            && let Some(n) = self.active.get_mut(key)
        {
            *n -= 1;
            if *n == 0 {
                self.active.remove(key);
            }
        }
    }

    fn view(&self, id: &str) -> Option<JobRecord> {
        let j = self.jobs.get(id)?;
        if j.loaded {
            return Some(j.record.clone());
        }
        let mut v = j.record.clone();
        if v.state == State::Running {
            v.progress = j.control.progress();
        }
        v.position = (v.state == State::Queued)
            .then(|| self.queue.iter().position(|q| q == id).map(|p| p + 1))
            .flatten();
        let now = Instant::now();
        let secs = |d: Duration| (d.as_secs_f64() * 1000.0).round() / 1000.0;
        v.timings = Timings {
            queued_s: Some(secs(
                j.started
                    .unwrap_or(j.finished.unwrap_or(now))
                    .duration_since(j.enqueued),
            )),
            running_s: j
                .started
                .map(|s| secs(j.finished.unwrap_or(now).duration_since(s))),
        };
        Some(v)
    }
}

impl LocalQueue {
    /// Queues a job; with `sync`, returns once its record is durable.
    async fn queue_job(&self, job: NewJob, sync: bool) -> Result<JobRecord> {
        let (record, durable) = {
            let mut inner = self.lock();
            inner.admits(self.capacity, job.owner.as_ref())?;
            let (done, _) = watch::channel(State::Queued);
            let record = job.queued_record();
            let (id, cost) = (job.id.clone(), job.cost());
            inner.jobs.insert(
                id.clone(),
                Job {
                    record,
                    loaded: false,
                    cost,
                    work: Some(job.into_work()),
                    enqueued: Instant::now(),
                    started: None,
                    finished: None,
                    control: Control::new(),
                    done,
                    ahead: None,
                },
            );
            inner.queue.push(id.clone());
            inner.queued(&id);
            let v = inner.view(&id).expect("just inserted");
            let durable = self.record(&v);
            (v, durable)
        };
        self.ready.notify_one();
        if sync {
            let _ = durable.await;
        }
        Ok(record)
    }
}

#[async_trait]
impl JobQueue for LocalQueue {
    async fn admission(&self, owner: Option<&Owner>) -> Result<()> {
        self.lock().admits(self.capacity, owner)
    }

    async fn submit(&self, job: NewJob) -> Result<JobRecord> {
        self.queue_job(job, true).await
    }

    async fn submit_deferred(&self, job: NewJob) -> Result<JobRecord> {
        self.queue_job(job, false).await
    }

    async fn persist(&self, id: &str) -> Result<()> {
        let durable = {
            let inner = self.lock();
            let Some(v) = inner.view(id) else {
                return Ok(());
            };
            self.record(&v)
        };
        let _ = durable.await;
        Ok(())
    }

    async fn get(&self, id: &str) -> Result<Option<JobRecord>> {
        Ok(self.lock().view(id))
    }

    async fn wait(&self, id: &str, timeout: Duration) -> Result<Option<JobRecord>> {
        let Some(mut rx) = self.lock().jobs.get(id).map(|j| j.done.subscribe()) else {
            return Ok(None);
        };
        let _ = tokio::time::timeout(timeout, rx.wait_for(|s| s.is_final())).await;
        self.get(id).await
    }

    async fn cancel(&self, id: &str) -> Result<Option<JobRecord>> {
        let (record, durable) = {
            let mut inner = self.lock();
            let Some(job) = inner.jobs.get_mut(id) else {
                return Ok(None);
            };
            if job.record.state.is_final() {
                return Err(Error::new(
                    ErrorKind::NotCancelable,
                    format!("job {id} has already {}", job.record.state.name()),
                ));
            }
            job.control.cancel();
            if job.record.state == State::Running {
                job.record.progress = job.control.progress();
            }
            job.record.state = State::Canceled;
            job.finished = Some(Instant::now());
            job.work = None;
            job.done.send_replace(State::Canceled);
            inner.queue.retain(|q| q != id);
            inner.ended(id);
            let v = inner.view(id).expect("present");
            let durable = self.record(&v);
            (v, durable)
        };
        let _ = durable.await;
        Ok(Some(record))
    }

    async fn next(&self) -> Option<Claim> {
        loop {
            // Registered before looking, so a submit between the look and the wait still wakes.
            let notified = self.ready.notified();
            {
                let mut inner = self.lock();
                let now = Instant::now();
                let score =
                    |j: &Job| priority(j.cost, now.duration_since(j.enqueued).as_secs_f64());
                let pick = inner
                    .queue
                    .iter()
                    .enumerate()
                    .min_by(|(_, a), (_, b)| {
                        score(&inner.jobs[*a]).total_cmp(&score(&inner.jobs[*b]))
                    })
                    .map(|(i, _)| i);
                if let Some(i) = pick {
                    let id = inner.queue.remove(i);
                    let job = inner.jobs.get_mut(&id).expect("queued job exists");
                    job.record.state = State::Running;
                    job.started = Some(now);
                    if let Some(at) = self.job_timeout.and_then(|t| now.checked_add(t)) {
                        job.control.set_deadline(at);
                    }
                    job.done.send_replace(State::Running);
                    return Some(Claim {
                        // The worker's alone: the mesh is freed as soon as its job is built.
                        work: job.work.take().expect("queued work"),
                        name: job.record.name.clone(),
                        control: job.control.clone(),
                        timeout: self.job_timeout,
                        volume_id: None,
                        guard: None,
                        id,
                    });
                }
                if inner.closed {
                    return None;
                }
            }
            notified.await;
        }
    }

    fn storing(&self, id: &str, volume_id: &str) {
        let mut inner = self.lock();
        let Some(mut v) = inner.view(id).filter(|v| v.state == State::Running) else {
            return;
        };
        v.state = State::Succeeded;
        v.volume_id = Some(volume_id.to_string());
        v.progress = 1.0;
        // Under the lock, like every record: written in the order of the changes.
        let durable = self.write(&v, true);
        if let Some(job) = inner.jobs.get_mut(id) {
            job.ahead = Some((volume_id.to_string(), durable));
        }
    }

    async fn finish(&self, id: &str, result: Result<String>) {
        // The final record is made durable first and shown after: a job seen finished stays
        // finished through a crash. A success written ahead (`storing`) is that record: it is
        // waited for instead, and this one, without the mark, is not.
        let (record, durable) = {
            let mut inner = self.lock();
            let now = Instant::now();
            let Some(job) = inner.jobs.get_mut(id) else {
                return;
            };
            job.work = None;
            let ahead = job.ahead.take();
            if job.record.state == State::Canceled {
                return;
            }
            let progress = job.control.progress();
            job.finished = Some(now);
            let mut v = inner.view(id).expect("present");
            match result {
                Ok(volume) => {
                    v.state = State::Succeeded;
                    v.volume_id = Some(volume);
                    v.progress = 1.0;
                }
                Err(e) => {
                    v.state = State::Failed;
                    v.progress = progress;
                    v.error = Some(e);
                }
            }
            let durable = self.record(&v);
            let durable = match ahead {
                Some((volume, ahead)) if v.volume_id.as_ref() == Some(&volume) => ahead,
                _ => durable,
            };
            (v, durable)
        };
        let _ = durable.await;
        let mut inner = self.lock();
        if let Some(job) = inner.jobs.get_mut(id) {
            // A cancel that came meanwhile was recorded after this record, and wins.
            if job.record.state == State::Running {
                job.record.state = record.state;
                job.record.volume_id = record.volume_id;
                job.record.progress = record.progress;
                job.record.error = record.error;
                job.done.send_replace(job.record.state);
                inner.ended(id);
            }
        }
        drop(inner);
        self.prune(self.keep_finished);
    }

    async fn close(&self, why: Error) -> usize {
        let acks: Vec<_> = {
            let mut inner = self.lock();
            inner.closed = true;
            let queued: Vec<String> = std::mem::take(&mut inner.queue);
            let mut acks = vec![];
            for id in &queued {
                if let Some(job) = inner.jobs.get_mut(id) {
                    job.record.state = State::Failed;
                    job.record.error = Some(why.clone());
                    job.work = None;
                    job.finished = Some(Instant::now());
                    job.done.send_replace(State::Failed);
                    inner.ended(id);
                }
                if let Some(v) = inner.view(id) {
                    acks.push(self.record(&v));
                }
            }
            acks
        };
        self.ready.notify_waiters();
        let n = acks.len();
        for a in acks {
            let _ = a.await;
        }
        n
    }

    async fn stats(&self) -> QueueStats {
        let inner = self.lock();
        let mut by: HashMap<(State, String), u64> = HashMap::new();
        let mut running = 0;
        for j in inner.jobs.values() {
            *by.entry((j.record.state, j.record.method.clone()))
                .or_insert(0) += 1;
            running += usize::from(j.record.state == State::Running);
        }
        let mut by_state: Vec<(State, String, u64)> =
            by.into_iter().map(|((s, m), n)| (s, m, n)).collect();
        by_state.sort_by(|a, b| (a.0.name(), &a.1).cmp(&(b.0.name(), &b.1)));
        let now = Instant::now();
        let oldest_queued_s = inner
            .queue
            .iter()
            .filter_map(|id| inner.jobs.get(id))
            .map(|j| now.duration_since(j.enqueued).as_secs_f64())
            .fold(0.0, f64::max);
        QueueStats {
            depth: inner.queue.len(),
            running,
            by_state,
            oldest_queued_s,
            ..QueueStats::default()
        }
    }
}

#[cfg(test)]
mod tests;
