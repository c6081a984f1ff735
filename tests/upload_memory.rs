//! Uploads are admitted by the memory their parse will cost (`src/mesh/cost.rs`) and carry no
//! copies of degenerate triangles (`src/mesh/degenerate.rs`): a gzip'd binary STL of millions
//! of identical degenerate triangles (a few hundred kilobytes) is voxelized at the memory of
//! the dozen triangles it really has, and an upload whose estimate exceeds the whole budget is
//! refused before it is parsed. The real `voxd serve` on 127.0.0.1; its peak memory (VmHWM)
//! read from /proc.

use std::io::Write;

use crate::common::*;
use crate::service::Server;

/// `voxd serve` with a memory budget of `max_memory` bytes.
fn serve(name: &str, max_memory: u64) -> (Scratch, Server) {
    let dir = Scratch::new(name);
    let srv = Server::start(&dir, &["--max-memory", &max_memory.to_string()]);
    (dir, srv)
}

/// POSTs a gzip'd STL to be voxelized at resolution 16.
fn upload(srv: &Server, body: &[u8]) -> Resp {
    request(
        &srv.addr,
        "POST",
        "/v1/voxelize?resolution=16&wait=60",
        &[("Content-Type", "model/stl"), ("Content-Encoding", "gzip")],
        body,
    )
}

/// A process's peak resident memory so far (VmHWM), in bytes.
fn vm_hwm(pid: u32) -> u64 {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).expect("/proc status");
    let line = status
        .lines()
        .find(|l| l.starts_with("VmHWM:"))
        .expect("a VmHWM line");
    let kib: u64 = line
        .split_whitespace()
        .nth(1)
        .and_then(|n| n.parse().ok())
        .expect("VmHWM in kB");
    kib * 1024
}

/// A gzip'd binary STL: the 12 triangles of a unit box, then `copies` records of one
/// degenerate triangle (all three corners at the box's corner 0,0,0), compressed as written.
fn degenerate_bomb(copies: u32) -> Vec<u8> {
    let boxed = box_mesh([0.0; 3], [1.0; 3]);
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    gz.write_all(&[0u8; 80]).unwrap();
    let n = boxed.triangles().len() as u32 + copies;
    gz.write_all(&n.to_le_bytes()).unwrap();
    for t in 0..boxed.triangles().len() {
        let mut rec = [0u8; 50];
        for (v, p) in boxed.triangle(t).iter().enumerate() {
            for (i, c) in p.iter().enumerate() {
                let o = 12 + 12 * v + 4 * i;
                rec[o..o + 4].copy_from_slice(&(*c as f32).to_le_bytes());
            }
        }
        gz.write_all(&rec).unwrap();
    }
    let zeros = vec![0u8; 50 * 10_000];
    for _ in 0..copies / 10_000 {
        gz.write_all(&zeros).unwrap();
    }
    gz.write_all(&zeros[..50 * (copies % 10_000) as usize])
        .unwrap();
    gz.finish().unwrap()
}

const COPIES: u32 = 3_000_000;

/// Before: the 150 MB of decoded records were held whole, then 9 M positions (216 MB) and 3 M
/// triangles (36 MB) were built and diagnosed: over 400 MB at the peak. Now the records are
/// read as decoded and all but one copy dropped; the bound leaves the server's own baseline
/// (threads, the runtime, a few decode windows) room, and is well under the old peak.
const PEAK_BOUND: u64 = 200 << 20;

#[test]
fn a_gzip_stl_of_degenerate_copies_is_accepted_at_the_memory_of_its_real_triangles() {
    let body = degenerate_bomb(COPIES);
    assert!(body.len() < 2 << 20, "{} bytes of gzip", body.len());
    let (_dir, srv) = serve("upload-memory-bomb", 4 << 30);
    let r = upload(&srv, &body);
    assert_eq!(r.status, 201, "{}", String::from_utf8_lossy(&r.body));
    let v = r.json();
    let d = &v["diagnostics"];
    assert_eq!(d["dropped_triangles"], COPIES as u64 - 1, "{v}");
    assert_eq!(d["triangles"], 13, "the box and one copy of the point: {v}");
    let peak = vm_hwm(srv.child.id());
    assert!(
        peak < PEAK_BOUND,
        "the server peaked at {peak} bytes, over {PEAK_BOUND}"
    );
}

#[test]
fn an_upload_whose_parse_would_exceed_the_whole_budget_is_refused() {
    // 2 M triangles declared (and present): about 2 M · 256 bytes to parse and diagnose, over
    // a 64 MiB budget whatever they hold.
    let body = degenerate_bomb(2_000_000);
    let (_dir, srv) = serve("upload-memory-over", 64 << 20);
    let r = upload(&srv, &body);
    let p = r.problem(422, "too-much-memory");
    let detail = p["detail"].as_str().unwrap_or_default();
    assert!(detail.contains("parsing the mesh"), "{p}");
    // A small mesh still fits.
    let r = upload(&srv, &degenerate_bomb(10));
    assert_eq!(r.status, 201, "{}", String::from_utf8_lossy(&r.body));
}
