//! The sweep of uploads no job refers to: a job's upload (`uploads/{id}` in the store) lives
//! while the job is queued or running and is deleted when it ends. One left behind is deleted
//! at start and periodically, whichever queue and store the process uses:
//! * at once when the queue knows its job as ended (the process was killed between recording
//!   the job's end and deleting the upload: nothing will read it again);
//! * once older than a grace period (`--upload-grace`) when the queue does not know its job
//!   (killed between storing it and recording the job, or the job forgotten). The grace
//!   covers an upload being stored for a job not yet recorded: keep it above the time a
//!   submit takes.

use std::sync::Arc;
use std::time::{Duration, SystemTime};

use super::super::queue::JobQueue;
use super::super::store::VolumeStore;

/// `--upload-grace` by default: an hour.
pub const UPLOAD_GRACE_S: u64 = 3600;

/// Deletes the uploads in `store` whose job `queue` knows as ended, and those older than
/// `grace` whose job it does not know; how many.
pub async fn sweep(store: &dyn VolumeStore, queue: &dyn JobQueue, grace: Duration) -> usize {
    let uploads = match store.list_uploads().await {
        Ok(u) => u,
        Err(e) => {
            tracing::warn!("cannot list uploads to sweep: {e}");
            return 0;
        }
    };
    let now = SystemTime::now();
    let mut swept = 0;
    for (id, written) in uploads {
        let young = now.duration_since(written).unwrap_or_default() < grace;
        match queue.get(&id).await {
            Ok(Some(r)) if !r.state.is_final() => continue,
            // Its job has ended, whatever the upload's age.
            Ok(Some(_)) => {}
            // Perhaps a job about to be recorded.
            Ok(None) if young => continue,
            Ok(None) => {}
            // Not known whether a job needs it: kept.
            Err(_) => continue,
        }
        match store.delete_upload(&id).await {
            Ok(()) => swept += 1,
            Err(e) => tracing::warn!(job = %id, "cannot delete an orphaned upload: {e}"),
        }
    }
    if swept > 0 {
        tracing::info!(swept, "orphaned uploads deleted");
    }
    swept
}

/// Sweeps uploads and kept meshes ([`crate::app::sources::sweep`]) at once, then every quarter
/// of `grace` (between 5 s and 15 min), until the queue is dropped.
pub async fn sweep_periodically(
    store: Arc<dyn VolumeStore>,
    queue: std::sync::Weak<dyn JobQueue>,
    grace: Duration,
) {
    let every = (grace / 4).clamp(Duration::from_secs(5), Duration::from_secs(900));
    loop {
        let Some(q) = queue.upgrade() else { return };
        sweep(&*store, &*q, grace).await;
        drop(q);
        // And the kept meshes no volume refers to (a process killed between keeping one and
        // committing its volume), after the same grace.
        super::super::sources::sweep(&*store, grace).await;
        tokio::time::sleep(every).await;
    }
}
