//! `voxd serve --store s3://…` end to end against a real S3 server: two processes on one
//! bucket, wrong credentials, the store going away mid-operation, a put interrupted after its
//! data, damage that must never download whole. The store's own contract is in `super`.

use super::*;

struct Server {
    child: Child,
    addr: String,
}

impl Server {
    /// `voxd serve --store s3://voxd/PREFIX` with the server's credentials (or `vars`).
    fn start(vars: &[(String, String)], prefix: &str, extra: &[(&str, &str)]) -> Server {
        match Server::try_start(vars, prefix, extra) {
            Ok(s) => s,
            Err((status, err)) => panic!("voxd serve did not start ({status}): {err}"),
        }
    }

    /// The server, or its exit status and stderr when it refused to start.
    fn try_start(
        vars: &[(String, String)],
        prefix: &str,
        env: &[(&str, &str)],
    ) -> Result<Server, (std::process::ExitStatus, String)> {
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_voxd"));
        cmd.args([
            "serve",
            "--addr",
            "127.0.0.1:0",
            "--store",
            &format!("s3://{BUCKET}/{prefix}"),
            "--engine",
            "cpu",
        ])
        .env("VOXD_LOG", "warn")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
        for (k, v) in vars {
            cmd.env(k, v);
        }
        for (k, v) in env {
            cmd.env(k, v);
        }
        let mut child = cmd.spawn().unwrap();
        let mut line = String::new();
        BufReader::new(child.stdout.take().unwrap())
            .read_line(&mut line)
            .unwrap();
        let stderr = child.stderr.take().unwrap();
        match line.trim().strip_prefix("voxd listening on http://") {
            Some(addr) => {
                // Keep stderr flowing (to the test's) so the server never blocks on it.
                std::thread::spawn(move || {
                    let mut r = BufReader::new(stderr);
                    let mut l = String::new();
                    while r.read_line(&mut l).is_ok_and(|n| n > 0) {
                        eprint!("voxd: {l}");
                        l.clear();
                    }
                });
                Ok(Server {
                    child,
                    addr: addr.to_string(),
                })
            }
            None => {
                let mut err = String::new();
                let _ = BufReader::new(stderr).read_to_string(&mut err);
                let status = child.wait().unwrap();
                Err((status, err))
            }
        }
    }

    fn req(&self, method: &str, path: &str, headers: &[(&str, &str)], body: &[u8]) -> Resp {
        request(&self.addr, method, path, headers, body)
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn ids(listing: &Value) -> Vec<String> {
    listing["volumes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v["id"].as_str().unwrap().to_string())
        .collect()
}

const GRID: &str = "origin=-1,-1,-1&voxel_size=0.05&dims=40,40,44";

#[test]
fn two_replicas_on_one_bucket_answer_for_each_others_volumes() {
    let Some(weed) = s3::shared() else { return };
    let prefix = s3::prefix("serve");
    let a = Server::start(&weed.vars(), &prefix, &[]);
    let b = Server::start(&weed.vars(), &prefix, &[]);
    let spot = std::fs::read(data("spot.obj")).unwrap();
    // A real mesh through A, fetched through B: the library's bits, the same ETag on both.
    let t = Instant::now();
    let made = a
        .req(
            "POST",
            "/v1/voxelize?resolution=48&wait=60&name=spot",
            &[("Content-Type", "model/obj")],
            &spot,
        )
        .ok(201)
        .json();
    eprintln!(
        "voxelize spot at 48 through A (S3 store): {:?}",
        t.elapsed()
    );
    let id = made["id"].as_str().unwrap();
    assert_eq!(
        ids(&b.req("GET", "/v1/volumes", &[], &[]).ok(200).json()),
        [id]
    );
    assert_eq!(
        b.req("GET", &format!("/v1/volumes/{id}"), &[], &[])
            .ok(200)
            .json(),
        made
    );
    let da = a
        .req("GET", &format!("/v1/volumes/{id}/data"), &[], &[])
        .ok(200);
    let t = Instant::now();
    let db = b
        .req("GET", &format!("/v1/volumes/{id}/data"), &[], &[])
        .ok(200);
    eprintln!(
        "download of {} bytes through B: {:?}",
        db.body.len(),
        t.elapsed()
    );
    assert_eq!(da.body, db.body);
    let etag = da.headers.get("etag").expect("an ETag");
    assert_eq!(db.headers.get("etag"), Some(etag));
    let want = voxelize_file(
        &data("spot.obj"),
        GridSpec::Resolution {
            n: 48,
            cubic: false,
        },
        0,
        Method::Solid,
    );
    assert_eq!(decode_bits(&db.body).words(), want.words());
    let cached = b.req(
        "GET",
        &format!("/v1/volumes/{id}/data"),
        &[("If-None-Match", etag)],
        &[],
    );
    assert_eq!(cached.status, 304);
    // CSG between volumes made on different replicas, on one explicit grid.
    let va = a
        .req(
            "POST",
            &format!("/v1/voxelize?{GRID}&wait=60&name=spot"),
            &[("Content-Type", "model/obj")],
            &spot,
        )
        .ok(201)
        .json();
    let boxed = std::fs::read(data("Box.gltf")).unwrap();
    let vb = b
        .req(
            "POST",
            &format!("/v1/voxelize?{GRID}&wait=60&name=box"),
            &[("Content-Type", "model/gltf+json")],
            &boxed,
        )
        .ok(201)
        .json();
    let (ia, ib) = (va["id"].as_str().unwrap(), vb["id"].as_str().unwrap());
    let expr = format!("{{\"op\":\"difference\",\"operands\":[\"{ia}\",\"{ib}\"]}}");
    let diff = a
        .req("POST", "/v1/volumes/csg", &[], expr.as_bytes())
        .ok(201)
        .json();
    let inter = b
        .req(
            "POST",
            "/v1/volumes/intersect",
            &[],
            format!("{{\"a\":\"{ia}\",\"b\":\"{ib}\"}}").as_bytes(),
        )
        .ok(200)
        .json();
    assert_eq!(
        diff["solid_voxels"].as_u64().unwrap() + inter["voxels"].as_u64().unwrap(),
        va["solid_voxels"].as_u64().unwrap()
    );
    let dd = diff["id"].as_str().unwrap();
    let via_b = b
        .req("GET", &format!("/v1/volumes/{dd}/data"), &[], &[])
        .ok(200);
    assert_eq!(
        decode_bits(&via_b.body).count_ones(),
        diff["solid_voxels"].as_u64().unwrap()
    );
    // Both list the same four, paged alike; a delete on B is seen by A.
    let la = ids(&a.req("GET", "/v1/volumes?limit=3", &[], &[]).ok(200).json());
    let lb = ids(&b.req("GET", "/v1/volumes?limit=3", &[], &[]).ok(200).json());
    assert_eq!((la.len(), &la), (3, &lb));
    b.req("DELETE", &format!("/v1/volumes/{dd}"), &[], &[])
        .ok(204);
    a.req("GET", &format!("/v1/volumes/{dd}"), &[], &[])
        .problem(404, "not-found");
    a.req("GET", &format!("/v1/volumes/{dd}/data"), &[], &[])
        .problem(404, "not-found");
    let all = ids(&a.req("GET", "/v1/volumes", &[], &[]).ok(200).json());
    assert_eq!(all.len(), 3);
    assert!(!all.iter().any(|i| i == dd));
    let ready = b.req("GET", "/readyz", &[], &[]).ok(200).json();
    assert!(ready["stored_bytes"].as_u64().unwrap() > 0);
}

#[test]
fn wrong_credentials_or_a_missing_bucket_stop_serve_naming_the_bucket() {
    let Some(weed) = s3::shared() else { return };
    let (status, err) = Server::try_start(&weed.vars_with_secret("not-the-secret"), "x", &[])
        .err()
        .expect("voxd serve started with wrong credentials");
    assert!(!status.success());
    assert!(
        err.contains("\"voxd\"") && err.contains("credentials"),
        "{err}"
    );
    assert!(
        !err.contains("not-the-secret") && !err.contains(s3::SECRET_KEY),
        "{err}"
    );
    let mut cmd_vars = weed.vars();
    cmd_vars.push(("VOXD_STORE".into(), "s3://no-such-bucket/x".into()));
    // VOXD_STORE is overridden by --store; check the variable with a server of its own.
    let out = Command::new(env!("CARGO_BIN_EXE_voxd"))
        .args(["serve", "--addr", "127.0.0.1:0", "--engine", "cpu"])
        .envs(cmd_vars)
        .stdin(Stdio::null())
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("no-such-bucket"), "{err}");
}

#[test]
fn the_store_going_away_is_503_storage_unavailable_and_leaves_no_half_volume() {
    let Some(mut weed) = Weed::start("unavailable") else {
        return;
    };
    let srv = Server::start(&weed.vars(), "p", &[]);
    let spot = std::fs::read(data("spot.obj")).unwrap();
    let first = srv
        .req(
            "POST",
            "/v1/voxelize?resolution=24&wait=60",
            &[("Content-Type", "model/obj")],
            &spot,
        )
        .ok(201)
        .json();
    weed.kill();
    let t = Instant::now();
    let p = srv
        .req(
            "POST",
            "/v1/voxelize?resolution=24&wait=60",
            &[("Content-Type", "model/obj")],
            &spot,
        )
        .problem(503, "storage-unavailable");
    eprintln!("a job failing on a dead store: {:?}; {p}", t.elapsed());
    assert!(p["detail"].as_str().unwrap().contains("\"voxd\""), "{p}");
    srv.req("GET", "/v1/volumes", &[], &[])
        .problem(503, "storage-unavailable");
    let id = first["id"].as_str().unwrap();
    srv.req("GET", &format!("/v1/volumes/{id}/data"), &[], &[])
        .problem(503, "storage-unavailable");
    srv.req("GET", "/readyz", &[], &[])
        .problem(503, "storage-unavailable");
    weed.restart();
    // Back: only the first volume is there, and new work is stored again.
    let deadline = Instant::now() + Duration::from_secs(60);
    let listing = loop {
        let r = srv.req("GET", "/v1/volumes", &[], &[]);
        if r.status == 200 {
            break r.json();
        }
        assert!(Instant::now() < deadline, "the store did not come back");
        std::thread::sleep(Duration::from_millis(200));
    };
    assert_eq!(ids(&listing), [id]);
    srv.req(
        "POST",
        "/v1/voxelize?resolution=24&wait=60",
        &[("Content-Type", "model/obj")],
        &spot,
    )
    .ok(201);
    srv.req("GET", "/readyz", &[], &[]).ok(200);
    assert_eq!(
        ids(&srv.req("GET", "/v1/volumes", &[], &[]).ok(200).json()).len(),
        2
    );
}

/// A paused store (SIGSTOP: connections are taken, nothing is answered) makes `/readyz` answer
/// `503 storage-unavailable` once its cached health (30 s after the last good write) runs out,
/// each probe bounded by its timeout (2 s): every `/readyz` is answered meanwhile, none hangs.
/// Once the store goes on, `/readyz` is 200 again.
#[test]
fn readyz_answers_503_while_the_store_is_paused() {
    let Some(weed) = Weed::start("paused") else {
        return;
    };
    let srv = Server::start(&weed.vars(), "p", &[]);
    srv.req("GET", "/readyz", &[], &[]).ok(200);
    weed.pause(true);
    // Before, the probe hung with the store: the client's 120 s read timeout ended an
    // exchange with no answer (a panic in `req`). Now each is answered.
    let deadline = Instant::now() + Duration::from_secs(90);
    let (mut answered, mut slowest) = (0, Duration::ZERO);
    let r = loop {
        let t = Instant::now();
        let r = srv.req("GET", "/readyz", &[], &[]);
        slowest = slowest.max(t.elapsed());
        answered += 1;
        if r.status != 200 || Instant::now() > deadline {
            break r;
        }
        std::thread::sleep(Duration::from_millis(500));
    };
    weed.pause(false);
    r.problem(503, "storage-unavailable");
    eprintln!("readyz with the store paused: {answered} answered, the slowest in {slowest:?}");
    let deadline = Instant::now() + Duration::from_secs(60);
    while srv.req("GET", "/readyz", &[], &[]).status != 200 {
        assert!(
            Instant::now() < deadline,
            "/readyz not 200 after the store went on"
        );
        std::thread::sleep(Duration::from_millis(200));
    }
}

#[cfg(feature = "fault-injection")]
#[test]
fn a_replica_killed_between_data_and_commit_leaves_nothing_listed() {
    let Some(weed) = s3::shared() else { return };
    let prefix = s3::prefix("fault");
    let spot = std::fs::read(data("spot.obj")).unwrap();
    for fault in ["abort-mid-data", "abort-after-data"] {
        let srv = Server::start(&weed.vars(), &prefix, &[("VOXD_FAULT", fault)]);
        let r = http_exchange(
            &srv.addr,
            "POST",
            "/v1/voxelize?resolution=24&wait=60",
            &[("Content-Type", "model/obj")],
            &spot,
        );
        assert!(
            r.is_err(),
            "{fault}: the server answered {:?}",
            r.map(|r| r.0)
        );
        drop(srv);
    }
    // Another replica: nothing listed, though the data objects are in the bucket.
    let srv = Server::start(&weed.vars(), &prefix, &[]);
    let listing = srv.req("GET", "/v1/volumes", &[], &[]).ok(200).json();
    assert_eq!(ids(&listing), Vec::<String>::new());
    rt().block_on(async {
        let left = bytes_in_bucket(weed, &prefix).await;
        assert!(left > 0, "the interrupted puts left no data");
        let store = open(weed, &prefix, 1 << 30).await;
        // Each left its reservation and its (torn or whole) data.
        assert_eq!(store.sweep(Duration::ZERO).await.unwrap(), 4);
        // And the mesh they kept (before their data), one object for both, is left to the
        // kept meshes' sweep: their markers say a put may still be in progress for an hour.
        let kept = store.list_sources().await.unwrap();
        assert_eq!(kept.len(), 1, "{kept:?}");
        let mesh = store.get_source(&kept[0].0).await.unwrap().unwrap();
        assert_eq!(bytes_in_bucket(weed, &prefix).await, mesh.len() as u64);
        assert_eq!(voxd::app::sources::sweep(&store, Duration::ZERO).await, 0);
        assert!(store.source_referred(&kept[0].0).await.unwrap());
    });
}

#[test]
fn a_damaged_volume_never_downloads_whole() {
    let Some(weed) = s3::shared() else { return };
    let prefix = s3::prefix("download");
    let srv = Server::start(&weed.vars(), &prefix, &[]);
    let spot = std::fs::read(data("spot.obj")).unwrap();
    let mut ids = vec![];
    for _ in 0..2 {
        let v = srv
            .req(
                "POST",
                "/v1/voxelize?resolution=64&wait=60",
                &[("Content-Type", "model/obj")],
                &spot,
            )
            .ok(201)
            .json();
        ids.push(v["id"].as_str().unwrap().to_string());
    }
    let good = srv
        .req("GET", &format!("/v1/volumes/{}/data", ids[0]), &[], &[])
        .ok(200);
    assert_eq!(
        good.headers.get("content-length").map(String::as_str),
        Some(good.body.len().to_string().as_str())
    );
    rt().block_on(async {
        let client = weed.client();
        let key = |id: &str| Key::from(format!("{prefix}/volumes/{id}.vxl"));
        // A byte flipped: the transfer breaks before its end (fewer bytes than announced).
        let mut bad = good.body.clone();
        bad[10] ^= 1;
        client
            .put(&key(&ids[0]), Bytes::from(bad).into())
            .await
            .unwrap();
        // Cut short: refused before anything is sent.
        let b = client
            .get(&key(&ids[1]))
            .await
            .unwrap()
            .bytes()
            .await
            .unwrap();
        client
            .put(&key(&ids[1]), b.slice(..b.len() / 2).into())
            .await
            .unwrap();
    });
    let r = http_exchange(
        &srv.addr,
        "GET",
        &format!("/v1/volumes/{}/data", ids[0]),
        &[],
        &[],
    );
    assert!(
        r.as_ref().is_err() || r.as_ref().is_ok_and(|r| r.0 != 200),
        "a damaged volume downloaded whole: {:?}",
        r.map(|r| (r.0, r.2.len()))
    );
    srv.req("GET", &format!("/v1/volumes/{}/data", ids[1]), &[], &[])
        .problem(500, "internal");
}
