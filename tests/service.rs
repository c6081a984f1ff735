//! The HTTP service, end to end: the real `voxd serve` binary on 127.0.0.1 with an ephemeral
//! port, spoken to over TCP with a small HTTP/1.1 client. Loopback only; every loop is bounded.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use crate::common::*;
use serde_json::Value;
use voxd::codec::VolumeFormat;
use voxd::engine::cpu::CpuEngine;
use voxd::engine::{Engine, GridMesh, Method};
use voxd::grid::{Grid, GridSpec};
use voxd::volume::Volume;

pub(crate) struct Server {
    pub child: Child,
    pub addr: String,
    dir: PathBuf,
}

impl Server {
    pub fn start(dir: &Path, extra: &[&str]) -> Server {
        let (child, addr) = spawn_serve(
            Command::new(env!("CARGO_BIN_EXE_voxd"))
                .args([
                    "serve",
                    "--addr",
                    "127.0.0.1:0",
                    "--data-dir",
                    dir.to_str().unwrap(),
                ])
                // The CPU engine unless `extra` names one.
                .args(if extra.contains(&"--engine") {
                    &[][..]
                } else {
                    &["--engine", "cpu"][..]
                })
                .args(extra)
                .env("VOXD_LOG", "warn")
                .stderr(Stdio::inherit()),
        );
        Server {
            child,
            addr,
            dir: dir.to_path_buf(),
        }
    }

    fn req(&self, method: &str, path: &str, headers: &[(&str, &str)], body: &[u8]) -> Resp {
        request(&self.addr, method, path, headers, body)
    }

    /// SIGTERM, then the exit status.
    fn stop(mut self) -> std::process::ExitStatus {
        Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status()
            .unwrap();
        let deadline = Instant::now() + Duration::from_secs(60);
        loop {
            if let Some(s) = self.child.try_wait().unwrap() {
                return s;
            }
            assert!(Instant::now() < deadline, "server did not stop");
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn assert_problem(r: &Resp, status: u16, slug: &str) -> Value {
    assert_eq!(r.status, status, "{}", String::from_utf8_lossy(&r.body));
    assert_eq!(r.header("content-type"), Some("application/problem+json"));
    let p = r.json();
    assert_eq!(
        p["type"],
        format!("https://voxd.dev/problems/{slug}"),
        "{p}"
    );
    assert_eq!(p["status"], status);
    assert!(p["title"].as_str().is_some_and(|t| !t.is_empty()));
    assert!(p["detail"].as_str().is_some_and(|t| t.len() > 10), "{p}");
    assert_eq!(p["request_id"].as_str(), r.header("x-request-id"));
    p
}

#[test]
fn every_upload_format_and_download_format_matches_the_library() {
    let srv = Server::start(&tmpdir("formats"), &[]);
    let spot = std::fs::read(data("spot.obj")).unwrap();
    let stl = {
        // Binary STL of spot, written here.
        let m = voxd::mesh::load_file(&data("spot.obj"), usize::MAX).unwrap();
        let mut b = vec![0u8; 80];
        b.extend_from_slice(&(m.triangles().len() as u32).to_le_bytes());
        for t in 0..m.triangles().len() {
            b.extend_from_slice(&[0u8; 12]);
            for p in m.triangle(t) {
                for c in p {
                    b.extend_from_slice(&(c as f32).to_le_bytes());
                }
            }
            b.extend_from_slice(&[0, 0]);
        }
        b
    };
    let stl_path = tmpdir("stl").join("spot.stl");
    std::fs::write(&stl_path, &stl).unwrap();
    // ASCII PLY of spot with quads-free faces, written here.
    let ply = {
        let m = voxd::mesh::load_file(&data("spot.obj"), usize::MAX).unwrap();
        let mut t = format!(
            "ply\nformat ascii 1.0\nelement vertex {}\nproperty double x\nproperty double y\nproperty double z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
            m.positions().len(),
            m.triangles().len()
        );
        for p in m.positions() {
            t += &format!("{} {} {}\n", p[0], p[1], p[2]);
        }
        for f in m.triangles() {
            t += &format!("3 {} {} {}\n", f[0], f[1], f[2]);
        }
        t.into_bytes()
    };
    // (what, body, headers, the file the library reads for the expected bits)
    type Case<'a> = (&'a str, Vec<u8>, Vec<(&'a str, &'a str)>, PathBuf);
    let cases: Vec<Case> = vec![
        (
            "obj",
            spot.clone(),
            vec![("Content-Type", "model/obj")],
            data("spot.obj"),
        ),
        (
            "obj gzip",
            gz(&spot),
            vec![("Content-Type", "model/obj"), ("Content-Encoding", "gzip")],
            data("spot.obj"),
        ),
        (
            "glb",
            std::fs::read(data("Fox.glb")).unwrap(),
            vec![("Content-Type", "model/gltf-binary")],
            data("Fox.glb"),
        ),
        (
            "gltf",
            std::fs::read(data("Box.gltf")).unwrap(),
            vec![("Content-Type", "model/gltf+json")],
            data("Box.gltf"),
        ),
        (
            "stl",
            stl.clone(),
            vec![("Content-Type", "model/stl")],
            stl_path.clone(),
        ),
        (
            "ply",
            ply,
            vec![("Content-Type", "model/ply")],
            data("spot.obj"),
        ),
        ("stl by query", stl, vec![], stl_path),
    ];
    for (what, body, headers, path) in cases {
        let q = if what == "stl by query" {
            "&format=stl"
        } else {
            ""
        };
        let r = srv.req(
            "POST",
            &format!("/v1/voxelize?resolution=40&method=conservative&wait=60{q}"),
            &headers,
            &body,
        );
        assert_eq!(
            r.status,
            201,
            "{what}: {}",
            String::from_utf8_lossy(&r.body)
        );
        let meta = r.json();
        let id = meta["id"].as_str().unwrap();
        assert_eq!(
            r.header("location"),
            Some(format!("/v1/volumes/{id}").as_str())
        );
        let want = voxelize_file(
            &path,
            GridSpec::Resolution {
                n: 40,
                cubic: false,
            },
            0,
            Method::Conservative,
        );
        assert_eq!(meta["solid_voxels"], want.count_ones(), "{what}");
        for f in ["vxl", "npy", "binvox"] {
            let d = srv.req(
                "GET",
                &format!("/v1/volumes/{id}/data?format={f}"),
                &[],
                &[],
            );
            assert_eq!(d.status, 200, "{what} {f}");
            let got = decode_bits(&d.body);
            if f == "binvox" {
                assert_eq!(got.count_ones(), want.count_ones(), "{what} {f}");
            } else {
                assert_eq!(got.words(), want.words(), "{what} {f}");
            }
        }
    }
}

#[test]
fn polling_wait_cancel_and_caching() {
    let srv = Server::start(&tmpdir("poll"), &[]);
    let spot = std::fs::read(data("spot.obj")).unwrap();
    // wait=0: 202 and a job to poll.
    let r = srv.req(
        "POST",
        "/v1/voxelize?resolution=64&name=spot",
        &[("Content-Type", "model/obj")],
        &spot,
    );
    assert_eq!(r.status, 202);
    let job = r.json();
    let id = job["id"].as_str().unwrap().to_string();
    assert_eq!(
        r.header("location"),
        Some(format!("/v1/jobs/{id}").as_str())
    );
    assert!(["queued", "running", "succeeded"].contains(&job["state"].as_str().unwrap()));
    let deadline = Instant::now() + Duration::from_secs(60);
    let done = loop {
        let j = srv.req("GET", &format!("/v1/jobs/{id}"), &[], &[]).json();
        if j["state"] == "succeeded" {
            break j;
        }
        assert!(j["state"] != "failed" && Instant::now() < deadline, "{j}");
        std::thread::sleep(Duration::from_millis(20));
    };
    assert_eq!(done["progress"], 1.0);
    let vid = done["volume_id"].as_str().unwrap();
    let meta = srv
        .req("GET", &format!("/v1/volumes/{vid}"), &[], &[])
        .json();
    assert_eq!(meta["name"], "spot");
    assert_eq!(meta["source"]["triangles"], 5856);
    assert_eq!(meta["diagnostics"]["watertight"], true);
    // ETag / If-None-Match, and compression of uncompressed formats.
    let d = srv.req(
        "GET",
        &format!("/v1/volumes/{vid}/data?format=npy"),
        &[("Accept-Encoding", "gzip")],
        &[],
    );
    assert_eq!(d.header("content-encoding"), Some("gzip"));
    let etag = d.header("etag").unwrap().to_string();
    let again = srv.req(
        "GET",
        &format!("/v1/volumes/{vid}/data?format=npy"),
        &[("If-None-Match", &etag)],
        &[],
    );
    assert_eq!(again.status, 304);
    assert!(again.body.is_empty());
    let vxl = srv.req(
        "GET",
        &format!("/v1/volumes/{vid}/data"),
        &[("Accept-Encoding", "gzip")],
        &[],
    );
    assert_eq!(vxl.header("content-type"), Some("application/vnd.voxd.vxl"));
    assert_eq!(
        vxl.header("content-encoding"),
        None,
        "vxl is compressed already"
    );
    // Cancel: a big job occupies the worker, the next one waits and is canceled.
    let big = srv
        .req(
            "POST",
            "/v1/voxelize?resolution=1000&method=conservative",
            &[("Content-Type", "model/obj")],
            &spot,
        )
        .json();
    let queued = srv
        .req(
            "POST",
            "/v1/voxelize?resolution=32",
            &[("Content-Type", "model/obj")],
            &spot,
        )
        .json();
    let qid = queued["id"].as_str().unwrap();
    let c = srv.req("DELETE", &format!("/v1/jobs/{qid}"), &[], &[]);
    assert_eq!(c.status, 200, "{}", String::from_utf8_lossy(&c.body));
    assert_eq!(c.json()["state"], "canceled");
    assert_problem(
        &srv.req("DELETE", &format!("/v1/jobs/{qid}"), &[], &[]),
        409,
        "not-cancelable",
    );
    let bid = big["id"].as_str().unwrap();
    let c = srv.req("DELETE", &format!("/v1/jobs/{bid}"), &[], &[]);
    assert_eq!(c.status, 200);
    assert_eq!(
        srv.req("GET", &format!("/v1/jobs/{bid}"), &[], &[]).json()["state"],
        "canceled"
    );
    // Delete a volume.
    assert_eq!(
        srv.req("DELETE", &format!("/v1/volumes/{vid}"), &[], &[])
            .status,
        204
    );
    assert_problem(
        &srv.req("GET", &format!("/v1/volumes/{vid}"), &[], &[]),
        404,
        "not-found",
    );
}

#[test]
fn every_error_is_a_problem_document() {
    let dir = tmpdir("errors");
    let srv = Server::start(
        &dir,
        &[
            "--max-triangles",
            "1000",
            "--max-body-bytes",
            "400000",
            "--max-voxels",
            "1000000",
        ],
    );
    let spot = std::fs::read(data("spot.obj")).unwrap();
    let obj = [("Content-Type", "model/obj")];
    let post =
        |q: &str, h: &[(&str, &str)], b: &[u8]| srv.req("POST", &format!("/v1/voxelize{q}"), h, b);
    assert_problem(
        &post("", &obj, b"v 0 0 0\nv 1 0 0\nf 1 2 9\n"),
        422,
        "invalid-mesh",
    );
    assert_problem(&post("", &obj, b""), 422, "invalid-mesh");
    assert_problem(
        &post("", &[("Content-Type", "text/html")], b"<html>"),
        415,
        "unsupported-media-type",
    );
    assert_problem(
        &post("?format=dwg", &[], b"x"),
        415,
        "unsupported-media-type",
    );
    assert_problem(
        &post("", &[], b"hello there"),
        415,
        "unsupported-media-type",
    );
    let ext = r#"{"asset":{"version":"2.0"},"buffers":[{"uri":"/etc/passwd","byteLength":12}],"meshes":[],"scenes":[]}"#;
    assert_problem(
        &post("", &[("Content-Type", "model/gltf+json")], ext.as_bytes()),
        422,
        "external-resource",
    );
    assert_problem(&post("", &obj, &spot), 422, "too-many-triangles");
    let big = vec![b' '; 500_000];
    assert_problem(&post("", &obj, &big), 413, "body-too-large");
    let small = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\n";
    assert_problem(&post("?resolution=200", &obj, small), 422, "grid-too-large");
    assert_problem(
        &post("?method=sculpt", &obj, small),
        400,
        "invalid-parameter",
    );
    assert_problem(&post("?fill=blob", &obj, small), 400, "invalid-parameter");
    assert_problem(
        &post("?resolution=-3", &obj, small),
        400,
        "invalid-parameter",
    );
    assert_problem(
        &post("?origin=0,0&dims=2,2,2&voxel_size=1", &obj, small),
        400,
        "invalid-parameter",
    );
    assert_problem(&post("?colour=red", &obj, small), 400, "invalid-parameter");
    assert_problem(&post("?wait=1000", &obj, small), 400, "invalid-parameter");
    assert_problem(&srv.req("GET", "/v1/jobs/nope", &[], &[]), 404, "not-found");
    assert_problem(
        &srv.req("GET", "/v1/volumes/nope/data", &[], &[]),
        404,
        "not-found",
    );
    assert_problem(
        &srv.req("GET", "/v1/nothing-here", &[], &[]),
        404,
        "not-found",
    );
    assert_problem(
        &srv.req("GET", "/v1/volumes?limit=0", &[], &[]),
        400,
        "invalid-parameter",
    );
    // The request id a caller sends comes back in the problem.
    let r = srv.req("GET", "/v1/jobs/nope", &[("x-request-id", "abc-123")], &[]);
    assert_eq!(
        assert_problem(&r, 404, "not-found")["request_id"],
        "abc-123"
    );
    drop(srv);
    // A store that is full.
    let srv = Server::start(&tmpdir("full"), &["--max-store-bytes", "100"]);
    let r = srv.req(
        "POST",
        "/v1/voxelize?resolution=16&wait=30",
        &[("Content-Type", "model/obj")],
        small,
    );
    assert_problem(&r, 507, "storage-full");
}

#[test]
fn a_full_queue_says_429_and_loses_nothing_accepted() {
    let srv = Server::start(&tmpdir("flood"), &["--queue-capacity", "3"]);
    let spot = std::fs::read(data("spot.obj")).unwrap();
    let obj = [("Content-Type", "model/obj")];
    // Occupy the worker, then flood.
    srv.req(
        "POST",
        "/v1/voxelize?resolution=1000&method=conservative",
        &obj,
        &spot,
    );
    let (mut accepted, mut refused) = (vec![], 0);
    for _ in 0..12 {
        let depth = String::from_utf8(srv.req("GET", "/metrics", &[], &[]).body).unwrap();
        let depth: usize = depth
            .lines()
            .find_map(|l| l.strip_prefix("voxd_queue_depth "))
            .unwrap()
            .parse()
            .unwrap();
        assert!(depth <= 3, "queue depth {depth} over capacity");
        let r = srv.req("POST", "/v1/voxelize?resolution=24", &obj, &spot);
        match r.status {
            202 => accepted.push(r.json()["id"].as_str().unwrap().to_string()),
            429 => {
                assert_problem(&r, 429, "queue-full");
                assert_eq!(r.header("retry-after"), Some("5"));
                refused += 1;
            }
            s => panic!("unexpected {s}"),
        }
    }
    assert!(
        refused >= 1 && accepted.len() >= 3,
        "{refused} refused, {} accepted",
        accepted.len()
    );
    let deadline = Instant::now() + Duration::from_secs(120);
    for id in &accepted {
        loop {
            let j = srv.req("GET", &format!("/v1/jobs/{id}"), &[], &[]).json();
            if j["state"] == "succeeded" {
                break;
            }
            assert!(j["state"] != "failed" && Instant::now() < deadline, "{j}");
            std::thread::sleep(Duration::from_millis(50));
        }
    }
}

#[test]
fn concurrent_clients_get_their_own_results() {
    let srv = Server::start(&tmpdir("concurrent"), &["--workers", "2"]);
    let spot = std::fs::read(data("spot.obj")).unwrap();
    let addr = srv.addr.clone();
    let handles: Vec<_> = (0..6u32)
        .map(|i| {
            let (addr, spot) = (addr.clone(), spot.clone());
            std::thread::spawn(move || {
                let n = 20 + 7 * i;
                let r = request(
                    &addr,
                    "POST",
                    &format!("/v1/voxelize?resolution={n}&wait=60"),
                    &[("Content-Type", "model/obj")],
                    &spot,
                );
                assert_eq!(r.status, 201);
                (n, r.json())
            })
        })
        .collect();
    for h in handles {
        let (n, meta) = h.join().unwrap();
        let want = voxelize_file(
            &data("spot.obj"),
            GridSpec::Resolution { n, cubic: false },
            0,
            Method::Solid,
        );
        assert_eq!(meta["solid_voxels"], want.count_ones(), "resolution {n}");
        assert_eq!(meta["grid"]["dims"], serde_json::json!(want.dims()));
    }
}

#[test]
fn restart_keeps_volumes_and_sigterm_finishes_the_running_job() {
    let dir = tmpdir("restart");
    let srv = Server::start(&dir, &[]);
    let spot = std::fs::read(data("spot.obj")).unwrap();
    let obj = [("Content-Type", "model/obj")];
    let kept = srv
        .req("POST", "/v1/voxelize?resolution=50&wait=60", &obj, &spot)
        .json();
    let kept_id = kept["id"].as_str().unwrap().to_string();
    let bytes = srv
        .req("GET", &format!("/v1/volumes/{kept_id}/data"), &[], &[])
        .body;
    // A job still running when SIGTERM arrives is finished and stored.
    let running = srv
        .req(
            "POST",
            "/v1/voxelize?resolution=500&method=conservative",
            &obj,
            &spot,
        )
        .json();
    let deadline = Instant::now() + Duration::from_secs(30);
    while srv
        .req(
            "GET",
            &format!("/v1/jobs/{}", running["id"].as_str().unwrap()),
            &[],
            &[],
        )
        .json()["state"]
        == "queued"
    {
        assert!(Instant::now() < deadline);
        std::thread::sleep(Duration::from_millis(10));
    }
    // A job queued behind it when SIGTERM arrives is failed explicitly.
    let queued = srv
        .req("POST", "/v1/voxelize?resolution=20", &obj, &spot)
        .json();
    assert_eq!(queued["state"], "queued");
    // A leftover of an interrupted write must not survive a restart.
    std::fs::write(dir.join("volumes/.half-written.vxl.1.tmp"), b"junk").unwrap();
    let status = srv.stop();
    assert!(status.success(), "{status:?}");
    let srv = Server::start(&dir, &[]);
    assert!(!dir.join("volumes/.half-written.vxl.1.tmp").exists());
    let list = srv.req("GET", "/v1/volumes?limit=1", &[], &[]).json();
    assert_eq!(list["volumes"].as_array().unwrap().len(), 1);
    let next = list["next"].as_str().expect("a second page");
    let rest = srv.req("GET", next, &[], &[]).json();
    let all: Vec<Value> = list["volumes"]
        .as_array()
        .unwrap()
        .iter()
        .chain(rest["volumes"].as_array().unwrap())
        .cloned()
        .collect();
    assert_eq!(
        all.len(),
        2,
        "the finished and the interrupted-by-SIGTERM volume"
    );
    assert!(all.iter().any(|v| {
        v["grid"]["dims"][1] == 500
            || v["grid"]["dims"]
                .as_array()
                .unwrap()
                .contains(&serde_json::json!(500))
    }));
    assert_eq!(
        srv.req("GET", &format!("/v1/volumes/{kept_id}/data"), &[], &[])
            .body,
        bytes
    );
    assert_eq!(srv.dir, dir);
}

#[test]
fn health_metrics_and_the_openapi_document() {
    let srv = Server::start(&tmpdir("health"), &[]);
    assert_eq!(srv.req("GET", "/healthz", &[], &[]).json()["status"], "ok");
    let ready = srv.req("GET", "/readyz", &[], &[]).json();
    assert_eq!(ready["status"], "ready");
    assert_eq!(ready["engine"], "cpu");
    srv.req(
        "POST",
        "/v1/voxelize?resolution=16&wait=30",
        &[("Content-Type", "model/obj")],
        &std::fs::read(data("spot.obj")).unwrap(),
    );
    let m = String::from_utf8(srv.req("GET", "/metrics", &[], &[]).body).unwrap();
    for want in [
        "voxd_jobs{state=\"succeeded\",method=\"solid\"} 1",
        "voxd_queue_depth 0",
        "voxd_job_duration_seconds_count 1",
        "voxd_engine_info{engine=\"cpu\"} 1",
    ] {
        assert!(m.contains(want), "{want} missing from\n{m}");
    }
    // The GPU's counters only where it runs.
    assert!(!m.contains("voxd_gpu_"), "{m}");
    let doc = srv.req("GET", "/openapi.yaml", &[], &[]);
    assert_eq!(doc.header("content-type"), Some("application/yaml"));
    assert_eq!(doc.body, std::fs::read(repo_file("openapi.yaml")).unwrap());
}

/// The route table (voxd::service::ROUTES) and openapi.yaml list the same paths and methods, and every
/// documented operation answers on the live server (not the fallback).
#[test]
fn router_and_openapi_agree() {
    let yaml = std::fs::read_to_string(repo_file("openapi.yaml")).unwrap();
    let mut documented = std::collections::BTreeSet::new();
    let mut path = None;
    for line in yaml.lines() {
        if line == "components:" {
            break;
        }
        if let Some(p) = line.strip_prefix("  /").and_then(|l| l.strip_suffix(':')) {
            path = Some(format!("/{p}"));
        } else if let (Some(p), Some(m)) = (
            &path,
            line.strip_prefix("    ").and_then(|l| l.strip_suffix(':')),
        ) && ["get", "post", "delete", "put", "patch"].contains(&m)
        {
            documented.insert((p.clone(), m.to_uppercase()));
        }
    }
    let routed: std::collections::BTreeSet<(String, String)> = voxd::service::ROUTES
        .iter()
        .flat_map(|(p, ms)| ms.iter().map(|m| (p.to_string(), m.to_string())))
        .collect();
    assert_eq!(documented, routed, "openapi.yaml and the router disagree");
    let srv = Server::start(&tmpdir("openapi"), &[]);
    for (p, m) in &documented {
        let r = srv.req(m, &p.replace("{id}", "x"), &[], &[]);
        let fallback =
            r.status == 404 && String::from_utf8_lossy(&r.body).contains("no such route");
        assert!(
            !fallback && r.status != 405,
            "{m} {p} is documented but not routed ({})",
            r.status
        );
    }
}

/// Checks `v` against the subset of JSON Schema openapi.yaml uses: $ref, type, nullable,
/// required, properties, items, enum.
fn validate(doc: &Value, schema: &Value, v: &Value, at: &str) -> Result<(), String> {
    if let Some(r) = schema.get("$ref").and_then(Value::as_str) {
        let name = r
            .strip_prefix("#/components/schemas/")
            .ok_or(format!("unsupported $ref {r}"))?;
        return validate(doc, &doc["components"]["schemas"][name], v, at);
    }
    if v.is_null() && schema.get("nullable") == Some(&Value::Bool(true)) {
        return Ok(());
    }
    let ok = match schema.get("type").and_then(Value::as_str) {
        None => true,
        Some("object") => v.is_object(),
        Some("array") => v.is_array(),
        Some("string") => v.is_string(),
        Some("integer") => v.is_i64() || v.is_u64(),
        Some("number") => v.is_number(),
        Some("boolean") => v.is_boolean(),
        Some(t) => return Err(format!("{at}: unsupported type {t}")),
    };
    if !ok {
        return Err(format!("{at}: {v} is not of type {}", schema["type"]));
    }
    if let Some(e) = schema.get("enum").and_then(Value::as_array)
        && !e.contains(v)
    {
        return Err(format!("{at}: {v} is not one of {e:?}"));
    }
    for r in schema
        .get("required")
        .and_then(Value::as_array)
        .into_iter()
        .flatten()
    {
        let k = r.as_str().unwrap();
        if v.get(k).is_none() {
            return Err(format!("{at}: required field {k} is missing"));
        }
    }
    if let Some(props) = schema.get("properties").and_then(Value::as_object) {
        for (k, s) in props {
            if let Some(x) = v.get(k) {
                validate(doc, s, x, &format!("{at}.{k}"))?;
            }
        }
    }
    if let (Some(items), Some(arr)) = (schema.get("items"), v.as_array()) {
        for (i, x) in arr.iter().enumerate() {
            validate(doc, items, x, &format!("{at}[{i}]"))?;
        }
    }
    Ok(())
}

/// Real responses, checked against the operation's documented status codes, media types and
/// schemas in openapi.yaml.
#[test]
fn real_responses_match_the_openapi_schemas() {
    let yaml = std::fs::read_to_string(repo_file("openapi.yaml")).unwrap();
    let doc: Value = serde_norway::from_str(&yaml).unwrap();
    let srv = Server::start(&tmpdir("schemas"), &[]);
    let spot = std::fs::read(data("spot.obj")).unwrap();
    let obj: &[(&str, &str)] = &[("Content-Type", "model/obj")];
    let mut checked = 0;
    let mut check = |template: &str, method: &str, r: &Resp| {
        let op = &doc["paths"][template][method];
        assert!(op.is_object(), "{method} {template} is not documented");
        let mut resp = &op["responses"][r.status.to_string()];
        assert!(
            resp.is_object(),
            "{method} {template} answered {} which is not documented",
            r.status
        );
        if let Some(name) = resp.get("$ref").and_then(Value::as_str) {
            resp = &doc["components"]["responses"]
                [name.strip_prefix("#/components/responses/").unwrap()];
        }
        let Some(content) = resp.get("content") else {
            assert!(
                r.body.is_empty(),
                "{method} {template} {}: undocumented body",
                r.status
            );
            return;
        };
        let ct = r
            .header("content-type")
            .unwrap_or("")
            .split(';')
            .next()
            .unwrap()
            .to_string();
        let media = content.get(&ct).unwrap_or_else(|| {
            panic!(
                "{method} {template} {}: media type {ct} not documented",
                r.status
            )
        });
        if ct.ends_with("json")
            && let Err(e) = validate(&doc, &media["schema"], &r.json(), "body")
        {
            panic!("{method} {template} {}: {e}", r.status);
        }
        checked += 1;
    };
    let r = srv.req(
        "POST",
        "/v1/voxelize?resolution=30&wait=60&name=a",
        obj,
        &spot,
    );
    check("/v1/voxelize", "post", &r);
    let vid = r.json()["id"].as_str().unwrap().to_string();
    let bowl = to_obj(&open_bowl());
    let r = srv.req(
        "POST",
        "/v1/voxelize?resolution=20&wait=60&fill=auto",
        obj,
        &bowl,
    );
    assert!(r.json()["fill"]["winding"].is_object());
    check("/v1/voxelize", "post", &r);
    let r = srv.req("POST", "/v1/voxelize?resolution=20&wait=60", obj, &bowl);
    assert!(r.json()["fill"]["warning"].is_string());
    check("/v1/voxelize", "post", &r);
    let r = srv.req("POST", "/v1/voxelize?resolution=31", obj, &spot);
    check("/v1/voxelize", "post", &r);
    let jid = r.json()["id"].as_str().unwrap().to_string();
    check(
        "/v1/voxelize",
        "post",
        &srv.req("POST", "/v1/voxelize?method=x", obj, &spot),
    );
    check(
        "/v1/voxelize",
        "post",
        &srv.req("POST", "/v1/voxelize", obj, b"v 1 2 3\n"),
    );
    check(
        "/v1/voxelize",
        "post",
        &srv.req(
            "POST",
            "/v1/voxelize",
            &[("Content-Type", "image/png")],
            b"x",
        ),
    );
    std::thread::sleep(Duration::from_millis(300));
    check(
        "/v1/jobs/{id}",
        "get",
        &srv.req("GET", &format!("/v1/jobs/{jid}"), &[], &[]),
    );
    check(
        "/v1/jobs/{id}",
        "get",
        &srv.req("GET", "/v1/jobs/none", &[], &[]),
    );
    check(
        "/v1/jobs/{id}",
        "delete",
        &srv.req("DELETE", &format!("/v1/jobs/{jid}"), &[], &[]),
    );
    check(
        "/v1/volumes",
        "get",
        &srv.req("GET", "/v1/volumes?limit=1", &[], &[]),
    );
    check(
        "/v1/volumes",
        "get",
        &srv.req("GET", "/v1/volumes?limit=x", &[], &[]),
    );
    check(
        "/v1/volumes/{id}",
        "get",
        &srv.req("GET", &format!("/v1/volumes/{vid}"), &[], &[]),
    );
    for f in ["vxl", "npy", "binvox"] {
        check(
            "/v1/volumes/{id}/data",
            "get",
            &srv.req(
                "GET",
                &format!("/v1/volumes/{vid}/data?format={f}"),
                &[],
                &[],
            ),
        );
    }
    check(
        "/v1/volumes/{id}/data",
        "get",
        &srv.req(
            "GET",
            &format!("/v1/volumes/{vid}/data?format=obj"),
            &[],
            &[],
        ),
    );
    check("/healthz", "get", &srv.req("GET", "/healthz", &[], &[]));
    check("/readyz", "get", &srv.req("GET", "/readyz", &[], &[]));
    check("/metrics", "get", &srv.req("GET", "/metrics", &[], &[]));
    check(
        "/openapi.yaml",
        "get",
        &srv.req("GET", "/openapi.yaml", &[], &[]),
    );
    check(
        "/v1/volumes/{id}",
        "delete",
        &srv.req("DELETE", &format!("/v1/volumes/{vid}"), &[], &[]),
    );
    check(
        "/v1/volumes/{id}",
        "delete",
        &srv.req("DELETE", &format!("/v1/volumes/{vid}"), &[], &[]),
    );
    assert_eq!(checked, 22);
}

#[test]
fn density_over_http() {
    let srv = Server::start(&tmpdir("density"), &[]);
    let spot = std::fs::read(data("spot.obj")).unwrap();
    let r = srv.req(
        "POST",
        "/v1/voxelize?resolution=30&method=density&wait=60",
        &[("Content-Type", "model/obj")],
        &spot,
    );
    assert_eq!(r.status, 201, "{}", String::from_utf8_lossy(&r.body));
    let meta = r.json();
    assert_eq!(meta["kind"], "density");
    let id = meta["id"].as_str().unwrap();
    let (mesh, g) = mesh_and_grid(
        &data("spot.obj"),
        GridSpec::Resolution {
            n: 30,
            cubic: false,
        },
        0,
    );
    let d = mesh.diagnostics();
    let parity = voxd::engine::fill::Fill::Parity;
    let (want, _) =
        voxd::engine::density::density(&CpuEngine, &mesh, &g, 2, Default::default(), parity, &d)
            .unwrap();
    assert!(
        (meta["volume"].as_f64().unwrap() - want.occupied_voxels() * g.voxel_size.powi(3)).abs()
            < 1e-12
    );
    let npy = srv.req(
        "GET",
        &format!("/v1/volumes/{id}/data?format=npy"),
        &[],
        &[],
    );
    let Volume::Density(got) = VolumeFormat::Npy.decode(&npy.body).unwrap() else {
        panic!("npy should hold density")
    };
    assert_eq!(got.data(), want.data());
    let raw = srv.req(
        "GET",
        &format!("/v1/volumes/{id}/data?format=raw"),
        &[],
        &[],
    );
    assert_eq!(raw.body, want.data());
    let Volume::Density(v) = VolumeFormat::Vxl
        .decode(
            &srv.req("GET", &format!("/v1/volumes/{id}/data"), &[], &[])
                .body,
        )
        .unwrap()
    else {
        panic!("vxl should hold density")
    };
    assert_eq!(v, want);
    assert_problem(
        &srv.req(
            "GET",
            &format!("/v1/volumes/{id}/data?format=binvox"),
            &[],
            &[],
        ),
        400,
        "invalid-parameter",
    );
    let r = srv.req(
        "POST",
        "/v1/voxelize?method=density&density_factor=3",
        &[("Content-Type", "model/obj")],
        &spot,
    );
    assert_problem(&r, 400, "invalid-parameter");
    let r = srv.req(
        "POST",
        "/v1/voxelize?method=density&density_factor=4&resolution=700",
        &[("Content-Type", "model/obj")],
        &spot,
    );
    assert_problem(&r, 422, "grid-too-large");
}

/// Every fill over HTTP gives the library's bits, and the volume says which fill was used.
#[test]
fn fills_over_http() {
    use voxd::engine::fill::{Fill, voxelize};
    let srv = Server::start(&tmpdir("fills"), &[]);
    let mesh = open_bowl();
    let bowl = to_obj(&mesh);
    let d = mesh.diagnostics();
    let (lo, hi) = mesh.bounds();
    let spec = GridSpec::Resolution {
        n: 24,
        cubic: false,
    };
    let g = Grid::fit(lo, hi, spec, 0, Default::default()).unwrap();
    for (fill, method, used) in [
        ("auto", "solid", "winding"),
        ("winding", "conservative", "winding"),
        ("vote", "interior", "vote"),
        ("flood", "solid", "flood"),
        ("parity", "solid", "parity"),
    ] {
        let r = srv.req(
            "POST",
            &format!("/v1/voxelize?resolution=24&wait=60&fill={fill}&method={method}"),
            &[("Content-Type", "model/obj")],
            &bowl,
        );
        assert_eq!(r.status, 201, "{}", String::from_utf8_lossy(&r.body));
        let meta = r.json();
        assert_eq!(meta["fill"]["requested"], fill);
        assert_eq!(meta["fill"]["used"], used);
        assert!(meta["fill"]["odd_parity_columns"].as_u64().unwrap() > 0);
        assert_eq!(meta["fill"]["warning"].is_string(), used == "parity");
        assert_eq!(meta["fill"]["winding"].is_object(), used == "winding");
        let id = meta["id"].as_str().unwrap();
        let got = decode_bits(
            &srv.req("GET", &format!("/v1/volumes/{id}/data"), &[], &[])
                .body,
        );
        let m: Method = method.parse().unwrap();
        let (want, report) = voxelize(&CpuEngine, &mesh, &g, m, fill.parse().unwrap(), &d).unwrap();
        assert_eq!(got, want, "{fill} {method}");
        assert_eq!(meta["fill"], serde_json::to_value(&report).unwrap());
    }
    // Density under the winding fill.
    let r = srv.req(
        "POST",
        "/v1/voxelize?resolution=12&wait=60&fill=winding&method=density",
        &[("Content-Type", "model/obj")],
        &bowl,
    );
    assert_eq!(r.status, 201, "{}", String::from_utf8_lossy(&r.body));
    let meta = r.json();
    assert_eq!(meta["fill"]["used"], "winding");
    let id = meta["id"].as_str().unwrap();
    let Volume::Density(got) = VolumeFormat::Vxl
        .decode(
            &srv.req("GET", &format!("/v1/volumes/{id}/data"), &[], &[])
                .body,
        )
        .unwrap()
    else {
        panic!("density expected")
    };
    let g12 = Grid::fit(
        lo,
        hi,
        GridSpec::Resolution {
            n: 12,
            cubic: false,
        },
        0,
        Default::default(),
    )
    .unwrap();
    let (want, _) = voxd::engine::density::density(
        &CpuEngine,
        &mesh,
        &g12,
        2,
        Default::default(),
        Fill::Winding,
        &d,
    )
    .unwrap();
    assert_eq!(got, want);
}

pub(crate) fn box_obj(lo: [f64; 3], hi: [f64; 3]) -> Vec<u8> {
    to_obj(&box_mesh(lo, hi))
}

#[test]
fn csg_and_intersect_over_http() {
    let srv = Server::start(&tmpdir("csg"), &[]);
    let obj = [("Content-Type", "model/obj")];
    let grid = "origin=0,0,0&voxel_size=0.5&dims=30,28,26";
    let up = |lo, hi| {
        let r = srv.req(
            "POST",
            &format!("/v1/voxelize?{grid}&wait=60"),
            &obj,
            &box_obj(lo, hi),
        );
        assert_eq!(r.status, 201, "{}", String::from_utf8_lossy(&r.body));
        r.json()["id"].as_str().unwrap().to_string()
    };
    let a = up([1.2, 1.1, 1.3], [9.3, 8.7, 9.1]);
    let b = up([5.4, 0.3, 0.2], [14.1, 13.2, 12.4]);
    let expr = serde_json::json!({"op": "difference", "operands": [a, {"op": "union", "operands": [b, b]}]});
    let r = srv.req(
        "POST",
        "/v1/volumes/csg?name=a-minus-b",
        &[("Content-Type", "application/json")],
        expr.to_string().as_bytes(),
    );
    assert_eq!(r.status, 201, "{}", String::from_utf8_lossy(&r.body));
    let meta = r.json();
    assert_eq!(meta["provenance"], expr);
    assert_eq!(meta["grid"]["dims"], serde_json::json!([30, 28, 26]));
    let id = meta["id"].as_str().unwrap();
    let got = decode_bits(
        &srv.req("GET", &format!("/v1/volumes/{id}/data"), &[], &[])
            .body,
    );
    // Exactly the voxelization of the known boolean (A − B is the box of A left of x = 5.4).
    let g = Grid {
        origin: [0.0; 3],
        voxel_size: 0.5,
        dims: [30, 28, 26],
    };
    let mut p = vec![];
    let mut t = vec![];
    push_box(&mut p, &mut t, [1.2, 1.1, 1.3], [5.4, 8.7, 9.1]);
    let want = CpuEngine
        .voxelize(
            &GridMesh::new(&voxd::mesh::Mesh::new(p, t).unwrap(), &g).unwrap(),
            Method::Solid,
        )
        .unwrap();
    assert_eq!(got, want);
    let i = srv
        .req(
            "POST",
            "/v1/volumes/intersect",
            &[],
            serde_json::json!({"a": a, "b": b}).to_string().as_bytes(),
        )
        .json();
    let inter = srv
        .req(
            "POST",
            "/v1/volumes/csg",
            &[],
            serde_json::json!({"op": "intersection", "operands": [a, b]})
                .to_string()
                .as_bytes(),
        )
        .json();
    assert_eq!(i["voxels"], inter["solid_voxels"]);
    assert!(i["voxels"].as_u64().unwrap() > 0);
    // Errors: misaligned grids, a density operand, unknown ids, bad expressions.
    let r = srv.req(
        "POST",
        "/v1/voxelize?origin=0.25,0,0&voxel_size=0.5&dims=4,4,4&wait=60",
        &obj,
        &box_obj([0.5; 3], [1.5; 3]),
    );
    let shifted = r.json()["id"].as_str().unwrap().to_string();
    let bad =
        |e: serde_json::Value| srv.req("POST", "/v1/volumes/csg", &[], e.to_string().as_bytes());
    assert_problem(
        &bad(serde_json::json!({"op": "union", "operands": [a, shifted]})),
        422,
        "misaligned-grids",
    );
    let d = srv
        .req(
            "POST",
            &format!("/v1/voxelize?{grid}&method=density&wait=60"),
            &obj,
            &box_obj([1.0; 3], [2.0; 3]),
        )
        .json();
    assert_problem(
        &bad(serde_json::json!({"op": "union", "operands": [a, d["id"]]})),
        422,
        "wrong-volume-kind",
    );
    assert_problem(
        &bad(serde_json::json!({"op": "union", "operands": [a, "nope"]})),
        404,
        "not-found",
    );
    assert_problem(
        &bad(serde_json::json!({"op": "sum", "operands": [a]})),
        400,
        "invalid-parameter",
    );
    assert_problem(
        &bad(serde_json::json!({"op": "union", "operands": []})),
        400,
        "invalid-parameter",
    );
    assert_problem(&bad(serde_json::json!(42)), 400, "invalid-parameter");
    let far = srv
        .req(
            "POST",
            "/v1/voxelize?origin=100,100,100&voxel_size=0.5&dims=4,4,4&wait=60",
            &obj,
            &box_obj([100.5; 3], [101.5; 3]),
        )
        .json();
    assert_problem(
        &bad(serde_json::json!({"op": "intersection", "operands": [a, far["id"]]})),
        422,
        "empty-intersection",
    );
    assert_eq!(
        srv.req(
            "POST",
            "/v1/volumes/intersect",
            &[],
            serde_json::json!({"a": a, "b": far["id"]})
                .to_string()
                .as_bytes()
        )
        .json()["voxels"],
        0
    );
    assert_problem(
        &srv.req("POST", "/v1/volumes/intersect", &[], b"{}"),
        400,
        "invalid-parameter",
    );
}

#[test]
fn morphology_over_http() {
    let srv = Server::start(&tmpdir("morph"), &["--max-voxels", "200000"]);
    let r = srv.req(
        "POST",
        "/v1/voxelize?origin=0,0,0&voxel_size=1&dims=20,20,20&wait=60",
        &[("Content-Type", "model/obj")],
        &box_obj([5.0; 3], [12.0; 3]),
    );
    let id = r.json()["id"].as_str().unwrap().to_string();
    let stored = decode_bits(
        &srv.req("GET", &format!("/v1/volumes/{id}/data"), &[], &[])
            .body,
    );
    let body = serde_json::json!({"op": "dilate", "radius": 2, "kernel": "sphere", "grow": true});
    let r = srv.req(
        "POST",
        &format!("/v1/volumes/{id}/morphology?name=fat"),
        &[],
        body.to_string().as_bytes(),
    );
    assert_eq!(r.status, 201, "{}", String::from_utf8_lossy(&r.body));
    let meta = r.json();
    assert_eq!(meta["grid"]["dims"], serde_json::json!([24, 24, 24]));
    assert_eq!(meta["provenance"]["morphology"]["of"], id.as_str());
    let got = decode_bits(
        &srv.req(
            "GET",
            &format!("/v1/volumes/{}/data", meta["id"].as_str().unwrap()),
            &[],
            &[],
        )
        .body,
    );
    let want = voxd::volume::morph::apply(
        &stored,
        voxd::volume::morph::MorphOp::Dilate,
        2,
        voxd::volume::morph::Kernel::Sphere,
        true,
    );
    assert_eq!(got, want);
    let post = |b: serde_json::Value| {
        srv.req(
            "POST",
            &format!("/v1/volumes/{id}/morphology"),
            &[],
            b.to_string().as_bytes(),
        )
    };
    assert_eq!(
        post(serde_json::json!({"op": "erode", "radius": 1})).json()["solid_voxels"],
        5 * 5 * 5
    );
    assert_problem(
        &post(serde_json::json!({"op": "melt", "radius": 1})),
        400,
        "invalid-parameter",
    );
    assert_problem(
        &post(serde_json::json!({"op": "erode", "radius": 99})),
        400,
        "invalid-parameter",
    );
    assert_problem(
        &post(serde_json::json!({"op": "erode", "radius": 1, "kernel": "star"})),
        400,
        "invalid-parameter",
    );
    assert_problem(
        &post(serde_json::json!({"op": "dilate", "radius": 30, "grow": true})),
        422,
        "grid-too-large",
    );
    assert_problem(
        &srv.req(
            "POST",
            "/v1/volumes/nope/morphology",
            &[],
            br#"{"op":"erode","radius":1}"#,
        ),
        404,
        "not-found",
    );
}

/// Decodes an 8-bit grayscale PNG (checking every chunk's CRC): (width, height, pixels).
fn decode_png(b: &[u8]) -> (u32, u32, Vec<u8>) {
    assert_eq!(&b[..8], b"\x89PNG\r\n\x1a\n");
    let (mut pos, mut w, mut h, mut idat) = (8, 0, 0, Vec::new());
    loop {
        let len = u32::from_be_bytes(b[pos..pos + 4].try_into().unwrap()) as usize;
        let kind = &b[pos + 4..pos + 8];
        let data = &b[pos + 8..pos + 8 + len];
        let mut crc = flate2::Crc::new();
        crc.update(kind);
        crc.update(data);
        assert_eq!(
            crc.sum().to_be_bytes(),
            b[pos + 8 + len..pos + 12 + len],
            "CRC of {:?}",
            String::from_utf8_lossy(kind)
        );
        match kind {
            b"IHDR" => {
                w = u32::from_be_bytes(data[..4].try_into().unwrap());
                h = u32::from_be_bytes(data[4..8].try_into().unwrap());
                assert_eq!(&data[8..], &[8, 0, 0, 0, 0]);
            }
            b"IDAT" => idat.extend_from_slice(data),
            b"IEND" => break,
            _ => {}
        }
        pos += 12 + len;
    }
    let mut raw = Vec::new();
    flate2::read::ZlibDecoder::new(&idat[..])
        .read_to_end(&mut raw)
        .unwrap();
    assert_eq!(raw.len(), (h * (w + 1)) as usize);
    let pixels = raw
        .chunks(w as usize + 1)
        .flat_map(|r| {
            assert_eq!(r[0], 0);
            r[1..].to_vec()
        })
        .collect();
    (w, h, pixels)
}

#[test]
fn preview_pictures() {
    let srv = Server::start(&tmpdir("preview"), &[]);
    let r = srv.req(
        "POST",
        "/v1/voxelize?origin=0,0,0&voxel_size=1&dims=12,10,8&wait=60",
        &[("Content-Type", "model/obj")],
        &box_obj([2.0, 3.0, 1.0], [6.0, 9.0, 4.0]),
    );
    let id = r.json()["id"].as_str().unwrap().to_string();
    let png = srv.req(
        "GET",
        &format!("/v1/volumes/{id}/preview.png?axis=z&slice=2"),
        &[],
        &[],
    );
    assert_eq!(png.header("content-type"), Some("image/png"));
    let (w, h, px) = decode_png(&png.body);
    assert_eq!((w, h), (12, 10));
    // Row 0 is the top (y = 9): the box covers x 2..6, y 3..9 on slice z = 2.
    for (i, &p) in px.iter().enumerate() {
        let (x, y) = (i as u32 % w, h - 1 - i as u32 / w);
        assert_eq!(
            p,
            if (2..6).contains(&x) && (3..9).contains(&y) {
                255
            } else {
                0
            },
            "pixel ({x},{y})"
        );
    }
    let (w, h, px) = decode_png(
        &srv.req(
            "GET",
            &format!("/v1/volumes/{id}/preview.png?axis=x&projection=sum"),
            &[],
            &[],
        )
        .body,
    );
    assert_eq!((w, h), (10, 8));
    assert_eq!(px.iter().filter(|&&p| p == 255).count(), 6 * 3);
    assert_problem(
        &srv.req(
            "GET",
            &format!("/v1/volumes/{id}/preview.png?slice=99"),
            &[],
            &[],
        ),
        404,
        "not-found",
    );
    assert_problem(
        &srv.req(
            "GET",
            &format!("/v1/volumes/{id}/preview.png?axis=w"),
            &[],
            &[],
        ),
        400,
        "invalid-parameter",
    );
}

/// `--job-timeout`: a job that runs past it is stopped and fails with a problem naming the
/// timeout; nothing is stored.
#[test]
fn a_job_past_its_deadline_fails_with_the_timeout_problem() {
    let srv = Server::start(&tmpdir("job-timeout"), &["--job-timeout", "0.000001"]);
    let spot = std::fs::read(data("spot.obj")).unwrap();
    let r = srv.req(
        "POST",
        "/v1/voxelize?resolution=64&fill=winding&wait=60",
        &[("Content-Type", "model/obj")],
        &spot,
    );
    let p = assert_problem(&r, 408, "timeout");
    let detail = p["detail"].as_str().unwrap();
    assert!(
        detail.contains("the job ran longer than --job-timeout (0.000001 s)"),
        "{p}"
    );
    let job = p["instance"].as_str().unwrap().to_string();
    let j = srv.req("GET", &job, &[], &[]).json();
    assert_eq!(j["state"], "failed", "{j}");
    assert_eq!(j["problem"]["detail"].as_str(), Some(detail), "{j}");
    assert!(j["progress"].as_f64().unwrap() < 1.0, "{j}");
    let list = srv.req("GET", "/v1/volumes", &[], &[]).json();
    assert_eq!(list["volumes"].as_array().unwrap().len(), 0, "{list}");
}

/// A service on the GPU engine (lavapipe in CI) with 4 workers: jobs posted at once all
/// succeed, and `/metrics` counts the slabs, the submissions they went in (never more than the
/// slabs) and the buffers the pool served. Skips without an adapter unless VOXD_REQUIRE_GPU=1.
#[test]
#[cfg(feature = "gpu")]
fn gpu_jobs_at_once_succeed_and_their_submissions_are_counted() {
    if crate::gpu::gpu().is_none() {
        return;
    }
    let srv = Server::start(
        &tmpdir("gpu-service"),
        &["--engine", "gpu", "--workers", "4"],
    );
    let spot = std::fs::read(data("spot.obj")).unwrap();
    let jobs = 12;
    std::thread::scope(|s| {
        let posts: Vec<_> = (0..jobs)
            .map(|_| {
                s.spawn(|| {
                    srv.req(
                        "POST",
                        "/v1/voxelize?resolution=24&wait=60",
                        &[("Content-Type", "model/obj")],
                        &spot,
                    )
                })
            })
            .collect();
        for p in posts {
            let r = p.join().unwrap();
            assert_eq!(r.status, 201, "{}", String::from_utf8_lossy(&r.body));
        }
    });
    let m = String::from_utf8(srv.req("GET", "/metrics", &[], &[]).body).unwrap();
    let value = |name: &str| -> u64 {
        m.lines()
            .find_map(|l| l.strip_prefix(name)?.strip_prefix(' ')?.parse().ok())
            .unwrap_or_else(|| panic!("{name} missing from\n{m}"))
    };
    // One slab per job at 24³ (and a few warm-up ones at start, if any).
    let slabs = value("voxd_gpu_slabs_total");
    assert!(slabs >= jobs, "{slabs}");
    let submissions = value("voxd_gpu_submissions_total");
    assert!(
        (1..=slabs).contains(&submissions),
        "{submissions} of {slabs}"
    );
    assert!(value("voxd_gpu_buffers_reused_total") > 0);
    assert!(value("voxd_gpu_pool_idle_bytes") > 0);
    assert!(m.contains(&format!(
        "voxd_jobs{{state=\"succeeded\",method=\"solid\"}} {jobs}"
    )));
    assert!(m.contains("voxd_engine_info{engine=\"gpu ("), "{m}");
}
