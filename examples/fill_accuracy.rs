//! Measures, for meshes that are not watertight, the share of voxels where each fill disagrees
//! with the exact winding number (|w| ≥ ½, w summed over every triangle), on voxels sampled away
//! from the surface (outside the surface dilated by one voxel, so every centre within one voxel of
//! a triangle is left out) and with |w| not within 0.01 of ½.
//!
//! cargo run --release --example fill_accuracy -- [RESOLUTION] [SAMPLES] MESH...

use rayon::prelude::*;
use voxd::engine::cpu::CpuEngine;
use voxd::engine::fill::{Fill, solid};
use voxd::engine::winding::exact_winding_number;
use voxd::engine::{Engine, GridMesh, Method};
use voxd::grid::{Grid, GridSpec};
use voxd::volume::morph::{Kernel, dilate};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let n: u32 = args.first().and_then(|a| a.parse().ok()).unwrap_or(128);
    let samples: usize = args.get(1).and_then(|a| a.parse().ok()).unwrap_or(20_000);
    for path in &args[2..] {
        let mesh = voxd::mesh::load_file(path.as_ref(), usize::MAX).expect("mesh");
        let (lo, hi) = mesh.bounds();
        let spec = GridSpec::Resolution { n, cubic: false };
        let g = Grid::fit(lo, hi, spec, 1, Default::default()).expect("grid");
        let surface = CpuEngine
            .voxelize(&GridMesh::new(&mesh, &g).unwrap(), Method::Surface)
            .unwrap();
        let near = dilate(&surface, 1, Kernel::Cube);
        // Deterministic, spread samples: a multiplicative walk over the voxel indices.
        let total = g.voxel_count();
        let mut picks = Vec::new();
        let mut i = 0u64;
        while picks.len() < samples && i < 4 * samples as u64 + total {
            let v = (i.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 7) % total;
            i += 1;
            let [_, ny, nz] = g.dims.map(|d| d as u64);
            let p = [v / (ny * nz), v / nz % ny, v % nz].map(|c| c as u32);
            if !near.get(p[0], p[1], p[2]) {
                picks.push(p);
            }
        }
        let tris: Vec<_> = (0..mesh.triangles().len())
            .map(|t| mesh.triangle(t))
            .collect();
        let truth: Vec<([u32; 3], bool)> = picks
            .par_iter()
            .filter_map(|&[x, y, z]| {
                let w = exact_winding_number(tris.iter().copied(), g.voxel_center(x, y, z));
                ((w.abs() - 0.5).abs() > 0.01).then_some(([x, y, z], w.abs() >= 0.5))
            })
            .collect();
        let mut line = format!("{path} at {n}: {} samples;", truth.len());
        for fill in [Fill::Parity, Fill::Vote, Fill::Flood, Fill::Winding] {
            let t = std::time::Instant::now();
            let v = solid(&CpuEngine, &mesh, &g, fill).unwrap().0;
            let secs = t.elapsed().as_secs_f64();
            let wrong = truth
                .iter()
                .filter(|([x, y, z], inside)| v.get(*x, *y, *z) != *inside)
                .count();
            line += &format!(
                " {fill} {:.3}% ({secs:.2} s)",
                100.0 * wrong as f64 / truth.len() as f64
            );
        }
        println!("{line}");
    }
}
