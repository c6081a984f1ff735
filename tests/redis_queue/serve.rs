//! The shared queue through the real `voxd serve` binary: two or three processes on one Redis
//! and one data directory stand for replicas (the library's side is in the parent module, whose
//! helpers this uses). Not here: the queue's contract through the library.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::Value;

use super::request;
use crate::common::redis_server::RedisServer;
use crate::common::{Resp, data, decode_bits, spawn_serve, tmpdir};
use voxd::engine::cpu::CpuEngine;
use voxd::engine::fill::Fill;
use voxd::queue::redis::volume_id_for;

struct Replica {
    child: Child,
    addr: String,
}

impl Replica {
    fn start(redis: &RedisServer, dir: &Path, extra: &[&str]) -> Replica {
        let (child, addr) = spawn_serve(
            Command::new(env!("CARGO_BIN_EXE_voxd"))
                .args(["serve", "--addr", "127.0.0.1:0", "--engine", "cpu"])
                .args(["--data-dir", dir.to_str().unwrap(), "--queue", &redis.url()])
                .args(extra)
                .env("VOXD_LOG", "warn")
                .env_remove("VOXD_FAULT")
                .stderr(Stdio::inherit()),
        );
        Replica { child, addr }
    }

    fn req(&self, method: &str, path: &str, body: &[u8]) -> Resp {
        let h = [("Content-Type", "model/obj")];
        let headers: &[(&str, &str)] = if body.is_empty() { &[] } else { &h };
        crate::common::request(&self.addr, method, path, headers, body)
    }

    fn submit(&self, query: &str, mesh: &[u8]) -> String {
        let r = self.req("POST", &format!("/v1/voxelize?{query}"), mesh);
        assert_eq!(r.status, 202, "{}", String::from_utf8_lossy(&r.body));
        r.json()["id"].as_str().unwrap().to_string()
    }

    fn job(&self, id: &str) -> Value {
        let r = self.req("GET", &format!("/v1/jobs/{id}"), &[]);
        assert_eq!(r.status, 200, "{}", String::from_utf8_lossy(&r.body));
        r.json()
    }

    /// Polls job `id` until `done` holds for it, for at most `secs`.
    fn until(&self, id: &str, secs: u64, what: &str, done: impl Fn(&Value) -> bool) -> Value {
        let deadline = Instant::now() + Duration::from_secs(secs);
        loop {
            let j = self.job(id);
            if done(&j) {
                return j;
            }
            assert!(
                Instant::now() < deadline,
                "job {id} not {what} within {secs} s: {j}"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    fn kill(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Drop for Replica {
    fn drop(&mut self) {
        self.kill();
    }
}

fn state(j: &Value) -> &str {
    j["state"].as_str().unwrap_or("")
}

/// spot with every 5th face left out: not watertight, with caps all over its surface, so
/// `fill=winding` has real work (blocks that caps cut near the mesh are decided voxel by voxel);
/// at resolution 256 a job of about 6 s on 2 cores. (Every 50th face was enough before blocks
/// were certified by intervals: that mesh now takes 0.5 s at 512³.)
fn holey_spot() -> Vec<u8> {
    let spot = std::fs::read_to_string(data("spot.obj")).unwrap();
    let mut faces = 0;
    let mut out = String::new();
    for line in spot.lines() {
        if line.starts_with("f ") {
            faces += 1;
            if faces % 5 == 0 {
                continue;
            }
        }
        out.push_str(line);
        out.push('\n');
    }
    out.into_bytes()
}

const SLOW: &str = "resolution=256&fill=winding";

fn replica_dir(name: &str) -> PathBuf {
    tmpdir(&format!("replicas-{name}"))
}

#[test]
fn a_job_submitted_to_one_replica_is_polled_and_downloaded_through_another_bit_for_bit() {
    let Some(redis) = RedisServer::start("two-replicas") else {
        return;
    };
    let dir = replica_dir("two");
    let a = Replica::start(&redis, &dir, &[]);
    let b = Replica::start(&redis, &dir, &[]);
    let spot = std::fs::read(data("spot.obj")).unwrap();
    for (i, (to, other)) in [(&a, &b), (&b, &a), (&a, &b), (&b, &a)]
        .into_iter()
        .enumerate()
    {
        let res = 24 + 8 * i as u32;
        let id = to.submit(&format!("resolution={res}&name=n{i}"), &spot);
        let j = other.until(&id, 120, "succeeded", |j| state(j) == "succeeded");
        let vid = j["volume_id"].as_str().unwrap();
        assert_eq!(vid, volume_id_for(&id));
        let (da, db) = (
            to.req("GET", &format!("/v1/volumes/{vid}/data"), &[]),
            other.req("GET", &format!("/v1/volumes/{vid}/data"), &[]),
        );
        assert_eq!((da.status, db.status), (200, 200));
        assert_eq!(da.body, db.body);
        assert_eq!(da.headers.get("etag"), db.headers.get("etag"));
        let (_, want) =
            voxd::app::voxelize(&request(&spot, res, false, Fill::Parity), &CpuEngine).unwrap();
        let voxd::volume::Volume::Bits(want) = want.volume else {
            panic!("bits")
        };
        assert!(
            decode_bits(&db.body) == want,
            "resolution {res}: not the library's voxels"
        );
        assert_eq!(
            other.req("GET", &format!("/v1/volumes/{vid}"), &[]).json()["name"],
            format!("n{i}")
        );
    }
    // `wait` on one replica hears of a job whichever replica runs it.
    let r = b.req("POST", "/v1/voxelize?resolution=16&wait=60", &spot);
    assert_eq!(r.status, 201, "{}", String::from_utf8_lossy(&r.body));
    // The shared queue's gauges, on either replica.
    let m = String::from_utf8(a.req("GET", "/metrics", &[]).body).unwrap();
    for line in [
        "voxd_queue_depth 0",
        "voxd_queue_running 0",
        "voxd_queue_oldest_seconds 0",
        "voxd_queue_available 1",
        "voxd_queue_class_depth{class=\"small\"} 0",
        "voxd_jobs{state=\"succeeded\",method=\"solid\"} 5",
    ] {
        assert!(m.lines().any(|l| l == line), "{line} not in\n{m}");
    }
    assert_eq!(b.req("GET", "/readyz", &[]).status, 200);
    // A bad mesh is refused at once, on the replica that was sent it.
    let r = a.req("POST", "/v1/voxelize", b"v 0 0 0\nf 1 2 3\n");
    assert_eq!(r.status, 422, "{}", String::from_utf8_lossy(&r.body));
}

#[test]
fn a_replica_killed_mid_job_has_its_job_finished_by_another() {
    let Some(redis) = RedisServer::start("kill-replica") else {
        return;
    };
    let dir = replica_dir("kill");
    let lease = ["--lease-seconds", "2"];
    let mut a = Replica::start(&redis, &dir, &lease);
    let mesh = holey_spot();
    let id = a.submit(SLOW, &mesh);
    a.until(&id, 120, "running", |j| {
        state(j) == "running" && j["progress"].as_f64() > Some(0.0)
    });
    let b = Replica::start(&redis, &dir, &lease);
    a.kill();
    let killed = Instant::now();
    let j = b.until(&id, 120, "taken over", |j| j["attempts"] == 2);
    let takeover = killed.elapsed();
    let j = if state(&j) == "succeeded" {
        j
    } else {
        b.until(&id, 300, "succeeded", |j| state(j) == "succeeded")
    };
    println!(
        "measured: a job of a replica killed with SIGKILL (lease 2 s) was taken over after {:.1} s and finished {:.1} s after the kill",
        takeover.as_secs_f64(),
        killed.elapsed().as_secs_f64()
    );
    let vid = j["volume_id"].as_str().unwrap();
    let d = b.req("GET", &format!("/v1/volumes/{vid}/data"), &[]);
    assert_eq!(d.status, 200);
    assert_eq!(
        decode_bits(&d.body).grid().dims,
        serde_json::from_value::<[u32; 3]>(j["grid"]["dims"].clone()).unwrap()
    );
    assert_eq!(
        b.req("GET", &format!("/v1/volumes/{vid}"), &[]).json()["fill"]["used"],
        "winding"
    );
}

#[test]
fn a_job_whose_replicas_all_die_fails_with_a_problem_after_its_last_attempt() {
    let Some(redis) = RedisServer::start("all-die") else {
        return;
    };
    let dir = replica_dir("all-die");
    let opts = ["--lease-seconds", "2", "--max-attempts", "2"];
    let mut a = Replica::start(&redis, &dir, &opts);
    let id = a.submit(SLOW, &holey_spot());
    a.until(&id, 120, "running", |j| state(j) == "running");
    let mut b = Replica::start(&redis, &dir, &opts);
    a.kill();
    b.until(&id, 120, "taken over", |j| {
        state(j) == "running" && j["attempts"] == 2
    });
    let c = Replica::start(&redis, &dir, &opts);
    b.kill();
    let j = c.until(&id, 120, "failed", |j| state(j) == "failed");
    assert_eq!(j["attempts"], 2);
    let p = &j["problem"];
    assert_eq!(p["type"], "https://voxd.dev/problems/engine-failure", "{j}");
    assert!(
        p["detail"]
            .as_str()
            .unwrap()
            .contains("started 2 times (--max-attempts)"),
        "{p}"
    );
    let vid = volume_id_for(&id);
    assert_eq!(c.req("GET", &format!("/v1/volumes/{vid}"), &[]).status, 404);
    assert!(!dir.join(format!("uploads/{id}")).exists());
}

#[test]
fn redis_killed_and_restarted_loses_no_accepted_job_and_replicas_reconnect() {
    let Some(mut redis) = RedisServer::start("restart") else {
        return;
    };
    let dir = replica_dir("restart");
    let a = Replica::start(&redis, &dir, &["--lease-seconds", "2"]);
    let spot = std::fs::read(data("spot.obj")).unwrap();
    // One job runs (the only worker), one waits behind it.
    let slow = a.submit(SLOW, &holey_spot());
    a.until(&slow, 120, "running", |j| state(j) == "running");
    let queued = a.submit("resolution=32", &spot);
    assert_eq!(state(&a.job(&queued)), "queued");
    redis.kill();
    let r = a.req("GET", &format!("/v1/jobs/{queued}"), &[]);
    assert_eq!(r.status, 503, "{}", String::from_utf8_lossy(&r.body));
    assert_eq!(
        r.json()["type"],
        "https://voxd.dev/problems/queue-unavailable"
    );
    assert!(r.headers.contains_key("retry-after"));
    assert_eq!(a.req("GET", "/readyz", &[]).status, 503);
    let r = a.req("POST", "/v1/voxelize?resolution=8", &spot);
    assert_eq!(r.status, 503, "{}", String::from_utf8_lossy(&r.body));
    redis.restart();
    // Both accepted jobs finish; the replica reconnected by itself.
    a.until(&queued, 300, "succeeded", |j| state(j) == "succeeded");
    a.until(&slow, 300, "succeeded", |j| state(j) == "succeeded");
    let after = a.submit("resolution=16", &spot);
    a.until(&after, 120, "succeeded", |j| state(j) == "succeeded");
    assert_eq!(a.req("GET", "/readyz", &[]).status, 200);
}

#[test]
fn cancel_and_the_shared_capacity_span_replicas() {
    let Some(redis) = RedisServer::start("cancel-429") else {
        return;
    };
    let dir = replica_dir("cancel");
    let opts = ["--lease-seconds", "2", "--queue-capacity", "1"];
    let a = Replica::start(&redis, &dir, &opts);
    let b = Replica::start(&redis, &dir, &opts);
    let mesh = holey_spot();
    let spot = std::fs::read(data("spot.obj")).unwrap();
    // Both workers busy (one each), then one job waits: the queue is full for both replicas.
    let s1 = a.submit(SLOW, &mesh);
    let s2 = b.submit(SLOW, &mesh);
    for s in [&s1, &s2] {
        a.until(s, 120, "running", |j| state(j) == "running");
    }
    let q1 = a.submit("resolution=16", &spot);
    // The shared queue's gauges, the same on the replica that did not take it.
    let m = String::from_utf8(b.req("GET", "/metrics", &[]).body).unwrap();
    for line in [
        "voxd_queue_depth 1",
        "voxd_queue_running 2",
        "voxd_queue_class_depth{class=\"small\"} 1",
    ] {
        assert!(m.lines().any(|l| l == line), "{line} not in\n{m}");
    }
    assert!(
        m.lines()
            .any(|l| l.starts_with("voxd_queue_oldest_seconds "))
    );
    let r = b.req("POST", "/v1/voxelize?resolution=16", &spot);
    assert_eq!(r.status, 429, "{}", String::from_utf8_lossy(&r.body));
    assert_eq!(r.headers.get("retry-after").map(String::as_str), Some("5"));
    assert_eq!(r.json()["type"], "https://voxd.dev/problems/queue-full");
    // Cancel the waiting one and both running ones through the replica that did not take them.
    let c = b.req("DELETE", &format!("/v1/jobs/{q1}"), &[]);
    assert_eq!((c.status, state(&c.json())), (200, "canceled"));
    assert!(!dir.join(format!("uploads/{q1}")).exists());
    for (s, via) in [(&s1, &b), (&s2, &a)] {
        let c = via.req("DELETE", &format!("/v1/jobs/{s}"), &[]);
        assert_eq!((c.status, state(&c.json())), (200, "canceled"));
    }
    let c = a.req("DELETE", &format!("/v1/jobs/{q1}"), &[]);
    assert_eq!(c.status, 409);
    // The workers stop (each clears its job's upload when it does) and store nothing.
    let deadline = Instant::now() + Duration::from_secs(120);
    while std::fs::read_dir(dir.join("uploads")).unwrap().count() > 0 {
        assert!(Instant::now() < deadline, "canceled jobs still running");
        std::thread::sleep(Duration::from_millis(20));
    }
    for s in [&s1, &s2] {
        assert_eq!(state(&a.job(s)), "canceled");
        assert!(
            !dir.join(format!("volumes/{}.json", volume_id_for(s)))
                .exists()
        );
    }
    // Free again: a new job runs.
    let j = b.submit("resolution=16", &spot);
    a.until(&j, 120, "succeeded", |j| state(j) == "succeeded");
}

/// An unreachable or malformed `--queue`: `voxd serve` refuses to start, saying why (and never
/// showing the URL's password). Needs no Redis.
#[test]
fn serve_refuses_to_start_without_its_queue() {
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let dir = tmpdir("no-queue");
    for (url, says) in [
        (
            format!("redis://:hunter2@127.0.0.1:{port}"),
            "cannot reach the job queue at redis://***@127.0.0.1",
        ),
        ("http://example".to_string(), "is not a Redis URL"),
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_voxd"))
            .args(["serve", "--addr", "127.0.0.1:0", "--engine", "cpu"])
            .args(["--data-dir", dir.to_str().unwrap(), "--queue", &url])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && out.stdout.is_empty(), "{err}");
        assert!(err.contains(says) && !err.contains("hunter2"), "{err}");
    }
}
