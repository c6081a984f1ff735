//! Crash safety, end to end: the real `voxd serve` on 127.0.0.1 (ephemeral port) is killed with
//! SIGKILL during uploads, during a running job and, with the `fault-injection` feature, by an
//! abort inside a store write (`VOXD_FAULT`, src/store/fs.rs), round after round on one data
//! directory. After every restart:
//!
//! - no temporary file (a name starting with `.`) is left in `volumes/` or `jobs/`, and every
//!   `{id}.vxl` has its `{id}.json` and the other way round, and no pack ends in a torn record
//!   (read by the test's own reader of the pack format);
//! - the volumes listed by `GET /v1/volumes` (paged) are exactly those on disk; each downloads,
//!   its length, sha256 and ETag agree with its metadata, and it decodes to its grid;
//! - every volume the service acknowledged (a `201`, a job seen succeeded) is still there unless
//!   this test deleted it, and a volume whose delete was answered is gone;
//! - every job id the service answered with is known and terminal (succeeded, failed, canceled),
//!   queued, or running again (a job answered `202` is kept and run again after a restart), and
//!   a succeeded job's volume exists;
//! - `/readyz`'s `stored_bytes` is the sum of the sizes of the volume files in `volumes/`, of
//!   the live records in its packs and of the kept meshes in `sources/`.
//!
//! The kill points are drawn from a seeded generator (`VOXD_CRASH_SEED`, `VOXD_CRASH_ROUNDS`
//! for longer runs on demand). Loopback only, every loop bounded; timeouts are safety bounds,
//! never assertions.

use std::collections::{BTreeMap, BTreeSet};
use std::os::unix::process::ExitStatusExt;
use std::path::Path;
use std::process::Command;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use crate::common::{Resp, Rng, data, tmpdir};
use serde_json::{Value, json};

mod server;
use server::{SIGABRT, SIGKILL, Server, request, try_wait_exit, wait_exit};

/// One aligned grid for the uploads that CSG combines (spot and the unit box fit in it).
const GRID: &str = "origin=-1,-1,-1&voxel_size=0.05&dims=40,40,44";

/// What the service told this test, across all rounds.
#[derive(Default)]
struct Known {
    /// Job ids from `202` answers.
    jobs: BTreeSet<String>,
    /// Volumes acknowledged as stored: `201` answers and the volumes of jobs seen succeeded.
    acked: BTreeSet<String>,
    /// Jobs seen succeeded (job → volume) before a kill.
    succeeded: BTreeMap<String, String>,
    /// Volumes whose delete was sent (answered or not) and those whose delete was answered.
    delete_sent: BTreeSet<String>,
    deleted: BTreeSet<String>,
    /// Jobs seen succeeded and found failed after a restart (reported, not failed on).
    regressed: usize,
    /// 5xx answers during the workloads (the service must not give any).
    server_errors: Vec<String>,
}

impl Known {
    /// Records what a request's answer says.
    fn note(&mut self, what: &str, r: &std::io::Result<Resp>) {
        let Ok(r) = r else { return };
        if r.status >= 500 {
            let body = String::from_utf8_lossy(&r.body);
            self.server_errors
                .push(format!("{what}: {} {body}", r.status));
        }
        let Some(v) = r.try_json() else { return };
        let id = v["id"].as_str().map(str::to_string);
        match (r.status, id) {
            (202, Some(id)) if what.starts_with("POST /v1/voxelize") => {
                self.jobs.insert(id);
            }
            (201, Some(id)) => {
                self.acked.insert(id);
            }
            _ => {}
        }
        if what.starts_with("GET /v1/jobs/")
            && v["state"] == "succeeded"
            && let (Some(j), Some(vol)) = (v["id"].as_str(), v["volume_id"].as_str())
        {
            self.succeeded.insert(j.into(), vol.into());
            self.acked.insert(vol.into());
        }
    }
}

/// Meshes the workload uploads: (content type, bytes).
struct Meshes {
    spot: Vec<u8>,
    boxm: Vec<u8>,
    fox: Vec<u8>,
}

impl Meshes {
    fn load() -> Meshes {
        Meshes {
            spot: std::fs::read(data("spot.obj")).unwrap(),
            boxm: std::fs::read(data("Box.gltf")).unwrap(),
            fox: std::fs::read(data("Fox.glb")).unwrap(),
        }
    }
}

/// One step of a workload, drawn from `rng`: an upload (aligned grid or by resolution, with or
/// without wait), a CSG union of two stored volumes, a delete, a cancel, or a job poll.
fn step(srv_addr: &str, rng: &mut Rng, meshes: &Meshes, known: &Mutex<Known>) -> bool {
    let pick = |set: &BTreeSet<String>, rng: &mut Rng| -> Option<String> {
        (!set.is_empty()).then(|| {
            set.iter()
                .nth(rng.below(set.len() as u64) as usize)
                .unwrap()
                .clone()
        })
    };
    let wait = if rng.below(2) == 0 { "&wait=30" } else { "" };
    let (what, path, ctype, body): (String, String, &str, Vec<u8>) = match rng.below(10) {
        0..=2 => {
            let (ct, b) = if rng.below(2) == 0 {
                ("model/obj", &meshes.spot)
            } else {
                ("model/gltf+json", &meshes.boxm)
            };
            let p = format!("/v1/voxelize?{GRID}{wait}");
            (format!("POST {p}"), p, ct, b.clone())
        }
        3..=4 => {
            let res = 12 + rng.below(40);
            let (ct, b) = if rng.below(2) == 0 {
                ("model/obj", &meshes.spot)
            } else {
                ("model/gltf-binary", &meshes.fox)
            };
            let p = format!("/v1/voxelize?resolution={res}&method=conservative{wait}");
            (format!("POST {p}"), p, ct, b.clone())
        }
        5 => {
            // Grids that CSG can combine: the aligned uploads (their dims say so).
            let k = known.lock().unwrap();
            let a = pick(&k.acked, rng);
            let b = pick(&k.acked, rng);
            drop(k);
            let (Some(a), Some(b)) = (a, b) else {
                return true;
            };
            let body = json!({"op": "union", "operands": [a, b]})
                .to_string()
                .into_bytes();
            let p = "/v1/volumes/csg?name=crash-union".to_string();
            (format!("POST {p}"), p, "application/json", body)
        }
        6 => {
            let mut k = known.lock().unwrap();
            let Some(v) = pick(&k.acked, rng) else {
                return true;
            };
            k.delete_sent.insert(v.clone());
            drop(k);
            let p = format!("/v1/volumes/{v}");
            let r = request(srv_addr, "DELETE", &p, "", b"");
            if r.as_ref().is_ok_and(|r| r.status == 204) {
                known.lock().unwrap().deleted.insert(v);
            }
            known.lock().unwrap().note(&format!("DELETE {p}"), &r);
            return r.is_ok();
        }
        7 => {
            let Some(j) = pick(&known.lock().unwrap().jobs, rng) else {
                return true;
            };
            let p = format!("/v1/jobs/{j}");
            (format!("DELETE {p}"), p, "", vec![])
        }
        _ => {
            let Some(j) = pick(&known.lock().unwrap().jobs, rng) else {
                return true;
            };
            let p = format!("/v1/jobs/{j}");
            let r = request(srv_addr, "GET", &p, "", b"");
            known.lock().unwrap().note(&format!("GET {p}"), &r);
            return r.is_ok();
        }
    };
    let method = what.split(' ').next().unwrap().to_string();
    let r = request(srv_addr, &method, &path, ctype, &body);
    // CSG over grids that do not line up (a resolution upload) is refused: that is fine.
    if what.contains("/csg") && r.as_ref().is_ok_and(|r| r.status == 422) {
        return true;
    }
    known.lock().unwrap().note(&what, &r);
    r.is_ok()
}

/// Runs `threads` clients of up to `steps` steps each against `srv` and SIGKILLs it once
/// `kill_after` answers have come back (or when the clients are done).
fn kill_during_traffic(
    srv: &mut Server,
    rng: &mut Rng,
    meshes: &Arc<Meshes>,
    known: &Arc<Mutex<Known>>,
    threads: u64,
    steps: u64,
    kill_after: usize,
) {
    let answered = Arc::new(AtomicUsize::new(0));
    let stop = Arc::new(AtomicBool::new(false));
    let clients: Vec<_> = (0..threads)
        .map(|_| {
            let (addr, meshes, known) = (srv.addr.clone(), meshes.clone(), known.clone());
            let (answered, stop) = (answered.clone(), stop.clone());
            let mut rng = Rng::new(rng.next());
            std::thread::spawn(move || {
                for _ in 0..steps {
                    if stop.load(Ordering::SeqCst) || !step(&addr, &mut rng, &meshes, &known) {
                        break;
                    }
                    answered.fetch_add(1, Ordering::SeqCst);
                }
            })
        })
        .collect();
    let deadline = Instant::now() + Duration::from_secs(300);
    while answered.load(Ordering::SeqCst) < kill_after && !clients.iter().all(|c| c.is_finished()) {
        assert!(Instant::now() < deadline, "the workload did not progress");
        std::thread::sleep(Duration::from_millis(1));
    }
    srv.child.kill().unwrap();
    let status = wait_exit(&mut srv.child, "SIGKILL");
    stop.store(true, Ordering::SeqCst);
    for c in clients {
        c.join().unwrap();
    }
    assert_eq!(status.signal(), Some(SIGKILL), "{status:?}");
}

/// Starts a job big enough to be seen running, queues small ones behind it, SIGKILLs the server
/// while it runs.
fn kill_during_job(srv: &mut Server, rng: &mut Rng, meshes: &Meshes, known: &Mutex<Known>) {
    let res = 120 + rng.below(60);
    let p = format!("/v1/voxelize?resolution={res}&fill=winding");
    let r = srv.req("POST", &p, "model/obj", &meshes.spot);
    known.lock().unwrap().note(&format!("POST {p}"), &r);
    let job = r
        .ok()
        .and_then(|r| r.try_json())
        .and_then(|v| v["id"].as_str().map(str::to_string));
    let job = job.expect("the big job was accepted");
    for _ in 0..rng.below(3) {
        let p = format!("/v1/voxelize?{GRID}");
        let r = srv.req("POST", &p, "model/obj", &meshes.spot);
        known.lock().unwrap().note(&format!("POST {p}"), &r);
    }
    // Bounded poll until it runs (or already finished: then the kill lands between jobs).
    let mut seen = Value::Null;
    for _ in 0..20_000 {
        let p = format!("/v1/jobs/{job}");
        let r = srv.req("GET", &p, "", b"");
        known.lock().unwrap().note(&format!("GET {p}"), &r);
        seen = r
            .ok()
            .and_then(|r| r.try_json())
            .map(|v| v["state"].clone())
            .unwrap_or_default();
        if seen != "queued" {
            break;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    std::thread::sleep(Duration::from_millis(rng.below(50)));
    srv.child.kill().unwrap();
    let status = wait_exit(&mut srv.child, "SIGKILL");
    assert_eq!(status.signal(), Some(SIGKILL), "{status:?}");
    eprintln!("crash: killed with job {job} ({res}³ winding) last seen {seen}");
}

/// Sends one client's traffic until the armed fault aborts the server.
fn abort_by_fault(
    srv: &mut Server,
    rng: &mut Rng,
    meshes: &Meshes,
    known: &Mutex<Known>,
    fault: &str,
) {
    // Mixed traffic first (the fault may fire in any of its writes).
    for _ in 0..40 {
        if !step(&srv.addr, rng, meshes, known) {
            break;
        }
    }
    // Then uploads that each put a volume (and write job records) until the fault fires: a
    // request that fails is the server gone. Bounded: N is at most 3.
    for _ in 0..100 {
        let p = format!("/v1/voxelize?{GRID}&wait=30");
        let r = srv.req("POST", &p, "model/obj", &meshes.spot);
        if r.is_err() {
            break;
        }
        known.lock().unwrap().note(&format!("POST {p}"), &r);
    }
    // The fault fired during the traffic above (the server is gone) or never will.
    let Some(status) = try_wait_exit(&mut srv.child, 30) else {
        panic!("VOXD_FAULT={fault} never fired: the server is still up after the workload");
    };
    assert_eq!(
        status.signal(),
        Some(SIGABRT),
        "VOXD_FAULT={fault} did not abort the server: {status:?}"
    );
}

/// Files of `dir` (name → size).
fn files(dir: &Path) -> BTreeMap<String, u64> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| {
            let e = e.unwrap();
            (
                e.file_name().into_string().unwrap(),
                e.metadata().unwrap().len(),
            )
        })
        .collect()
}

/// The volume packs of `dir` (`volumes/*.pack`), read by this test's own reader of the record
/// format (src/store/packs.rs's table): the live volumes (id → record bytes) and whether some
/// pack ends in bytes that are not a whole, valid record (a torn tail).
fn packs(dir: &Path) -> (BTreeMap<String, u64>, bool) {
    let mut puts = BTreeMap::new();
    let mut removed = BTreeSet::new();
    let mut torn = false;
    for (name, _) in files(dir) {
        if !name.ends_with(".pack") {
            continue;
        }
        let b = std::fs::read(dir.join(&name)).unwrap();
        let mut at = 0usize;
        while b.len() - at >= 32 {
            let h = &b[at..at + 32];
            let id_len = u32::from_le_bytes(h[8..12].try_into().unwrap()) as usize;
            let meta_len = u32::from_le_bytes(h[12..16].try_into().unwrap()) as usize;
            let data_len = u64::from_le_bytes(h[16..24].try_into().unwrap()) as usize;
            let end = at + 32 + id_len + meta_len + data_len;
            if &h[..4] != b"VXP1" || h[4] > 1 || id_len > 128 || end > b.len() {
                break;
            }
            let mut hashed = h[..24].to_vec();
            hashed.extend_from_slice(&b[at + 32..at + 32 + id_len + meta_len]);
            let want: String = h[24..32].iter().map(|x| format!("{x:02x}")).collect();
            if voxd::app::sha256_hex(&hashed)[..16] != want {
                break;
            }
            let id = String::from_utf8(b[at + 32..at + 32 + id_len].to_vec()).unwrap();
            if h[4] == 0 {
                let data = &b[end - data_len..end];
                let meta: Value =
                    serde_json::from_slice(&b[at + 32 + id_len..end - data_len]).unwrap();
                if meta["sha256"].as_str() != Some(&voxd::app::sha256_hex(data)) {
                    break;
                }
                puts.insert(id, (end - at) as u64);
            } else {
                removed.insert(id);
            }
            at = end;
        }
        torn |= at < b.len();
    }
    puts.retain(|id, _| !removed.contains(id));
    (puts, torn)
}

/// Waits (120 s at most) until every job answered for is final: a restart runs kept jobs again.
/// False when the server died meanwhile (an armed fault fired during such a run).
fn settle(srv: &mut Server, known: &Known) -> bool {
    let deadline = Instant::now() + Duration::from_secs(120);
    loop {
        if srv.child.try_wait().ok().flatten().is_some() {
            return false;
        }
        let pending =
            known.jobs.iter().any(
                |j| match srv.req("GET", &format!("/v1/jobs/{j}"), "", b"") {
                    Ok(r) => r
                        .try_json()
                        .is_some_and(|v| v["state"] == "queued" || v["state"] == "running"),
                    Err(_) => true,
                },
            );
        if !pending {
            return true;
        }
        assert!(Instant::now() < deadline, "kept jobs still run after 120 s");
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Every check of a restarted server on `dir` once its kept jobs have run again (before any new
/// write of the test's).
fn check(srv: &Server, dir: &Path, known: &mut Known, round: usize) {
    let vols = files(&dir.join("volumes"));
    let jobs = files(&dir.join("jobs"));
    for name in vols.keys().chain(jobs.keys()) {
        assert!(
            !name.starts_with('.'),
            "round {round}: temporary file {name} left after restart"
        );
    }
    let stem = |n: &str, ext: &str| n.strip_suffix(ext).map(str::to_string);
    let data: BTreeSet<String> = vols.keys().filter_map(|n| stem(n, ".vxl")).collect();
    let metas: BTreeSet<String> = vols.keys().filter_map(|n| stem(n, ".json")).collect();
    assert_eq!(data, metas, "round {round}: a volume file without its pair");
    let (packed, torn) = packs(&dir.join("volumes"));
    assert!(
        !torn,
        "round {round}: a pack's torn end was not cut off at open"
    );
    let mut stored: BTreeSet<String> = metas.clone();
    for id in packed.keys() {
        assert!(
            stored.insert(id.clone()),
            "round {round}: {id} is in a pack and in files"
        );
    }
    // Paged listing.
    let mut listed = vec![];
    let mut next = Some("/v1/volumes?limit=3".to_string());
    for _ in 0..10_000 {
        let Some(page) = next.take() else { break };
        let r = srv.must("GET", &page, b"");
        assert_eq!(r.status, 200);
        let v = r.try_json().unwrap();
        listed.extend(v["volumes"].as_array().unwrap().iter().cloned());
        next = v["next"].as_str().map(str::to_string);
    }
    assert!(next.is_none(), "round {round}: listing did not end");
    let ids: Vec<String> = listed
        .iter()
        .map(|v| v["id"].as_str().unwrap().to_string())
        .collect();
    assert!(
        ids.windows(2).all(|w| w[0] < w[1]),
        "round {round}: list not in id order: {ids:?}"
    );
    let ids: BTreeSet<String> = ids.into_iter().collect();
    assert_eq!(
        ids, stored,
        "round {round}: listed volumes differ from those on disk"
    );
    // Each volume reads back whole.
    for v in &listed {
        let id = v["id"].as_str().unwrap();
        let meta = srv
            .must("GET", &format!("/v1/volumes/{id}"), b"")
            .try_json()
            .unwrap();
        let sha = meta["sha256"].as_str().unwrap();
        let r = srv.must("GET", &format!("/v1/volumes/{id}/data"), b"");
        assert_eq!(
            r.status,
            200,
            "round {round}: volume {id}: {}",
            String::from_utf8_lossy(&r.body)
        );
        assert_eq!(
            r.body.len() as u64,
            meta["bytes"].as_u64().unwrap(),
            "round {round}: {id}"
        );
        assert_eq!(
            voxd::app::sha256_hex(&r.body),
            sha,
            "round {round}: volume {id}"
        );
        let etag = r.headers.get("etag").map(String::as_str).unwrap_or("");
        assert!(
            etag.contains(&sha[..16]),
            "round {round}: {id}: ETag {etag} for sha256 {sha}"
        );
        let (vol, _) = voxd::codec::vxl::decode(&r.body)
            .unwrap_or_else(|e| panic!("round {round}: volume {id} does not decode: {e}"));
        assert_eq!(
            json!(vol.grid().dims),
            meta["grid"]["dims"],
            "round {round}: volume {id}"
        );
    }
    // Nothing acknowledged is lost; nothing deleted comes back.
    for v in &known.acked {
        assert!(
            ids.contains(v) || known.delete_sent.contains(v),
            "round {round}: acknowledged volume {v} was lost"
        );
    }
    for v in &known.deleted {
        assert!(
            !ids.contains(v),
            "round {round}: deleted volume {v} came back"
        );
    }
    // Every job answered for is known, and terminal or queued.
    let mut regressed = vec![];
    for j in &known.jobs {
        let r = srv.must("GET", &format!("/v1/jobs/{j}"), b"");
        assert_eq!(
            r.status,
            200,
            "round {round}: job {j} was lost: {}",
            String::from_utf8_lossy(&r.body)
        );
        let v = r.try_json().unwrap();
        let state = v["state"].as_str().unwrap();
        // Running: a kept job queued or interrupted at the kill, run again since the restart.
        assert!(
            ["succeeded", "failed", "canceled", "queued", "running"].contains(&state),
            "round {round}: job {j} is {state} after a restart"
        );
        if state == "succeeded" {
            let vol = v["volume_id"].as_str().unwrap();
            // A job run again since the restart may have ended after the listing.
            let there = ids.contains(vol)
                || known.delete_sent.contains(vol)
                || srv.must("GET", &format!("/v1/volumes/{vol}"), b"").status == 200;
            assert!(
                there,
                "round {round}: job {j} succeeded but its volume {vol} is gone"
            );
        } else if let Some(vol) = known.succeeded.get(j) {
            regressed.push((
                j.clone(),
                format!("{j} (volume {vol}): was seen succeeded, is now {state}"),
            ));
        }
    }
    for (j, _) in &regressed {
        known.succeeded.remove(j);
        known.regressed += 1;
    }
    let regressed: Vec<String> = regressed.into_iter().map(|(_, m)| m).collect();
    if !regressed.is_empty() {
        // The queue publishes a finished job before its record is durable (src/queue/local.rs,
        // `finish`): a kill in between loses the state change, never the volume (checked above).
        eprintln!("NOTICE: crash round {round}: job states regressed: {regressed:?}");
    }
    // The quota counts every byte stored: volume files, live pack records and kept meshes
    // (`sources/`, temporaries of interrupted writes aside: removed at open).
    let kept: u64 = files(&dir.join("sources"))
        .iter()
        .filter(|(n, _)| !n.starts_with('.'))
        .map(|(_, len)| len)
        .sum();
    let on_disk: u64 = vols
        .iter()
        .filter(|(n, _)| n.ends_with(".vxl") || n.ends_with(".json"))
        .map(|(_, len)| len)
        .sum::<u64>()
        + packed.values().sum::<u64>()
        + kept;
    let ready = srv.must("GET", "/readyz", b"");
    assert_eq!(
        ready.status,
        200,
        "{}",
        String::from_utf8_lossy(&ready.body)
    );
    assert_eq!(
        ready.try_json().unwrap()["stored_bytes"].as_u64(),
        Some(on_disk),
        "round {round}: stored_bytes against the files in volumes/ and sources/"
    );
    eprintln!(
        "crash round {round}: {} volumes ({on_disk} bytes), {} jobs checked",
        ids.len(),
        known.jobs.len()
    );
}

#[test]
fn sigkill_and_aborts_inside_writes_lose_nothing_acknowledged() {
    let seed = std::env::var("VOXD_CRASH_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0x5eed_c4a5);
    let rounds: usize = std::env::var("VOXD_CRASH_ROUNDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(12);
    let faults = cfg!(feature = "fault-injection");
    if !faults {
        eprintln!(
            "NOTICE: built without the fault-injection feature: the crash test kills with SIGKILL \
             only (no aborts inside store writes); `cargo test --features fault-injection` runs them"
        );
    }
    eprintln!("crash test: seed {seed}, {rounds} rounds");
    let dir = tmpdir("crash");
    let mut rng = Rng::new(seed);
    let meshes = Arc::new(Meshes::load());
    let known = Arc::new(Mutex::new(Known::default()));
    const SITES: [&str; 4] = ["after-data", "mid-data", "mid-job-record", "after-commit"];
    for round in 0..rounds {
        // Kinds in turn: traffic, a job, then (with the feature) one fault site after another.
        let kind = round % 4;
        let site = SITES[(round / 4 * 2 + kind.saturating_sub(2)) % SITES.len()];
        let fault = (faults && kind >= 2).then(|| format!("abort-{site}:{}", 1 + rng.below(3)));
        let Some(mut srv) = Server::start(&dir, fault.as_deref()) else {
            eprintln!("crash round {round}: {fault:?} fired while the server recovered");
            continue;
        };
        if !settle(&mut srv, &known.lock().unwrap()) {
            eprintln!("crash round {round}: {fault:?} fired while kept jobs ran again");
            continue;
        }
        check(&srv, &dir, &mut known.lock().unwrap(), round);
        match (kind, &fault) {
            (_, Some(f)) => {
                abort_by_fault(&mut srv, &mut rng, &meshes, &known, f);
                // The abort left what that site leaves, for the restart to cope with.
                let vols = files(&dir.join("volumes"));
                let temp = |d: &BTreeMap<String, u64>| d.keys().any(|n| n.starts_with('.'));
                let orphan = vols.keys().any(|n| {
                    n.strip_suffix(".vxl")
                        .is_some_and(|id| !vols.contains_key(&format!("{id}.json")))
                });
                let (_, torn) = packs(&dir.join("volumes"));
                let packed = vols.keys().any(|n| n.ends_with(".pack"));
                match site {
                    // Small volumes go to packs: half a group's records, or half a file.
                    "mid-data" => assert!(
                        temp(&vols) || torn,
                        "no temporary .vxl and no torn pack after {f}"
                    ),
                    "mid-job-record" => {
                        let log = std::fs::read(dir.join("jobs/records.log")).unwrap();
                        assert!(
                            log.last().is_some_and(|&b| b != b'\n'),
                            "no torn line at the end of jobs/records.log after {f}"
                        )
                    }
                    // A pack's records written, not yet synced (nothing to see on disk).
                    "after-data" => assert!(
                        orphan || packed,
                        "no uncommitted .vxl and no pack after {f}"
                    ),
                    _ => {}
                }
            }
            (1, None) => kill_during_job(&mut srv, &mut rng, &meshes, &known),
            _ => {
                let kill_after = 2 + rng.below(30) as usize;
                kill_during_traffic(&mut srv, &mut rng, &meshes, &known, 3, 16, kill_after)
            }
        }
        let how = fault.as_deref().unwrap_or(if kind == 1 {
            "during a job"
        } else {
            "during traffic"
        });
        eprintln!("crash round {round}: killed ({how})");
    }
    // The last restart is checked too, and the server still works and stops cleanly.
    let mut srv = Server::start(&dir, None).unwrap();
    assert!(settle(&mut srv, &known.lock().unwrap()), "the server died");
    check(&srv, &dir, &mut known.lock().unwrap(), rounds);
    let r = srv
        .req(
            "POST",
            &format!("/v1/voxelize?{GRID}&wait=60"),
            "model/obj",
            &meshes.spot,
        )
        .unwrap();
    assert_eq!(r.status, 201, "{}", String::from_utf8_lossy(&r.body));
    // How the accepted jobs ended: a job answered `202` finishes or fails for a reason of its
    // own; interrupted only once the process died during each of its --max-attempts starts.
    let mut ends: BTreeMap<String, usize> = BTreeMap::new();
    for j in &known.lock().unwrap().jobs {
        let v = srv
            .must("GET", &format!("/v1/jobs/{j}"), b"")
            .try_json()
            .unwrap();
        let detail = v["problem"]["detail"].as_str().unwrap_or_default();
        let end = if detail.starts_with("interrupted") {
            assert!(
                v["attempts"].as_u64() >= Some(3),
                "job {j} was accepted and ended interrupted before its attempts: {v}"
            );
            "interrupted after 3 starts".to_string()
        } else {
            v["state"].as_str().unwrap().to_string()
        };
        *ends.entry(end).or_default() += 1;
    }
    eprintln!("crash test: accepted jobs ended {ends:?}");
    let pid = srv.child.id().to_string();
    assert!(
        Command::new("kill")
            .args(["-TERM", &pid])
            .status()
            .unwrap()
            .success()
    );
    let status = wait_exit(&mut srv.child, "SIGTERM");
    assert!(status.success(), "SIGTERM: {status:?}");
    let k = known.lock().unwrap();
    assert!(
        k.server_errors.is_empty(),
        "5xx answers: {:?}",
        k.server_errors
    );
    assert!(
        !k.acked.is_empty() && !k.jobs.is_empty(),
        "the workload stored nothing"
    );
    eprintln!(
        "crash test: {} jobs, {} volumes acknowledged, {} deletes answered, {} job states regressed",
        k.jobs.len(),
        k.acked.len(),
        k.deleted.len(),
        k.regressed
    );
}
