//! The crash test's server: `voxd serve` started on a data directory (with a fault to inject,
//! or none), its requests, and waiting for it to exit.

use std::io::{BufRead, BufReader};
use std::os::unix::process::ExitStatusExt;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use crate::common::{Resp, try_request};

/// One HTTP/1.1 exchange with a content type (none when empty); any failure (the server killed
/// mid-way) is an error, never a panic.
pub(super) fn request(
    addr: &str,
    method: &str,
    path: &str,
    ctype: &str,
    body: &[u8],
) -> std::io::Result<Resp> {
    let h = [("Content-Type", ctype)];
    let headers: &[(&str, &str)] = if ctype.is_empty() { &[] } else { &h };
    try_request(addr, method, path, headers, body)
}

pub(super) struct Server {
    pub(super) child: Child,
    pub(super) addr: String,
}

impl Server {
    /// Starts `voxd serve` on `dir`; `None` when it died before listening (a fault armed with
    /// `fault` may fire while it recovers, writing the records of interrupted jobs).
    pub(super) fn start(dir: &Path, fault: Option<&str>) -> Option<Server> {
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_voxd"));
        cmd.args([
            "serve",
            "--addr",
            "127.0.0.1:0",
            "--data-dir",
            dir.to_str().unwrap(),
            "--engine",
            "cpu",
            "--workers",
            "2",
        ])
        .env("VOXD_LOG", "error")
        .env_remove("VOXD_FAULT")
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit());
        if let Some(f) = fault {
            cmd.env("VOXD_FAULT", f);
        }
        let mut child = cmd.spawn().unwrap();
        // The first line, read on a thread so that a server that hangs before listening fails
        // the test instead of stalling it.
        let stdout = child.stdout.take().unwrap();
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let mut line = String::new();
            let _ = BufReader::new(stdout).read_line(&mut line);
            let _ = tx.send(line);
        });
        let Ok(line) = rx.recv_timeout(Duration::from_secs(120)) else {
            let _ = child.kill();
            let _ = child.wait();
            panic!("voxd neither listened nor exited within 120 s");
        };
        match line.trim().strip_prefix("voxd listening on http://") {
            Some(addr) => Some(Server {
                addr: addr.to_string(),
                child,
            }),
            None => {
                let status = wait_exit(&mut child, "closing its stdout");
                assert!(
                    fault.is_some() && status.signal() == Some(SIGABRT),
                    "voxd did not start ({status:?}, first line {line:?})"
                );
                None
            }
        }
    }

    pub(super) fn req(
        &self,
        method: &str,
        path: &str,
        ctype: &str,
        body: &[u8],
    ) -> std::io::Result<Resp> {
        request(&self.addr, method, path, ctype, body)
    }

    /// A request that must succeed (the server is meant to be up).
    pub(super) fn must(&self, method: &str, path: &str, body: &[u8]) -> Resp {
        self.req(method, path, "", body)
            .unwrap_or_else(|e| panic!("{method} {path}: {e}"))
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

pub(super) const SIGKILL: i32 = 9;
pub(super) const SIGABRT: i32 = 6;

/// Waits (bounded) for `child` to exit; `None` if it is still running after `secs`.
pub(super) fn try_wait_exit(child: &mut Child, secs: u64) -> Option<std::process::ExitStatus> {
    let deadline = Instant::now() + Duration::from_secs(secs);
    loop {
        if let Some(s) = child.try_wait().unwrap() {
            return Some(s);
        }
        if Instant::now() >= deadline {
            return None;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// Waits (bounded) for `child` to exit after `what`.
pub(super) fn wait_exit(child: &mut Child, what: &str) -> std::process::ExitStatus {
    try_wait_exit(child, 120).unwrap_or_else(|| panic!("voxd did not exit after {what}"))
}
