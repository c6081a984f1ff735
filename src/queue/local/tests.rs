//! The in-process queue's tests: scheduling, capacity, cancel, records through a restart,
//! success written ahead, pruning.

use super::*;
use crate::app::store::Vxl;
use crate::testkit::Scratch;

/// A fresh directory store of 1 MiB in a scratch directory (removed when the test ends), and
/// the directory.
fn scratch_store(name: &str) -> (Scratch, Arc<dyn VolumeStore>) {
    let dir = Scratch::new(&format!("localq-{name}"));
    let store = Arc::new(crate::store::fs::FsStore::open(&dir, 1 << 20).unwrap());
    (dir, store)
}

fn tiny_job(id: &str) -> NewJob {
    crate::app::testing::tiny_job(id, 4)
}

/// The lines of job `id` in the record log of the store in `dir`, oldest first.
fn log_lines(dir: &std::path::Path, id: &str) -> Vec<String> {
    std::fs::read_to_string(dir.join("jobs/records.log"))
        .unwrap()
        .lines()
        .filter(|l| l.contains(&format!(" {id} ")))
        .map(str::to_string)
        .collect()
}

/// The group commit: changes queued up together are written as one batch, each job's
/// newest change only, in order per job (a removal after a write removes; a write after a
/// removal writes), and every change is acknowledged only once its batch is on disk.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn records_are_group_committed_newest_per_job() {
    let (dir, store) = scratch_store("group");
    let (tx, rx) = mpsc::unbounded_channel();
    let mut acks = Vec::new();
    // 10 jobs × 30 versions, queued before the writer starts: one batch of 256, then the
    // rest. Job 3 ends removed, job 4 removed and then written again.
    for v in 0..30 {
        for j in 0..10 {
            let (ack, done) = oneshot::channel();
            let bytes = match (j, v) {
                (3, 29) | (4, 28) => None,
                _ => Some(Bytes::from(format!("{{\"job\":{j},\"v\":{v}}}"))),
            };
            tx.send((format!("{j:016x}"), bytes, ack)).unwrap();
            acks.push(done);
        }
    }
    tokio::spawn(write_records(store.clone(), rx));
    for a in acks {
        a.await.unwrap();
    }
    let mut got: Vec<String> = store
        .job_records()
        .await
        .unwrap()
        .iter()
        .map(|b| String::from_utf8(b.to_vec()).unwrap())
        .collect();
    got.sort();
    let want: Vec<String> = (0..10)
        .filter(|&j| j != 3)
        .map(|j| format!("{{\"job\":{j},\"v\":29}}"))
        .collect();
    assert_eq!(got, want);
    // No temporary file is left behind: the log alone.
    let left: Vec<String> = std::fs::read_dir(dir.join("jobs"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(left, vec!["records.log".to_string()]);
}

/// Finished jobs are remembered up to the limit (plus a tenth), then the oldest are
/// forgotten, in memory and in the store; the newest stay.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn old_finished_jobs_are_forgotten() {
    let (dir, store) = scratch_store("keep");
    let q = LocalQueue::open(4, store.clone())
        .await
        .unwrap()
        .with_keep_finished(10);
    for n in 0..30 {
        let mut job = tiny_job(&format!("j{n:02}"));
        job.created = format!("2026-12-01T00:00:{n:02}Z");
        q.submit(job).await.unwrap();
        let c = q.next().await.unwrap();
        q.finish(&c.id, Ok(format!("v{n}"))).await;
    }
    // Pruned down to 10 whenever more than 11 were known.
    let known: Vec<usize> = (0..30)
        .filter(|n| {
            futures_util::FutureExt::now_or_never(q.get(&format!("j{n:02}")))
                .unwrap()
                .unwrap()
                .is_some()
        })
        .collect();
    assert!(known.len() <= 11 && known.len() >= 10, "{known:?}");
    assert_eq!(*known.last().unwrap(), 29);
    assert!(
        known.windows(2).all(|w| w[1] == w[0] + 1),
        "the newest stay: {known:?}"
    );
    // The store forgets them too (after the writer has caught up), also after a reopen.
    let mut records = usize::MAX;
    for _ in 0..200 {
        records = store.job_records().await.unwrap().len();
        if records == known.len() {
            break;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    assert_eq!(records, known.len());
    drop((q, store));
    let again = crate::store::fs::FsStore::open(&dir, 1 << 20).unwrap();
    assert_eq!(again.job_records().await.unwrap().len(), known.len());
}

/// The queue lets go of a job's mesh when a worker takes the job: the claim holds the only
/// reference, so the worker frees it once the job is built (many jobs may wait on the store
/// after that, and their meshes must not).
#[tokio::test]
async fn a_claimed_jobs_mesh_is_held_by_the_claim_alone() {
    let (_dir, store) = scratch_store("claimed");
    let q = LocalQueue::open(2, store.clone()).await.unwrap();
    q.submit(tiny_job("m1")).await.unwrap();
    let claim = q.next().await.unwrap();
    let Work::Prepared(work) = &claim.work else {
        panic!("the in-process queue hands over prepared work");
    };
    assert_eq!(Arc::strong_count(work), 1);
    let mesh = Arc::downgrade(work);
    drop(claim);
    assert!(mesh.upgrade().is_none(), "the mesh outlived its claim");
    q.finish("m1", Ok("vol".into())).await;
}

/// A job that finished before anyone waited is seen as finished at once (on a paused
/// clock: had `wait` sat out its timeout, virtual time would have moved by an hour).
#[tokio::test(start_paused = true)]
async fn waiting_on_a_finished_job_returns_at_once_and_records_persist() {
    let (_dir, store) = scratch_store("wait");
    let q = LocalQueue::open(2, store.clone()).await.unwrap();
    q.submit(tiny_job("a1")).await.unwrap();
    q.submit(tiny_job("b2")).await.unwrap();
    let e = q.submit(tiny_job("c3")).await.unwrap_err();
    assert_eq!((e.kind, e.retry_after), (ErrorKind::QueueFull, Some(5)));
    let claim = q.next().await.unwrap();
    q.finish(&claim.id, Ok("vol".into())).await;
    let t = tokio::time::Instant::now();
    let r = q
        .wait(&claim.id, Duration::from_secs(3600))
        .await
        .unwrap()
        .unwrap();
    assert_eq!(r.state, State::Succeeded);
    assert_eq!(tokio::time::Instant::now(), t, "wait sat out its timeout");
    // The other job is canceled; both records are durable and a new queue sees them.
    let other = if claim.id == "a1" { "b2" } else { "a1" };
    assert_eq!(
        q.cancel(other).await.unwrap().unwrap().state,
        State::Canceled
    );
    assert_eq!(
        q.cancel(other).await.unwrap_err().kind,
        ErrorKind::NotCancelable
    );
    let again = LocalQueue::open(2, store).await.unwrap();
    assert_eq!(
        again.get(&claim.id).await.unwrap().unwrap().state,
        State::Succeeded
    );
    assert_eq!(
        again.get(other).await.unwrap().unwrap().state,
        State::Canceled
    );
}

/// A success written ahead of its volume (`storing`): after a crash (a new queue over the
/// same records, the old one never finishing) it stands where the volume was stored, and
/// is rewritten without the mark; where the volume was not, the job failed (interrupted)
/// and names no volume. A job that finished waits for that record, not for another.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_success_written_ahead_stands_only_with_its_volume() {
    let (dir, store) = scratch_store("ahead");
    let q = LocalQueue::open(8, store.clone()).await.unwrap();
    let lines = |id: &str| log_lines(&dir, id);
    for id in ["a1", "b2", "c3"] {
        q.submit_deferred(tiny_job(id)).await.unwrap();
        assert_eq!(q.next().await.unwrap().id, id);
    }
    q.storing("a1", "va");
    q.storing("b2", "vb");
    q.storing("c3", "vc");
    // Only a1's and c3's volumes are stored; c3 finishes.
    for v in ["va", "vc"] {
        let data = format!("volume {v}").into_bytes();
        let meta = crate::store::fs::tests::meta(v, &data);
        store.put(meta, Vxl::from(data)).await.unwrap();
    }
    q.finish("c3", Ok("vc".into())).await;
    assert_eq!(q.get("c3").await.unwrap().unwrap().state, State::Succeeded);
    // The records written ahead are durable once c3's is (one writer, in order).
    for id in ["a1", "b2"] {
        let l = lines(id);
        let last = l.last().unwrap();
        assert!(
            last.contains("\"succeeded\"") && last.contains("\"unconfirmed_volume\":true"),
            "{id}: {l:?}"
        );
    }
    let again = LocalQueue::open(8, store.clone()).await.unwrap();
    let a1 = again.get("a1").await.unwrap().unwrap();
    assert_eq!(
        (a1.state, a1.volume_id.as_deref()),
        (State::Succeeded, Some("va"))
    );
    let b2 = again.get("b2").await.unwrap().unwrap();
    assert_eq!((b2.state, b2.volume_id.as_deref()), (State::Failed, None));
    assert!(b2.error.unwrap().detail.contains("interrupted"));
    let c3 = again.get("c3").await.unwrap().unwrap();
    assert_eq!(
        (c3.state, c3.volume_id.as_deref()),
        (State::Succeeded, Some("vc"))
    );
    // Rewritten: a1 without the mark, b2 as failed (so the next start looks up nothing).
    let a1 = lines("a1");
    assert!(!a1.last().unwrap().contains("unconfirmed_volume"), "{a1:?}");
    assert!(lines("b2").last().unwrap().contains("\"failed\""));
    drop((q, again, store));
}

/// `submit_deferred` writes nothing before the job runs: a job that finishes before the
/// record writer gets to it is written once, in its final state (two writes after
/// `submit`), and `persist` makes the record durable before it returns. On one thread,
/// the writer runs only where the test awaits.
#[tokio::test]
async fn deferred_records_are_written_once_or_when_persisted() {
    let (dir, store) = scratch_store("defer");
    let q = LocalQueue::open(4, store.clone()).await.unwrap();
    let lines = |id: &str| log_lines(&dir, id);
    q.submit_deferred(tiny_job("d2")).await.unwrap();
    let c = q.next().await.unwrap();
    assert_eq!(c.id, "d2");
    assert!(lines("d2").is_empty());
    q.finish("d2", Ok("v2".into())).await;
    let d2 = lines("d2");
    assert_eq!(d2.len(), 1, "{d2:?}");
    assert!(d2[0].contains("\"succeeded\""), "{d2:?}");
    // The same with `submit` (a kept job): the queued record first, its start (durable
    // before it runs, so that it counts as an attempt), then the final one.
    q.submit(tiny_job("s3")).await.unwrap();
    assert_eq!(lines("s3").len(), 1);
    let c = q.next().await.unwrap();
    assert_eq!(lines("s3").len(), 2);
    assert!(lines("s3")[1].contains("\"running\""));
    q.finish(&c.id, Ok("v3".into())).await;
    assert_eq!(lines("s3").len(), 3);
    // Persisted: on disk when `persist` returns, still queued.
    q.submit_deferred(tiny_job("p1")).await.unwrap();
    assert!(lines("p1").is_empty());
    q.persist("p1").await.unwrap();
    // Kept: its upload is stored first (the writer may write the record as it was meanwhile),
    // then its record with its request.
    let p1 = lines("p1");
    assert!((1..=2).contains(&p1.len()), "{p1:?}");
    let last = p1.last().unwrap();
    assert!(
        last.contains("\"queued\"") && last.contains("\"spec\""),
        "{p1:?}"
    );
    assert!(store.get_upload("p1").await.unwrap().is_some());
    drop((q, store));
}

/// The indexes kept for pruning and for keys' limits (`finished`, `active`) against a walk
/// of every job, after each step of a random run of submits, takes, finishes (succeeded
/// and failed), cancels of queued and running jobs, prunes and a close; and a key's limit
/// refuses exactly when the walk counts the limit reached.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_indexes_agree_with_a_walk_of_every_job() {
    /// Jobs queued or running per key, by a walk of every job.
    fn walked(inner: &Inner) -> HashMap<String, usize> {
        let mut active: HashMap<String, usize> = HashMap::new();
        for j in inner.jobs.values() {
            if let (false, Some(k)) = (j.record.state.is_final(), &j.record.key_name) {
                *active.entry(k.clone()).or_insert(0) += 1;
            }
        }
        active
    }
    fn check(q: &LocalQueue) {
        let inner = q.lock();
        let finished: BTreeSet<(String, String)> = inner
            .jobs
            .values()
            .filter(|j| j.record.state.is_final())
            .map(|j| (j.record.created.clone(), j.record.id.clone()))
            .collect();
        assert_eq!(inner.finished, finished);
        assert_eq!(inner.active, walked(&inner));
    }
    let (_dir, store) = scratch_store("indexes");
    let q = LocalQueue::open(8, store.clone())
        .await
        .unwrap()
        .with_keep_finished(6);
    let mut seed = 0x2545_f491_4f6c_dd1d_u64;
    let mut rand = move |n: u64| {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        seed % n
    };
    let owners = ["alpha", "beta"];
    let mut running: Vec<String> = vec![];
    let (mut refused, mut forgotten) = (0, 0);
    for step in 0..600u64 {
        match rand(6) {
            0 | 1 => {
                let mut job = tiny_job(&format!("j{step:03}"));
                // Ties in the creation time: the id decides the order among them.
                job.created = format!("2026-12-03T00:{:02}:00Z", step / 7);
                let owner = rand(3) as usize;
                job.owner = owners.get(owner).map(|name| Owner {
                    name: name.to_string(),
                    max_jobs: 3,
                    tenant: name.to_string(),
                    role: crate::app::queue::Role::User,
                });
                let active = job
                    .owner
                    .as_ref()
                    .map_or(0, |o| walked(&q.lock()).get(&o.name).copied().unwrap_or(0));
                let queued = q.lock().queue.len();
                match q.submit(job).await {
                    Ok(_) => assert!(active < 3 && queued < 8),
                    Err(e) => {
                        assert!(active >= 3 || queued >= 8, "{e:?}");
                        refused += 1;
                    }
                }
            }
            2 => {
                if !q.lock().queue.is_empty() {
                    running.push(q.next().await.unwrap().id);
                }
            }
            3 | 4 if !running.is_empty() => {
                let id = running.remove(rand(running.len() as u64) as usize);
                let result = if rand(4) == 0 {
                    Err(Error::new(ErrorKind::Internal, "failed on purpose"))
                } else {
                    Ok(format!("v-{id}"))
                };
                let before = q.lock().jobs.len();
                q.finish(&id, result).await;
                forgotten += (before + 1).saturating_sub(q.lock().jobs.len());
            }
            _ => {
                let ids: Vec<String> = q.lock().jobs.keys().cloned().collect();
                if let Some(id) = ids.get(rand(ids.len().max(1) as u64) as usize) {
                    // Finished jobs are not cancelable; running ones stay claimed until
                    // their worker finishes them (which then changes nothing).
                    let _ = q.cancel(id).await;
                }
            }
        }
        check(&q);
    }
    assert!(refused > 0 && forgotten > 0, "{refused} {forgotten}");
    q.close(Error::new(ErrorKind::ShuttingDown, "closing"))
        .await;
    check(&q);
    for id in running {
        q.finish(&id, Ok("v".into())).await;
        check(&q);
    }
    // What is left active: the kept jobs that the close left queued for the next start.
    let inner = q.lock();
    let kept_queued = inner
        .jobs
        .values()
        .filter(|j| j.kept && j.record.state == State::Queued && j.record.key_name.is_some())
        .count();
    assert_eq!(inner.active.values().sum::<usize>(), kept_queued);
    drop(inner);
    drop((q, store));
}

/// A kept job (answered `202`: `submit`, or `persist` after `submit_deferred`) survives the
/// process: its upload is in the store until it ends, a start finds it queued again, and each
/// start that the process does not survive counts; at `max_attempts` starts it fails
/// ("interrupted N times") and its upload goes. A shutdown (`close`) leaves it queued; a job
/// that ends deletes its upload; a job never kept fails at the next start, as before.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn kept_jobs_run_again_after_a_crash_up_to_their_attempts() {
    let (_dir, store) = scratch_store("kept");
    let open = || LocalQueue::open_with(8, store.clone(), Limits::default(), 2);
    let has_upload = |id: &'static str| {
        let store = store.clone();
        async move { store.get_upload(id).await.unwrap().is_some() }
    };
    let q = open().await.unwrap();
    q.submit(tiny_job("k1")).await.unwrap();
    q.submit_deferred(tiny_job("d2")).await.unwrap();
    q.persist("d2").await.unwrap();
    q.submit_deferred(tiny_job("w3")).await.unwrap();
    assert!(has_upload("k1").await && has_upload("d2").await);
    assert!(
        !has_upload("w3").await,
        "a job not answered yet is not kept"
    );
    // The process dies with all three queued (the old queue never runs again).
    let q2 = open().await.unwrap();
    for id in ["k1", "d2"] {
        let state = q2.get(id).await.unwrap().unwrap().state;
        assert_eq!(state, State::Queued, "{id}");
    }
    // Not kept: failed, or not known at all where its record was never written (its client
    // never got its id).
    let w3 = q2.get("w3").await.unwrap();
    assert!(
        w3.as_ref().is_none_or(|r| r.state == State::Failed),
        "{w3:?}"
    );
    // Both start (in either order: they wait as long); the process dies during k1, d2 runs
    // to its end.
    let (c, d) = (q2.next().await.unwrap(), q2.next().await.unwrap());
    let mut ids = [c.id.as_str(), d.id.as_str()];
    ids.sort();
    assert_eq!(ids, ["d2", "k1"]);
    assert!(
        matches!(c.work, Work::Stored { .. }) && matches!(d.work, Work::Stored { .. }),
        "prepared from their uploads"
    );
    assert_eq!(q2.get("k1").await.unwrap().unwrap().attempts, Some(1));
    q2.finish("d2", Err(Error::internal("ended"))).await;
    assert!(!has_upload("d2").await, "an ended job's upload goes");
    // Started once: queued again. Started twice (the limit): failed, its upload gone.
    let q3 = open().await.unwrap();
    assert_eq!(q3.get("k1").await.unwrap().unwrap().state, State::Queued);
    assert_eq!(q3.next().await.unwrap().id, "k1");
    let q4 = open().await.unwrap();
    let k1 = q4.get("k1").await.unwrap().unwrap();
    assert_eq!((k1.state, k1.attempts), (State::Failed, Some(2)));
    assert!(k1.error.unwrap().detail.contains("interrupted 2 times"));
    assert!(!has_upload("k1").await);
    // A shutdown keeps a kept queued job for the next start.
    q4.submit(tiny_job("s5")).await.unwrap();
    assert_eq!(q4.close(Error::internal("closing")).await, 0);
    assert!(q4.next().await.is_none());
    let q5 = open().await.unwrap();
    assert_eq!(q5.get("s5").await.unwrap().unwrap().state, State::Queued);
    assert!(has_upload("s5").await);
    drop((q, q2, q3, q4, q5));
}
