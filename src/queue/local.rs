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
use crate::app::voxelize::Prepared;
use crate::cancel::Control;
use crate::limits::Limits;

mod records;
use records::{Recovery, Stored, Write, parse_record, recover, write_records};

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
    /// The job's request as data (the `JobSpec` as JSON), written with its records while it
    /// is kept.
    spec: Option<String>,
    /// Kept: its prepared mesh is in the store (`uploads/{id}`) and its records carry `spec`,
    /// so that it runs again after a crash (see [`records`]); the upload goes when it ends.
    kept: bool,
    /// A job submitted with a wait ([`JobQueue::submit_deferred`]): its prepared mesh, until
    /// [`JobQueue::persist`] keeps it (the answer is then `202`) or the job ends.
    prepared: Option<Arc<Prepared>>,
}

impl Job {
    /// The request its records carry: a kept job's.
    fn kept_spec(&self) -> Option<&str> {
        self.spec.as_deref().filter(|_| self.kept)
    }
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
    /// Where kept jobs' uploads are.
    store: Arc<dyn VolumeStore>,
}

impl LocalQueue {
    /// A queue of `capacity` waiting jobs whose records live in `store` ([`LocalQueue::open_with`]
    /// with this build's default limits and `--max-attempts`).
    pub async fn open(capacity: usize, store: Arc<dyn VolumeStore>) -> Result<LocalQueue> {
        let attempts = crate::limits::serve::MAX_ATTEMPTS;
        LocalQueue::open_with(capacity, store, Limits::default(), attempts).await
    }

    /// A queue of `capacity` waiting jobs whose records live in `store`. Records of earlier
    /// processes are loaded; a kept job (answered `202`) that was queued or running when that
    /// process died is queued again, to be prepared from its stored upload under `limits`,
    /// unless it was started `max_attempts` times already ([`records`]); other unfinished jobs
    /// are marked failed (interrupted), and so is one whose success was written ahead of a
    /// volume the store does not have and that was not kept. Spawns the record writer.
    pub async fn open_with(
        capacity: usize,
        store: Arc<dyn VolumeStore>,
        limits: Limits,
        max_attempts: u32,
    ) -> Result<LocalQueue> {
        let (writes, rx) = mpsc::unbounded_channel();
        tokio::spawn(write_records(store.clone(), rx));
        let mut jobs = HashMap::new();
        // Records written again: those of interrupted jobs, requeued ones, confirmed successes.
        let mut rewrite = vec![];
        // Jobs queued again, and uploads of jobs that will not run again.
        let (mut queue, mut gone) = (vec![], vec![]);
        for bytes in store.job_records().await? {
            let Some(Stored {
                mut record,
                unconfirmed,
                spec,
            }) = parse_record(&bytes)
            else {
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
                    rewrite.push((record.clone(), None));
                    gone.push(record.id.clone());
                } else {
                    record.state = State::Running;
                    record.volume_id = None;
                    record.progress = 0.0;
                }
            }
            let mut requeued = None;
            if !record.state.is_final() {
                record.position = None;
                match recover(&record, spec.as_deref(), max_attempts) {
                    Recovery::Requeue => {
                        record.state = State::Queued;
                        record.progress = 0.0;
                        requeued = spec;
                        queue.push((record.created.clone(), record.id.clone()));
                    }
                    Recovery::Fail(e) => {
                        record.state = State::Failed;
                        record.error = Some(e);
                        gone.push(record.id.clone());
                    }
                }
                rewrite.push((record.clone(), requeued.clone()));
            }
            let (done, _) = watch::channel(record.state);
            let now = Instant::now();
            let kept = requeued.is_some();
            jobs.insert(
                record.id.clone(),
                Job {
                    record,
                    loaded: !kept,
                    work: requeued.clone().map(|spec| Work::Stored { spec, limits }),
                    cost: 0.0,
                    enqueued: now,
                    started: None,
                    finished: (!kept).then_some(now),
                    control: Control::new(),
                    done,
                    ahead: None,
                    spec: requeued,
                    kept,
                    prepared: None,
                },
            );
        }
        // Oldest first: the order they were accepted in.
        queue.sort();
        let queue: Vec<String> = queue.into_iter().map(|(_, id)| id).collect();
        tracing::info!(
            jobs = jobs.len(),
            requeued = queue.len(),
            "job records loaded"
        );
        let finished = jobs
            .values()
            .filter(|j| j.record.state.is_final())
            .map(|j| (j.record.created.clone(), j.record.id.clone()))
            .collect();
        let mut inner = Inner {
            jobs,
            queue: vec![],
            closed: false,
            finished,
            active: HashMap::new(),
        };
        for id in queue {
            inner.queue.push(id.clone());
            inner.queued(&id);
        }
        let q = LocalQueue {
            inner: Mutex::new(inner),
            ready: Notify::new(),
            capacity,
            job_timeout: None,
            writes,
            keep_finished: KEEP_FINISHED,
            store: store.clone(),
        };
        let acks: Vec<_> = rewrite
            .iter()
            .map(|(r, spec)| q.write(r, false, spec.as_deref()))
            .collect();
        for a in acks {
            let _ = a.await;
        }
        // Their final records are durable: the uploads of jobs that will not run again go.
        for id in gone {
            if let Err(e) = store.delete_upload(&id).await {
                tracing::warn!(job = %id, "cannot delete the job's upload: {e}");
            }
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
    /// The job's request goes with it while the job is kept (`spec`).
    fn record(&self, r: &JobRecord, spec: Option<&str>) -> oneshot::Receiver<()> {
        self.write(r, false, spec)
    }

    /// [`LocalQueue::record`], marked [`records::UNCONFIRMED`] when `unconfirmed`.
    fn write(&self, r: &JobRecord, unconfirmed: bool, spec: Option<&str>) -> oneshot::Receiver<()> {
        let (tx, rx) = oneshot::channel();
        let bytes = records::encode(r, unconfirmed, spec);
        let _ = self.writes.send((r.id.clone(), Some(bytes), tx));
        rx
    }

    /// Deletes a kept job's upload once its final record is durable.
    async fn drop_upload(&self, id: &str) {
        if let Err(e) = self.store.delete_upload(id).await {
            tracing::warn!(job = %id, "cannot delete the job's upload: {e}");
        }
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
    /// Queues a job; with `sync`, keeps it (its upload stored first, see [`records`]) and
    /// returns once its record is durable.
    async fn queue_job(&self, job: NewJob, sync: bool) -> Result<JobRecord> {
        // Asked before the upload is written, and again once it is.
        self.lock().admits(self.capacity, job.owner.as_ref())?;
        let spec = serde_json::to_string(&job.spec).expect("a spec serialises");
        let record = job.queued_record();
        let (id, cost, owner) = (job.id.clone(), job.cost(), job.owner.clone());
        let (work, prepared) = if sync {
            let (work, bytes) = job.into_shared().await?;
            self.store
                .put_upload(&id, bytes)
                .await
                .map_err(|e| Error::from(e).context("cannot keep the job's upload"))?;
            (work, None)
        } else {
            let work = job.into_work();
            let Work::Prepared(p) = &work else {
                unreachable!("a new job's work is prepared")
            };
            let p = p.clone();
            (work, Some(p))
        };
        let admitted = {
            let mut inner = self.lock();
            inner.admits(self.capacity, owner.as_ref()).map(|()| {
                let (done, _) = watch::channel(State::Queued);
                inner.jobs.insert(
                    id.clone(),
                    Job {
                        record,
                        loaded: false,
                        cost,
                        work: Some(work),
                        enqueued: Instant::now(),
                        started: None,
                        finished: None,
                        control: Control::new(),
                        done,
                        ahead: None,
                        spec: Some(spec),
                        kept: sync,
                        prepared,
                    },
                );
                inner.queue.push(id.clone());
                inner.queued(&id);
                let v = inner.view(&id).expect("just inserted");
                let durable = self.record(&v, inner.jobs[&id].kept_spec());
                (v, durable)
            })
        };
        let (record, durable) = match admitted {
            Ok(r) => r,
            Err(e) => {
                if sync {
                    self.drop_upload(&id).await;
                }
                return Err(e);
            }
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
        // A job answered `202` is kept: its upload is stored first, then its record.
        let prepared = {
            let mut inner = self.lock();
            match inner.jobs.get_mut(id) {
                Some(j) if !j.record.state.is_final() && !j.kept => j.prepared.take(),
                _ => None,
            }
        };
        let mut ended = false;
        if let Some(p) = prepared {
            let bytes = tokio::task::spawn_blocking(move || crate::app::jobs::stored::encode(&p))
                .await
                .map_err(|e| Error::internal(format!("encoding the job panicked: {e}")))?;
            self.store
                .put_upload(id, Bytes::from(bytes))
                .await
                .map_err(|e| Error::from(e).context("cannot keep the job's upload"))?;
            let mut inner = self.lock();
            if let Some(j) = inner.jobs.get_mut(id) {
                j.kept = true;
                // Ended meanwhile: its end did not know of the upload.
                ended = j.record.state.is_final();
            }
        }
        let durable = {
            let inner = self.lock();
            let Some(v) = inner.view(id) else {
                return Ok(());
            };
            self.record(&v, inner.jobs[id].kept_spec())
        };
        let _ = durable.await;
        if ended {
            self.drop_upload(id).await;
        }
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
        let (record, durable, kept) = {
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
            job.prepared = None;
            let kept = job.kept;
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
            let durable = self.record(&v, None);
            (v, durable, kept)
        };
        let _ = durable.await;
        if kept {
            self.drop_upload(id).await;
        }
        Ok(Some(record))
    }

    async fn next(&self) -> Option<Claim> {
        loop {
            // Registered before looking, so a submit between the look and the wait still wakes.
            let notified = self.ready.notified();
            // The guard is dropped before any await (the future must be `Send`).
            let picked = {
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
                    job.record.attempts = Some(job.record.attempts.unwrap_or(0) + 1);
                    job.started = Some(now);
                    if let Some(at) = self.job_timeout.and_then(|t| now.checked_add(t)) {
                        job.control.set_deadline(at);
                    }
                    job.done.send_replace(State::Running);
                    // A kept job's start is durable before it runs: each start counts
                    // against `--max-attempts` if the process dies during it.
                    let started = job.kept.then(|| {
                        let v = inner.view(&id).expect("present");
                        self.record(&v, inner.jobs[&id].kept_spec())
                    });
                    let job = inner.jobs.get_mut(&id).expect("queued job exists");
                    let claim = Claim {
                        // The worker's alone: the mesh is freed as soon as its job is built.
                        work: job.work.take().expect("queued work"),
                        name: job.record.name.clone(),
                        owner: job.record.owner.clone(),
                        request_id: job.record.request_id.clone(),
                        control: job.control.clone(),
                        timeout: self.job_timeout,
                        volume_id: None,
                        guard: None,
                        id,
                    };
                    Some((claim, started))
                } else if inner.closed {
                    return None;
                } else {
                    None
                }
            };
            if let Some((claim, started)) = picked {
                if let Some(durable) = started {
                    let _ = durable.await;
                }
                return Some(claim);
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
        let durable = self.write(&v, true, inner.jobs.get(id).and_then(Job::kept_spec));
        if let Some(job) = inner.jobs.get_mut(id) {
            job.ahead = Some((volume_id.to_string(), durable));
        }
    }

    async fn finish(&self, id: &str, result: Result<String>) {
        // The final record is made durable first and shown after: a job seen finished stays
        // finished through a crash. A success written ahead (`storing`) is that record: it is
        // waited for instead, and this one, without the mark, is not.
        let (record, durable, kept) = {
            let mut inner = self.lock();
            let now = Instant::now();
            let Some(job) = inner.jobs.get_mut(id) else {
                return;
            };
            job.work = None;
            job.prepared = None;
            let ahead = job.ahead.take();
            let kept = job.kept;
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
            let durable = self.record(&v, None);
            let durable = match ahead {
                Some((volume, ahead)) if v.volume_id.as_ref() == Some(&volume) => ahead,
                _ => durable,
            };
            (v, durable, kept)
        };
        let _ = durable.await;
        if kept {
            self.drop_upload(id).await;
        }
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
        // Kept jobs (answered `202`) stay queued, in the store as in memory: the next start
        // runs them. Jobs whose requests still wait for their answer fail now.
        let acks: Vec<_> = {
            let mut inner = self.lock();
            inner.closed = true;
            let queued: Vec<String> = std::mem::take(&mut inner.queue);
            let mut acks = vec![];
            let mut kept = 0;
            for id in &queued {
                let Some(job) = inner.jobs.get_mut(id) else {
                    continue;
                };
                if job.kept {
                    kept += 1;
                    continue;
                }
                job.record.state = State::Failed;
                job.record.error = Some(why.clone());
                job.work = None;
                job.prepared = None;
                job.finished = Some(Instant::now());
                job.done.send_replace(State::Failed);
                inner.ended(id);
                if let Some(v) = inner.view(id) {
                    acks.push(self.record(&v, None));
                }
            }
            if kept > 0 {
                tracing::info!(kept, "queued jobs kept for the next start");
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
