//! Jobs over HTTP: submission in every upload format and download in every volume format,
//! polling, waiting, cancelling and caching, a full queue, concurrent clients, a restart with
//! SIGTERM, deadlines and the GPU engine.
//!
//! Not here: the error documents and the OpenAPI contract (`contract`), the volume operations
//! (`ops`).

use super::*;

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
    assert_eq!(
        d.header("content-disposition"),
        Some("attachment; filename=\"spot.npy\"")
    );
    let etag = d.header("etag").unwrap().to_string();
    let again = srv.req(
        "GET",
        &format!("/v1/volumes/{vid}/data?format=npy"),
        &[("Accept-Encoding", "gzip"), ("If-None-Match", &etag)],
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
#[cfg(feature = "gpu")]
#[test]
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
