//! The in-process queue's records in the store, and what a start makes of them.
//!
//! A job answered with `202` before it ends is *kept*: its prepared mesh is in the store under
//! `uploads/{id}` ([`VolumeStore::put_upload`], the bytes of [`crate::app::queue::NewJob::into_shared`],
//! as the shared queue keeps them) and its record carries its request as data ([`SPEC`]) until
//! it ends, when the upload is deleted. Its start is recorded (state `running`, `attempts`
//! counted) before it runs. At the next start ([`recover`]) a kept job that was queued is
//! queued again, and one that was running is queued again unless it was started
//! `--max-attempts` times already (each start ended by the process dying: a job that brings
//! the server down stops doing so); then it fails, "interrupted N times". A job that was not
//! kept (a request still waiting for its answer when the process died) failed (interrupted),
//! as before: its client was never told its id.

use std::collections::HashMap;
use std::sync::Arc;

use bytes::Bytes;
use tokio::sync::{mpsc, oneshot};

use crate::app::queue::{Error, ErrorKind, JobRecord, State};
use crate::app::store::VolumeStore;

/// The mark of a success written ahead of its volume (see the queue's documentation).
pub(super) const UNCONFIRMED: &str = "unconfirmed_volume";

/// A kept job's request as data (the `JobSpec` as JSON), in its records until it ends.
pub(super) const SPEC: &str = "spec";

/// A record as read back: the record, whether it is a success written ahead of its volume
/// ([`UNCONFIRMED`]), and a kept job's request ([`SPEC`]).
pub(super) struct Stored {
    pub record: JobRecord,
    pub unconfirmed: bool,
    pub spec: Option<String>,
}

/// A record's bytes: `r`, marked [`UNCONFIRMED`] when `unconfirmed`, with the kept job's
/// request `spec` while it has not ended.
pub(super) fn encode(r: &JobRecord, unconfirmed: bool, spec: Option<&str>) -> Bytes {
    let spec = spec.filter(|_| !r.state.is_final() || unconfirmed);
    let bytes = if unconfirmed || spec.is_some() {
        let mut v = serde_json::to_value(r).expect("job record serialises");
        if unconfirmed {
            v[UNCONFIRMED] = true.into();
        }
        if let Some(s) = spec {
            v[SPEC] = s.into();
        }
        serde_json::to_vec(&v)
    } else {
        serde_json::to_vec(r)
    };
    Bytes::from(bytes.expect("job record serialises"))
}

/// Reads a record ([`Stored`]); records of earlier versions carried a problem document
/// instead of `error`.
pub(super) fn parse_record(bytes: &[u8]) -> Option<Stored> {
    let mut v: serde_json::Value = serde_json::from_slice(bytes).ok()?;
    let o = v.as_object_mut()?;
    let unconfirmed = o
        .remove(UNCONFIRMED)
        .is_some_and(|b| b == serde_json::Value::Bool(true));
    let spec = o.remove(SPEC).and_then(|s| s.as_str().map(str::to_string));
    if let Some(p) = o.remove("problem") {
        let kind = p
            .get("type")
            .and_then(|t| t.as_str())
            .and_then(|t| t.rsplit('/').next())
            .and_then(|slug| slug.parse::<ErrorKind>().ok())
            .unwrap_or(ErrorKind::Internal);
        let detail = p.get("detail").and_then(|d| d.as_str()).unwrap_or("");
        v["error"] = serde_json::to_value(Error::new(kind, detail)).ok()?;
    }
    Some(Stored {
        record: serde_json::from_value(v).ok()?,
        unconfirmed,
        spec,
    })
}

/// What a start does with a job found unfinished.
#[derive(Debug, PartialEq)]
pub(super) enum Recovery {
    /// Queued again (kept, under its limit of starts).
    Requeue,
    /// Failed: why.
    Fail(Error),
}

/// What a start does with `record`, unfinished, whose request is `spec` if it was kept, with
/// `max_attempts` starts per job at most.
pub(super) fn recover(record: &JobRecord, spec: Option<&str>, max_attempts: u32) -> Recovery {
    let attempts = record.attempts.unwrap_or(0);
    if spec.is_none() {
        return Recovery::Fail(Error::new(
            ErrorKind::ShuttingDown,
            "interrupted: the server stopped before this job finished; submit it again",
        ));
    }
    if record.state == State::Running && attempts >= max_attempts.max(1) {
        let times = if attempts == 1 { "time" } else { "times" };
        return Recovery::Fail(Error::new(
            ErrorKind::ShuttingDown,
            format!(
                "interrupted {attempts} {times}: the job was started {attempts} {times} \
                 (--max-attempts) and each time the server stopped before it finished (it \
                 died or was killed); a job that brings the server down may need a coarser \
                 grid or a cheaper fill"
            ),
        ));
    }
    Recovery::Requeue
}

/// A record to write (`None`: to remove), and who waits for it.
pub(super) type Write = (String, Option<Bytes>, oneshot::Sender<()>);

/// Records waiting to be written at most per group commit.
const GROUP_MAX: usize = 256;

/// The one writer of job records, in order, each acknowledged once durable: a group commit.
/// Whatever has queued up while the last batch was being written goes in the next one, each
/// job's newest record only (a job that was queued, started and finished meanwhile is written
/// once, in its last state), and every change in a batch is acknowledged once the whole batch
/// is durable. Order per job is kept: a batch holds the
/// newest change of each of its jobs, and batches are written one after the other.
pub(super) async fn write_records(
    store: Arc<dyn VolumeStore>,
    mut rx: mpsc::UnboundedReceiver<Write>,
) {
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
