//! The CPU engine against brute-force oracles and analytic shapes.

use crate::common::*;
use voxd::engine::cpu::CpuEngine;
use voxd::engine::{Engine, GridMesh, Method};
use voxd::grid::Grid;
use voxd::mesh::Mesh;
use voxd::volume::BitVolume;

fn run(mesh: &Mesh, g: &Grid, m: Method) -> BitVolume {
    CpuEngine
        .voxelize(&GridMesh::new(mesh, g).unwrap(), m)
        .unwrap()
}

fn assert_same(got: &BitVolume, want: &BitVolume, what: &str) {
    if let Some(d) = first_difference(got, want) {
        panic!("{what}: {d}");
    }
}

fn random_dims(rng: &mut Rng) -> [u32; 3] {
    // z sometimes crosses one or two 64-bit words.
    [
        1 + rng.below(12) as u32,
        1 + rng.below(12) as u32,
        [1, 7, 63, 64, 65, 130][rng.below(6) as usize],
    ]
}

#[test]
fn every_method_matches_brute_force_on_random_meshes() {
    for seed in 0..160u64 {
        let mut rng = Rng::new(seed);
        let dims = random_dims(&mut rng);
        let mesh = random_mesh(&mut rng, dims, seed);
        // One seed in four also uses a grid that is not the unit lattice, so snapping rounds.
        let g = if seed % 4 == 3 {
            off_lattice_grid(dims)
        } else {
            unit_grid(dims)
        };
        let solid = solid_brute(&mesh, &g);
        let surface = surface_brute(&mesh, &g);
        assert_same(
            &run(&mesh, &g, Method::Solid),
            &solid,
            &format!("solid, seed {seed}"),
        );
        assert_same(
            &run(&mesh, &g, Method::Surface),
            &surface,
            &format!("surface, seed {seed}"),
        );
        let mut conservative = solid.clone();
        conservative.union_with(&surface);
        assert_same(
            &run(&mesh, &g, Method::Conservative),
            &conservative,
            &format!("conservative, seed {seed}"),
        );
        let mut interior = solid.clone();
        interior.subtract(&surface);
        assert_same(
            &run(&mesh, &g, Method::Interior),
            &interior,
            &format!("interior, seed {seed}"),
        );
    }
}

/// Small triangles (a fraction of a voxel to two voxels) with corners on, just off and beside
/// voxel faces, flat ones in one layer, and ones reaching out of the grid: the shapes the
/// surface method decides without the z-dependent axes (one column, one layer) and the ones
/// just outside those cases, each against the brute-force oracle.
#[test]
fn small_triangles_at_voxel_faces_match_brute_force() {
    // Offsets inside a voxel, in 1/256 of a voxel (the unit grid snaps them exactly).
    const OFF: [i32; 11] = [-2, -1, 0, 1, 2, 127, 128, 254, 255, 256, 257];
    for seed in 0..40u64 {
        let mut rng = Rng::new(1000 + seed);
        let dims = [4, 5, [3, 7, 65][rng.below(3) as usize]];
        let coord = |rng: &mut Rng, a: usize| {
            let cell = rng.below(dims[a] as u64 + 2) as i32 - 1;
            (cell * 256 + OFF[rng.below(OFF.len() as u64) as usize]) as f64 / 256.0
        };
        let (mut p, mut t) = (vec![], vec![]);
        for _ in 0..60 {
            let a = [0, 1, 2].map(|k| coord(&mut rng, k));
            let mut v = [a; 3];
            for q in &mut v[1..] {
                for c in q.iter_mut() {
                    // Up to two voxels away, on the same 1/256 lattice.
                    *c += (rng.below(513) as f64 - 256.0) / 256.0 * (1 + rng.below(2)) as f64;
                }
            }
            match rng.below(4) {
                0 => v.iter_mut().for_each(|q| q[2] = a[2]), // flat: one z
                1 => v[2] = v[1],                            // a segment
                _ => {}
            }
            let b = p.len() as u32;
            p.extend_from_slice(&v);
            t.push([b, b + 1, b + 2]);
        }
        let mesh = Mesh::new(p, t).unwrap();
        let g = unit_grid(dims);
        assert_same(
            &run(&mesh, &g, Method::Surface),
            &surface_brute(&mesh, &g),
            &format!("surface, seed {seed}"),
        );
    }
}

/// Independent of the tie rules' code: for closed solids whose vertices sit on column centres and
/// voxel faces, every voxel centre not on the surface is solid iff the winding number is odd.
#[test]
fn parity_equals_winding_number_off_the_surface() {
    let mut checked = 0;
    for seed in 0..60u64 {
        let mut rng = Rng::new(1000 + seed);
        let dims = [
            2 + rng.below(9) as u32,
            2 + rng.below(9) as u32,
            2 + rng.below(9) as u32,
        ];
        let mesh = random_closed(&mut rng, dims);
        let g = unit_grid(dims);
        let solid = run(&mesh, &g, Method::Solid);
        for x in 0..dims[0] {
            for y in 0..dims[1] {
                for z in 0..dims[2] {
                    let (w, dist) = winding_and_distance(&mesh, g.voxel_center(x, y, z));
                    if dist < 1e-9 {
                        continue;
                    }
                    let want = (w.round() as i64).rem_euclid(2) == 1;
                    assert!(
                        (w - w.round()).abs() < 1e-6,
                        "winding {w} not an integer (seed {seed})"
                    );
                    assert_eq!(
                        solid.get(x, y, z),
                        want,
                        "seed {seed} voxel ({x},{y},{z}) winding {w}"
                    );
                    checked += 1;
                }
            }
        }
    }
    assert!(checked > 5000, "only {checked} voxels checked");
}

#[test]
fn box_with_faces_on_voxel_faces() {
    let (mut p, mut t) = (vec![], vec![]);
    push_box(&mut p, &mut t, [2.0; 3], [5.0; 3]);
    let mesh = Mesh::new(p, t).unwrap();
    let g = unit_grid([8, 8, 8]);
    let solid = run(&mesh, &g, Method::Solid);
    assert_eq!(solid.count_ones(), 27);
    assert_eq!(solid.solid_bounds(), Some(([2; 3], [4; 3])));
    // Closed boxes: every voxel touching the closed box [2,5]³ except the one strictly inside.
    let surface = run(&mesh, &g, Method::Surface);
    assert_eq!(surface.count_ones(), 5 * 5 * 5 - 1);
    assert!(
        !surface.get(3, 3, 3)
            && surface.get(1, 1, 1)
            && surface.get(5, 5, 5)
            && !surface.get(6, 5, 5)
    );
    assert_eq!(run(&mesh, &g, Method::Conservative).count_ones(), 125);
    assert_eq!(
        run(&mesh, &g, Method::Interior)
            .iter_ones()
            .collect::<Vec<_>>(),
        vec![[3, 3, 3]]
    );
}

#[test]
fn box_with_faces_through_voxel_centres_counts_each_centre_once() {
    // Faces at 2.5 and 5.5 pass through centres: the tie rules make the count the exact volume
    // (3 per axis), never 2 or 4.
    let (mut p, mut t) = (vec![], vec![]);
    push_box(&mut p, &mut t, [2.5; 3], [5.5; 3]);
    let mesh = Mesh::new(p, t).unwrap();
    let solid = run(&mesh, &unit_grid([8, 8, 8]), Method::Solid);
    assert_eq!(solid.count_ones(), 27);
    // z: the centre on the bottom face is not above it; the one on the top face is not above the top.
    let (lo, hi) = solid.solid_bounds().unwrap();
    assert_eq!((lo[2], hi[2]), (3, 5));
}

#[test]
fn fitted_grid_puts_the_max_face_in_the_last_voxel() {
    // Box.gltf-like: the mesh's bbox is the grid's box. Solid is everything; surface is the shell.
    for n in [1u32, 2, 7, 64, 65] {
        let (mut p, mut t) = (vec![], vec![]);
        push_box(&mut p, &mut t, [-0.5; 3], [0.5; 3]);
        let mesh = Mesh::new(p, t).unwrap();
        let (lo, hi) = mesh.bounds();
        let g = Grid::fit(
            lo,
            hi,
            voxd::GridSpec::Resolution { n, cubic: true },
            0,
            Default::default(),
        )
        .unwrap();
        let n3 = (n as u64).pow(3);
        assert_eq!(run(&mesh, &g, Method::Solid).count_ones(), n3, "n={n}");
        let inner = (n as u64).saturating_sub(2).pow(3);
        assert_eq!(
            run(&mesh, &g, Method::Surface).count_ones(),
            n3 - inner,
            "n={n}"
        );
    }
}

/// An icosphere: solid voxels are exactly the centres inside the polyhedron (checked against its
/// face planes, away from them), surface voxels all lie within half a diagonal of the surface.
#[test]
fn sphere_solid_is_centres_inside_the_polyhedron() {
    let mesh = icosphere(3);
    let (lo, hi) = mesh.bounds();
    for n in [16u32, 33, 70] {
        let g = Grid::fit(
            lo,
            hi,
            voxd::GridSpec::Resolution { n, cubic: true },
            1,
            Default::default(),
        )
        .unwrap();
        let solid = run(&mesh, &g, Method::Solid);
        let surface = run(&mesh, &g, Method::Surface);
        let planes: Vec<([f64; 3], f64)> = (0..mesh.triangles().len())
            .map(|t| {
                let [a, b, c] = mesh.triangle(t);
                let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
                let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
                let nrm = [
                    u[1] * v[2] - u[2] * v[1],
                    u[2] * v[0] - u[0] * v[2],
                    u[0] * v[1] - u[1] * v[0],
                ];
                let l = (nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2]).sqrt();
                let nrm = nrm.map(|x| x / l);
                (nrm, nrm[0] * a[0] + nrm[1] * a[1] + nrm[2] * a[2])
            })
            .collect();
        let mut inside_count = 0;
        let margin = 0.01 * g.voxel_size;
        let half_diag = g.voxel_size * 3f64.sqrt() / 2.0;
        for x in 0..n + 2 {
            for y in 0..n + 2 {
                for z in 0..n + 2 {
                    let c = g.voxel_center(x, y, z);
                    let sd = planes
                        .iter()
                        .map(|(nr, d)| nr[0] * c[0] + nr[1] * c[1] + nr[2] * c[2] - d)
                        .fold(f64::MIN, f64::max);
                    if sd.abs() > margin {
                        assert_eq!(
                            solid.get(x, y, z),
                            sd < 0.0,
                            "n={n} voxel ({x},{y},{z}) sd {sd}"
                        );
                        inside_count += (sd < 0.0) as u32;
                    }
                    if surface.get(x, y, z) {
                        assert!(
                            sd.abs() <= half_diag + 1e-9 || sd < 0.0,
                            "surface voxel far outside: {sd}"
                        );
                    }
                }
            }
        }
        assert!(inside_count > 0);
        // Conservative covers solid; interior lies inside solid and off the surface.
        let cons = run(&mesh, &g, Method::Conservative);
        let inter = run(&mesh, &g, Method::Interior);
        assert!(
            cons.count_ones() >= solid.count_ones() && inter.count_ones() <= solid.count_ones()
        );
        assert_eq!(cons.count_ones() - inter.count_ones(), surface.count_ones());
    }
}

fn icosphere(subdiv: u32) -> Mesh {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut p: Vec<[f64; 3]> = vec![
        [-1., t, 0.],
        [1., t, 0.],
        [-1., -t, 0.],
        [1., -t, 0.],
        [0., -1., t],
        [0., 1., t],
        [0., -1., -t],
        [0., 1., -t],
        [t, 0., -1.],
        [t, 0., 1.],
        [-t, 0., -1.],
        [-t, 0., 1.],
    ];
    let mut f: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    let unit = |v: [f64; 3]| {
        let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        v.map(|c| 1.3 * c / l + 0.1)
    };
    p = p.into_iter().map(unit).collect();
    for _ in 0..subdiv {
        let mut cache = std::collections::HashMap::new();
        let mut mid = |a: u32, b: u32, p: &mut Vec<[f64; 3]>| {
            *cache.entry((a.min(b), a.max(b))).or_insert_with(|| {
                let (x, y) = (p[a as usize], p[b as usize]);
                let m = [0, 1, 2].map(|i| (x[i] + y[i]) / 2.0 - 0.1);
                p.push(unit(m));
                p.len() as u32 - 1
            })
        };
        let mut nf = vec![];
        for [a, b, c] in f {
            let (ab, bc, ca) = (mid(a, b, &mut p), mid(b, c, &mut p), mid(c, a, &mut p));
            nf.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        f = nf;
    }
    Mesh::new(p, f).unwrap()
}

#[test]
fn huge_triangles_and_far_geometry() {
    // One triangle covering the whole xy plane below the grid flips every column.
    let p = vec![
        [-1000.0, -1000.0, -5000.0],
        [3000.0, -1000.0, -5000.0],
        [-1000.0, 3000.0, -5000.0],
    ];
    let mesh = Mesh::new(p, vec![[0, 1, 2]]).unwrap();
    let g = unit_grid([9, 10, 11]);
    assert_eq!(run(&mesh, &g, Method::Solid).count_ones(), 990);
    assert_eq!(run(&mesh, &g, Method::Surface).count_ones(), 0);
    // A mesh entirely above or beside the grid changes nothing.
    let p = vec![
        [0.0, 0.0, 50.0],
        [5.0, 0.0, 50.0],
        [0.0, 5.0, 50.0],
        [-9.0, 0.0, 0.0],
        [-8.0, 5.0, 0.0],
        [-9.0, 5.0, 1.0],
    ];
    let mesh = Mesh::new(p, vec![[0, 1, 2], [3, 4, 5]]).unwrap();
    assert_eq!(run(&mesh, &g, Method::Conservative).count_ones(), 0);
    // A vertex millions of voxels away from a triangle that crosses the grid is refused clearly.
    let p = vec![[0.0, 0.0, 0.0], [5.0, 0.0, 0.0], [0.0, 5.0, 9e6]];
    let mesh = Mesh::new(p, vec![[0, 1, 2]]).unwrap();
    let e = GridMesh::new(&mesh, &g).unwrap_err();
    assert!(e.to_string().contains("voxels from the grid"), "{e}");
}

/// Steep triangles 10⁵ voxels across whose planes pass through a small grid inside them: at the
/// grid's columns every vertex is far, so the depth numerators pass 2⁶³ and the engine's
/// 128-bit path decides them (smaller ones take an i64 path); against the brute-force oracle.
#[test]
fn huge_steep_triangles_around_a_small_grid_match_brute_force() {
    let dims = [6, 7, 9];
    let g = unit_grid(dims);
    for seed in 0..24u64 {
        let mut rng = Rng::new(5100 + seed);
        let (mut p, mut t) = (vec![], vec![]);
        for _ in 0..3 {
            // The plane z = o.z + gx (x − o.x) + gy (y − o.y) through a point o of the grid.
            let o = [0, 1, 2].map(|k| rng.range(0.0, dims[k] as f64));
            let (gx, gy) = (rng.range(-3.0, 3.0), rng.range(-3.0, 3.0));
            let r = rng.range(5e4, 2e5);
            let turn = rng.range(0.0, std::f64::consts::TAU);
            let i = p.len() as u32;
            for j in 0..3 {
                let angle = turn + j as f64 * std::f64::consts::TAU / 3.0;
                let (x, y) = (o[0] + r * angle.cos(), o[1] + r * angle.sin());
                p.push([x, y, o[2] + gx * (x - o[0]) + gy * (y - o[1])]);
            }
            t.push([i, i + 1, i + 2]);
        }
        let mesh = Mesh::new(p, t).unwrap();
        let want = solid_brute(&mesh, &g);
        // Not vacuous: the planes cut the grid, so some voxels are set and some are not.
        let n = want.count_ones();
        assert!(n > 0 && n < 6 * 7 * 9, "seed {seed}: {n}");
        assert_same(
            &run(&mesh, &g, Method::Solid),
            &want,
            &format!("seed {seed}"),
        );
    }
}

#[test]
fn big_box_on_a_big_grid() {
    // A 12-triangle box spanning a 1024 × 1024 × 300 grid: huge triangles, exact counts.
    let (mut p, mut t) = (vec![], vec![]);
    push_box(&mut p, &mut t, [0.0, 0.0, 0.0], [1024.0, 1024.0, 300.0]);
    push_box(&mut p, &mut t, [100.0, 200.0, 50.0], [400.0, 500.0, 250.0]);
    let mesh = Mesh::new(p, t).unwrap();
    let g = unit_grid([1024, 1024, 300]);
    let solid = run(&mesh, &g, Method::Solid);
    assert_eq!(solid.count_ones(), 1024 * 1024 * 300 - 300 * 300 * 200);
    assert!(!solid.get(100, 200, 50) && solid.get(99, 200, 50) && solid.get(100, 200, 49));
}
