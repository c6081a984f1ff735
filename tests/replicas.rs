//! The replica topology end to end, as the deployment has it: SeaweedFS as the S3 store, a real
//! `redis-server` (append-only) as the shared queue, two `voxd serve` replicas on one bucket and
//! one queue, and nginx balancing over them. A real mesh submitted through the balancer is
//! polled on one replica and fetched through the other and through the balancer, equal to the
//! single-process (library) result bit for bit; both replicas list the same volumes with the
//! same ETags; CSG works across replicas; a replica SIGKILLed mid-job has its job finished by
//! the other while the balancer keeps answering. Skipped with a notice where SeaweedFS, Redis
//! or nginx is absent (scripts/provision.sh installs them, scripts/test.sh requires them).
//! Loopback only; every wait is bounded.

use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use bytes::Bytes;
use serde_json::Value;
use voxd::app::{GridOptions, MeshSource, MethodSpec, VoxelizeRequest};
use voxd::engine::Method;
use voxd::engine::cpu::CpuEngine;
use voxd::engine::fill::Fill;

use crate::common::nginx::Nginx;
use crate::common::redis_server::RedisServer;
use crate::common::{Resp, decode_bits, request, scratch_root, spawn_serve};
use crate::common::{data, s3};

struct Replica {
    child: Child,
    addr: String,
}

impl Replica {
    fn start(store: &str, weed: &s3::Weed, redis: &RedisServer, extra: &[&str]) -> Replica {
        Replica::start_at("127.0.0.1:0", store, weed, redis, extra)
    }

    fn start_at(
        addr: &str,
        store: &str,
        weed: &s3::Weed,
        redis: &RedisServer,
        extra: &[&str],
    ) -> Replica {
        // One data directory that every replica shares (their volumes and jobs are on S3 and
        // Redis), under the tests' scratch root; never emptied while a replica may be running.
        let dir = scratch_root().join("replica");
        let (child, addr) = spawn_serve(
            Command::new(env!("CARGO_BIN_EXE_voxd"))
                .args(["serve", "--addr", addr, "--engine", "cpu"])
                .args(["--store", store, "--queue", &redis.url()])
                .arg("--data-dir")
                .arg(&dir)
                .args(extra)
                .envs(weed.vars())
                .env("VOXD_LOG", "warn")
                .env_remove("VOXD_FAULT")
                .stderr(Stdio::inherit()),
        );
        Replica { child, addr }
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

fn req(addr: &str, method: &str, path: &str, ctype: &str, body: &[u8]) -> Resp {
    let h = [("Content-Type", ctype)];
    let headers: &[(&str, &str)] = if body.is_empty() { &[] } else { &h };
    request(addr, method, path, headers, body)
}

fn get(addr: &str, path: &str) -> Resp {
    req(addr, "GET", path, "", b"")
}

/// Polls job `id` on `addr` until it is final, for at most `secs`.
fn until_final(addr: &str, id: &str, secs: u64) -> Value {
    let deadline = Instant::now() + Duration::from_secs(secs);
    loop {
        let r = get(addr, &format!("/v1/jobs/{id}"));
        assert_eq!(r.status, 200, "{}", String::from_utf8_lossy(&r.body));
        let j = r.json();
        if matches!(
            j["state"].as_str(),
            Some("succeeded" | "failed" | "canceled")
        ) {
            return j;
        }
        assert!(
            Instant::now() < deadline,
            "job {id} not done in {secs} s: {j}"
        );
        std::thread::sleep(Duration::from_millis(25));
    }
}

/// The single-process result: the library on the same bytes and options.
fn library(mesh: &[u8], resolution: u32, fill: Fill) -> voxd::BitVolume {
    let req = VoxelizeRequest {
        source: MeshSource::Bytes {
            bytes: Bytes::copy_from_slice(mesh),
            format: None,
        },
        grid: GridOptions {
            resolution: Some(resolution),
            ..GridOptions::default()
        }
        .spec(256)
        .unwrap(),
        padding: 0,
        method: MethodSpec::Bits(Method::Solid),
        fill,
        attributes: Default::default(),
        limits: voxd::app::Limits::SERVICE,
    };
    let (_, out) = voxd::app::voxelize(&req, &CpuEngine).unwrap();
    match out.volume {
        voxd::volume::Volume::Bits(b) => b,
        _ => panic!("density"),
    }
}

#[test]
fn two_replicas_on_s3_and_redis_behind_nginx() {
    let (Some(weed), Some(redis)) = (s3::shared(), RedisServer::start("topology")) else {
        return;
    };
    let store = format!("s3://{}/{}", s3::BUCKET, s3::prefix("topology"));
    let lease = ["--lease-seconds", "2"];
    let mut a = Replica::start(&store, weed, &redis, &lease);
    let b = Replica::start(&store, weed, &redis, &lease);
    let Some(lb) = Nginx::start("topology", &[&a.addr, &b.addr]) else {
        return;
    };
    // A real mesh (the glTF sample fox, 576 triangles) through the balancer; polled on B.
    let fox = std::fs::read(data("Fox.glb")).unwrap();
    let r = req(
        &lb.addr,
        "POST",
        "/v1/voxelize?resolution=96&fill=parity&name=fox",
        "model/gltf-binary",
        &fox,
    );
    assert_eq!(r.status, 202, "{}", String::from_utf8_lossy(&r.body));
    let job = r.json()["id"].as_str().unwrap().to_string();
    let j = until_final(&b.addr, &job, 120);
    assert_eq!(j["state"], "succeeded", "{j}");
    let vid = j["volume_id"].as_str().unwrap().to_string();
    // Fetched through A, B and the balancer: the same bytes and ETag, the library's voxels.
    let path = format!("/v1/volumes/{vid}/data");
    let (da, db, dl) = (
        get(&a.addr, &path),
        get(&b.addr, &path),
        get(&lb.addr, &path),
    );
    assert_eq!((da.status, db.status, dl.status), (200, 200, 200));
    assert!(da.body == db.body && db.body == dl.body);
    assert_eq!(da.headers.get("etag"), db.headers.get("etag"));
    assert!(
        decode_bits(&da.body) == library(&fox, 96, Fill::Parity),
        "the replicas' fox is not the single-process fox"
    );
    // A second volume made through the other replica; both list both, alike.
    let spot = std::fs::read(data("spot.obj")).unwrap();
    let r = req(
        &a.addr,
        "POST",
        "/v1/voxelize?resolution=32&wait=120",
        "model/obj",
        &spot,
    );
    assert_eq!(r.status, 201, "{}", String::from_utf8_lossy(&r.body));
    let sid = r.json()["id"].as_str().unwrap().to_string();
    let ids = |addr: &str| -> Vec<String> {
        let l = get(addr, "/v1/volumes?limit=100").json();
        l["volumes"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v["id"].as_str().unwrap().to_string())
            .collect()
    };
    let listed = ids(&a.addr);
    assert_eq!(listed, ids(&b.addr));
    assert!(listed.contains(&vid) && listed.contains(&sid), "{listed:?}");
    // CSG between a volume of each: one grid needed, so an aligned pair (the fox's grid given
    // explicitly to a second upload on the other replica).
    let g = get(&b.addr, &format!("/v1/volumes/{vid}")).json()["grid"].clone();
    let grid = format!(
        "origin={},{},{}&voxel_size={}&dims={},{},{}",
        g["origin"][0],
        g["origin"][1],
        g["origin"][2],
        g["voxel_size"],
        g["dims"][0],
        g["dims"][1],
        g["dims"][2]
    );
    let r = req(
        &b.addr,
        "POST",
        &format!("/v1/voxelize?{grid}&wait=120&method=surface"),
        "model/gltf-binary",
        &fox,
    );
    assert_eq!(r.status, 201, "{}", String::from_utf8_lossy(&r.body));
    let surf = r.json()["id"].as_str().unwrap().to_string();
    let body = format!(r#"{{"op":"union","operands":["{vid}","{surf}"]}}"#);
    let r = req(
        &lb.addr,
        "POST",
        "/v1/volumes/csg",
        "application/json",
        body.as_bytes(),
    );
    assert_eq!(r.status, 201, "{}", String::from_utf8_lossy(&r.body));
    // A replica SIGKILLed mid-job. B stops first so that the slow job surely runs on A; B comes
    // back on its address (the balancer's upstream), then A is killed: B must finish the job,
    // and the balancer keeps answering (the dead upstream is skipped).
    let b_addr = b.addr.clone();
    drop(b);
    let mut faces = 0;
    let holey: String = std::fs::read_to_string(data("spot.obj"))
        .unwrap()
        .lines()
        .filter(|l| {
            faces += l.starts_with("f ") as usize;
            !(l.starts_with("f ") && faces % 5 == 0)
        })
        .map(|l| format!("{l}\n"))
        .collect();
    let r = req(
        &a.addr,
        "POST",
        "/v1/voxelize?resolution=192&fill=winding",
        "model/obj",
        holey.as_bytes(),
    );
    assert_eq!(r.status, 202, "{}", String::from_utf8_lossy(&r.body));
    let slow = r.json()["id"].as_str().unwrap().to_string();
    let deadline = Instant::now() + Duration::from_secs(120);
    loop {
        let j = get(&a.addr, &format!("/v1/jobs/{slow}")).json();
        if j["state"] == "running" && j["progress"].as_f64() > Some(0.0) {
            break;
        }
        assert!(j["state"] == "queued" || j["state"] == "running", "{j}");
        assert!(Instant::now() < deadline, "never ran: {j}");
        std::thread::sleep(Duration::from_millis(20));
    }
    let _b = Replica::start_at(&b_addr, &store, weed, &redis, &lease);
    a.kill();
    let j = until_final(&lb.addr, &slow, 300);
    assert_eq!(j["state"], "succeeded", "{j}");
    assert_eq!(j["attempts"], 2, "{j}");
    let d = get(
        &lb.addr,
        &format!("/v1/volumes/{}/data", j["volume_id"].as_str().unwrap()),
    );
    assert_eq!(d.status, 200);
    assert!(decode_bits(&d.body) == library(&holey.into_bytes(), 192, Fill::Winding));
    assert_eq!(get(&lb.addr, "/readyz").status, 200);
}
