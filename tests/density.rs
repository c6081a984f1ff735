//! Density: analytic partial-voxel counts, the reduction against a naive count, and (with an
//! adapter) GPU == CPU.

use crate::common::*;
use voxd::engine::cpu::CpuEngine;
use voxd::engine::density::{density, fine_grid};
use voxd::engine::fill::Fill;
use voxd::engine::{Engine, GridMesh, Method};
use voxd::grid::{Grid, GridLimits};
use voxd::mesh::Mesh;

/// Sub-voxel centres of voxel i (factor f) strictly inside (lo, hi) along one axis.
fn axis_count(lo: f64, hi: f64, i: u32, f: u32) -> u32 {
    (0..f)
        .filter(|k| {
            let c = i as f64 + (*k as f64 + 0.5) / f as f64;
            lo < c && c < hi
        })
        .count() as u32
}

#[test]
fn a_box_has_the_analytic_partial_counts() {
    let (lo, hi) = ([0.4, 0.1, 1.6], [2.6, 1.3, 3.9]);
    let (mut p, mut t) = (vec![], vec![]);
    push_box(&mut p, &mut t, lo, hi);
    let mesh = Mesh::new(p, t).unwrap();
    let g = unit_grid([4, 4, 5]);
    for f in [2, 4] {
        let d = density(
            &CpuEngine,
            &mesh,
            &g,
            f,
            GridLimits::default(),
            Fill::Parity,
            &mesh.diagnostics(),
        )
        .unwrap()
        .0;
        assert_eq!(d.max() as u32, f * f * f);
        for x in 0..4 {
            for y in 0..4 {
                for z in 0..5 {
                    let want = axis_count(lo[0], hi[0], x, f)
                        * axis_count(lo[1], hi[1], y, f)
                        * axis_count(lo[2], hi[2], z, f);
                    assert_eq!(d.get(x, y, z) as u32, want, "f={f} voxel ({x},{y},{z})");
                }
            }
        }
        // The total is the product of the sampled lengths per axis (each within 1/f of the true one).
        let dims = [4, 4, 5];
        let sampled: f64 = (0..3)
            .map(|a| {
                (0..dims[a])
                    .map(|i| axis_count(lo[a], hi[a], i, f))
                    .sum::<u32>() as f64
                    / f as f64
            })
            .product();
        assert_eq!(d.occupied_voxels(), sampled, "f={f}");
        for a in 0..3 {
            let len = (0..dims[a])
                .map(|i| axis_count(lo[a], hi[a], i, f))
                .sum::<u32>() as f64
                / f as f64;
            assert!(
                (len - (hi[a] - lo[a])).abs() <= 1.0 / f as f64,
                "axis {a}: {len}"
            );
        }
    }
}

#[test]
fn the_reduction_counts_the_fine_solid() {
    for seed in 0..20u64 {
        let mut rng = Rng::new(300 + seed);
        let dims = [
            1 + rng.below(9) as u32,
            1 + rng.below(9) as u32,
            [1, 15, 16, 17, 33][rng.below(5) as usize],
        ];
        let mesh = random_closed(&mut rng, dims);
        let g = Grid {
            origin: [-0.3, 0.2, -0.1],
            voxel_size: 0.97,
            dims,
        };
        for f in [2u32, 4] {
            let d = density(
                &CpuEngine,
                &mesh,
                &g,
                f,
                GridLimits::default(),
                Fill::Parity,
                &mesh.diagnostics(),
            )
            .unwrap()
            .0;
            let fine = fine_grid(&g, f, GridLimits::default()).unwrap();
            let s = CpuEngine
                .voxelize(&GridMesh::new(&mesh, &fine).unwrap(), Method::Solid)
                .unwrap();
            for x in 0..dims[0] {
                for y in 0..dims[1] {
                    for z in 0..dims[2] {
                        let mut n = 0;
                        for (dx, dy, dz) in (0..f)
                            .flat_map(|a| (0..f).flat_map(move |b| (0..f).map(move |c| (a, b, c))))
                        {
                            n += s.get(x * f + dx, y * f + dy, z * f + dz) as u32;
                        }
                        assert_eq!(d.get(x, y, z) as u32, n, "seed {seed} f={f} ({x},{y},{z})");
                    }
                }
            }
        }
    }
}

#[test]
fn the_finer_grid_must_fit_the_budget() {
    let mesh = Mesh::new(
        vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        vec![[0, 1, 2]],
    )
    .unwrap();
    let e = density(
        &CpuEngine,
        &mesh,
        &unit_grid([64, 64, 64]),
        4,
        GridLimits {
            max_voxels: 1 << 20,
        },
        Fill::Parity,
        &mesh.diagnostics(),
    )
    .unwrap_err();
    assert!(
        e.to_string().contains("4× finer grid") && e.to_string().contains("over the limit"),
        "{e}"
    );
}

/// Normals of a sphere's density point outward: all boundary voxels within 35° of the radial
/// direction, and most within 20°.
#[test]
fn normals_of_a_sphere_point_outward() {
    use voxd::volume::Volume;
    use voxd::volume::normals::normal_at;
    // An octahedron subdivided onto a sphere of radius 10 centred at (12, 12, 12).
    let (p, t) = sphere([12.0; 3], 10.0, 4);
    let mesh = Mesh::new(p, t).unwrap();
    let g = unit_grid([24, 24, 24]);
    let d = density(
        &CpuEngine,
        &mesh,
        &g,
        2,
        GridLimits::default(),
        Fill::Parity,
        &mesh.diagnostics(),
    )
    .unwrap()
    .0;
    let v = Volume::Density(d.clone());
    let (mut n, mut good) = (0, 0);
    for x in 0..24 {
        for y in 0..24 {
            for z in 0..24 {
                let val = d.get(x, y, z);
                if val == 0 || val == 8 {
                    continue;
                }
                let c = g.voxel_center(x, y, z);
                let r = [c[0] - 12.0, c[1] - 12.0, c[2] - 12.0];
                let rl = (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt();
                let nn = normal_at(&v, c).expect("boundary voxels have a gradient");
                let cos = (0..3).map(|k| nn[k] * r[k] / rl).sum::<f64>();
                assert!(
                    cos > 35f64.to_radians().cos(),
                    "voxel ({x},{y},{z}): normal {nn:?} vs radial {r:?}"
                );
                n += 1;
                good += (cos > 20f64.to_radians().cos()) as u32;
            }
        }
    }
    // Central differences on a 24³ density: measured 888 of 984 (90%) within 20°.
    assert!(
        n > 500 && good as f64 > 0.85 * n as f64,
        "{good} of {n} within 20°"
    );
    assert_eq!(
        normal_at(&v, [12.0, 12.0, 12.0]),
        None,
        "no gradient deep inside"
    );
    assert_eq!(normal_at(&v, [-5.0, 0.0, 0.0]), None, "outside the grid");
}
