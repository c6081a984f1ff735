//! The queue shared by replicas (`--queue redis://…`), against a real `redis-server` on
//! 127.0.0.1 (tests/common/redis_server.rs; skipped with a notice where it is not installed,
//! required with `VOXD_REQUIRE_REDIS=1`).
//!
//! First the queue's contract through the library (two or three `RedisQueue`s on one Redis
//! stand for replicas): submit, get, wait, cancel queued and running, the shared capacity,
//! size classes, statistics, a dead worker's job taken over, the attempts limit, a run that
//! lost its job storing nothing, Redis going away and coming back. Then the real `voxd serve`
//! binary, two or three processes on one Redis and one data directory: a job submitted to one
//! is polled and downloaded through the other, bit for bit the library's result; a replica
//! killed mid-job (SIGKILL) has its job finished by another; a job whose replicas all die
//! fails with a problem; Redis killed and restarted (append-only file) loses no accepted job;
//! cancel and 429 work across replicas (the binary's tests are in `redis_queue/serve.rs`).
//! Loopback only, every loop bounded, no timing asserted.

mod serve;

use std::sync::Arc;
use std::time::{Duration, Instant};

use bytes::Bytes;

use crate::common::redis_server::RedisServer;
use crate::common::{decode_bits, tmpdir};
use voxd::app::queue::{JobQueue, NewJob, State};
use voxd::app::store::VolumeStore;
use voxd::app::{ErrorKind, GridOptions, JobSpec, MeshSource, MethodSpec, VoxelizeRequest};
use voxd::cancel::Control;
use voxd::engine::cpu::CpuEngine;
use voxd::engine::fill::Fill;
use voxd::engine::{Engine, EngineError, GridMesh, Method};
use voxd::queue::redis::{RedisOptions, RedisQueue, volume_id_for};
use voxd::store::fs::FsStore;
use voxd::volume::BitVolume;

const TETRA: &[u8] = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";

fn request(mesh: &[u8], resolution: u32, cubic: bool, fill: Fill) -> VoxelizeRequest {
    VoxelizeRequest {
        source: MeshSource::Bytes {
            bytes: Bytes::copy_from_slice(mesh),
            format: None,
        },
        grid: GridOptions {
            resolution: Some(resolution),
            cubic,
            ..GridOptions::default()
        }
        .spec(256)
        .unwrap(),
        padding: 0,
        method: MethodSpec::Bits(Method::Solid),
        fill,
        attributes: Default::default(),
        limits: voxd::app::Limits::SERVICE,
    }
}

/// A job as the submit route makes it: prepared, and the same request as data.
fn job(id: &str, resolution: u32, cubic: bool) -> NewJob {
    let req = request(TETRA, resolution, cubic, Fill::Parity);
    NewJob {
        id: id.into(),
        work: voxd::app::prepare(&req).unwrap(),
        spec: JobSpec::of(&req),
        name: Some(format!("job {id}")),
        owner: None,
        request_id: Some(format!("req-{id}")),
        created: "2026-01-01T00:00:00Z".into(),
    }
}

fn store(name: &str) -> Arc<dyn VolumeStore> {
    Arc::new(FsStore::open(&tmpdir(&format!("redisq-{name}")), 1 << 30).unwrap())
}

async fn queue(
    redis: &RedisServer,
    store: &Arc<dyn VolumeStore>,
    prefix: &str,
    set: impl FnOnce(&mut RedisOptions),
) -> RedisQueue {
    let mut o = RedisOptions::new(16);
    o.prefix = prefix.into();
    set(&mut o);
    RedisQueue::open(&redis.url(), o, store.clone())
        .await
        .unwrap()
}

/// The CPU engine behind check points of a millisecond each: a job that takes a while and
/// stops when told.
struct Slow;

impl Engine for Slow {
    fn name(&self) -> &'static str {
        "slow"
    }
    fn voxelize_with(
        &self,
        mesh: &GridMesh,
        method: Method,
        ctl: &Control,
    ) -> Result<BitVolume, EngineError> {
        for i in 0..60_000 {
            ctl.check()?;
            ctl.set(f64::from(i) / 60_000.0);
            std::thread::sleep(Duration::from_millis(1));
        }
        CpuEngine.voxelize_with(mesh, method, ctl)
    }
}

/// Polls `f` every 20 ms until it gives something, for at most `secs`.
async fn eventually<T>(secs: u64, what: &str, mut f: impl AsyncFnMut() -> Option<T>) -> T {
    let deadline = Instant::now() + Duration::from_secs(secs);
    loop {
        if let Some(t) = f().await {
            return t;
        }
        assert!(Instant::now() < deadline, "not within {secs} s: {what}");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn submit_get_wait_cancel_capacity_and_stats_follow_the_contract() {
    let Some(redis) = RedisServer::start("contract") else {
        return;
    };
    let store = store("contract");
    let q = queue(&redis, &store, "c", |o| o.capacity = 2).await;
    let r = q.submit(job("a", 8, false)).await.unwrap();
    assert_eq!((r.state, r.position), (State::Queued, Some(1)));
    assert_eq!(
        q.submit(job("b", 8, false)).await.unwrap().position,
        Some(2)
    );
    let e = q.submit(job("c", 8, false)).await.unwrap_err();
    assert_eq!((e.kind, e.retry_after), (ErrorKind::QueueFull, Some(5)));
    assert!(store.get_upload("c").await.unwrap().is_none());
    // What is stored is the prepared job, not the uploaded file.
    let stored = store.get_upload("a").await.unwrap().unwrap();
    assert!(voxd::app::jobs::stored::is_prepared(&stored));
    // Another replica sees the same records.
    let other = queue(&redis, &store, "c", |o| o.capacity = 2).await;
    let a = other.get("a").await.unwrap().unwrap();
    assert_eq!((a.state, a.position), (State::Queued, Some(1)));
    assert_eq!(a.name.as_deref(), Some("job a"));
    assert_eq!(a.grid, job("a", 8, false).work.grid);
    assert!(other.get("nope").await.unwrap().is_none());
    let s = q.stats().await;
    assert_eq!((s.depth, s.running, s.unavailable), (2, 0, None));
    assert_eq!(s.classes, vec![("small", 2), ("medium", 0), ("large", 0)]);
    assert!(s.by_state.contains(&(State::Queued, "solid".into(), 2)));
    // Cancel a queued job from the other replica: gone from the queue, its upload removed.
    let c = other.cancel("b").await.unwrap().unwrap();
    assert_eq!(c.state, State::Canceled);
    assert!(store.get_upload("b").await.unwrap().is_none());
    assert_eq!(
        q.cancel("b").await.unwrap_err().kind,
        ErrorKind::NotCancelable
    );
    assert!(q.cancel("nope").await.unwrap().is_none());
    assert_eq!(q.stats().await.depth, 1);
    // Run it: the claim names the volume after the job, and the record follows.
    let claim = q.next().await.unwrap();
    assert_eq!(claim.id, "a");
    assert_eq!(
        claim.volume_id.as_deref(),
        Some(volume_id_for("a").as_str())
    );
    let r = other.get("a").await.unwrap().unwrap();
    assert_eq!(
        (r.state, r.attempts, r.position),
        (State::Running, Some(1), None)
    );
    assert_eq!(q.stats().await.running, 1);
    let meta = voxd::app::jobs::run(Arc::new(CpuEngine), &*store, &claim)
        .await
        .unwrap();
    assert_eq!(meta.id, volume_id_for("a"));
    q.finish("a", Ok(meta.id.clone())).await;
    let r = other
        .wait("a", Duration::from_secs(3600))
        .await
        .unwrap()
        .unwrap();
    assert_eq!((r.state, r.progress), (State::Succeeded, 1.0));
    assert_eq!(r.volume_id.as_deref(), Some(meta.id.as_str()));
    assert!(r.timings.running_s.is_some() && r.timings.queued_s.is_some());
    assert!(store.get_upload("a").await.unwrap().is_none());
    assert_eq!(
        other.cancel("a").await.unwrap_err().kind,
        ErrorKind::NotCancelable
    );
    let s = other.stats().await;
    assert_eq!((s.depth, s.running, s.oldest_queued_s), (0, 0, 0.0));
    assert!(s.by_state.contains(&(State::Succeeded, "solid".into(), 1)));
    assert!(s.by_state.contains(&(State::Canceled, "solid".into(), 1)));
    // Closing a replica fails nothing queued (the others run it) and refuses new jobs there.
    q.submit(job("d", 8, false)).await.unwrap();
    assert_eq!(q.close(voxd::app::Error::internal("bye")).await, 0);
    assert!(q.next().await.is_none());
    assert_eq!(
        q.submit(job("e", 8, false)).await.unwrap_err().kind,
        ErrorKind::ShuttingDown
    );
    assert_eq!(other.get("d").await.unwrap().unwrap().state, State::Queued);
}

/// An API key's limit of jobs queued or running is one count over every replica: jobs of
/// the key submitted to either count, the one past the limit is refused (`too-many-jobs`, its
/// upload not kept) on both, another key is not held back, and a job that finished, ran or was
/// canceled frees its place.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_keys_job_limit_spans_replicas() {
    let Some(redis) = RedisServer::start("owner") else {
        return;
    };
    let store = store("owner");
    let a = queue(&redis, &store, "o", |_| {}).await;
    let b = queue(&redis, &store, "o", |_| {}).await;
    let owned = |id: &str, name: &str, max_jobs: usize| NewJob {
        owner: Some(voxd::app::queue::Owner {
            name: name.into(),
            max_jobs,
            tenant: name.into(),
            role: voxd::app::queue::Role::User,
        }),
        ..job(id, 8, false)
    };
    assert_eq!(
        a.submit(owned("k1", "team", 2))
            .await
            .unwrap()
            .key_name
            .as_deref(),
        Some("team")
    );
    b.submit(owned("k2", "team", 2)).await.unwrap();
    for q in [&a, &b] {
        let e = q.submit(owned("k3", "team", 2)).await.unwrap_err();
        assert_eq!((e.kind, e.retry_after), (ErrorKind::TooManyJobs, Some(5)));
        assert!(
            e.detail.contains("team") && e.detail.contains("at most 2"),
            "{e}"
        );
    }
    assert!(store.get_upload("k3").await.unwrap().is_none());
    // Another key, and a key without a limit, are not held back.
    b.submit(owned("x1", "other", 1)).await.unwrap();
    b.submit(owned("x2", "unlimited", 0)).await.unwrap();
    b.submit(owned("x3", "unlimited", 0)).await.unwrap();
    // The record shows the key's name from any replica.
    assert_eq!(
        b.get("k1").await.unwrap().unwrap().key_name.as_deref(),
        Some("team")
    );
    // A canceled job frees its place (on the other replica)...
    b.cancel("k1").await.unwrap();
    a.submit(owned("k4", "team", 2)).await.unwrap();
    assert_eq!(
        b.submit(owned("k5", "team", 2)).await.unwrap_err().kind,
        ErrorKind::TooManyJobs
    );
    // ...and so does one that ran to its end: run every queued job.
    for _ in 0..5 {
        let claim = a.next().await.unwrap();
        let meta = voxd::app::jobs::run(Arc::new(CpuEngine), &*store, &claim)
            .await
            .unwrap();
        a.finish(&claim.id, Ok(meta.id)).await;
    }
    assert_eq!(a.stats().await.depth, 0);
    b.submit(owned("k6", "team", 2)).await.unwrap();
    a.submit(owned("k7", "team", 2)).await.unwrap();
    assert_eq!(
        a.submit(owned("k8", "team", 2)).await.unwrap_err().kind,
        ErrorKind::TooManyJobs
    );
}

/// A job run by another replica than the one it was submitted to is decoded there, not
/// parsed: its stored upload is no mesh file (the loader refuses it), yet it runs to the volume
/// the submitting replica would have made, with the upload's sha256 as its source. A job whose
/// upload an older replica stored as the raw mesh file still runs, to the same volume.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_job_run_elsewhere_is_decoded_not_parsed_and_an_older_upload_still_runs() {
    let Some(redis) = RedisServer::start("decoded") else {
        return;
    };
    let store = store("decoded");
    let a = queue(&redis, &store, "p", |_| {}).await;
    let b = queue(&redis, &store, "p", |_| {}).await;
    a.submit(job("new", 8, false)).await.unwrap();
    a.submit(job("old", 8, false)).await.unwrap();
    let stored = store.get_upload("new").await.unwrap().unwrap();
    let opts = voxd::mesh::LoadOptions::default();
    assert!(voxd::mesh::load_bytes(&stored, None, &opts).is_err());
    // As a replica of the previous release stored it.
    store
        .put_upload("old", Bytes::from_static(TETRA))
        .await
        .unwrap();
    let voxd::volume::Volume::Bits(here) =
        voxd::app::voxelize(&request(TETRA, 8, false, Fill::Parity), &CpuEngine)
            .unwrap()
            .1
            .volume
    else {
        panic!("a solid voxelization is a bit volume")
    };
    let mut ran = vec![];
    for _ in 0..2 {
        let claim = b.next().await.unwrap();
        assert!(matches!(claim.work, voxd::app::queue::Work::Stored { .. }));
        // The request that submitted it, for the job's log lines on this replica.
        assert_eq!(claim.request_id, Some(format!("req-{}", claim.id)));
        let meta = voxd::app::jobs::run(Arc::new(CpuEngine), &*store, &claim)
            .await
            .unwrap();
        b.finish(&claim.id, Ok(meta.id.clone())).await;
        assert_eq!(
            meta.source.sha256,
            voxd::app::sha256_hex(TETRA),
            "{}",
            claim.id
        );
        assert_eq!(meta.source.format, "obj");
        let vxl = store.read(&meta.id).await.unwrap().unwrap();
        assert_eq!(decode_bits(&vxl), here, "{}", claim.id);
        ran.push(claim.id);
    }
    ran.sort();
    assert_eq!(ran, ["new", "old"]);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn small_jobs_overtake_large_ones_until_those_have_waited_long_enough() {
    let Some(redis) = RedisServer::start("classes") else {
        return;
    };
    let store = store("classes");
    let q = queue(&redis, &store, "k", |_| {}).await;
    // 300³ voxels: over a 256³ job, the medium class.
    q.submit(job("m1", 300, true)).await.unwrap();
    q.submit(job("s1", 8, false)).await.unwrap();
    let s = q.stats().await;
    assert_eq!(s.classes, vec![("small", 1), ("medium", 1), ("large", 0)]);
    assert!(s.oldest_queued_s >= 0.0);
    let first = q.next().await.unwrap();
    assert_eq!(first.id, "s1", "the small job overtakes");
    q.finish("s1", Err(voxd::app::Error::internal("not run")))
        .await;
    // Every second waited earns a 256³ job's cost: after 2.5 s the medium job (27 M voxels)
    // goes before a new small one.
    tokio::time::sleep(Duration::from_millis(2500)).await;
    q.submit(job("s2", 8, false)).await.unwrap();
    assert!(q.stats().await.oldest_queued_s >= 2.5);
    assert_eq!(q.next().await.unwrap().id, "m1", "the aged job goes first");
    assert_eq!(q.next().await.unwrap().id, "s2");
    let failed = q.get("s1").await.unwrap().unwrap();
    assert_eq!(failed.state, State::Failed);
    assert_eq!(failed.error.unwrap().detail, "not run");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_job_canceled_on_another_replica_stops_where_it_runs_and_stores_nothing() {
    let Some(redis) = RedisServer::start("cancel-running") else {
        return;
    };
    let store = store("cancel-running");
    let a = queue(&redis, &store, "r", |_| {}).await;
    let b = queue(&redis, &store, "r", |_| {}).await;
    b.submit(job("j", 8, false)).await.unwrap();
    let claim = a.next().await.unwrap();
    let ctl = claim.control.clone();
    let worker = {
        let store = store.clone();
        tokio::spawn(async move {
            let r = voxd::app::jobs::run(Arc::new(Slow), &*store, &claim).await;
            (claim, r)
        })
    };
    // Its progress reaches the other replica with the lease renewals.
    eventually(30, "progress shown", async || {
        (b.get("j").await.unwrap().unwrap().progress > 0.0).then_some(())
    })
    .await;
    let r = b.cancel("j").await.unwrap().unwrap();
    assert_eq!(r.state, State::Canceled);
    let (claim, result) = worker.await.unwrap();
    assert!(ctl.is_canceled() && ctl.progress() < 1.0);
    let e = result.unwrap_err();
    assert_eq!(e.detail, "canceled");
    a.finish(&claim.id, Err(e)).await;
    let r = a.get("j").await.unwrap().unwrap();
    assert_eq!(r.state, State::Canceled);
    assert!(r.progress > 0.0 && r.progress < 1.0, "{}", r.progress);
    assert!(store.list(None, 10).await.unwrap().0.is_empty());
    assert!(store.get_upload("j").await.unwrap().is_none());
    assert_eq!(a.stats().await.running, 0);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_job_past_its_deadline_fails_with_the_timeout_problem() {
    let Some(redis) = RedisServer::start("deadline") else {
        return;
    };
    let store = store("deadline");
    let q = queue(&redis, &store, "t", |o| {
        o.job_timeout = Some(Duration::ZERO)
    })
    .await;
    q.submit(job("j", 8, false)).await.unwrap();
    let claim = q.next().await.unwrap();
    assert!(claim.control.deadline().is_some());
    assert_eq!(claim.timeout, Some(Duration::ZERO));
    let e = voxd::app::jobs::run(Arc::new(Slow), &*store, &claim)
        .await
        .unwrap_err();
    assert_eq!(e.kind, ErrorKind::Timeout);
    q.finish("j", Err(e.clone())).await;
    let r = q.get("j").await.unwrap().unwrap();
    assert_eq!((r.state, r.error), (State::Failed, Some(e)));
    assert!(store.list(None, 10).await.unwrap().0.is_empty());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_dead_workers_job_is_taken_over_then_failed_after_its_last_attempt() {
    let Some(redis) = RedisServer::start("attempts") else {
        return;
    };
    let store = store("attempts");
    let opts = |o: &mut RedisOptions| {
        o.lease = Duration::from_secs(1);
        o.max_attempts = 2;
    };
    let a = queue(&redis, &store, "d", opts).await;
    a.submit(job("j", 8, false)).await.unwrap();
    let first = a.next().await.unwrap();
    // The replica dies: nothing renews its lease any more.
    drop(first);
    drop(a);
    let b = queue(&redis, &store, "d", opts).await;
    let second = tokio::time::timeout(Duration::from_secs(30), b.next())
        .await
        .expect("taken over within 30 s")
        .unwrap();
    assert_eq!(second.id, "j");
    let r = b.get("j").await.unwrap().unwrap();
    assert_eq!((r.state, r.attempts), (State::Running, Some(2)));
    drop(second);
    drop(b);
    // The last attempt's worker died too: the next replica that looks fails the job.
    let c = Arc::new(queue(&redis, &store, "d", opts).await);
    let looking = {
        let c = c.clone();
        tokio::spawn(async move { c.next().await.map(|x| x.id) })
    };
    let r = eventually(30, "the job failed", async || {
        let r = c.get("j").await.unwrap().unwrap();
        (r.state == State::Failed).then_some(r)
    })
    .await;
    let e = r.error.unwrap();
    assert_eq!(e.kind, ErrorKind::EngineFailure);
    assert!(
        e.detail.contains("started 2 times (--max-attempts)")
            && e.detail.contains("--lease-seconds"),
        "{}",
        e.detail
    );
    // The replica that failed the job removes its upload right after (`clean_up`), not in the
    // same step, and in the task that looks for work: wait for it before that task is stopped
    // (stopped first, the removal may never run: the CI run of 2026-12-04 saw that; a real
    // replica's leftover is swept after --upload-grace).
    eventually(30, "the failed job's upload removed", async || {
        store.get_upload("j").await.unwrap().is_none().then_some(())
    })
    .await;
    assert!(!looking.is_finished(), "nothing else to run");
    looking.abort();
    assert_eq!(c.stats().await.running, 0);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_run_that_lost_its_job_stores_nothing_and_the_job_has_one_volume() {
    let Some(redis) = RedisServer::start("lost") else {
        return;
    };
    let store = store("lost");
    // `a` renews every second; `b` takes over anything idle for 0.3 s: it takes a's job
    // although a is alive (as when a replica stalls past its lease).
    let a = queue(&redis, &store, "l", |_| {}).await;
    let b = queue(&redis, &store, "l", |o| {
        o.lease = Duration::from_millis(300)
    })
    .await;
    a.submit(job("j", 16, false)).await.unwrap();
    let ca = a.next().await.unwrap();
    let cb = tokio::time::timeout(Duration::from_secs(30), b.next())
        .await
        .expect("taken over")
        .unwrap();
    assert_eq!((ca.id.as_str(), cb.id.as_str()), ("j", "j"));
    assert_eq!(ca.volume_id, cb.volume_id);
    let engine: Arc<dyn Engine> = Arc::new(CpuEngine);
    let ra = voxd::app::jobs::run(engine.clone(), &*store, &ca).await;
    assert!(ra.is_err(), "the run that lost its job stored a volume");
    a.finish("j", ra.map(|m| m.id)).await;
    let rb = voxd::app::jobs::run(engine, &*store, &cb).await.unwrap();
    b.finish("j", Ok(rb.id.clone())).await;
    let r = a.get("j").await.unwrap().unwrap();
    assert_eq!((r.state, r.attempts), (State::Succeeded, Some(2)));
    assert_eq!(r.volume_id, Some(rb.id));
    assert_eq!(store.list(None, 10).await.unwrap().0.len(), 1);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_unreachable_redis_is_queue_unavailable_and_the_queue_reconnects() {
    let Some(mut redis) = RedisServer::start("restart-lib") else {
        return;
    };
    let store = store("restart-lib");
    let q = queue(&redis, &store, "u", |_| {}).await;
    q.submit(job("kept", 8, false)).await.unwrap();
    redis.kill();
    for e in [
        q.submit(job("x", 8, false)).await.unwrap_err(),
        q.get("kept").await.unwrap_err(),
    ] {
        assert_eq!(
            (e.kind, e.retry_after),
            (ErrorKind::QueueUnavailable, Some(5))
        );
        assert!(e.detail.contains(&redis.url()), "{}", e.detail);
    }
    assert!(q.stats().await.unavailable.is_some());
    // Refused at start while down.
    let o = RedisOptions::new(4);
    let e = RedisQueue::open(&redis.url(), o, store.clone())
        .await
        .err()
        .unwrap();
    assert!(
        e.contains("cannot reach the job queue at redis://127.0.0.1"),
        "{e}"
    );
    redis.restart();
    // The accepted job survived (append-only file); the queue reconnected by itself.
    let r = eventually(60, "reconnected", async || q.get("kept").await.ok()).await;
    assert_eq!(r.unwrap().state, State::Queued);
    q.submit(job("after", 8, false)).await.unwrap();
    assert_eq!(q.stats().await.depth, 2);
    assert_eq!(q.next().await.unwrap().id, "kept");
}
