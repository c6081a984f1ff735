//! Running queued jobs: what any worker does with a job it took from a [`JobQueue`], whichever
//! front queued it and whichever process runs it.

use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::Instant;

use bytes::Bytes;

use super::error::{Error, ErrorKind, Result};
use super::metadata::{self, Origin};
use super::ops::blocking;
use crate::engine::Engine;
use crate::queue::{Claim, JobQueue};
use crate::store::{VolumeMeta, VolumeStore};

/// Runs a claimed job on `engine` and stores its volume (unless the job was canceled
/// meanwhile: then nothing is stored and the error says so).
pub async fn run(
    engine: Arc<dyn Engine>,
    store: &dyn VolumeStore,
    claim: &Claim,
) -> Result<VolumeMeta> {
    let work = claim.work.clone();
    let (id, name) = (claim.id.clone(), claim.name.clone());
    let built = blocking(move || {
        let v = super::voxelize::run(&work, &*engine)?;
        metadata::build(
            &v.volume,
            &Origin::Mesh {
                prepared: &work,
                fill: &v.fill,
                job: Some(&id),
            },
            name,
            &engine.describe(),
        )
    })
    .await?;
    if claim.canceled.load(Ordering::SeqCst) {
        return Err(Error::new(ErrorKind::NotCancelable, "canceled"));
    }
    store
        .put(built.meta.clone(), Bytes::from(built.vxl))
        .await?;
    Ok(built.meta)
}

/// What a worker reports after each job, for metrics.
pub trait JobObserver: Send + Sync {
    fn job_done(&self, secs: f64, result: &Result<VolumeMeta>);
}

/// Takes jobs from `queue` and runs them until the queue is closed and drained.
pub async fn work(
    queue: Arc<dyn JobQueue>,
    store: Arc<dyn VolumeStore>,
    engine: Arc<dyn Engine>,
    observer: Arc<dyn JobObserver>,
) {
    while let Some(claim) = queue.next().await {
        let span = tracing::info_span!("job", id = %claim.id, method = claim.work.method.name(), dims = ?claim.work.grid.dims);
        let t = Instant::now();
        let result = {
            let _e = span.enter();
            tracing::info!("job started");
            drop(_e);
            run(engine.clone(), &*store, &claim).await
        };
        let secs = t.elapsed().as_secs_f64();
        {
            let _e = span.enter();
            match &result {
                Ok(m) => tracing::info!(volume = %m.id, secs, "job succeeded"),
                Err(e) => tracing::warn!(problem = %e.detail, secs, "job failed"),
            }
        }
        observer.job_done(secs, &result);
        queue.finish(&claim.id, result.map(|m| m.id)).await;
    }
}
