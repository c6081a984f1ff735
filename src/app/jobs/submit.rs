//! The one submission path of a voxelization job, whichever front submits it (the HTTP route, a
//! batch runner, a queue consumer): admission, the upload, preparation, the record, then queued
//! or waited for. A front translates its input into a [`Submission`] and the outcome
//! ([`Submitted`]) into its output; nothing here knows HTTP. Not here: running the job (the
//! worker, `super`).

use std::future::Future;
use std::time::Duration;

use bytes::Bytes;

use super::super::error::{Error, Result};
use super::super::memory::{MemoryBudget, MemoryPermit};
use super::super::queue::{JobQueue, JobRecord, NewJob, Owner, State};
use super::super::request::{JobSpec, MeshSource, MethodSpec, VoxelizeRequest};
use super::super::store::{VolumeMeta, VolumeStore};
use crate::engine::fill::Fill;
use crate::grid::GridSpec;
use crate::limits::Limits;
use crate::mesh::{self, Format};

/// A voxelization job as a front asks for it, all but the upload's bytes.
#[derive(Clone, Debug)]
pub struct Submission {
    /// The upload's format as declared (`None`: sniffed).
    pub format: Option<Format>,
    pub grid: GridSpec,
    pub padding: u32,
    pub method: MethodSpec,
    pub fill: Fill,
    /// The attribute channels asked for (checked against the method).
    pub attributes: crate::engine::colour::Want,
    pub limits: Limits,
    pub name: Option<String>,
    /// The API key that submits it, and its limit of jobs at once.
    pub owner: Option<Owner>,
    /// How long to wait for the job before answering with it unfinished (zero: not at all).
    pub wait: Duration,
    /// The id of the request that submits it (kept in the job's record, on its log lines).
    pub request_id: Option<String>,
}

impl Submission {
    /// The voxelization of `upload`.
    pub fn request(&self, upload: Bytes) -> VoxelizeRequest {
        VoxelizeRequest {
            source: MeshSource::Bytes {
                bytes: upload,
                format: self.format,
            },
            grid: self.grid,
            padding: self.padding,
            method: self.method,
            fill: self.fill,
            attributes: self.attributes,
            limits: self.limits,
        }
    }
}

/// Where a submitted job stands when [`submit`] answers.
#[derive(Debug)]
pub enum Submitted {
    /// It succeeded within the wait: its volume.
    Done { id: String, meta: Box<VolumeMeta> },
    /// It failed within the wait: job `id`, and why.
    Failed { id: String, error: Error },
    /// Queued or running (its record is durable).
    Pending(Box<JobRecord>),
}

/// Where a job goes: the queue, the store its volumes go to, and the pool that parses meshes
/// (`None`: rayon's global pool).
#[derive(Clone, Copy)]
pub struct Jobs<'a> {
    pub queue: &'a dyn JobQueue,
    pub store: &'a dyn VolumeStore,
    pub pool: Option<&'a rayon::ThreadPool>,
    /// The budget an upload's parse is admitted by (`None`: not admitted).
    pub memory: Option<&'a MemoryBudget>,
}

/// How long an upload's parse waits for memory before it is answered `busy`.
pub const PARSE_WAIT: Duration = Duration::from_secs(10);

/// Admits the parse of an uploaded mesh by its estimate ([`mesh::cost`]), and holds the parse to
/// the decoded size the estimate assumed (so it holds for the file as parsed).
async fn admit_parse(
    memory: Option<&MemoryBudget>,
    req: &mut VoxelizeRequest,
) -> Result<MemoryPermit> {
    let (Some(memory), MeshSource::Bytes { bytes, format }) = (memory, &req.source) else {
        return Ok(MemoryPermit::none());
    };
    let opts = req.load_options();
    let est = mesh::cost::estimate(bytes, *format, &opts);
    req.limits.max_decompressed_bytes = req.limits.max_decompressed_bytes.min(est.decoded);
    memory
        .admit(est.bytes, "parsing the mesh", PARSE_WAIT)
        .await
}

/// Submits a voxelization job: asks the queue whether it would take one (before the upload is
/// read, so an overloaded server spends nothing on meshes it cannot take), reads the upload
/// (`upload` gives its bytes and a guard, say a memory budget, held until the job is queued),
/// prepares it (load, diagnose, fit: a mesh that cannot run is refused here, parsed once for the
/// job), records and queues it, and with a wait, waits for it.
pub async fn submit<G: Send>(
    jobs: Jobs<'_>,
    sub: Submission,
    upload: impl Future<Output = Result<(Bytes, G)>>,
) -> Result<Submitted> {
    jobs.queue.admission(sub.owner.as_ref()).await?;
    let (bytes, guard) = upload.await?;
    let mut req = sub.request(bytes);
    let spec = JobSpec::of(&req);
    // Held through the parse and until the job is queued, as the upload's guard is.
    let parse = admit_parse(jobs.memory, &mut req).await?;
    let work = super::super::ops::on_pool(jobs.pool, move || super::super::prepare(&req)).await?;
    // A job that could never get its memory is refused now, not failed later.
    if let Some(m) = jobs.memory {
        m.check_fits(super::job_bytes(&work), "the voxelization")?;
    }
    let id = super::super::new_id();
    // The request's span (when a request submits it) names the job it made.
    tracing::Span::current().record("job", id.as_str());
    let job = NewJob {
        id: id.clone(),
        work,
        spec,
        name: sub.name,
        owner: sub.owner,
        request_id: sub.request_id,
        created: super::super::rfc3339(std::time::SystemTime::now()),
    };
    let (method, request_id) = (job.method(), job.request_id.clone());
    let wait = !sub.wait.is_zero();
    // With a wait, the answer comes once the job is final (its final record durable), or else
    // after `persist` below: the queued record need not be synced first.
    let record = if wait {
        jobs.queue.submit_deferred(job).await?
    } else {
        jobs.queue.submit(job).await?
    };
    tracing::info!(
        job = id.as_str(),
        request_id = request_id.as_deref(),
        method,
        "job queued"
    );
    // The upload's budget is given back once the job is queued (a shared queue has stored
    // the prepared job by then, which the budget stood for meanwhile).
    drop(guard);
    drop(parse);
    if !wait {
        return Ok(Submitted::Pending(Box::new(record)));
    }
    let r = jobs.queue.wait(&id, sub.wait).await?.unwrap_or(record);
    match (r.state, &r.volume_id, &r.error) {
        (State::Succeeded, Some(v), _) => {
            if let Some(meta) = jobs.store.get(v).await? {
                return Ok(Submitted::Done {
                    id,
                    meta: Box::new(meta),
                });
            }
        }
        (State::Failed, _, Some(e)) => {
            return Ok(Submitted::Failed {
                id,
                error: e.clone(),
            });
        }
        _ => {}
    }
    // Answered with the job's id before it is final: its record must survive a crash.
    jobs.queue.persist(&id).await?;
    Ok(Submitted::Pending(Box::new(r)))
}
