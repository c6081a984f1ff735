//! `sdf` against an independent brute-force oracle: every voxel of small grids, the least
//! distance over every triangle by Ericson's closest-point regions (Real-Time Collision
//! Detection, 5.1.5) in exact integers (the squared distance as a fraction, compared with the
//! band's square exactly), not `geom::lattice`; signs against `method=solid` with each fill.

use std::collections::BTreeSet;

use super::*;
use crate::engine::cpu::CpuEngine;
use crate::mesh::Mesh;

use crate::engine::exact::{P, cross, dot, sub};

/// Squared distance from p to segment ab, as (numerator, denominator).
fn segment2(p: P, a: P, b: P) -> (i128, i128) {
    let (ab, ap) = (sub(b, a), sub(p, a));
    let (t, l) = (dot(ap, ab), dot(ab, ab));
    if t <= 0 || l == 0 {
        (dot(ap, ap), 1)
    } else if t >= l {
        let bp = sub(p, b);
        (dot(bp, bp), 1)
    } else {
        (dot(ap, ap) * l - t * t, l)
    }
}

/// Squared distance from p to triangle abc, exactly, as (numerator, denominator > 0), by the
/// Voronoi region of the closest point (Ericson's ClosestPtPointTriangle).
fn oracle2(p: P, t: [P; 3]) -> (i128, i128) {
    let [a, b, c] = t;
    let (ab, ac) = (sub(b, a), sub(c, a));
    let n = cross(ab, ac);
    if n == [0; 3] {
        // No area: the closest of its three segments.
        let s = [segment2(p, a, b), segment2(p, b, c), segment2(p, c, a)];
        return *s
            .iter()
            .min_by(|x, y| (x.0 as f64 / x.1 as f64).total_cmp(&(y.0 as f64 / y.1 as f64)))
            .unwrap();
    }
    let ap = sub(p, a);
    let (d1, d2) = (dot(ab, ap), dot(ac, ap));
    if d1 <= 0 && d2 <= 0 {
        return (dot(ap, ap), 1);
    }
    let bp = sub(p, b);
    let (d3, d4) = (dot(ab, bp), dot(ac, bp));
    if d3 >= 0 && d4 <= d3 {
        return (dot(bp, bp), 1);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0 && d1 >= 0 && d3 <= 0 {
        return segment2(p, a, b);
    }
    let cp = sub(p, c);
    let (d5, d6) = (dot(ab, cp), dot(ac, cp));
    if d6 >= 0 && d5 <= d6 {
        return (dot(cp, cp), 1);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0 && d2 >= 0 && d6 <= 0 {
        return segment2(p, a, c);
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0 {
        return segment2(p, b, c);
    }
    let q = dot(n, ap);
    (q * q, dot(n, n))
}

/// The mesh's triangles snapped by the definition (round half away from zero of
/// (p − origin)·256/s), none dropped.
fn snapped(mesh: &Mesh, grid: &Grid) -> Vec<[P; 3]> {
    (0..mesh.triangles().len())
        .map(|t| {
            mesh.triangle(t).map(|v| {
                [0, 1, 2]
                    .map(|a| ((v[a] - grid.origin[a]) * 256.0 / grid.voxel_size).round() as i128)
            })
        })
        .collect()
}

/// Per voxel of the grid (x-major): (in band `k` exactly, the least distance in voxels).
fn oracle(mesh: &Mesh, grid: &Grid, k: Option<i128>) -> Vec<(bool, f64)> {
    let tris = snapped(mesh, grid);
    let [nx, ny, nz] = grid.dims;
    let mut out = Vec::new();
    for x in 0..nx {
        for y in 0..ny {
            for z in 0..nz {
                let p = [x, y, z].map(|c| i128::from(c) * 256 + 128);
                let mut best = f64::INFINITY;
                let mut band = k.is_none();
                for &t in &tris {
                    let (num, den) = oracle2(p, t);
                    if let Some(k) = k {
                        band |= num < k * k * 65536 * den;
                    }
                    best = best.min(num as f64 / den as f64);
                }
                out.push((band, best.sqrt() / 256.0));
            }
        }
    }
    out
}

/// A box with corners `lo`, `hi`, outward triangles; `open` leaves out its top (z = hi) face.
fn cuboid(lo: [f64; 3], hi: [f64; 3], open: bool) -> Mesh {
    let v: Vec<[f64; 3]> = (0..8)
        .map(|i| {
            [
                if i & 1 == 0 { lo[0] } else { hi[0] },
                if i & 2 == 0 { lo[1] } else { hi[1] },
                if i & 4 == 0 { lo[2] } else { hi[2] },
            ]
        })
        .collect();
    let mut f = vec![
        [0, 2, 1],
        [1, 2, 3], // z = lo
        [0, 1, 4],
        [1, 5, 4], // y = lo
        [2, 6, 3],
        [3, 6, 7], // y = hi
        [0, 4, 2],
        [2, 4, 6], // x = lo
        [1, 3, 5],
        [3, 7, 5], // x = hi
    ];
    if !open {
        f.extend([[4, 5, 6], [5, 7, 6]]);
    }
    Mesh::new(v, f).unwrap()
}

struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Triangles of every size: a few larger than the grid, most about a voxel, some far smaller,
/// and degenerate ones (a segment, a point).
fn soup(seed: u64, n: usize, g: &Grid) -> Mesh {
    let mut r = Rng(seed);
    let ext = g.dims.map(|d| d as f64 * g.voxel_size);
    let mut pos = vec![];
    let mut tris = vec![];
    for i in 0..n {
        let size = [3.0, 0.3, 0.05, 0.002][i % 4] * ext[0];
        let c = [0, 1, 2].map(|a| g.origin[a] + ext[a] * (r.next() * 1.2 - 0.1));
        let mut p = [0; 3].map(|_| [0, 1, 2].map(|a| c[a] + size * (r.next() - 0.5)));
        if i % 11 == 5 {
            p[2] = [0, 1, 2].map(|a| (p[0][a] + p[1][a]) / 2.0);
        }
        if i % 13 == 7 {
            p = [p[0]; 3];
        }
        let b = pos.len() as u32;
        pos.extend(p);
        tris.push([b, b + 1, b + 2]);
    }
    Mesh::new(pos, tris).unwrap()
}

fn grid(origin: [f64; 3], s: f64, dims: [u32; 3]) -> Grid {
    Grid {
        origin,
        voxel_size: s,
        dims,
    }
}

fn spot() -> Mesh {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/spot.obj");
    crate::mesh::load_file(std::path::Path::new(path), usize::MAX).unwrap()
}

/// Checks `sdf` of `mesh` on `g` at band `k` with every fill against the oracle and the solid;
/// returns the largest |d − d_exact| / s seen.
fn check(mesh: &Mesh, g: &Grid, band: Band, fills: &[Fill]) -> f64 {
    let k = match band {
        Band::Voxels(k) => Some(i128::from(k)),
        Band::All => None,
    };
    let truth = oracle(mesh, g, k);
    let diag = mesh.diagnostics();
    let s = g.voxel_size;
    let (bg, tile) = band.values(s);
    let mut worst = 0.0f64;
    let [nx, ny, nz] = g.dims;
    for &fill in fills {
        let (sdf, _) = sdf_with(&CpuEngine, mesh, g, band, fill, &diag, &Control::none()).unwrap();
        let (solid, _) = fill::voxelize_with(
            &CpuEngine,
            mesh,
            g,
            Method::Solid,
            fill,
            &diag,
            &Control::none(),
        )
        .unwrap();
        assert_eq!((sdf.background(), sdf.tile_value()), (bg, tile));
        // Per brick: (any voxel in band, any inside, all inside).
        let bd = brick_dims(g);
        let mut want = std::collections::BTreeMap::new();
        let mut i = 0;
        for x in 0..nx {
            for y in 0..ny {
                for z in 0..nz {
                    let (in_band, d) = truth[i];
                    i += 1;
                    let v = sdf.get(x, y, z);
                    let inside = solid.get(x, y, z);
                    assert_eq!(v.is_sign_negative(), inside, "sign at {x},{y},{z} ({fill})");
                    if in_band {
                        assert!(v.abs() < bg, "{x},{y},{z}: {v} in band, not active");
                        // One rounding to f32 (half an ulp: 2⁻²⁴ of the value at most) over
                        // an f64 value within 2⁻⁵⁰: within 1e-6·s wherever d ≤ 16 voxels.
                        let e = (f64::from(v.abs()) - d * s).abs();
                        let bound = d * s * (2f64.powi(-24) + 2f64.powi(-45));
                        assert!(e <= bound, "{x},{y},{z}: {v} vs {}", d * s);
                        if d <= 16.0 {
                            assert!(e <= 1e-6 * s, "{x},{y},{z}: {v} vs {}", d * s);
                            worst = worst.max(e / s);
                        }
                    } else {
                        assert_eq!(v, if inside { tile } else { bg }, "{x},{y},{z} out of band");
                    }
                    let e = want
                        .entry([x / 8, y / 8, z / 8])
                        .or_insert((false, false, true));
                    e.0 |= in_band;
                    e.1 |= inside;
                    e.2 &= inside;
                }
            }
        }
        let stored: BTreeSet<[u32; 3]> = sdf.bricks().map(|(k, _)| k).collect();
        let tiles: BTreeSet<[u32; 3]> = sdf.tiles().collect();
        let want_stored: BTreeSet<[u32; 3]> = want
            .iter()
            .filter(|(_, v)| v.0 || (v.1 && !v.2))
            .map(|(k, _)| *k)
            .collect();
        let want_tiles: BTreeSet<[u32; 3]> = want
            .iter()
            .filter(|(_, v)| !v.0 && v.2)
            .map(|(k, _)| *k)
            .collect();
        if band == Band::All {
            assert_eq!(stored.len() as u32, bd.iter().product::<u32>());
            assert!(tiles.is_empty());
        } else {
            assert_eq!(stored, want_stored, "stored bricks ({fill})");
            assert_eq!(tiles, want_tiles, "tiles ({fill})");
        }
    }
    worst
}

const FILLS: [Fill; 5] = [
    Fill::Parity,
    Fill::Vote,
    Fill::Winding,
    Fill::Flood,
    Fill::Auto,
];

#[test]
fn a_closed_an_open_and_an_inverted_box_match_the_oracle_with_every_fill() {
    let g = grid([-0.13, -0.21, -0.07], 0.1, [21, 19, 26]);
    let closed = cuboid([0.31, 0.22, 0.45], [1.53, 1.41, 2.09], false);
    let open = cuboid([0.31, 0.22, 0.45], [1.53, 1.41, 2.09], true);
    let mut worst = 0.0f64;
    for m in [&closed, &open, &closed.flipped()] {
        worst = worst.max(check(m, &g, Band::Voxels(3), &FILLS));
    }
    // A wide box: voxels deep inside, out of band, make tiles.
    let wide = grid([-0.13, -0.21, -0.07], 0.1, [34, 30, 33]);
    let big = cuboid([0.05, 0.02, 0.11], [3.13, 2.81, 3.09], false);
    worst = worst.max(check(
        &big,
        &wide,
        Band::Voxels(1),
        &[Fill::Parity, Fill::Winding],
    ));
    eprintln!("boxes: max |d − d_exact| = {worst:.3e}·s");
}

#[test]
fn random_triangles_of_every_size_match_the_oracle() {
    let g = grid([0.05, -0.3, 0.2], 0.07, [18, 23, 17]);
    let mut worst = 0.0f64;
    for seed in 1..4 {
        let m = soup(0x9e37_79b9 * seed, 60, &g);
        for k in [1, 2, 5] {
            worst = worst.max(check(
                &m,
                &g,
                Band::Voxels(k),
                &[Fill::Winding, Fill::Parity],
            ));
        }
    }
    eprintln!("random: max |d − d_exact| = {worst:.3e}·s");
}

#[test]
fn band_all_stores_every_brick_and_matches_the_oracle() {
    let g = grid([0.05, -0.3, 0.2], 0.07, [18, 23, 17]);
    let m = soup(77, 40, &g);
    let w = check(&m, &g, Band::All, &[Fill::Winding]);
    let open = cuboid([0.31, 0.22, 0.45], [1.03, 1.21, 1.09], true);
    let w2 = check(&open, &g, Band::All, &FILLS);
    eprintln!("band=all: max |d − d_exact| = {:.3e}·s", w.max(w2));
}

#[test]
fn a_real_mesh_matches_the_oracle_with_every_fill() {
    let m = spot();
    let (lo, hi) = m.bounds();
    let s = (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max) / 14.0;
    let g = grid(lo.map(|c| c - 2.3 * s), s, [19, 19, 19].map(|d: u32| d));
    let w = check(&m, &g, Band::Voxels(3), &FILLS);
    // Open: the same mesh with a tenth of its triangles gone.
    let tris: Vec<[u32; 3]> = m
        .triangles()
        .iter()
        .enumerate()
        .filter(|(i, _)| i % 10 != 3)
        .map(|(_, t)| *t)
        .collect();
    let holed = Mesh::new(m.positions().to_vec(), tris).unwrap();
    let w2 = check(&holed, &g, Band::Voxels(2), &FILLS);
    eprintln!("spot: max |d − d_exact| = {:.3e}·s", w.max(w2));
}

#[test]
fn the_band_parses_and_a_canceled_control_stops_the_work() {
    assert_eq!(Band::parse("3"), Ok(Band::Voxels(3)));
    assert_eq!(Band::parse("all"), Ok(Band::All));
    for bad in ["0", "65", "-1", "1.5", "ALL", ""] {
        assert!(Band::parse(bad).is_err(), "{bad}");
    }
    let g = grid([0.0; 3], 0.1, [16; 3]);
    let m = cuboid([0.3; 3], [1.2; 3], false);
    let ctl = Control::new();
    ctl.cancel();
    let r = sdf_with(
        &CpuEngine,
        &m,
        &g,
        Band::DEFAULT,
        Fill::Parity,
        &m.diagnostics(),
        &ctl,
    );
    assert!(matches!(r, Err(EngineError::Canceled(_))));
    // The candidate count bounds the bricks stored near the surface.
    let tris = lattice_triangles(&m, &g, Band::DEFAULT.reach()).unwrap();
    let n = candidate_bricks(&tris, &g, Band::DEFAULT);
    let (v, _) = sdf_with(
        &CpuEngine,
        &m,
        &g,
        Band::DEFAULT,
        Fill::Parity,
        &m.diagnostics(),
        &Control::none(),
    )
    .unwrap();
    assert!(
        v.brick_count() as u64 <= n && n <= 8,
        "{} of {n}",
        v.brick_count()
    );
}
