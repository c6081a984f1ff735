//! The HTTP service, end to end: the real `voxd serve` binary on 127.0.0.1 with an ephemeral
//! port, spoken to over TCP with a small HTTP/1.1 client. Loopback only; every loop is bounded.
//!
//! Here: what the themes share (the [`Server`] under test, the problem-document check, a box
//! mesh, which `connections` uses too); the tests are in `jobs`, `contract` and `ops`. Not here:
//! the router in-process (`src/service/routes/tests/`), connection limits (`connections`).

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

mod colour;
mod colour_ops;
mod contract;
mod distance;
mod distance_ops;
mod hermite;
mod http;
mod inputs;
mod jobs;
mod mesh;
mod ops;
mod viewer;
mod vox;
mod zip_upload;

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

    /// POSTs `body` to `path`, which must answer 201 Created: the created resource's JSON.
    fn created(&self, path: &str, headers: &[(&str, &str)], body: &[u8]) -> Value {
        let r = self.req("POST", path, headers, body);
        assert_eq!(r.status, 201, "{}", String::from_utf8_lossy(&r.body));
        r.json()
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

pub(crate) fn box_obj(lo: [f64; 3], hi: [f64; 3]) -> Vec<u8> {
    to_obj(&box_mesh(lo, hi))
}

/// A `.npy`'s data, its header skipped.
pub(crate) fn npy_payload(b: &[u8]) -> &[u8] {
    let n = u16::from_le_bytes([b[8], b[9]]) as usize;
    &b[10 + n..]
}

/// The dense `rgba` array of volume `id` (`format=npy&attributes=rgba`), voxel by voxel in C
/// order.
pub(crate) fn rgba_of(srv: &Server, id: &str) -> Vec<[u8; 4]> {
    let b = srv
        .req(
            "GET",
            &format!("/v1/volumes/{id}/data?format=npy&attributes=rgba"),
            &[],
            &[],
        )
        .ok(200)
        .body;
    npy_payload(&b)
        .chunks(4)
        .map(|c| [c[0], c[1], c[2], c[3]])
        .collect()
}
