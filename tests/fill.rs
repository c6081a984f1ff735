//! Robust fills: vote and flood against the parity solid and the winding number, on closed
//! shapes and on meshes with holes smaller than a voxel.

use crate::common::*;
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
        let vote = solid(&CpuEngine, &mesh, &g, Fill::Vote).unwrap().0;
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
        let flood = solid(&CpuEngine, &mesh, &g, Fill::Flood).unwrap().0;
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
    let truth = solid(&CpuEngine, &closed, &g, Fill::Parity).unwrap().0;
    let parity = solid(&CpuEngine, &holed, &g, Fill::Parity).unwrap().0;
    let vote = solid(&CpuEngine, &holed, &g, Fill::Vote).unwrap().0;
    let flood = solid(&CpuEngine, &holed, &g, Fill::Flood).unwrap().0;
    let closed_flood = solid(&CpuEngine, &closed, &g, Fill::Flood).unwrap().0;
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
fn unknown_fills_are_refused_clearly() {
    let e = "blob".parse::<Fill>().unwrap_err();
    assert!(e.contains("unknown fill") && e.contains("winding") && e.contains("auto"));
    for f in Fill::ALL {
        assert_eq!(f.name().parse::<Fill>(), Ok(f));
    }
}

/// `(voxel, |w| ≥ ½)` for the exact winding number w at `voxels`, leaving out voxels whose centre
/// is within one voxel of the surface or whose |w| is within `tol` of ½. (In parallel: the
/// winding number of every voxel against every triangle is the bulk of these tests' time.)
fn exact_truth(
    mesh: &Mesh,
    g: &voxd::grid::Grid,
    voxels: impl IntoIterator<Item = [u32; 3]>,
    tol: f64,
) -> Vec<([u32; 3], bool)> {
    use rayon::prelude::*;
    let voxels: Vec<[u32; 3]> = voxels.into_iter().collect();
    voxels
        .into_par_iter()
        .filter_map(|[x, y, z]| {
            let (w, dist) = winding_and_distance(mesh, g.voxel_center(x, y, z));
            (dist > g.voxel_size && (w.abs() - 0.5).abs() > tol)
                .then_some(([x, y, z], w.abs() >= 0.5))
        })
        .collect()
}

/// The voxels of `truth` where `got` differs.
fn disagreements(got: &voxd::BitVolume, truth: &[([u32; 3], bool)]) -> Vec<[u32; 3]> {
    truth
        .iter()
        .filter(|([x, y, z], inside)| got.get(*x, *y, *z) != *inside)
        .map(|(v, _)| *v)
        .collect()
}

fn all_voxels(dims: [u32; 3]) -> impl Iterator<Item = [u32; 3]> {
    (0..dims[0])
        .flat_map(move |x| (0..dims[1]).flat_map(move |y| (0..dims[2]).map(move |z| [x, y, z])))
}

/// A random closed shape (a sphere, sometimes overlapped by a box, where w = 2) with holes
/// punched in it: a few random triangles, sometimes a whole cap (an open bowl), sometimes with
/// every triangle flipped.
fn holey_mesh(rng: &mut Rng, dims: [u32; 3]) -> Mesh {
    let d = dims.map(|d| d as f64);
    let c = [0, 1, 2].map(|a| d[a] / 2.0 + rng.range(-1.0, 1.0));
    let r = rng.range(3.0, d.iter().cloned().fold(f64::MAX, f64::min) / 2.0 - 1.2);
    let (mut p, mut t) = sphere(c, r, 2 + rng.below(2) as u32);
    if rng.below(3) == 0 {
        let lo = [0, 1, 2].map(|a| c[a] + rng.range(-r, 0.0));
        let hi = [0, 1, 2].map(|a| (lo[a] + rng.range(2.0, r + 2.0)).min(d[a] - 0.3));
        push_box(&mut p, &mut t, lo, hi);
    }
    match rng.below(3) {
        0 => {
            // An open bowl: everything above a random height goes.
            let h = c[2] + rng.range(0.2, 0.9) * r;
            t.retain(|tri| tri.iter().map(|&v| p[v as usize][2]).sum::<f64>() / 3.0 < h);
        }
        _ => {
            for _ in 0..1 + rng.below(6) {
                let i = rng.below(t.len() as u64) as usize;
                t.remove(i);
            }
        }
    }
    let m = Mesh::new(p, t).unwrap();
    if rng.below(2) == 0 { m.flipped() } else { m }
}

#[test]
fn winding_matches_the_exact_winding_number_on_meshes_with_holes() {
    let mut total = (0, 0);
    for seed in 0..24u64 {
        let mut rng = Rng::new(7100 + seed);
        let dims = [0, 1, 2].map(|_| 12 + rng.below(10) as u32);
        let mesh = holey_mesh(&mut rng, dims);
        assert!(!mesh.diagnostics().watertight);
        let g = unit_grid(dims);
        let (got, stats) = solid(&CpuEngine, &mesh, &g, Fill::Winding).unwrap();
        let stats = stats.unwrap();
        assert!(stats.cap_triangles > 0);
        assert_eq!(
            stats.exact_voxels
                + stats.cap_block_voxels
                + stats.mesh_block_voxels
                + stats.cap_evaluated_voxels
                + stats.mesh_evaluated_voxels
                + stats.near_evaluated_voxels,
            g.voxel_count()
        );
        let truth = exact_truth(&mesh, &g, all_voxels(dims), 0.01);
        let wrong = disagreements(&got, &truth);
        assert!(
            wrong.is_empty(),
            "seed {seed}: {} of {} voxels differ: {:?}",
            wrong.len(),
            truth.len(),
            &wrong[..wrong.len().min(5)]
        );
        total.0 += truth.len();
        total.1 += stats.cap_evaluated_voxels + stats.near_evaluated_voxels;
    }
    // Both parts of the evaluation were exercised.
    assert!(total.0 > 20_000 && total.1 > 2_000, "{total:?}");
}

#[test]
fn winding_of_a_flipped_mesh_is_the_same_solid() {
    for seed in 0..12u64 {
        let mut rng = Rng::new(7300 + seed);
        let dims = [0, 1, 2].map(|_| 10 + rng.below(12) as u32);
        let mesh = holey_mesh(&mut rng, dims);
        let g = unit_grid(dims);
        let a = solid(&CpuEngine, &mesh, &g, Fill::Winding).unwrap().0;
        let b = solid(&CpuEngine, &mesh.flipped(), &g, Fill::Winding)
            .unwrap()
            .0;
        assert_eq!(first_difference(&a, &b), None, "seed {seed}");
        assert!(a.count_ones() > 0);
    }
}

#[test]
fn winding_equals_parity_on_a_watertight_mesh() {
    let (mesh, g) = mesh_and_grid(
        &data("spot.obj"),
        voxd::grid::GridSpec::Resolution {
            n: 64,
            cubic: false,
        },
        1,
    );
    let (w, stats) = solid(&CpuEngine, &mesh, &g, Fill::Winding).unwrap();
    let stats = stats.unwrap();
    assert_eq!(
        (stats.cap_triangles, stats.exact_voxels),
        (0, g.voxel_count())
    );
    let p = solid(&CpuEngine, &mesh, &g, Fill::Parity).unwrap().0;
    assert_eq!(first_difference(&w, &p), None);
}

/// Closed shells that overlap (winding number 2 where two outward boxes meet) or are nested the
/// other way round (an inward box inside an outward one: 0, a cavity): closed as chains, so
/// the winding fill counts signed crossings alone, with no caps. Checked against the exact
/// winding number at every voxel; parity, which sees 2 as outside, must differ somewhere.
#[test]
fn winding_counts_overlapping_and_nested_closed_shells() {
    let mut parity_differs = 0;
    for seed in 0..8u64 {
        let mut rng = Rng::new(7700 + seed);
        let dims = [0, 1, 2].map(|_| 14 + rng.below(8) as u32);
        let (mut p, mut t) = (vec![], vec![]);
        for b in 0..4 {
            let lo = dims.map(|d| rng.range(1.0, 1.0 + d as f64 * 0.4));
            let hi = [0, 1, 2].map(|a| rng.range(lo[a] + 2.0, dims[a] as f64 - 1.0));
            let first = t.len();
            push_box(&mut p, &mut t, lo, hi);
            // Every other box inward (after the first): a cavity where it lies inside another.
            if b % 2 == 1 {
                for tri in &mut t[first..] {
                    tri.swap(1, 2);
                }
            }
        }
        let mesh = Mesh::new(p, t).unwrap();
        let g = unit_grid(dims);
        let (got, stats) = solid(&CpuEngine, &mesh, &g, Fill::Winding).unwrap();
        assert_eq!(
            stats.unwrap().cap_triangles,
            0,
            "seed {seed}: closed shells need no caps"
        );
        let truth = exact_truth(&mesh, &g, all_voxels(dims), 0.01);
        let wrong = disagreements(&got, &truth);
        assert!(
            wrong.is_empty(),
            "seed {seed}: {:?}",
            &wrong[..wrong.len().min(5)]
        );
        let parity = solid(&CpuEngine, &mesh, &g, Fill::Parity).unwrap().0;
        parity_differs += disagreements(&parity, &truth).len();
    }
    assert!(parity_differs > 20, "{parity_differs}");
}

/// A fine sphere with single triangles (smaller than a voxel) removed: vote, flood and winding
/// all agree with the exact winding number away from the surface; parity does not.
#[test]
fn every_robust_fill_handles_holes_smaller_than_a_voxel() {
    for seed in 0..2u64 {
        let mut rng = Rng::new(7500 + seed);
        let (p, mut t) = sphere([12.3, 11.8, 12.1], 9.0, 5);
        // Holes in the upper cap, where the columns through them cross the whole solid.
        let g = unit_grid([25, 24, 25]);
        let covers_a_column = |tri: &[u32; 3]| {
            let one = Mesh::new(p.clone(), vec![*tri]).unwrap();
            let s = &snap(&one, &g)[0];
            (0..25).any(|x| (0..24).any(|y| column_depth(s, [centre(x), centre(y)]).is_some()))
        };
        for _ in 0..2 {
            loop {
                let i = rng.below(t.len() as u64) as usize;
                if p[t[i][0] as usize][2] > 19.0 && covers_a_column(&t[i]) {
                    t.remove(i);
                    break;
                }
            }
        }
        let mesh = Mesh::new(p, t).unwrap();
        let mut parity_wrong = 0;
        let truth = exact_truth(&mesh, &g, all_voxels(g.dims), 0.01);
        assert!(truth.len() > 5000);
        for fill in [Fill::Parity, Fill::Vote, Fill::Flood, Fill::Winding] {
            let got = solid(&CpuEngine, &mesh, &g, fill).unwrap().0;
            let wrong = disagreements(&got, &truth);
            if fill == Fill::Parity {
                parity_wrong = wrong.len();
            } else {
                assert!(
                    wrong.is_empty(),
                    "seed {seed} {fill}: {} of {}: {:?}",
                    wrong.len(),
                    truth.len(),
                    &wrong[..wrong.len().min(5)]
                );
            }
        }
        assert!(
            parity_wrong > 0,
            "seed {seed}: the holes should make parity streak"
        );
    }
}

#[test]
fn auto_picks_parity_for_watertight_meshes_and_winding_otherwise() {
    use voxd::engine::fill::voxelize;
    let (spot, g) = mesh_and_grid(
        &data("spot.obj"),
        voxd::grid::GridSpec::Resolution {
            n: 24,
            cubic: false,
        },
        0,
    );
    let d = spot.diagnostics();
    let (v, r) = voxelize(&CpuEngine, &spot, &g, Method::Solid, Fill::Auto, &d).unwrap();
    assert_eq!(
        (r.requested, r.used, r.odd_parity_columns),
        (Fill::Auto, Fill::Parity, 0)
    );
    assert!(r.warning.is_none() && r.winding.is_none());
    assert_eq!(
        v,
        CpuEngine
            .voxelize(&GridMesh::new(&spot, &g).unwrap(), Method::Solid)
            .unwrap()
    );

    let mut rng = Rng::new(7700);
    let mesh = holey_mesh(&mut rng, [16, 16, 16]);
    let g = unit_grid([16, 16, 16]);
    let d = mesh.diagnostics();
    for m in [Method::Solid, Method::Conservative, Method::Interior] {
        let (v, r) = voxelize(&CpuEngine, &mesh, &g, m, Fill::Auto, &d).unwrap();
        assert_eq!(r.used, Fill::Winding);
        assert!(r.winding.is_some() && r.warning.is_none());
        let (w, _) = voxelize(&CpuEngine, &mesh, &g, m, Fill::Winding, &d).unwrap();
        assert_eq!(v, w);
    }
    let (_, r) = voxelize(&CpuEngine, &mesh, &g, Method::Solid, Fill::Parity, &d).unwrap();
    assert!(r.warning.unwrap().contains("not watertight"));
    // Surface has no solid part: the fill changes nothing.
    let (s, _) = voxelize(&CpuEngine, &mesh, &g, Method::Surface, Fill::Winding, &d).unwrap();
    assert_eq!(
        s,
        CpuEngine
            .voxelize(&GridMesh::new(&mesh, &g).unwrap(), Method::Surface)
            .unwrap()
    );
}

/// Odd-parity columns against a brute-force count over every triangle, the ones above the grid
/// included.
#[test]
fn odd_parity_columns_match_brute_force() {
    for seed in 0..16u64 {
        let mut rng = Rng::new(7800 + seed);
        let dims = [0, 1, 2].map(|_| 10 + rng.below(10) as u32);
        let mesh = holey_mesh(&mut rng, dims);
        // A grid that holds only the lower part of the mesh: triangles above it still count.
        let g = unit_grid([dims[0], dims[1], dims[2] / 2]);
        let tris = snap(&mesh, &g);
        let mut odd = 0;
        for x in 0..g.dims[0] {
            for y in 0..g.dims[1] {
                let c = [centre(x), centre(y)];
                let n = tris.iter().filter(|t| column_depth(t, c).is_some()).count();
                odd += n % 2;
            }
        }
        let got = voxd::engine::cpu::odd_parity_columns(&mesh, &g);
        assert_eq!(got, odd as u64, "seed {seed}");
        if seed == 0 {
            assert_eq!(voxd::engine::cpu::odd_parity_columns(&sphere_mesh(), &g), 0);
        }
    }
}

/// A watertight mesh covers every column centre an even number of times, so the fill report
/// does not count odd-parity columns for one (it says 0): checked against the brute-force count
/// on random closed solids with vertices on column centres and faces on voxel faces, on grids
/// that cut them, and on spot. For meshes that are not watertight the report's count is the
/// counted one.
#[test]
fn watertight_meshes_have_no_odd_parity_column() {
    let brute = |mesh: &Mesh, g: &voxd::grid::Grid| {
        let tris = snap(mesh, g);
        let mut odd = 0u64;
        for x in 0..g.dims[0] {
            for y in 0..g.dims[1] {
                let c = [centre(x), centre(y)];
                odd += tris.iter().filter(|t| column_depth(t, c).is_some()).count() as u64 % 2;
            }
        }
        odd
    };
    let report = |mesh: &Mesh, g: &voxd::grid::Grid| {
        let d = mesh.diagnostics();
        let r = voxd::engine::fill::FillReport::new(Fill::Parity, mesh, g, &d);
        (d.watertight, r.odd_parity_columns)
    };
    let mut watertight = 0;
    for seed in 0..150u64 {
        let mut rng = Rng::new(8100 + seed);
        let dims = [0, 1, 2].map(|_| 4 + rng.below(12) as u32);
        let mesh = random_closed(&mut rng, dims);
        let g = unit_grid([dims[0], dims[1], 1 + dims[2] / 2]);
        let (closed, reported) = report(&mesh, &g);
        if closed {
            assert_eq!(brute(&mesh, &g), 0, "seed {seed}");
            assert_eq!(reported, 0);
            watertight += 1;
        } else {
            assert_eq!(reported, voxd::engine::cpu::odd_parity_columns(&mesh, &g));
        }
    }
    assert!(
        watertight >= 100,
        "only {watertight} meshes were watertight"
    );
    for seed in 0..8u64 {
        let mut rng = Rng::new(8300 + seed);
        let mesh = holey_mesh(&mut rng, [14, 14, 14]);
        let g = unit_grid([14, 14, 14]);
        let (closed, reported) = report(&mesh, &g);
        assert!(!closed);
        assert_eq!(reported, brute(&mesh, &g), "seed {seed}");
    }
    let spot = voxd::mesh::load_file(&data("spot.obj"), usize::MAX).unwrap();
    let d = spot.diagnostics();
    for n in [17, 64] {
        let spec = voxd::grid::GridSpec::Resolution { n, cubic: n == 17 };
        let g = voxd::grid::Grid::fit(d.bbox_min, d.bbox_max, spec, 1, Default::default()).unwrap();
        let (closed, reported) = report(&spot, &g);
        assert!(closed);
        assert_eq!((reported, brute(&spot, &g)), (0, 0), "spot at {n}");
    }
}

fn sphere_mesh() -> Mesh {
    let (p, t) = sphere([6.2, 5.9, 4.1], 3.5, 3);
    Mesh::new(p, t).unwrap()
}

#[test]
fn density_uses_the_fill() {
    let mut rng = Rng::new(7900);
    let mesh = holey_mesh(&mut rng, [12, 12, 12]);
    let g = unit_grid([6, 6, 6]);
    let d = mesh.diagnostics();
    let limits = voxd::grid::GridLimits::default();
    for fill in [Fill::Parity, Fill::Winding, Fill::Flood, Fill::Vote] {
        let (dens, r) =
            voxd::engine::density::density(&CpuEngine, &mesh, &g, 2, limits, fill, &d).unwrap();
        assert_eq!(r.used, fill);
        // The sub-voxel solid under the same fill, counted by hand.
        let fine = voxd::engine::density::fine_grid(&g, 2, limits).unwrap();
        let s = solid(&CpuEngine, &mesh, &fine, fill).unwrap().0;
        for [x, y, z] in all_voxels(g.dims) {
            let mut n = 0;
            for [a, b, c] in all_voxels([2, 2, 2]) {
                n += s.get(2 * x + a, 2 * y + b, 2 * z + c) as u8;
            }
            assert_eq!(dens.get(x, y, z), n, "{fill} at ({x},{y},{z})");
        }
    }
}

/// Each real mesh that is not watertight, at 128³: the winding fill is solid exactly where the
/// exact winding number says so, on sampled voxels away from the surface; the share of sampled
/// voxels where each fill disagrees is printed.
#[test]
fn real_open_meshes_follow_the_exact_winding_number() {
    let Some(dir) = shared_meshes() else { return };
    for name in [
        "stanford-bunny.obj",
        "teapot.obj",
        "suzanne.obj",
        "ogre.obj",
        "2CylinderEngine.gltf",
    ] {
        let (mesh, g) = mesh_and_grid(
            &dir.join(name),
            voxd::grid::GridSpec::Resolution {
                n: 128,
                cubic: false,
            },
            1,
        );
        assert!(!mesh.diagnostics().watertight, "{name}");
        let surface = CpuEngine
            .voxelize(&GridMesh::new(&mesh, &g).unwrap(), Method::Surface)
            .unwrap();
        let near = voxd::volume::morph::dilate(&surface, 1, voxd::volume::morph::Kernel::Cube);
        // Sample voxels off the dilated surface, half of them from the dilation of the solid
        // (where the fills differ) and half anywhere.
        let mut rng = Rng::new(8000);
        let wind = solid(&CpuEngine, &mesh, &g, Fill::Winding).unwrap().0;
        let zone = voxd::volume::morph::dilate(&wind, 3, voxd::volume::morph::Kernel::Cube);
        let mut samples = Vec::new();
        while samples.len() < 1200 {
            let v = [0, 1, 2].map(|a| rng.below(g.dims[a] as u64) as u32);
            if !near.get(v[0], v[1], v[2]) && (samples.len() % 2 == 0 || zone.get(v[0], v[1], v[2]))
            {
                samples.push(v);
            }
        }
        let truth = exact_truth(&mesh, &g, samples, 0.01);
        assert!(truth.len() > 1000, "{name}: {}", truth.len());
        let mut line = format!("{name}:");
        for fill in [Fill::Winding, Fill::Parity, Fill::Vote, Fill::Flood] {
            let got = if fill == Fill::Winding {
                wind.clone()
            } else {
                solid(&CpuEngine, &mesh, &g, fill).unwrap().0
            };
            let wrong = disagreements(&got, &truth);
            if fill == Fill::Winding {
                assert!(
                    wrong.is_empty(),
                    "{name}: {} of {}, first {:?}",
                    wrong.len(),
                    truth.len(),
                    wrong[0]
                );
            }
            line += &format!(
                " {fill} {:.2}%",
                100.0 * wrong.len() as f64 / truth.len() as f64
            );
        }
        println!("{line} of sampled voxels off the surface disagree with the exact winding number");
    }
}

/// A winding fill canceled once it has started stops at a check point: `Canceled`, with the
/// progress it had reached (below 1) and no volume; a control canceled before the run stops it
/// before any work, and one past its deadline says so.
#[test]
fn a_canceled_winding_fill_stops_at_a_check_point() {
    use std::time::{Duration, Instant};
    use voxd::cancel::{Canceled, Control};
    use voxd::engine::EngineError;
    let mesh = open_bowl();
    let (lo, hi) = mesh.bounds();
    let g = voxd::grid::Grid::fit(
        lo,
        hi,
        voxd::grid::GridSpec::Resolution {
            n: 160,
            cubic: false,
        },
        1,
        Default::default(),
    )
    .unwrap();
    let ctl = Control::new();
    let result = std::thread::scope(|s| {
        let watcher = ctl.clone();
        s.spawn(move || {
            // Cancel as soon as the fill has reported any progress (bounded).
            let t0 = Instant::now();
            while watcher.progress() == 0.0 && t0.elapsed() < Duration::from_secs(300) {
                std::thread::sleep(Duration::from_micros(200));
            }
            watcher.cancel();
        });
        voxd::engine::winding::solid_with(&mesh, &g, &ctl)
    });
    assert_eq!(
        result.map(|_| ()),
        Err(EngineError::Canceled(Canceled::Canceled))
    );
    let at = ctl.progress();
    assert!(at > 0.0 && at < 1.0, "stopped at {at}");
    let before = Control::new();
    before.cancel();
    let d = mesh.diagnostics();
    for fill in [Fill::Winding, Fill::Vote, Fill::Flood, Fill::Parity] {
        let r = voxd::engine::fill::voxelize_with(
            &CpuEngine,
            &mesh,
            &g,
            Method::Solid,
            fill,
            &d,
            &before,
        );
        assert_eq!(
            r.map(|_| ()),
            Err(EngineError::Canceled(Canceled::Canceled)),
            "{fill}"
        );
        assert_eq!(before.progress(), 0.0);
    }
    let expired = Control::new().with_deadline(Instant::now());
    let r = voxd::engine::density::density_with(
        &CpuEngine,
        &mesh,
        &unit_grid([8, 8, 8]),
        2,
        Default::default(),
        Fill::Winding,
        &d,
        &expired,
    );
    assert!(
        matches!(
            r,
            Err(voxd::engine::density::DensityError::Engine(
                EngineError::Canceled(Canceled::DeadlinePassed)
            ))
        ),
        "{r:?}"
    );
}

/// Progress under every fill and method rises monotonically (sampled from another thread
/// while the work runs) and ends at exactly 1, and the bits are those of a run without a
/// control.
#[test]
fn fill_progress_rises_monotonically_to_one() {
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::time::Duration;
    use voxd::cancel::Control;
    let mesh = open_bowl();
    let (lo, hi) = mesh.bounds();
    let g = voxd::grid::Grid::fit(
        lo,
        hi,
        voxd::grid::GridSpec::Resolution {
            n: 72,
            cubic: false,
        },
        1,
        Default::default(),
    )
    .unwrap();
    let d = mesh.diagnostics();
    for fill in [Fill::Winding, Fill::Vote, Fill::Flood, Fill::Parity] {
        for method in [Method::Solid, Method::Conservative, Method::Interior] {
            let ctl = Control::new();
            let done = AtomicBool::new(false);
            let (got, samples) = std::thread::scope(|s| {
                let sampler = s.spawn(|| {
                    let mut seen = vec![];
                    while !done.load(Ordering::Acquire) {
                        seen.push(ctl.progress());
                        std::thread::sleep(Duration::from_micros(100));
                    }
                    seen
                });
                let got = voxd::engine::fill::voxelize_with(
                    &CpuEngine, &mesh, &g, method, fill, &d, &ctl,
                )
                .unwrap();
                done.store(true, Ordering::Release);
                (got, sampler.join().unwrap())
            });
            let what = format!("{fill} {method}");
            assert!(
                samples.windows(2).all(|w| w[0] <= w[1]),
                "{what}: {samples:?}"
            );
            assert_eq!(ctl.progress(), 1.0, "{what}");
            let want =
                voxd::engine::fill::voxelize(&CpuEngine, &mesh, &g, method, fill, &d).unwrap();
            assert_eq!(got, want, "{what}");
        }
        let ctl = Control::new();
        voxd::engine::density::density_with(
            &CpuEngine,
            &mesh,
            &unit_grid([10, 10, 10]),
            2,
            Default::default(),
            fill,
            &d,
            &ctl,
        )
        .unwrap();
        assert_eq!(ctl.progress(), 1.0, "density {fill}");
    }
}

/// With every fill, conservative is the fill's solid with the surface added and interior the
/// fill's solid with the surface taken away (docs/methods.md), the two volumes computed apart
/// and combined here.
#[test]
fn conservative_and_interior_are_the_fills_solid_with_and_without_the_surface() {
    use voxd::engine::fill::voxelize;
    for seed in 0..4u64 {
        let mut rng = Rng::new(7900 + seed);
        let mesh = holey_mesh(&mut rng, [14, 15, 16]);
        let g = unit_grid([14, 15, 16]);
        let d = mesh.diagnostics();
        let surface = CpuEngine
            .voxelize(&GridMesh::new(&mesh, &g).unwrap(), Method::Surface)
            .unwrap();
        for fill in [Fill::Winding, Fill::Vote, Fill::Flood, Fill::Parity] {
            let (s, _) = solid(&CpuEngine, &mesh, &g, fill).unwrap();
            let (mut with, mut without) = (s.clone(), s.clone());
            with.union_with(&surface);
            without.subtract(&surface);
            // A test that cannot fail is a defect: the surface must change them (flood's solid
            // already holds its surface: it is everything the outside cannot reach).
            assert!(without != s, "seed {seed} {fill}");
            assert_eq!(with == s, fill == Fill::Flood, "seed {seed} {fill}");
            for (m, want) in [(Method::Conservative, &with), (Method::Interior, &without)] {
                let (got, _) = voxelize(&CpuEngine, &mesh, &g, m, fill, &d).unwrap();
                assert!(&got == want, "seed {seed} {fill} {m}");
            }
        }
    }
}
