//! What an operator's tools read from a running `voxd serve`: its log lines (`--log-format text`
//! and `json`, at the default level, as a log shipper takes them from stderr) and its metrics
//! (`/metrics`, as Prometheus scrapes them and `promtool check metrics` judges them).

use std::collections::BTreeMap;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::Value;

use crate::common::*;

/// A `voxd serve` on 127.0.0.1 whose stderr (its log) goes to a file, with `VOXD_LOG` unset:
/// the default level.
struct Logged {
    child: Child,
    addr: String,
    log: std::path::PathBuf,
}

impl Logged {
    fn start(dir: &Path, extra: &[&str]) -> Logged {
        let log = dir.join("stderr.log");
        let (child, addr) = spawn_serve(
            Command::new(env!("CARGO_BIN_EXE_voxd"))
                .args(["serve", "--addr", "127.0.0.1:0", "--engine", "cpu"])
                .arg("--data-dir")
                .arg(dir.join("data"))
                .args(extra)
                .env_remove("VOXD_LOG")
                .env_remove("VOXD_LOG_FORMAT")
                .stderr(Stdio::from(std::fs::File::create(&log).unwrap())),
        );
        Logged { child, addr, log }
    }

    fn req(&self, method: &str, path: &str, headers: &[(&str, &str)], body: &[u8]) -> Resp {
        request(&self.addr, method, path, headers, body)
    }

    /// The log's lines so far.
    fn lines(&self) -> Vec<String> {
        std::fs::read_to_string(&self.log)
            .unwrap()
            .lines()
            .map(str::to_string)
            .collect()
    }

    /// Waits (60 s at most) for a log line holding `what`.
    fn wait_for_line(&self, what: &str) {
        let deadline = Instant::now() + Duration::from_secs(60);
        while !self.lines().iter().any(|l| l.contains(what)) {
            assert!(Instant::now() < deadline, "no log line with {what:?}");
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    /// SIGTERM, and waits for the process to end: its whole log is written then.
    fn stop(mut self) -> Vec<String> {
        Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status()
            .unwrap();
        let deadline = Instant::now() + Duration::from_secs(60);
        while self.child.try_wait().unwrap().is_none() {
            assert!(Instant::now() < deadline, "server did not stop");
            std::thread::sleep(Duration::from_millis(20));
        }
        self.lines()
    }
}

impl Drop for Logged {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Request ids a caller might send to forge log fields: field syntax of the text format, a
/// quote and a tab, JSON syntax.
const HOSTILE_IDS: [&str; 3] = [
    "x} method=DELETE path=/v1/evil status=500",
    "a\"b\tc\\\" status=500 x=\"",
    "\",\"status\":500,\"method\":\"DELETE",
];

/// Requests every log test sends: hostile request ids, a fine one, a path that reads like
/// fields, a job made with a request id of its own. The job's id.
fn send_requests(srv: &Logged) -> String {
    for id in HOSTILE_IDS {
        let r = srv.req("GET", "/v1/volumes", &[("X-Request-Id", id)], &[]);
        assert_eq!(r.status, 200);
        // Replaced by an id of the server's, which the response names.
        let used = r.header("x-request-id").unwrap();
        assert_ne!(used, id);
        assert!(used.bytes().all(|b| b.is_ascii_alphanumeric()), "{used:?}");
    }
    let r = srv.req(
        "GET",
        "/v1/volumes",
        &[("X-Request-Id", "ok-id_1.2:3")],
        &[],
    );
    assert_eq!(r.header("x-request-id"), Some("ok-id_1.2:3"));
    let r = srv.req(
        "GET",
        "/v1/nope%22%20status=500%20method=DELETE",
        &[("X-Request-Id", "req-unmatched")],
        &[],
    );
    assert_eq!(r.status, 404);
    let r = srv.req(
        "GET",
        "/v1/volumes/0123456789abcdef",
        &[("X-Request-Id", "req-volume")],
        &[],
    );
    assert_eq!(r.status, 404);
    let made = srv.req(
        "POST",
        "/v1/voxelize?resolution=8&wait=30",
        &[("Content-Type", "model/obj"), ("X-Request-Id", "req-job-1")],
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n",
    );
    assert_eq!(made.status, 201, "{}", String::from_utf8_lossy(&made.body));
    // The volume's provenance names the job that made it.
    let job = made.json()["provenance"]["job"]
        .as_str()
        .map(str::to_string);
    // Not every volume says; the access line does (checked by the callers).
    job.unwrap_or_default()
}

/// The `key=value` fields of a text log line after `after`: values bare (up to a space) or
/// quoted (with backslash escapes), as tracing's text format writes them.
fn text_fields(line: &str, after: &str) -> Vec<(String, String)> {
    let rest = &line[line.find(after).unwrap_or_else(|| panic!("{line}")) + after.len()..];
    let mut out = Vec::new();
    let mut chars = rest.chars().peekable();
    loop {
        while chars.peek() == Some(&' ') {
            chars.next();
        }
        let mut key = String::new();
        while let Some(&c) = chars.peek() {
            if c == '=' || c == ' ' {
                break;
            }
            key.push(c);
            chars.next();
        }
        if key.is_empty() {
            break;
        }
        if chars.next() != Some('=') {
            // The message (a bare word) before the fields.
            out.push(("message".into(), key));
            continue;
        }
        let mut value = String::new();
        if chars.peek() == Some(&'"') {
            chars.next();
            while let Some(c) = chars.next() {
                match c {
                    '\\' => value.push(chars.next().unwrap_or('\\')),
                    '"' => break,
                    c => value.push(c),
                }
            }
        } else {
            while let Some(&c) = chars.peek() {
                if c == ' ' {
                    break;
                }
                value.push(c);
                chars.next();
            }
        }
        out.push((key, value));
    }
    out
}

/// A log line that forged a field holds a field twice, or a status of 500.
fn assert_unforged(fields: &[(String, String)], line: &str) {
    let mut seen = BTreeMap::new();
    for (k, v) in fields {
        assert!(
            seen.insert(k.clone(), v.clone()).is_none(),
            "field {k} twice: {line}"
        );
    }
    assert_ne!(
        seen.get("status").map(String::as_str),
        Some("500"),
        "{line}"
    );
    assert_ne!(
        seen.get("method").map(String::as_str),
        Some("DELETE"),
        "{line}"
    );
}

#[test]
fn text_log_lines_cannot_be_forged_and_tie_jobs_to_requests() {
    let dir = Scratch::new("log-text");
    let srv = Logged::start(&dir, &["--log-format", "text"]);
    let job = send_requests(&srv);
    let lines = srv.stop();
    let text = lines.join("\n");
    // Nothing a caller sent is written bare.
    assert!(!text.contains("x} method"), "{text}");
    assert!(!text.contains("\tc"), "{text}");
    let access: Vec<Vec<(String, String)>> = lines
        .iter()
        .filter(|l| l.contains("voxd::access:"))
        .map(|l| {
            let f = text_fields(l, "voxd::access: ");
            assert_unforged(&f, l);
            f
        })
        .collect();
    // One line per request (7), at the default level; the probes are not logged.
    assert_eq!(access.len(), 7, "{text}");
    let get = |f: &[(String, String)], k: &str| {
        f.iter()
            .find(|(key, _)| key == k)
            .map(|(_, v)| v.clone())
            .unwrap_or_default()
    };
    for f in &access {
        for k in ["method", "route", "status", "duration_ms", "request_id"] {
            assert!(!get(f, k).is_empty(), "{k} missing: {f:?}");
        }
    }
    let unmatched = access
        .iter()
        .find(|f| get(f, "request_id") == "req-unmatched")
        .unwrap();
    assert_eq!(get(unmatched, "route"), "unmatched");
    assert_eq!(
        get(unmatched, "path"),
        "/v1/nope%22%20status=500%20method=DELETE"
    );
    let volume = access
        .iter()
        .find(|f| get(f, "request_id") == "req-volume")
        .unwrap();
    assert_eq!(get(volume, "route"), "/v1/volumes/{id}");
    assert_eq!(get(volume, "status"), "404");
    let made = access
        .iter()
        .find(|f| get(f, "request_id") == "req-job-1")
        .unwrap();
    let job_id = get(made, "job");
    assert!(!job_id.is_empty(), "{made:?}");
    if !job.is_empty() {
        assert_eq!(job_id, job);
    }
    assert_eq!(get(made, "route"), "/v1/voxelize");
    assert_eq!(get(made, "status"), "201");
    // The job's lines carry its id and the request's.
    for what in ["job queued", "job started", "job succeeded"] {
        let l = lines
            .iter()
            .find(|l| l.contains(what) && l.contains(&job_id))
            .unwrap_or_else(|| panic!("no {what:?} line for job {job_id}: {text}"));
        assert!(l.contains("req-job-1"), "{l}");
    }
}

#[test]
fn json_log_lines_cannot_be_forged_and_tie_jobs_to_requests() {
    let dir = Scratch::new("log-json");
    let srv = Logged::start(&dir, &["--log-format", "json"]);
    send_requests(&srv);
    let lines = srv.stop();
    let objects: Vec<Value> = lines
        .iter()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{e}: {l}")))
        .collect();
    let access: Vec<&Value> = objects
        .iter()
        .filter(|o| o["target"] == "voxd::access")
        .collect();
    assert_eq!(access.len(), 7, "{lines:#?}");
    for a in &access {
        assert_eq!(a["level"], "INFO");
        assert_eq!(a["message"], "request");
        assert!(a["status"].is_u64() && a["status"] != 500, "{a}");
        assert!(a["duration_ms"].is_number(), "{a}");
        assert!(
            ["GET", "POST"].contains(&a["method"].as_str().unwrap()),
            "{a}"
        );
        let id = a["request_id"].as_str().unwrap();
        assert!(!HOSTILE_IDS.contains(&id), "{a}");
    }
    let by_id = |id: &str| {
        *access
            .iter()
            .find(|a| a["request_id"] == id)
            .unwrap_or_else(|| panic!("no access line of {id}"))
    };
    assert_eq!(by_id("req-unmatched")["route"], "unmatched");
    assert_eq!(
        by_id("req-unmatched")["path"],
        "/v1/nope%22%20status=500%20method=DELETE"
    );
    assert_eq!(by_id("req-volume")["route"], "/v1/volumes/{id}");
    let made = by_id("req-job-1");
    assert_eq!(made["status"], 201);
    assert!(made["bytes"].as_u64().is_some_and(|b| b > 100), "{made}");
    let job = made["job"].as_str().unwrap();
    // The worker's lines: the job's span names the job and the request.
    for what in ["job started", "job succeeded"] {
        let l = objects
            .iter()
            .find(|o| o["message"] == what && o["span"]["job"] == job)
            .unwrap_or_else(|| panic!("no {what:?} line for {job}: {lines:#?}"));
        assert_eq!(l["span"]["request_id"], "req-job-1", "{l}");
    }
    let queued = objects
        .iter()
        .find(|o| o["message"] == "job queued")
        .unwrap();
    assert_eq!(queued["job"], job);
    assert_eq!(queued["request_id"], "req-job-1");
}

/// `promtool check metrics` on `text`: its complaints (empty when clean); `None` without
/// promtool.
fn promtool_check(text: &str) -> Option<String> {
    use std::io::Write;
    let mut child = Command::new("promtool")
        .args(["check", "metrics"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .ok()?;
    child
        .stdin
        .take()
        .unwrap()
        .write_all(text.as_bytes())
        .unwrap();
    let out = child.wait_with_output().unwrap();
    let said = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    Some(if out.status.success() {
        String::new()
    } else {
        said
    })
}

/// The value of the series `series` (name and labels exactly as exposed).
fn sample(text: &str, series: &str) -> Option<f64> {
    text.lines()
        .find_map(|l| l.strip_prefix(series)?.strip_prefix(' ')?.parse().ok())
}

#[test]
fn metrics_count_requests_by_route_and_jobs_by_outcome_and_pass_promtool() {
    let dir = Scratch::new("metrics-slo");
    let srv = Logged::start(&dir, &["--max-store-bytes", "123456789", "--workers", "1"]);
    let obj = [("Content-Type", "model/obj")];
    assert_eq!(srv.req("GET", "/v1/volumes/abc123", &[], &[]).status, 404);
    assert_eq!(srv.req("GET", "/v1/volumes/def456", &[], &[]).status, 404);
    assert_eq!(srv.req("GET", "/no/such/route", &[], &[]).status, 404);
    assert_eq!(srv.req("BREW", "/v1/volumes", &[], &[]).status, 405);
    let made = srv.req(
        "POST",
        "/v1/voxelize?resolution=8&wait=30",
        &obj,
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n",
    );
    assert_eq!(made.status, 201, "{}", String::from_utf8_lossy(&made.body));
    // A job canceled while it runs: an outcome of its own, an info line, no failure.
    let spot = std::fs::read(data("spot.obj")).unwrap();
    let big = srv.req(
        "POST",
        "/v1/voxelize?resolution=1000&method=conservative",
        &obj,
        &spot,
    );
    assert_eq!(big.status, 202);
    let big = big.json()["id"].as_str().unwrap().to_string();
    let deadline = Instant::now() + Duration::from_secs(60);
    while srv.req("GET", &format!("/v1/jobs/{big}"), &[], &[]).json()["state"] != "running" {
        assert!(Instant::now() < deadline, "the big job never ran");
        std::thread::sleep(Duration::from_millis(20));
    }
    assert_eq!(
        srv.req("DELETE", &format!("/v1/jobs/{big}"), &[], &[])
            .status,
        200
    );
    srv.wait_for_line("job canceled");
    let text = String::from_utf8(srv.req("GET", "/metrics", &[], &[]).ok(200).body).unwrap();
    // The kernel's count of the server's CPU time (utime + stime), read after the scrape.
    let stat = std::fs::read_to_string(format!("/proc/{}/stat", srv.child.id())).unwrap();
    let f: Vec<&str> = stat[stat.rfind(')').unwrap() + 2..].split(' ').collect();
    // SAFETY: sysconf only reads a configuration value.
    let tick = unsafe { libc::sysconf(libc::_SC_CLK_TCK) } as f64;
    let kernel = (f[11].parse::<f64>().unwrap() + f[12].parse::<f64>().unwrap()) / tick;
    let lines = srv.stop();
    // The default log format is text, and a cancel is no failure.
    assert!(lines.iter().all(|l| !l.starts_with('{')), "{lines:#?}");
    let canceled = lines.iter().find(|l| l.contains("job canceled")).unwrap();
    assert!(
        canceled.contains(" INFO ") && canceled.contains(&big),
        "{canceled}"
    );
    assert!(
        !lines.iter().any(|l| l.contains("job failed")),
        "{lines:#?}"
    );

    if let Some(complaints) = promtool_check(&text) {
        assert_eq!(complaints, "", "promtool check metrics:\n{text}");
    } else {
        eprintln!("NOTICE: no promtool (apt-get install prometheus); not linted");
    }
    let get = |series: &str| sample(&text, series).unwrap_or_else(|| panic!("{series}:\n{text}"));
    // Route templates, never the ids callers sent; no route is `unmatched`; unknown methods
    // are `other`.
    assert_eq!(
        get("voxd_http_requests_total{route=\"/v1/volumes/{id}\",method=\"GET\",status=\"404\"}"),
        2.0
    );
    assert!(
        !text.contains("abc123") && !text.contains("/no/such"),
        "{text}"
    );
    assert_eq!(
        get("voxd_http_requests_total{route=\"unmatched\",method=\"GET\",status=\"404\"}"),
        1.0
    );
    assert!(text.contains("method=\"other\",status=\"405\"}"), "{text}");
    assert!(!text.contains("BREW"), "{text}");
    assert_eq!(
        get("voxd_http_requests_total{route=\"/v1/voxelize\",method=\"POST\",status=\"201\"}"),
        1.0
    );
    assert_eq!(
        get("voxd_http_request_duration_seconds_count{route=\"/v1/volumes/{id}\"}"),
        2.0
    );
    assert_eq!(
        get("voxd_http_request_duration_seconds_bucket{route=\"/v1/volumes/{id}\",le=\"+Inf\"}"),
        2.0
    );
    // Jobs by method and outcome; durations in buckets past the default job timeout.
    assert_eq!(
        get("voxd_jobs_finished_total{method=\"solid\",outcome=\"succeeded\"}"),
        1.0
    );
    assert_eq!(
        get("voxd_jobs_finished_total{method=\"conservative\",outcome=\"canceled\"}"),
        1.0
    );
    assert_eq!(get("voxd_job_duration_seconds_bucket{le=\"600\"}"), 2.0);
    assert_eq!(get("voxd_job_duration_seconds_count"), 2.0);
    // The store against its quota.
    assert_eq!(get("voxd_store_quota_bytes"), 123456789.0);
    assert!(get("voxd_store_used_bytes") > 0.0);
    assert_eq!(get("voxd_store_volumes"), 1.0);
    // The queue's gauges as before (the KEDA scaler reads voxd_queue_depth).
    assert_eq!(get("voxd_queue_depth"), 0.0);
    // The build and the process.
    let build = format!(
        "voxd_build_info{{version=\"{}\",",
        env!("CARGO_PKG_VERSION")
    );
    assert!(
        text.lines()
            .any(|l| l.starts_with(&build) && l.ends_with("} 1")),
        "{text}"
    );
    assert!(get("process_resident_memory_bytes") > 1e6);
    // The CPU time is counted in clock ticks (10 ms here), so a short-lived server may have
    // none yet: held to what the kernel said of the process just after the scrape instead.
    let cpu = get("process_cpu_seconds_total");
    assert!(
        cpu >= 0.0 && cpu <= kernel && kernel - cpu < 1.0,
        "process_cpu_seconds_total {cpu}, the kernel's utime + stime after the scrape {kernel}"
    );
    assert!(get("process_open_fds") > 3.0);
    assert!(get("process_max_fds") >= get("process_open_fds"));
    assert!(get("process_start_time_seconds") > 1.5e9);
}
