//! Connections a hostile or broken client holds open (issue 11, defect 3), against the real
//! server with short limits: idle and half-sent heads are closed after the header timeout, a
//! paused body gets 408, a client that stops reading a response is disconnected after the send
//! timeout, open connections stay under the cap (file descriptors counted in /proc), and heads
//! over the limits get problem documents (414, 431). Loopback only; every wait is bounded.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::{Duration, Instant};

use crate::common::{Scratch, http_exchange};
use crate::service::{Server, box_obj};

/// Reads until the peer closes (Ok: bytes read) or `within` passes (Err).
fn read_until_closed(s: &mut TcpStream, within: Duration) -> Result<Vec<u8>, String> {
    s.set_read_timeout(Some(Duration::from_millis(200)))
        .unwrap();
    let deadline = Instant::now() + within;
    let mut got = vec![];
    let mut buf = [0u8; 64 << 10];
    loop {
        match s.read(&mut buf) {
            Ok(0) => return Ok(got),
            Ok(n) => got.extend_from_slice(&buf[..n]),
            Err(e) if matches!(e.kind(), std::io::ErrorKind::ConnectionReset) => return Ok(got),
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                ) => {}
            Err(e) => return Err(e.to_string()),
        }
        if Instant::now() > deadline {
            return Err(format!(
                "still open after {within:?} ({} bytes read)",
                got.len()
            ));
        }
    }
}

fn open_fds(pid: u32) -> usize {
    std::fs::read_dir(format!("/proc/{pid}/fd")).map_or(0, |d| d.count())
}

#[test]
fn idle_half_sent_and_slow_connections_are_closed() {
    let dir = Scratch::new("conn-idle");
    let srv = Server::start(
        &dir,
        &[
            "--header-timeout",
            "1",
            "--body-timeout",
            "1",
            "--max-connections",
            "16",
        ],
    );
    // Idle: never a byte.
    let mut idle = TcpStream::connect(&srv.addr).unwrap();
    // Half a head.
    let mut half = TcpStream::connect(&srv.addr).unwrap();
    half.write_all(b"GET /healthz HTTP/1.1\r\nHost: x\r\n")
        .unwrap();
    // A body that stops after its first bytes.
    let mut paused = TcpStream::connect(&srv.addr).unwrap();
    paused
        .write_all(b"POST /v1/voxelize?format=obj HTTP/1.1\r\nHost: x\r\nContent-Length: 100000\r\n\r\nv 0 0 0\n")
        .unwrap();
    // Each is closed by the server (the whole test has a 30 s bound per socket; the limits
    // are 1 s).
    let within = Duration::from_secs(30);
    read_until_closed(&mut idle, within).expect("idle connection");
    read_until_closed(&mut half, within).expect("half-sent head");
    let reply = read_until_closed(&mut paused, within).expect("paused body");
    let reply = String::from_utf8_lossy(&reply);
    assert!(reply.starts_with("HTTP/1.1 408"), "{reply}");
    assert!(reply.contains("application/problem+json"), "{reply}");
    // Still serving.
    let (status, _, _) = http_exchange(&srv.addr, "GET", "/healthz", &[], b"").unwrap();
    assert_eq!(status, 200);
}

#[test]
fn open_connections_stay_under_the_cap() {
    let dir = Scratch::new("conn-cap");
    let srv = Server::start(&dir, &["--header-timeout", "1", "--max-connections", "8"]);
    let pid = srv.child.id();
    let before = open_fds(pid);
    // 40 idle sockets: the server accepts 8, the rest wait in the kernel's backlog.
    let socks: Vec<TcpStream> = (0..40)
        .map(|_| TcpStream::connect(&srv.addr).unwrap())
        .collect();
    std::thread::sleep(Duration::from_millis(500));
    let during = open_fds(pid);
    assert!(
        during <= before + 8 + 2,
        "{before} descriptors before, {during} with 40 idle clients (cap 8)"
    );
    // As the idle ones time out, the waiting ones get their turn; a real request is served.
    let (status, _, _) = http_exchange(&srv.addr, "GET", "/healthz", &[], b"").unwrap();
    assert_eq!(status, 200);
    drop(socks);
}

#[test]
fn a_client_that_stops_reading_is_disconnected() {
    let dir = Scratch::new("conn-send");
    let srv = Server::start(&dir, &["--send-timeout", "1"]);
    // A 320³ volume: 32 MiB as .npy, more than loopback's socket buffers hold.
    let (status, _, body) = http_exchange(
        &srv.addr,
        "POST",
        "/v1/voxelize?format=obj&origin=-1,-1,-1&voxel_size=0.00625&dims=320,320,320&wait=120",
        &[],
        &box_obj([-0.5; 3], [0.5; 3]),
    )
    .unwrap();
    assert_eq!(status, 201, "{}", String::from_utf8_lossy(&body));
    let id = serde_json::from_slice::<serde_json::Value>(&body).unwrap()["id"]
        .as_str()
        .unwrap()
        .to_string();
    let mut s = TcpStream::connect(&srv.addr).unwrap();
    write!(
        s,
        "GET /v1/volumes/{id}/data?format=npy HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n"
    )
    .unwrap();
    // Take nothing for well past the send timeout, then everything that is left.
    std::thread::sleep(Duration::from_secs(4));
    let got = read_until_closed(&mut s, Duration::from_secs(60)).expect("the download");
    let full = 32_768_000 + 128;
    assert!(
        got.len() < full,
        "the whole download ({} bytes) waited for a client that stopped reading",
        got.len()
    );
    let (status, _, _) = http_exchange(&srv.addr, "GET", "/healthz", &[], b"").unwrap();
    assert_eq!(status, 200);
}

#[test]
fn heads_over_the_limits_get_problem_documents() {
    let dir = Scratch::new("conn-head");
    let srv = Server::start(&dir, &[]);
    let problem = |status: u16, slug: &str, path: &str, headers: &[(&str, &str)]| {
        let (s, h, body) = http_exchange(&srv.addr, "GET", path, headers, b"").unwrap();
        assert_eq!(s, status, "{}", String::from_utf8_lossy(&body));
        assert_eq!(
            h.get("content-type").map(String::as_str),
            Some("application/problem+json")
        );
        let p: serde_json::Value = serde_json::from_slice(&body).unwrap();
        assert_eq!(
            p["type"],
            format!("https://voxd.dev/problems/{slug}"),
            "{p}"
        );
    };
    // A target over 8 KiB.
    let long = format!("/healthz?{}", "a".repeat(9000));
    problem(414, "uri-too-long", &long, &[]);
    // More than 100 fields.
    let names: Vec<String> = (0..120).map(|i| format!("x-h{i}")).collect();
    let many: Vec<(&str, &str)> = names.iter().map(|n| (n.as_str(), "1")).collect();
    problem(431, "headers-too-large", "/healthz", &many);
    // More than 64 KiB in one field.
    let big = "b".repeat(70 << 10);
    problem(431, "headers-too-large", "/healthz", &[("x-big", &big)]);
    // Just under the limits: served.
    let ok = "c".repeat(60 << 10);
    let (s, _, _) = http_exchange(&srv.addr, "GET", "/healthz", &[("x-ok", &ok)], b"").unwrap();
    assert_eq!(s, 200);
}

/// An upload refused before its body is read says `Connection: close` (the server cannot
/// reuse the connection, and a client must not send its next request into it); one that is
/// served keeps the connection.
#[test]
fn refused_uploads_say_the_connection_closes() {
    let dir = Scratch::new("conn-close");
    let srv = Server::start(&dir, &[]);
    let mesh = box_obj([0.0; 3], [1.0; 3]);
    for path in [
        "/v1/voxelize?resolution=abc",
        "/v1/voxelize?format=xyz",
        "/v1/voxelize?nonsense=1",
    ] {
        // A keep-alive request (http_exchange asks for close itself, which hyper would echo).
        let mut c = TcpStream::connect(&srv.addr).unwrap();
        write!(
            c,
            "POST {path} HTTP/1.1\r\nHost: x\r\nContent-Type: model/obj\r\nContent-Length: {}\r\n\r\n",
            mesh.len()
        )
        .unwrap();
        c.write_all(&mesh).unwrap();
        let got =
            read_until_closed(&mut c, Duration::from_secs(30)).expect("closed after the refusal");
        let head = String::from_utf8_lossy(&got).to_ascii_lowercase();
        assert!(head.starts_with("http/1.1 4"), "{path}: {head}");
        assert!(head.contains("\r\nconnection: close\r\n"), "{path}: {head}");
    }
    // Keep-alive after a success: two requests on one connection.
    let mut s = TcpStream::connect(&srv.addr).unwrap();
    s.write_all(b"GET /healthz HTTP/1.1\r\nHost: x\r\n\r\nGET /healthz HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n")
        .unwrap();
    let got = String::from_utf8_lossy(&read_until_closed(&mut s, Duration::from_secs(30)).unwrap())
        .to_string();
    assert_eq!(got.matches("HTTP/1.1 200").count(), 2, "{got}");
}

/// A child process killed and reaped when dropped, whatever the test did.
struct Reaped(std::process::Child);

impl std::ops::Deref for Reaped {
    type Target = std::process::Child;
    fn deref(&self) -> &std::process::Child {
        &self.0
    }
}

impl std::ops::DerefMut for Reaped {
    fn deref_mut(&mut self) -> &mut std::process::Child {
        &mut self.0
    }
}

impl Drop for Reaped {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// `voxd serve` with `--admin-addr` on free ports, and the two addresses it prints.
fn with_admin(dir: &std::path::Path, extra: &[&str]) -> (Reaped, String, String) {
    use std::io::BufRead;
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_voxd"))
        .args([
            "serve",
            "--addr",
            "127.0.0.1:0",
            "--admin-addr",
            "127.0.0.1:0",
        ])
        .args(["--data-dir", dir.to_str().unwrap(), "--engine", "cpu"])
        .args(extra)
        .env("VOXD_LOG", "warn")
        .stdout(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut out = std::io::BufReader::new(child.stdout.take().unwrap());
    let mut line = |prefix: &str| {
        let mut l = String::new();
        out.read_line(&mut l).unwrap();
        l.trim()
            .strip_prefix(prefix)
            .unwrap_or_else(|| panic!("expected {prefix:?}, got {l:?}"))
            .to_string()
    };
    let addr = line("voxd listening on http://");
    let admin = line("voxd admin listening on http://");
    (Reaped(child), addr, admin)
}

/// With every connection place of `--addr` taken by busy clients, a probe there waits in the
/// kernel's backlog, while `--admin-addr` (places of its own) answers `/healthz`, `/readyz` and
/// `/metrics` at once and nothing else; once the clients leave, the waiting probe is answered.
#[test]
fn probes_answer_on_the_admin_listener_while_clients_hold_every_place() {
    let dir = Scratch::new("conn-admin");
    let (child, addr, admin) =
        with_admin(&dir, &["--max-connections", "2", "--header-timeout", "30"]);
    // Two clients sending bodies take both places of the service's listener (busy connections
    // are never shed; idle ones would be, to make room).
    let hold: Vec<TcpStream> = (0..2)
        .map(|_| {
            let mut s = TcpStream::connect(&addr).unwrap();
            s.write_all(b"POST /v1/voxelize?format=obj HTTP/1.1\r\nHost: x\r\nContent-Length: 100000\r\n\r\nv 0 0 0\n")
                .unwrap();
            s
        })
        .collect();
    std::thread::sleep(Duration::from_millis(300));
    let mut waiting = TcpStream::connect(&addr).unwrap();
    waiting
        .write_all(b"GET /healthz HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n")
        .unwrap();
    waiting
        .set_read_timeout(Some(Duration::from_secs(1)))
        .unwrap();
    let mut buf = [0u8; 1024];
    let early = waiting.read(&mut buf);
    assert!(
        matches!(&early, Err(e) if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut)),
        "the service's listener answered with every place taken: {early:?}"
    );
    // The admin listener answers meanwhile.
    for path in ["/healthz", "/readyz"] {
        let (status, _, _) = http_exchange(&admin, "GET", path, &[], b"").unwrap();
        assert_eq!(status, 200, "{path}");
    }
    let (status, _, body) = http_exchange(&admin, "GET", "/metrics", &[], b"").unwrap();
    assert_eq!(status, 200);
    assert!(String::from_utf8_lossy(&body).contains("voxd_"), "metrics");
    // Nothing else: the API is not on the admin listener.
    let (status, headers, body) = http_exchange(&admin, "GET", "/v1/volumes", &[], b"").unwrap();
    assert_eq!(status, 404, "{}", String::from_utf8_lossy(&body));
    assert_eq!(
        headers.get("content-type").map(String::as_str),
        Some("application/problem+json")
    );
    // The clients leave: the waiting probe gets its place and its answer.
    drop(hold);
    let got = read_until_closed(&mut waiting, Duration::from_secs(30)).expect("probe answered");
    assert!(
        got.starts_with(b"HTTP/1.1 200"),
        "{}",
        String::from_utf8_lossy(&got)
    );
    drop(child);
}

/// After SIGTERM the service's listener closes at once, while the admin listener keeps
/// answering as long as the server drains (here: a request whose body is still coming):
/// `/healthz` 200, `/readyz` 503 `shutting-down`. Once that request is gone the process exits
/// cleanly, and the admin listener is closed with it.
#[test]
fn the_admin_listener_answers_until_the_server_has_drained() {
    let dir = Scratch::new("conn-admin-drain");
    let (mut child, addr, admin) =
        with_admin(&dir, &["--shutdown-timeout", "60", "--body-timeout", "60"]);
    let (status, _, _) = http_exchange(&admin, "GET", "/readyz", &[], b"").unwrap();
    assert_eq!(status, 200);
    // A request in flight: its head and the start of its body.
    let mut slow = TcpStream::connect(&addr).unwrap();
    slow.write_all(b"POST /v1/voxelize?format=obj HTTP/1.1\r\nHost: x\r\nContent-Length: 100000\r\n\r\nv 0 0 0\n")
        .unwrap();
    std::thread::sleep(Duration::from_millis(300));
    let term = std::process::Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(term.success());
    // The service's listener closes (bounded wait)...
    let deadline = Instant::now() + Duration::from_secs(20);
    while TcpStream::connect(&addr).is_ok() {
        assert!(
            Instant::now() < deadline,
            "the service's listener still accepts"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    // ...while the admin listener answers.
    let (status, _, _) = http_exchange(&admin, "GET", "/healthz", &[], b"").unwrap();
    assert_eq!(status, 200);
    let (status, _, body) = http_exchange(&admin, "GET", "/readyz", &[], b"").unwrap();
    assert_eq!(status, 503, "{}", String::from_utf8_lossy(&body));
    let problem: serde_json::Value = serde_json::from_slice(&body).unwrap();
    assert_eq!(
        problem["type"], "https://voxd.dev/problems/shutting-down",
        "{problem}"
    );
    assert!(child.try_wait().unwrap().is_none(), "exited while draining");
    // The request goes away: the server finishes and the admin listener closes with it.
    drop(slow);
    let deadline = Instant::now() + Duration::from_secs(60);
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        assert!(Instant::now() < deadline, "the server did not exit");
        std::thread::sleep(Duration::from_millis(20));
    };
    assert!(status.success(), "{status:?}");
    assert!(
        TcpStream::connect(&admin).is_err(),
        "admin listener still open"
    );
}

/// An `Expect` other than `100-continue` cannot be met: 417 `expectation-failed` (issue 30); a
/// `100-continue` is still served.
#[test]
fn an_unknown_expectation_gets_417() {
    let dir = Scratch::new("conn-expect");
    let srv = Server::start(&dir, &[]);
    let (status, headers, body) =
        http_exchange(&srv.addr, "GET", "/healthz", &[("Expect", "200-ok")], b"").unwrap();
    assert_eq!(status, 417, "{}", String::from_utf8_lossy(&body));
    assert_eq!(
        headers.get("content-type").map(String::as_str),
        Some("application/problem+json")
    );
    assert!(String::from_utf8_lossy(&body).contains("expectation-failed"));
    let (status, _, _) = http_exchange(
        &srv.addr,
        "GET",
        "/healthz",
        &[("Expect", "100-continue")],
        b"",
    )
    .unwrap();
    assert_eq!(status, 200);
}
