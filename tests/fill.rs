//! Robust fills: vote and flood against the parity solid and the winding number, on closed
//! shapes and on meshes with holes smaller than a voxel.

mod common;

use common::*;
use voxd::engine::cpu::CpuEngine;
use voxd::engine::fill::{Fill, solid};
use voxd::engine::{Engine, GridMesh, Method};
use voxd::mesh::Mesh;

fn one_closed_shape(rng: &mut Rng, dims: [u32; 3]) -> Mesh {
    let (mut p, mut t) = (vec![], vec![]);
    let d = dims.map(|d| d as f64);
    match rng.below(2) {
        0 => {
            let lo = [0, 1, 2].map(|a| rng.half(0.5, d[a] / 2.0));
            let hi = [0, 1, 2].map(|a| lo[a] + rng.half(1.0, (d[a] - 0.5 - lo[a]).max(1.0)));
            push_box(&mut p, &mut t, lo, hi);
        }
        _ => {
            let c = [0, 1, 2].map(|a| d[a] / 2.0 + rng.range(-0.3, 0.3));
            let r = [0, 1, 2].map(|a| rng.range(1.0, d[a] / 2.0 - 0.6));
            push_octahedron(&mut p, &mut t, c, r);
        }
    }
    Mesh::new(p, t).unwrap()
}

#[test]
fn vote_equals_parity_and_flood_equals_conservative_on_closed_shapes() {
    for seed in 0..40u64 {
        let mut rng = Rng::new(1200 + seed);
        let dims = [
            4 + rng.below(8) as u32,
            4 + rng.below(8) as u32,
            4 + rng.below(70) as u32,
        ];
        let mesh = one_closed_shape(&mut rng, dims);
        let g = unit_grid(dims);
        let gm = GridMesh::new(&mesh, &g).unwrap();
        let parity = CpuEngine.voxelize(&gm, Method::Solid).unwrap();
        let vote = solid(&CpuEngine, &mesh, &g, Fill::Vote).unwrap();
        // Away from the surface (farther than the 1/256-voxel snapping can move it) all three
        // parities agree with the winding number.
        for x in 0..dims[0] {
            for y in 0..dims[1] {
                for z in 0..dims[2] {
                    let (w, dist) = winding_and_distance(&mesh, g.voxel_center(x, y, z));
                    if dist > 0.01 {
                        assert_eq!(
                            vote.get(x, y, z),
                            w.abs() > 0.5,
                            "seed {seed} vote at ({x},{y},{z})"
                        );
                        assert_eq!(parity.get(x, y, z), w.abs() > 0.5);
                    }
                }
            }
        }
        let flood = solid(&CpuEngine, &mesh, &g, Fill::Flood).unwrap();
        assert_eq!(
            flood,
            CpuEngine.voxelize(&gm, Method::Conservative).unwrap(),
            "seed {seed}: flood of one convex shape is solid ∪ surface"
        );
    }
}

/// A fine sphere with one triangle (smaller than a voxel) removed: parity streaks along the
/// column through the hole, vote and flood do not.
#[test]
fn small_holes_are_closed_by_vote_and_flood() {
    let (p, t) = sphere([12.3, 11.8, 12.1], 9.0, 5);
    let closed = Mesh::new(p.clone(), t.clone()).unwrap();
    // Remove an upper-hemisphere triangle whose xy projection holds the column centre (12.5, 11.5):
    // a hole smaller than a voxel that the column's ray passes through.
    let inside = |i: usize| {
        let [a, b, c] = t[i].map(|v| p[v as usize]);
        let e = |u: [f64; 3], v: [f64; 3]| {
            (v[0] - u[0]) * (11.5 - u[1]) - (v[1] - u[1]) * (12.5 - u[0])
        };
        let (x, y, z) = (e(a, b), e(b, c), e(c, a));
        a[2] > 12.1 && ((x > 0.0 && y > 0.0 && z > 0.0) || (x < 0.0 && y < 0.0 && z < 0.0))
    };
    let top = (0..t.len())
        .find(|&i| inside(i))
        .expect("a triangle over the column");
    let mut holed_t = t.clone();
    holed_t.remove(top);
    let holed = Mesh::new(p, holed_t).unwrap();
    assert!(!holed.diagnostics().watertight);
    let g = unit_grid([25, 24, 25]);
    let truth = solid(&CpuEngine, &closed, &g, Fill::Parity).unwrap();
    let parity = solid(&CpuEngine, &holed, &g, Fill::Parity).unwrap();
    let vote = solid(&CpuEngine, &holed, &g, Fill::Vote).unwrap();
    let flood = solid(&CpuEngine, &holed, &g, Fill::Flood).unwrap();
    let closed_flood = solid(&CpuEngine, &closed, &g, Fill::Flood).unwrap();
    let diff = |a: &voxd::BitVolume, b: &voxd::BitVolume| {
        a.words()
            .iter()
            .zip(b.words())
            .map(|(x, y)| (x ^ y).count_ones())
            .sum::<u32>()
    };
    assert!(
        diff(&parity, &truth) > 0,
        "the hole should make parity streak"
    );
    assert_eq!(
        diff(&vote, &truth),
        0,
        "vote repairs a hole smaller than a voxel"
    );
    assert_eq!(
        diff(&flood, &closed_flood),
        0,
        "flood is not fooled by a hole smaller than a voxel"
    );
}

#[test]
fn unknown_and_future_fills_are_refused_clearly() {
    assert!(
        "winding"
            .parse::<Fill>()
            .unwrap_err()
            .contains("not available yet")
    );
    assert!("blob".parse::<Fill>().unwrap_err().contains("unknown fill"));
}
