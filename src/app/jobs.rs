//! Jobs, from submission to their end, for every front and every queue: [`submit`] (admission,
//! preparation, the record, queued or waited for) is the one submission path, and the worker
//! ([`work`], [`run`]) is what any process does with a job it took from a [`JobQueue`]: it
//! prepares a job submitted elsewhere (once), runs it on the engine and stores its volume. Not
//! here: how a front reads its input (it hands a [`Submission`]) or how a queue keeps jobs.

use std::sync::Arc;
use std::time::{Duration, Instant};

use tracing::Instrument;

use super::cost;
use super::error::{Error, ErrorKind, Result};
use super::memory::{MemoryBudget, MemoryPermit};
use super::metadata::{self, Origin};
use super::ops::blocking;
use super::queue::{Claim, CommitGuard, JobQueue, Work};
use super::request::JobSpec;
use super::sources;
use super::store::{VolumeMeta, VolumeStore, source_key};
use super::voxelize::Prepared;
use crate::cancel::Canceled;
use crate::engine::Engine;

pub mod stored;
mod submit;
pub mod sweep;
pub use submit::{Jobs, Submission, Submitted, submit};

/// Runs a claimed job on `engine` under its control and stores its volume (under the claim's
/// volume id when it has one, once its guard agrees). A job canceled meanwhile stops at the
/// engine's next check point and stores nothing (the error says so); a job whose deadline
/// (`--job-timeout`) passes stops there too and fails with a problem naming the timeout.
pub async fn run(
    engine: Arc<dyn Engine>,
    store: &dyn VolumeStore,
    claim: &Claim,
) -> Result<VolumeMeta> {
    let work = prepared(store, &claim.id, claim.work.clone()).await?;
    let built = build(engine, work, claim).await?;
    keep(
        store,
        claim.volume_id.as_deref(),
        claim.guard.as_deref(),
        built,
    )
    .await
}

/// A job's work, prepared: as the queue handed it, or here from the job's stored request and
/// upload (a job submitted to another process), job `id`'s in `store`. The upload is the job
/// as the submitting process prepared it ([`stored`]): decoded, not parsed, so the mesh is
/// parsed once per job; one stored as the raw mesh file (by an older process) is prepared from
/// it, as it was then.
pub async fn prepared(store: &dyn VolumeStore, id: &str, work: Work) -> Result<Arc<Prepared>> {
    let (spec, limits) = match work {
        Work::Prepared(p) => return Ok(p),
        Work::Stored { spec, limits } => (spec, limits),
    };
    let spec: JobSpec = serde_json::from_str(&spec)
        .map_err(|e| Error::internal(format!("the job's stored request is unreadable: {e}")))?;
    let upload = store
        .get_upload(id)
        .await
        .map_err(|e| Error::from(e).context("cannot read the job's upload"))?
        .ok_or_else(|| {
            Error::internal(format!(
                "the job's upload is missing from the store ({})",
                store.describe()
            ))
        })?;
    let req = spec.request(upload.clone(), &limits)?;
    let p = blocking(move || {
        if stored::is_prepared(&upload) {
            stored::decode(&upload, &req)
        } else {
            super::prepare(&req)
        }
    })
    .await
    .inspect_err(|e| tracing::warn!(job = %id, "cannot prepare the job again: {}", e.detail))?;
    Ok(Arc::new(p))
}

/// The engine's part of [`run`]: the volume and its metadata (owned by the job's owner), not
/// yet stored.
async fn build(
    engine: Arc<dyn Engine>,
    work: Arc<Prepared>,
    claim: &Claim,
) -> Result<metadata::Built> {
    let (id, name) = (claim.id.clone(), claim.name.clone());
    let ctl = claim.control.clone();
    let gpu = engine.name() == "gpu";
    let job = move || {
        let v = super::voxelize::run(&work, &*engine, &ctl)?;
        let mut built = metadata::build(
            &v.volume,
            &Origin::Mesh {
                prepared: &work,
                fill: &v.fill,
                job: Some(&id),
            },
            name,
            &engine.describe(),
        )?;
        // An upload's mesh is kept under its sha256 for the volume's mesh-based downloads
        // (Hermite data, dual contouring): `sources`.
        if let Some(key) = work.source.sha256.as_deref().filter(|k| source_key(k)) {
            built.meta.source.kept = true;
            built.meta.source.sha256 = key.to_string();
            built.source = Some(super::sources::encode(&work.mesh));
        }
        Ok(built)
    };
    // The GPU engine waits for its device (for the batch its slab went in, or to lead the
    // next): not on the CPU pool, where a job taken up by a pool thread waiting inside another
    // could wait for a batch that thread was to lead.
    let built = if gpu {
        tokio::task::spawn_blocking(job)
            .await
            .map_err(|e| Error::internal(format!("the job panicked: {e}")))
            .and_then(|r| r)
    } else {
        blocking(job).await
    };
    // Canceled: the result is discarded whatever it is. Past the deadline: a job that failed
    // (at a check point) failed for that; one that finished in time keeps its result.
    match claim.control.check() {
        Err(Canceled::Canceled) => return Err(Error::new(ErrorKind::NotCancelable, "canceled")),
        Err(Canceled::DeadlinePassed) if built.is_err() => return Err(timed_out(claim.timeout)),
        _ => {}
    }
    // The volume is owned by the job's tenant.
    built.map(|mut b| {
        b.meta.owner = claim.owner.clone();
        b
    })
}

/// The store's part of [`run`]: the volume under the claim's volume id (if it has one), once
/// the claim's guard (if any) agrees.
async fn keep(
    store: &dyn VolumeStore,
    volume_id: Option<&str>,
    guard: Option<&dyn CommitGuard>,
    mut built: metadata::Built,
) -> Result<VolumeMeta> {
    if let Some(id) = volume_id {
        built.meta.id = id.to_string();
    }
    if let Some(guard) = guard {
        guard.confirm().await?;
    }
    let Some(source) = built.source else {
        store.put(built.meta.clone(), built.vxl).await?;
        return Ok(built.meta);
    };
    let key = built.meta.source.sha256.clone();
    // The mesh first, then the volume, then the mesh is made sure of (`sources`).
    sources::keep(store, &key, &source).await?;
    if let Err(e) = store.put(built.meta.clone(), built.vxl).await {
        if let Err(e) = sources::release(store, &key).await {
            tracing::warn!(source = %key, "cannot remove the mesh of a volume not stored: {e}");
        }
        return Err(e.into());
    }
    sources::kept(store, &key, source).await;
    Ok(built.meta)
}

/// The problem of a job stopped by its deadline.
pub fn timed_out(timeout: Option<Duration>) -> Error {
    let limit = timeout.map_or_else(
        || "its deadline".to_string(),
        |t| format!("--job-timeout ({} s)", t.as_secs_f64()),
    );
    Error::new(
        ErrorKind::Timeout,
        format!(
            "the job ran longer than {limit} and was stopped; use a coarser grid or a cheaper fill, or raise the server's --job-timeout"
        ),
    )
}

/// What a worker reports after each job, for metrics: its method (`unknown` for a job that
/// could not be prepared), how it ended, its time from being taken to being stored, and its
/// result.
pub trait JobObserver: Send + Sync {
    fn job_done(&self, method: &str, outcome: Outcome, secs: f64, result: &Result<VolumeMeta>);
}

crate::named_enum! {
    /// How a job a worker took ended (its metrics' `outcome`).
    pub enum Outcome: "job outcome" {
        Succeeded = "succeeded",
        Failed = "failed",
        Canceled = "canceled",
        TimedOut = "timed_out",
    }
}

impl Outcome {
    /// How a job whose control is `control` ended with `result`.
    pub fn of<T>(control: &crate::cancel::Control, result: &Result<T>) -> Outcome {
        match result {
            Ok(_) => Outcome::Succeeded,
            Err(_) if control.is_canceled() => Outcome::Canceled,
            Err(e) if e.kind == ErrorKind::Timeout => Outcome::TimedOut,
            Err(_) => Outcome::Failed,
        }
    }
}

/// Jobs a worker may have between its engine and the store: the one it is building and up to
/// this many minus one whose volumes are still being written. While the store syncs one job's
/// volume (a group commit gathers the volumes written meanwhile), the worker builds the next.
/// On a disk whose sync takes milliseconds the store, not the engine, limits small jobs: each
/// place is a job that can share the next group commit (16 places rather than 4: 1.15× the
/// jobs/s for a 12-triangle mesh at 64³ with 2 workers and 16 clients, 1.09× for spot; see
/// docs/bench-load.md).
pub const JOBS_PER_WORKER: usize = 16;

/// Bytes of encoded volumes a worker may have waiting on the store, so that many places do not
/// mean many large volumes in memory: a volume larger than this waits for the whole budget,
/// i.e. until the worker's other volumes are stored.
pub const STORE_BYTES_PER_WORKER: usize = 256 << 20;
/// The budget is counted in KiB: a semaphore's `acquire_many` takes a u32 count.
const BUDGET_UNIT: usize = 1 << 10;

/// Takes jobs from `queue` and runs them until the queue is closed and drained. One job at a time
/// is on the engine; its volume is stored by a task of its own, so that the next job starts
/// while the store syncs (at most [`JOBS_PER_WORKER`] jobs in all, and at most
/// [`STORE_BYTES_PER_WORKER`] of encoded volumes waiting on the store). A job is finished in the
/// queue, and its waiters answered, only once its volume is stored. Returns when every job it
/// took is finished.
pub async fn work(
    queue: Arc<dyn JobQueue>,
    store: Arc<dyn VolumeStore>,
    engine: Arc<dyn Engine>,
    observer: Arc<dyn JobObserver>,
    memory: Option<MemoryBudget>,
) {
    work_with(
        queue,
        store,
        engine,
        observer,
        memory,
        JOBS_PER_WORKER,
        STORE_BYTES_PER_WORKER,
    )
    .await
}

/// Memory a voxelization job holds while it runs: the engine's volume and working set by its
/// grid and method ([`cost::voxelize_job`]) and its mesh (positions and triangles, and its
/// encoding to be kept when it was uploaded).
pub fn job_bytes(work: &Prepared) -> u64 {
    let (v, t) = (work.mesh.positions().len(), work.mesh.triangles().len());
    let mut mesh = (24 * v + 12 * t) as u64;
    if work.source.sha256.is_some() {
        // The mesh kept for the volume (`sources`), encoded beside it until it is stored.
        mesh += crate::mesh::binary::encoded_len(v, t) as u64;
    }
    cost::voxelize_job(&work.grid, &work.method, work.candidate_bricks)
        .saturating_add(mesh)
        .saturating_add(cost::colour_job(&work.grid, work.attributes, &work.mesh))
}

/// Holds job `claim`'s memory before it runs ([`job_bytes`]): it waits in its worker while other
/// work holds the budget, looking at its control every second (a job canceled or past its
/// deadline meanwhile stops waiting); one larger than the whole budget fails with
/// `too-much-memory`.
async fn admit_job(memory: &MemoryBudget, work: &Prepared, claim: &Claim) -> Result<MemoryPermit> {
    let what = format!(
        "job {} ({} on {:?})",
        claim.id,
        work.method.name(),
        work.grid.dims
    );
    loop {
        match memory
            .admit(job_bytes(work), &what, Duration::from_secs(1))
            .await
        {
            Err(e) if e.kind == ErrorKind::Busy => match claim.control.check() {
                Err(Canceled::Canceled) => {
                    return Err(Error::new(ErrorKind::NotCancelable, "canceled"));
                }
                Err(Canceled::DeadlinePassed) => return Err(timed_out(claim.timeout)),
                Ok(()) => {}
            },
            r => return r,
        }
    }
}

/// [`work`] with `jobs` places and a budget of `store_bytes` (the tests use small ones).
async fn work_with(
    queue: Arc<dyn JobQueue>,
    store: Arc<dyn VolumeStore>,
    engine: Arc<dyn Engine>,
    observer: Arc<dyn JobObserver>,
    memory: Option<MemoryBudget>,
    jobs: usize,
    store_bytes: usize,
) {
    let places = Arc::new(tokio::sync::Semaphore::new(jobs.max(1)));
    let budget_units = (store_bytes / BUDGET_UNIT).max(1);
    let budget = Arc::new(tokio::sync::Semaphore::new(budget_units));
    let mut storing = tokio::task::JoinSet::new();
    loop {
        // A place first: a job is not taken from the queue before this worker can run it.
        let place = places
            .clone()
            .acquire_owned()
            .await
            .expect("the semaphore is never closed");
        let Some(claim) = queue.next().await else {
            break;
        };
        // Every line of the job carries its id and the id of the request that submitted it.
        let span = tracing::info_span!(
            "job",
            job = claim.id.as_str(),
            request_id = claim.request_id.as_deref(),
            method = tracing::field::Empty,
            dims = tracing::field::Empty
        );
        let control = claim.control.clone();
        let mut method = "unknown";
        let t = Instant::now();
        // Prepared here (once) when it was submitted elsewhere; a job that cannot be fails.
        let work = prepared(&*store, &claim.id, claim.work.clone())
            .instrument(span.clone())
            .await;
        let built = match work {
            Ok(work) => {
                method = work.method.name();
                span.record("method", method);
                span.record("dims", tracing::field::debug(work.grid.dims));
                // Its memory first (held until its volume is built and encoded).
                let permit = match &memory {
                    Some(m) => admit_job(m, &work, &claim)
                        .instrument(span.clone())
                        .await
                        .map(Some),
                    None => Ok(None),
                };
                match permit {
                    Ok(permit) => {
                        span.in_scope(|| tracing::info!("job started"));
                        let built = build(engine.clone(), work, &claim)
                            .instrument(span.clone())
                            .await;
                        drop(permit);
                        built
                    }
                    Err(e) => Err(e),
                }
            }
            Err(e) => Err(e),
        };
        // Only what storing needs from here on: the mesh (the claim's `work`, which the queue
        // no longer holds either) is freed now, before the wait for the byte budget below, not
        // when the store is done with the volume.
        let (id, volume_id, guard) = (claim.id, claim.volume_id, claim.guard);
        drop(claim.work);
        // The volume's share of the byte budget (the whole of it for one larger than that),
        // before the next job is taken: this worker's volumes waiting on the store stay within
        // the budget, plus the one just built.
        let units = built.as_ref().map_or(0, |b| {
            b.vxl.len().div_ceil(BUDGET_UNIT).clamp(1, budget_units) as u32
        });
        let bytes = budget
            .clone()
            .acquire_many_owned(units)
            .await
            .expect("the semaphore is never closed");
        let (queue, store, observer) = (queue.clone(), store.clone(), observer.clone());
        let end = async move {
            let result = match built {
                Ok(built) => {
                    // The queue may write the job's success while the volume is stored.
                    queue.storing(&id, volume_id.as_deref().unwrap_or(&built.meta.id));
                    keep(&*store, volume_id.as_deref(), guard.as_deref(), built).await
                }
                Err(e) => Err(e),
            };
            let secs = t.elapsed().as_secs_f64();
            let outcome = Outcome::of(&control, &result);
            // A cancel is the client's decision and a timeout the server's limit: neither is a
            // fault of the service (info); a failure is (warn).
            match (&result, outcome) {
                (Ok(m), _) => tracing::info!(volume = m.id.as_str(), secs, "job succeeded"),
                (Err(_), Outcome::Canceled) => tracing::info!(secs, "job canceled"),
                (Err(e), Outcome::TimedOut) => {
                    tracing::info!(problem = e.detail.as_str(), secs, "job timed out")
                }
                (Err(e), _) => tracing::warn!(problem = e.detail.as_str(), secs, "job failed"),
            }
            observer.job_done(method, outcome, secs, &result);
            queue.finish(&id, result.map(|m| m.id)).await;
            drop((place, bytes));
        };
        storing.spawn(end.instrument(span));
        while storing.try_join_next().is_some() {}
    }
    while storing.join_next().await.is_some() {}
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use bytes::Bytes;

    use super::*;
    use crate::app::queue::{NewJob, State};
    use crate::app::store::Vxl;
    use crate::cancel::Control;
    use crate::engine::cpu::CpuEngine;
    use crate::engine::{EngineError, GridMesh, Method};
    use crate::queue::local::LocalQueue;
    use crate::store::fs::FsStore;
    use crate::volume::BitVolume;

    /// The CPU engine behind `steps` check points of a millisecond each: a job that takes a
    /// while, checks its control and reports progress as an engine does.
    struct Slow {
        steps: u32,
    }

    impl Engine for Slow {
        fn name(&self) -> &'static str {
            "slow"
        }
        fn voxelize_with(
            &self,
            mesh: &GridMesh,
            method: Method,
            ctl: &Control,
        ) -> std::result::Result<BitVolume, EngineError> {
            for i in 0..self.steps {
                ctl.check()?;
                ctl.set(f64::from(i) / f64::from(self.steps));
                std::thread::sleep(Duration::from_millis(1));
            }
            CpuEngine.voxelize_with(mesh, method, &ctl.stage(0.99, 1.0))
        }
    }

    fn job(id: &str) -> NewJob {
        crate::app::testing::tiny_job(id, 16)
    }

    /// A fresh directory store (removed when the guard drops).
    fn open_store(name: &str) -> (crate::testkit::Scratch, Arc<dyn VolumeStore>) {
        let dir = crate::testkit::Scratch::new(&format!("jobs-{name}"));
        let store: Arc<dyn VolumeStore> = Arc::new(FsStore::open(&dir, 1 << 24).unwrap());
        (dir, store)
    }

    async fn open(
        name: &str,
        timeout: Option<Duration>,
    ) -> (crate::testkit::Scratch, Arc<dyn VolumeStore>, LocalQueue) {
        let (dir, store) = open_store(name);
        let q = LocalQueue::open(4, store.clone())
            .await
            .unwrap()
            .with_job_timeout(timeout);
        (dir, store, q)
    }

    async fn stored(store: &dyn VolumeStore) -> usize {
        store.list(None, 100).await.unwrap().0.len()
    }

    /// Canceling a running job stops its engine at the next check point: the worker's run
    /// returns the canceled error with the job's progress below 1, and nothing is stored.
    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_canceled_running_job_stops_at_a_check_point_and_stores_nothing() {
        let (_dir, store, q) = open("cancel", None).await;
        q.submit(job("j1")).await.unwrap();
        let claim = q.next().await.unwrap();
        let engine: Arc<dyn Engine> = Arc::new(Slow { steps: 100_000 });
        let ctl = claim.control.clone();
        let worker = {
            let store = store.clone();
            tokio::spawn(async move { run(engine, &*store, &claim).await })
        };
        // Running, and the record shows the engine's live progress.
        let mut shown = 0.0;
        for _ in 0..10_000 {
            shown = q.get("j1").await.unwrap().unwrap().progress;
            if shown > 0.0 {
                break;
            }
            tokio::time::sleep(Duration::from_millis(1)).await;
        }
        assert!(shown > 0.0 && shown < 1.0, "{shown}");
        let r = q.cancel("j1").await.unwrap().unwrap();
        assert_eq!(r.state, State::Canceled);
        let e = worker.await.unwrap().unwrap_err();
        assert_eq!(
            (e.kind, e.detail.as_str()),
            (ErrorKind::NotCancelable, "canceled")
        );
        assert!(ctl.progress() < 1.0, "{}", ctl.progress());
        q.finish("j1", Err(e)).await;
        let r = q.get("j1").await.unwrap().unwrap();
        assert_eq!(r.state, State::Canceled);
        assert!(r.progress > 0.0 && r.progress < 1.0, "{}", r.progress);
        assert_eq!(stored(&*store).await, 0);
    }

    /// A running job's record shows its progress as it rises, never falling, and 1 once done.
    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_running_jobs_progress_rises_to_one() {
        let (_dir, store, q) = open("progress", None).await;
        q.submit(job("j2")).await.unwrap();
        let claim = q.next().await.unwrap();
        let engine: Arc<dyn Engine> = Arc::new(Slow { steps: 200 });
        let worker = {
            let store = store.clone();
            tokio::spawn(async move { run(engine, &*store, &claim).await })
        };
        let mut seen = vec![];
        while !worker.is_finished() {
            seen.push(q.get("j2").await.unwrap().unwrap().progress);
            tokio::time::sleep(Duration::from_millis(2)).await;
        }
        let meta = worker.await.unwrap().unwrap();
        q.finish("j2", Ok(meta.id.clone())).await;
        assert!(seen.windows(2).all(|w| w[0] <= w[1]), "{seen:?}");
        assert!(seen.iter().any(|&p| p > 0.0 && p < 1.0), "{seen:?}");
        let r = q.get("j2").await.unwrap().unwrap();
        assert_eq!((r.state, r.progress), (State::Succeeded, 1.0));
        assert_eq!(stored(&*store).await, 1);
    }

    /// A store whose puts wait for a permit of `gate` (one each), counting the most under way.
    struct Gated {
        inner: Arc<dyn VolumeStore>,
        gate: Arc<tokio::sync::Semaphore>,
        now: std::sync::atomic::AtomicUsize,
        most: std::sync::atomic::AtomicUsize,
    }

    #[async_trait::async_trait]
    impl VolumeStore for Gated {
        async fn put(&self, meta: VolumeMeta, vxl: Vxl) -> StoreResult<()> {
            use std::sync::atomic::Ordering::SeqCst;
            let n = self.now.fetch_add(1, SeqCst) + 1;
            self.most.fetch_max(n, SeqCst);
            self.gate.acquire().await.unwrap().forget();
            self.now.fetch_sub(1, SeqCst);
            self.inner.put(meta, vxl).await
        }
        async fn get(&self, id: &str) -> StoreResult<Option<VolumeMeta>> {
            self.inner.get(id).await
        }
        async fn read(&self, id: &str) -> StoreResult<Option<Bytes>> {
            self.inner.read(id).await
        }
        async fn list(
            &self,
            after: Option<&str>,
            limit: usize,
        ) -> StoreResult<(Vec<VolumeMeta>, bool)> {
            self.inner.list(after, limit).await
        }
        async fn read_stream(
            &self,
            id: &str,
        ) -> StoreResult<Option<crate::app::store::ByteStream>> {
            self.inner.read_stream(id).await
        }
        async fn delete(&self, id: &str) -> StoreResult<bool> {
            self.inner.delete(id).await
        }
        async fn usage(&self) -> StoreResult<crate::app::store::Usage> {
            self.inner.usage().await
        }
        async fn health(&self) -> StoreResult<()> {
            self.inner.health().await
        }
        async fn put_job_record(&self, id: &str, record: Bytes) -> StoreResult<()> {
            self.inner.put_job_record(id, record).await
        }
        async fn delete_job_record(&self, id: &str) -> StoreResult<()> {
            self.inner.delete_job_record(id).await
        }
        async fn put_job_records(
            &self,
            batch: Vec<(String, Option<Bytes>)>,
            durable: bool,
        ) -> Vec<StoreResult<()>> {
            self.inner.put_job_records(batch, durable).await
        }
        async fn job_records(&self) -> StoreResult<Vec<Bytes>> {
            self.inner.job_records().await
        }
        async fn put_upload(&self, id: &str, bytes: Bytes) -> StoreResult<()> {
            self.inner.put_upload(id, bytes).await
        }
        async fn get_upload(&self, id: &str) -> StoreResult<Option<Bytes>> {
            self.inner.get_upload(id).await
        }
        async fn delete_upload(&self, id: &str) -> StoreResult<()> {
            self.inner.delete_upload(id).await
        }
        async fn put_source(&self, key: &str, bytes: Bytes) -> StoreResult<()> {
            self.inner.put_source(key, bytes).await
        }
        async fn get_source(&self, key: &str) -> StoreResult<Option<Bytes>> {
            self.inner.get_source(key).await
        }
        async fn delete_source(&self, key: &str) -> StoreResult<()> {
            self.inner.delete_source(key).await
        }
        async fn source_referred(&self, key: &str) -> StoreResult<bool> {
            self.inner.source_referred(key).await
        }
        async fn list_sources(&self) -> StoreResult<Vec<(String, std::time::SystemTime)>> {
            self.inner.list_sources().await
        }
        fn describe(&self) -> String {
            self.inner.describe()
        }
    }

    type StoreResult<T> = std::result::Result<T, crate::app::store::StoreError>;

    struct Quiet;
    impl JobObserver for Quiet {
        fn job_done(&self, _: &str, _: Outcome, _: f64, _: &Result<VolumeMeta>) {}
    }

    /// A worker keeps at most `jobs` jobs between its engine and the store, and at most the
    /// byte budget of volumes waiting on the store: with puts held back, the puts under way
    /// stop at the budget (room for 3 tiny volumes, with 16 places) or at the places
    /// (2, with a large budget), and every job still finishes once the puts go on.
    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_worker_holds_at_most_its_places_and_its_byte_budget_waiting_on_the_store() {
        use std::sync::atomic::Ordering::SeqCst;
        // One tiny volume's share of the budget, in units.
        let (_dir, store, q) = open("pipeline-size", None).await;
        q.submit(job("size")).await.unwrap();
        let claim = q.next().await.unwrap();
        let size = run(Arc::new(CpuEngine), &*store, &claim)
            .await
            .unwrap()
            .bytes as usize;
        let units = size.div_ceil(BUDGET_UNIT);
        for (name, jobs, bytes, bound) in [
            ("budget", 16, 3 * units * BUDGET_UNIT, 3),
            ("places", 2, 1 << 30, 2),
        ] {
            let (_dir, inner) = open_store(&format!("pipeline-{name}"));
            // Room for every job at once.
            let q = LocalQueue::open(16, inner.clone()).await.unwrap();
            let gate = Arc::new(tokio::sync::Semaphore::new(0));
            let store = Arc::new(Gated {
                inner,
                gate: gate.clone(),
                now: Default::default(),
                most: Default::default(),
            });
            let q = Arc::new(q);
            let ids: Vec<String> = (0..8).map(|i| format!("{name}{i}")).collect();
            for id in &ids {
                q.submit(job(id)).await.unwrap();
            }
            let worker = tokio::spawn(work_with(
                q.clone(),
                store.clone(),
                Arc::new(CpuEngine),
                Arc::new(Quiet),
                None,
                jobs,
                bytes,
            ));
            // The puts under way reach the bound and stay there while the gate is shut.
            for _ in 0..5_000 {
                if store.now.load(SeqCst) >= bound {
                    break;
                }
                tokio::time::sleep(Duration::from_millis(1)).await;
            }
            tokio::time::sleep(Duration::from_millis(50)).await;
            assert_eq!(store.now.load(SeqCst), bound, "{name}");
            gate.add_permits(ids.len());
            for id in &ids {
                let r = q.wait(id, Duration::from_secs(30)).await.unwrap().unwrap();
                assert_eq!(r.state, State::Succeeded, "{name} {id}");
            }
            assert_eq!(store.most.load(SeqCst), bound, "{name}");
            q.close(Error::internal("done")).await;
            worker.await.unwrap();
            assert_eq!(stored(&*store).await, ids.len());
        }
    }

    /// A job whose deadline has passed when it runs fails with the timeout problem, and
    /// nothing is stored.
    #[tokio::test]
    async fn a_job_past_its_deadline_fails_with_the_timeout_problem() {
        let (_dir, store, q) = open("deadline", Some(Duration::ZERO)).await;
        q.submit(job("j3")).await.unwrap();
        let claim = q.next().await.unwrap();
        assert!(claim.control.deadline().is_some());
        let e = run(Arc::new(CpuEngine), &*store, &claim).await.unwrap_err();
        assert_eq!(e.kind, ErrorKind::Timeout);
        assert!(
            e.detail
                .starts_with("the job ran longer than --job-timeout (0 s)"),
            "{}",
            e.detail
        );
        q.finish("j3", Err(e.clone())).await;
        let r = q.get("j3").await.unwrap().unwrap();
        assert_eq!((r.state, r.error), (State::Failed, Some(e)));
        assert_eq!(stored(&*store).await, 0);
        // Without a timeout the same job runs to its end.
        let (_dir2, store, q) = open("no-deadline", None).await;
        q.submit(job("j4")).await.unwrap();
        let claim = q.next().await.unwrap();
        assert!(claim.control.deadline().is_none());
        run(Arc::new(CpuEngine), &*store, &claim).await.unwrap();
    }

    /// A job submitted elsewhere is prepared from its stored form without parsing its mesh
    /// (the stored bytes are no mesh file: the loader refuses them) into the work the
    /// submitting process had; an upload an older process stored as the raw mesh file still
    /// runs, prepared from it, with the same source and its sha256.
    #[tokio::test]
    async fn a_stored_job_is_decoded_not_parsed_and_a_raw_upload_still_runs() {
        let (_dir, store) = open_store("stored");
        let new = job("s1");
        let spec = serde_json::to_string(&new.spec).unwrap();
        let here = new.work.clone();
        let (kept, bytes) = new.into_shared().await.unwrap();
        assert!(matches!(kept, Work::Prepared(_)));
        assert!(stored::is_prepared(&bytes));
        let opts = crate::mesh::LoadOptions::default();
        assert!(crate::mesh::load_bytes(&bytes, None, &opts).is_err());
        store.put_upload("s1", bytes).await.unwrap();
        let raw = Bytes::from_static(crate::app::testing::TETRA_OBJ);
        store.put_upload("s2", raw).await.unwrap();
        let work = || Work::Stored {
            spec: spec.clone(),
            limits: crate::limits::Limits::SERVICE,
        };
        for id in ["s1", "s2"] {
            let p = prepared(&*store, id, work()).await.unwrap();
            assert_eq!(p.mesh, here.mesh, "{id}");
            assert_eq!(p.diagnostics, here.diagnostics, "{id}");
            assert_eq!(p.source, here.source, "{id}");
            assert_eq!(
                (p.grid, p.method, p.fill),
                (here.grid, here.method, here.fill)
            );
        }
        // The decoded job keeps the submitting process's load times (nothing was loaded here).
        let p = prepared(&*store, "s1", work()).await.unwrap();
        assert_eq!((p.load_s, p.diagnose_s), (here.load_s, here.diagnose_s));
        // Held to this process's limits, as parsing would be.
        let few = Work::Stored {
            spec: spec.clone(),
            limits: crate::limits::Limits {
                max_triangles: 3,
                ..crate::limits::Limits::SERVICE
            },
        };
        let e = prepared(&*store, "s1", few).await.unwrap_err();
        assert_eq!(e.kind, ErrorKind::TooManyTriangles);
    }
}
