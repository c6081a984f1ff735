//! Throughput of many small jobs on the GPU engine: `JOBS` voxelizations of one mesh at one
//! resolution, from `THREADS` threads sharing one `GpuEngine` (as the service's workers share
//! it), and the same jobs on the CPU engine for comparison. Every GPU volume is checked against
//! the CPU engine's. Uses only the engine's public API, so it builds against any revision (for
//! paired before/after runs: bench/gpu/ab.sh).
//!
//! cargo run --release --example gpu_small_jobs -- MESH [RESOLUTION] [JOBS] [THREADS] [METHOD]

use std::time::Instant;

use voxd::engine::cpu::CpuEngine;
use voxd::engine::gpu::{GpuEngine, GpuOptions};
use voxd::engine::{Engine, GridMesh, Method};
use voxd::grid::{Grid, GridLimits, GridSpec};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(path) = args.first() else {
        eprintln!("usage: gpu_small_jobs MESH [RESOLUTION] [JOBS] [THREADS] [METHOD]");
        std::process::exit(2);
    };
    let arg =
        |i: usize, default: usize| args.get(i).and_then(|a| a.parse().ok()).unwrap_or(default);
    let (n, jobs, threads) = (arg(1, 64) as u32, arg(2, 400), arg(3, 4).max(1));
    let method = match args.get(4).map(String::as_str).unwrap_or("solid") {
        "solid" => Method::Solid,
        "surface" => Method::Surface,
        "conservative" => Method::Conservative,
        "interior" => Method::Interior,
        other => panic!("unknown method {other}"),
    };
    let mesh = voxd::mesh::load_file(path.as_ref(), usize::MAX).expect("mesh");
    let (lo, hi) = mesh.bounds();
    let spec = GridSpec::Resolution { n, cubic: true };
    let grid = Grid::fit(lo, hi, spec, 0, GridLimits::default()).expect("grid");
    let gm = GridMesh::new(&mesh, &grid).expect("grid mesh");
    let gpu = GpuEngine::new(GpuOptions {
        adapter: std::env::var("VOXD_ADAPTER").ok(),
        ..Default::default()
    })
    .expect("gpu");
    let expected = CpuEngine.voxelize(&gm, method).expect("cpu");
    // Warm-up: the first dispatch of each pipeline compiles it.
    for _ in 0..3 {
        assert!(gpu.voxelize(&gm, method).unwrap() == expected, "GPU != CPU");
    }
    let run = |engine: &dyn Engine| {
        let t = Instant::now();
        std::thread::scope(|s| {
            for k in 0..threads {
                let (gm, expected) = (&gm, &expected);
                s.spawn(move || {
                    for _ in (k..jobs).step_by(threads) {
                        let v = engine.voxelize(gm, method).unwrap();
                        assert!(v == *expected, "volume differs from the CPU engine's");
                    }
                });
            }
        });
        t.elapsed().as_secs_f64()
    };
    let g = run(&gpu);
    let c = run(&CpuEngine);
    println!(
        "{path} {} triangles {n}^3 {} x{jobs} threads {threads}: gpu {:.1} jobs/s ({:.2} ms/job), cpu {:.1} jobs/s; adapter {}",
        gm.triangles.len(),
        method.name(),
        jobs as f64 / g,
        g * 1000.0 / jobs as f64,
        jobs as f64 / c,
        gpu.adapter().name
    );
}
