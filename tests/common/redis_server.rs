//! A real `redis-server` (Debian's package) for the shared-queue tests: on 127.0.0.1 with a
//! free port, its data in a scratch directory, with the append-only file fsynced at every write
//! (`--appendonly yes --appendfsync always`), so a SIGKILL loses nothing it acknowledged and a
//! restart on the same port finds everything. Absent binary: `None` with a printed notice,
//! unless `VOXD_REQUIRE_REDIS=1` (scripts/test.sh sets it once it has installed Redis).
//! Every wait is bounded.

use std::io::{Read, Write};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

pub struct RedisServer {
    child: Option<Child>,
    pub port: u16,
    pub dir: PathBuf,
}

fn binary() -> Option<&'static str> {
    [
        "redis-server",
        "/usr/bin/redis-server",
        "/usr/local/bin/redis-server",
    ]
    .into_iter()
    .find(|b| {
        Command::new(b)
            .arg("--version")
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .is_ok_and(|s| s.success())
    })
}

/// A port nothing listens on now.
fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

impl RedisServer {
    /// A fresh server for test `name`; `None` (with a notice) when redis-server is not
    /// installed, a failure when `VOXD_REQUIRE_REDIS=1`.
    pub fn start(name: &str) -> Option<RedisServer> {
        if binary().is_none() {
            assert!(
                std::env::var("VOXD_REQUIRE_REDIS").as_deref() != Ok("1"),
                "VOXD_REQUIRE_REDIS=1 but redis-server is not installed (apt-get install redis-server)"
            );
            eprintln!(
                "NOTICE: redis-server is not installed; skipping the shared-queue test {name}"
            );
            return None;
        }
        let mut s = RedisServer {
            child: None,
            port: free_port(),
            dir: super::tmpdir(&format!("redis-{name}")),
        };
        s.restart();
        Some(s)
    }

    /// `redis://127.0.0.1:PORT`.
    pub fn url(&self) -> String {
        format!("redis://127.0.0.1:{}", self.port)
    }

    /// Starts the server (again, on the same port and data), and waits until it answers PING.
    pub fn restart(&mut self) {
        assert!(self.child.is_none(), "already running");
        let child = Command::new(binary().expect("redis-server"))
            .args(["--port", &self.port.to_string(), "--bind", "127.0.0.1"])
            .args(["--dir", self.dir.to_str().unwrap()])
            .args(["--appendonly", "yes", "--appendfsync", "always"])
            .args(["--save", "", "--daemonize", "no", "--protected-mode", "yes"])
            .args(["--logfile", self.dir.join("redis.log").to_str().unwrap()])
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("redis-server starts");
        self.child = Some(child);
        let deadline = Instant::now() + Duration::from_secs(30);
        while !self.answers() {
            assert!(
                Instant::now() < deadline,
                "redis-server on port {} did not answer within 30 s (see {}/redis.log)",
                self.port,
                self.dir.display()
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// SIGKILL, and waits for the process to be gone.
    pub fn kill(&mut self) {
        if let Some(mut c) = self.child.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }

    /// Does it answer `PING` with `PONG` (not `LOADING`)?
    fn answers(&self) -> bool {
        let Ok(mut s) = std::net::TcpStream::connect(("127.0.0.1", self.port)) else {
            return false;
        };
        let _ = s.set_read_timeout(Some(Duration::from_secs(2)));
        let mut buf = [0u8; 64];
        s.write_all(b"PING\r\n").is_ok()
            && s.read(&mut buf)
                .is_ok_and(|n| buf[..n].starts_with(b"+PONG"))
    }
}

impl Drop for RedisServer {
    fn drop(&mut self) {
        self.kill();
    }
}
