//! API keys end to end, against the real binary: `voxd keygen` prints a key and its keys-file
//! line (the digest checked here with an independent SHA-256), `voxd serve --api-keys-file`
//! guards every /v1 route with `Authorization: Bearer`, leaves the probes open, names the key
//! (never the key itself) in its log and in job records, and refuses to start on a bad file.

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use sha2::{Digest, Sha256};

use crate::common::{data, request, spawn_serve, tmpdir};

fn voxd() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_voxd"));
    c.env_remove("VOXD_FAULT")
        .env_remove("VOXD_API_KEYS_FILE")
        .env_remove("VOXD_PROTECT_METRICS");
    c
}

/// `voxd keygen NAME`: the key, and `NAME:hex(sha256(key))`.
pub fn keygen(name: &str) -> (String, String) {
    let out = voxd().args(["keygen", name]).output().unwrap();
    assert!(out.status.success(), "{out:?}");
    let text = String::from_utf8(out.stdout).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 2, "{text}");
    (lines[0].to_string(), lines[1].to_string())
}

#[test]
fn keygen_prints_a_new_key_and_the_line_of_its_digest() {
    let (key, line) = keygen("team-a");
    let (key2, _) = keygen("team-a");
    assert_ne!(key, key2, "two keys alike");
    assert!(key.len() >= 40 && key.starts_with("voxd_"), "{key}");
    let hex: String = Sha256::digest(key.as_bytes())
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    assert_eq!(line, format!("team-a:{hex}"));
    for bad in ["", "two words", "a:b", "ünï"] {
        let out = voxd().args(["keygen", bad]).output().unwrap();
        assert!(!out.status.success(), "{bad:?}");
        assert!(
            String::from_utf8_lossy(&out.stderr).contains("key name"),
            "{out:?}"
        );
    }
}

#[test]
fn serve_with_api_keys_guards_v1_and_logs_key_names_only() {
    let dir = tmpdir("auth-serve");
    let (key, line) = keygen("team-a");
    let (other, other_line) = keygen("team-b");
    let keys = dir.join("keys");
    std::fs::write(&keys, format!("# voxd keys\n{line}\n{other_line}:jobs=1\n")).unwrap();
    let log = dir.join("stderr.log");
    let (mut child, addr) = spawn_serve(
        voxd()
            .args(["serve", "--addr", "127.0.0.1:0", "--engine", "cpu"])
            .arg("--data-dir")
            .arg(dir.join("data"))
            .arg("--api-keys-file")
            .arg(&keys)
            .env("VOXD_LOG", "info")
            .stderr(std::fs::File::create(&log).unwrap()),
    );
    let auth = format!("Bearer {key}");
    let h = [("authorization", auth.as_str())];
    // Open: the probes. Guarded: /v1, with the challenge.
    for open in ["/healthz", "/readyz", "/metrics"] {
        request(&addr, "GET", open, &[], b"").ok(200);
    }
    let r = request(&addr, "GET", "/v1/volumes", &[], b"");
    r.problem(401, "unauthorized");
    assert_eq!(r.header("www-authenticate"), Some("Bearer realm=\"voxd\""));
    let r = request(
        &addr,
        "GET",
        "/v1/volumes",
        &[("authorization", "Bearer not-a-key")],
        b"",
    );
    r.problem(401, "unauthorized");
    assert!(
        r.header("www-authenticate")
            .unwrap()
            .contains("invalid_token")
    );
    // A refused upload is not read: the connection closes, and nothing is queued.
    let mesh = std::fs::read(data("spot.obj")).unwrap();
    request(
        &addr,
        "POST",
        "/v1/voxelize?resolution=16",
        &[("content-type", "model/obj")],
        &mesh,
    )
    .problem(401, "unauthorized");
    request(&addr, "GET", "/v1/volumes", &h, b"").ok(200);
    // A job with the key: its record names the key.
    let obj = [
        ("authorization", auth.as_str()),
        ("content-type", "model/obj"),
    ];
    let j = request(&addr, "POST", "/v1/voxelize?resolution=16", &obj, &mesh)
        .ok(202)
        .json();
    assert_eq!(j["key_name"], "team-a");
    let id = j["id"].as_str().unwrap().to_string();
    let deadline = Instant::now() + Duration::from_secs(120);
    let done = loop {
        let j = request(&addr, "GET", &format!("/v1/jobs/{id}"), &h, b"")
            .ok(200)
            .json();
        if j["state"] == "succeeded" {
            break j;
        }
        assert!(Instant::now() < deadline, "job not done: {j}");
        std::thread::sleep(Duration::from_millis(50));
    };
    assert_eq!(done["key_name"], "team-a");
    // The other key's line sets its own job limit (1): two at once is one too many, unless the
    // first has finished already (then the second simply queues).
    let b = format!("Bearer {other}");
    let bo = [("authorization", b.as_str()), ("content-type", "model/obj")];
    request(&addr, "POST", "/v1/voxelize?resolution=128", &bo, &mesh).ok(202);
    let second = request(&addr, "POST", "/v1/voxelize?resolution=16", &bo, &mesh);
    if second.status != 202 {
        second.problem(429, "too-many-jobs");
        assert_eq!(second.header("retry-after"), Some("5"));
    }
    let m = String::from_utf8(request(&addr, "GET", "/metrics", &[], b"").body).unwrap();
    assert!(m.contains("voxd_key_requests_total{key=\"team-a\"}"), "{m}");
    assert!(
        m.lines()
            .any(|l| l.starts_with("voxd_unauthorized_total ") && l != "voxd_unauthorized_total 0")
    );
    child.kill().unwrap();
    child.wait().unwrap();
    let text = std::fs::read_to_string(&log).unwrap();
    assert!(
        text.contains("key=\"team-a\""),
        "the key's name is not in the log:\n{text}"
    );
    assert!(
        text.contains("status=401"),
        "refusals are not in the log:\n{text}"
    );
    for secret in [&key, &other] {
        assert!(!text.contains(secret.as_str()), "a key is in the log");
        assert!(!text.contains(&secret[5..]), "a key is in the log");
    }
}

/// `voxd serve` on a free port with `args`, which must refuse to start: its stderr.
fn refused(dir: &std::path::Path, args: &[&std::ffi::OsStr]) -> String {
    let out = voxd()
        .args([
            "serve",
            "--addr",
            "127.0.0.1:0",
            "--engine",
            "cpu",
            "--data-dir",
        ])
        .arg(dir.join("data"))
        .args(args)
        .stdin(Stdio::null())
        .output()
        .unwrap();
    assert!(!out.status.success(), "voxd serve {args:?} started");
    String::from_utf8_lossy(&out.stderr).into_owned()
}

#[test]
fn serve_refuses_to_start_on_a_bad_keys_file() {
    let dir = tmpdir("auth-bad");
    let (_, line) = keygen("ok");
    let digest = line.split(':').nth(1).unwrap().to_string();
    let keys = dir.join("keys");
    for (text, says) in [
        (format!("{line}\nbroken\n"), "line 2"),
        ("# nothing\n".to_string(), "no keys"),
        (format!("{line}\n{line}\n"), "line 2"),
    ] {
        std::fs::write(&keys, &text).unwrap();
        let err = refused(&dir, &["--api-keys-file".as_ref(), keys.as_os_str()]);
        assert!(
            err.contains(says) && err.contains("API keys"),
            "{text:?}: {err}"
        );
        assert!(!err.contains(&digest), "{err}");
    }
    let err = refused(&dir, &["--protect-metrics".as_ref()]);
    assert!(err.contains("--api-keys-file"), "{err}");
    let missing = dir.join("missing");
    let err = refused(&dir, &["--api-keys-file".as_ref(), missing.as_os_str()]);
    assert!(err.contains("missing"), "{err}");
}
