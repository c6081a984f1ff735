//! Times the stages of one small job on one mesh, many times over, for profiling the
//! service's small jobs: `cargo run --release --example parse_small -- MESH [N] [RES]` prints
//! the time per parse, per diagnosis, per snap onto a RES³ grid (64 unless given), per count of
//! odd-parity columns (the fill report) and per CPU solid. Run it with `RAYON_NUM_THREADS=1`
//! for the time of one core.
use std::time::Instant;

use voxd::engine::{Engine, GridMesh, Method};
use voxd::grid::{Grid, GridLimits, GridSpec};

fn main() {
    // On a worker of rayon's pool, as the service runs it (a parse from outside the pool would
    // also time the wake-up of a worker for every parallel step).
    rayon::scope(|_| run());
}

/// Microseconds per call of `f`, over `n` calls.
fn per_call<T>(n: usize, mut f: impl FnMut() -> T) -> f64 {
    let t = Instant::now();
    for _ in 0..n {
        std::hint::black_box(f());
    }
    t.elapsed().as_secs_f64() / n as f64 * 1e6
}

fn run() {
    let mut args = std::env::args().skip(1);
    let path = args.next().expect("usage: parse_small MESH [N] [RES]");
    let n: usize = args.next().map_or(2000, |v| v.parse().expect("N"));
    let res: u32 = args.next().map_or(64, |v| v.parse().expect("RES"));
    let bytes = std::fs::read(&path).expect("read the mesh");
    let format = voxd::mesh::Format::from_path(std::path::Path::new(&path));
    let opts = voxd::mesh::LoadOptions::default();
    let load = || voxd::mesh::load_bytes(&bytes, format, &opts).expect("parse");
    let mesh = load();
    let parse = per_call(n, load);
    let diagnose = per_call(n, || voxd::mesh::MeshDiagnostics::of(&mesh));
    let (lo, hi) = mesh.bounds();
    let spec = GridSpec::Resolution {
        n: res,
        cubic: true,
    };
    let grid = Grid::fit(lo, hi, spec, 0, GridLimits::default()).expect("grid");
    let snap = per_call(n, || GridMesh::new(&mesh, &grid).expect("snap"));
    let odd = per_call(n, || voxd::engine::cpu::odd_parity_columns(&mesh, &grid));
    let gm = GridMesh::new(&mesh, &grid).expect("snap");
    let engine = voxd::engine::cpu::CpuEngine;
    let solid = per_call(n, || engine.voxelize(&gm, Method::Solid).expect("solid"));
    println!(
        "{path}: {} bytes, {} triangles; parse {parse:.1} us ({:.0} MB/s), diagnose {diagnose:.1} us, \
         snap {snap:.1} us, odd-parity columns {odd:.1} us, solid {solid:.1} us ({res}³)",
        bytes.len(),
        mesh.triangles().len(),
        bytes.len() as f64 / parse,
    );
}
