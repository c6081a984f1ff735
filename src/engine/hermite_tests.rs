//! Hermite data against an independent brute-force oracle: every edge of small grids against
//! every triangle, the segment–plane crossing as an exact rational and the point-in-triangle
//! test by the signs of three exact 3D determinants (not the projected edge functions of the
//! code under test).

use super::*;
use crate::engine::Method;
use crate::engine::cpu::CpuEngine;
use crate::engine::fill::{self, Fill};
use crate::mesh::Mesh;

use crate::engine::exact::{P, cross, dot, sub};

/// Where segment a→b meets triangle t: (t as f64, interior: strictly inside the triangle and
/// strictly between the ends), or `None`. Closed: touching an edge or an end counts.
fn meet(a: P, b: P, t: [P; 3]) -> Option<(f64, bool)> {
    let n = cross(sub(t[1], t[0]), sub(t[2], t[0]));
    let dir = sub(b, a);
    let den = dot(n, dir);
    if den == 0 {
        return None;
    }
    let num = dot(n, sub(t[0], a));
    // 0 ≤ num/den ≤ 1.
    let (num, den) = if den < 0 { (-num, -den) } else { (num, den) };
    if num < 0 || num > den {
        return None;
    }
    // The line a + s·dir is inside t iff the three triple products (v_i − a, v_j − a, dir)
    // share a sign (zero allowed: closed).
    let s = [0, 1, 2].map(|i| {
        let (u, v) = (sub(t[i], a), sub(t[(i + 1) % 3], a));
        dot(cross(u, v), dir).signum()
    });
    let pos = s.iter().all(|&x| x >= 0);
    let neg = s.iter().all(|&x| x <= 0);
    if !(pos || neg) {
        return None;
    }
    let interior = s.iter().all(|&x| x != 0) && num > 0 && num < den;
    Some((num as f64 / den as f64, interior))
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

/// A closed latitude–longitude ellipsoid, randomly placed, sized and turned.
fn ellipsoid(r: &mut Rng, g: &Grid) -> Mesh {
    let ext = g.dims.map(|d| d as f64 * g.voxel_size);
    let c = [0, 1, 2].map(|a| g.origin[a] + ext[a] * (0.35 + 0.3 * r.next()));
    let rad = [0, 1, 2].map(|a| ext[a] * (0.12 + 0.25 * r.next()));
    let (ang1, ang2) = (
        r.next() * std::f64::consts::TAU,
        r.next() * std::f64::consts::TAU,
    );
    let (m, n) = (7, 11);
    let mut pos = vec![];
    for i in 0..=m {
        let th = std::f64::consts::PI * i as f64 / m as f64;
        for j in 0..n {
            let ph = 2.0 * std::f64::consts::PI * j as f64 / n as f64;
            let p = [
                rad[0] * th.sin() * ph.cos(),
                rad[1] * th.sin() * ph.sin(),
                rad[2] * th.cos(),
            ];
            let (c1, s1, c2, s2) = (ang1.cos(), ang1.sin(), ang2.cos(), ang2.sin());
            let p = [c1 * p[0] - s1 * p[1], s1 * p[0] + c1 * p[1], p[2]];
            let p = [p[0], c2 * p[1] - s2 * p[2], s2 * p[1] + c2 * p[2]];
            pos.push([c[0] + p[0], c[1] + p[1], c[2] + p[2]]);
            if i == 0 || i == m {
                break;
            }
        }
    }
    // Rows: the pole 0, rings 1..m−1 of n, the pole at the end.
    let ring = |i: usize, j: usize| (1 + (i - 1) * n + j % n) as u32;
    let last = (1 + (m - 1) * n) as u32;
    let mut tris = vec![];
    for j in 0..n {
        tris.push([0, ring(1, j), ring(1, j + 1)]);
        tris.push([last, ring(m - 1, j + 1), ring(m - 1, j)]);
    }
    for i in 1..m - 1 {
        for j in 0..n {
            tris.push([ring(i, j), ring(i + 1, j), ring(i + 1, j + 1)]);
            tris.push([ring(i, j), ring(i + 1, j + 1), ring(i, j + 1)]);
        }
    }
    Mesh::new(pos, tris).unwrap()
}

/// Checks the Hermite data of `mesh`'s solid on `g` by `fill` against the oracle; returns
/// (edges, uncrossed).
fn check(mesh: &Mesh, g: &Grid, fill: Fill) -> (usize, usize) {
    let diag = mesh.diagnostics();
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
    let tris = crate::engine::sdf::lattice_triangles(mesh, g, Some(FIXED_ONE)).unwrap();
    let h = hermite(&tris, &solid, &Control::none()).unwrap();
    let big: Vec<[P; 3]> = tris.iter().map(|t| t.map(|v| v.map(i128::from))).collect();
    let d = g.dims;
    let mut n = 0;
    for a in 0..3 {
        for x in 0..d[0] {
            for y in 0..d[1] {
                for z in 0..d[2] {
                    let v = [x, y, z];
                    let mut w = v;
                    w[a] += 1;
                    if w[a] >= d[a] {
                        continue;
                    }
                    let differ = solid.get(x, y, z) != solid.get(w[0], w[1], w[2]);
                    let e = h.find(v, a);
                    assert_eq!(e.is_some(), differ, "{v:?} axis {a}");
                    let Some(e) = e else { continue };
                    n += 1;
                    assert_eq!(e.lower_inside, solid.get(x, y, z));
                    let pa = v.map(|c| i128::from(c) * 256 + 128);
                    let pb = w.map(|c| i128::from(c) * 256 + 128);
                    let hits: Vec<(f64, bool, usize)> = big
                        .iter()
                        .enumerate()
                        .filter_map(|(i, &t)| meet(pa, pb, t).map(|(s, int)| (s, int, i)))
                        .collect();
                    assert_eq!(e.crossed, !hits.is_empty(), "{v:?} axis {a}: {hits:?}");
                    if !e.crossed {
                        assert_eq!((e.t, e.normal), (0.5, [0.0; 3]));
                        continue;
                    }
                    // The chosen crossing is one of the oracle's, with its triangle's normal…
                    let ok = hits.iter().any(|&(s, _, i)| {
                        let nn = unit_normal(&tris[i]);
                        (s - e.t).abs() < 1e-12
                            && (0..3).all(|k| (nn[k] - e.normal[k]).abs() < 1e-12)
                    });
                    assert!(ok, "{v:?} axis {a}: {e:?} not in {hits:?}");
                    // …and none strictly inside the segment and triangle comes before it.
                    let first = hits
                        .iter()
                        .filter(|h| h.1)
                        .map(|h| h.0)
                        .fold(f64::INFINITY, f64::min);
                    assert!(e.t <= first + 1e-12, "{v:?} axis {a}: {e:?} after {first}");
                    let len = e.normal.iter().map(|c| c * c).sum::<f64>().sqrt();
                    assert!((len - 1.0).abs() < 1e-12);
                }
            }
        }
    }
    assert_eq!(n, h.edges.len());
    (n, h.uncrossed())
}

fn grid(origin: [f64; 3], s: f64, dims: [u32; 3]) -> Grid {
    Grid {
        origin,
        voxel_size: s,
        dims,
    }
}

#[test]
fn random_closed_meshes_match_the_oracle_and_every_edge_is_crossed() {
    let mut r = Rng(0x9e37_79b9_7f4a_7c15);
    let mut total = 0;
    for i in 0..24 {
        let g = grid(
            [-0.3, 0.1, 0.2],
            0.1 + 0.01 * i as f64,
            [9 + i % 5, 11, 8 + i % 3],
        );
        let m = ellipsoid(&mut r, &g);
        let (n, uncrossed) = check(&m, &g, Fill::Parity);
        assert_eq!(uncrossed, 0, "mesh {i}");
        total += n;
    }
    assert!(total > 1000, "{total}");
}

/// Vertices on voxel centres and faces through them: the closed rules and the ties.
#[test]
fn a_box_through_voxel_centres_is_crossed_at_the_ends_of_its_edges() {
    let m = {
        let (lo, hi) = ([0.5, 0.5, 0.5], [3.5, 2.5, 4.5]);
        let v: Vec<[f64; 3]> = (0..8)
            .map(|i| [0, 1, 2].map(|a| if i >> a & 1 == 0 { lo[a] } else { hi[a] }))
            .collect();
        let f = vec![
            [0, 2, 1],
            [1, 2, 3],
            [0, 1, 4],
            [1, 5, 4],
            [2, 6, 3],
            [3, 6, 7],
            [0, 4, 2],
            [2, 4, 6],
            [1, 3, 5],
            [3, 7, 5],
            [4, 5, 6],
            [5, 7, 6],
        ];
        Mesh::new(v, f).unwrap()
    };
    let g = grid([0.0; 3], 1.0, [6, 5, 7]);
    let (n, uncrossed) = check(&m, &g, Fill::Parity);
    assert!(n > 0);
    assert_eq!(uncrossed, 0);
}

#[test]
fn a_real_mesh_and_open_soups_match_the_oracle() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/spot.obj");
    let spot = crate::mesh::load_file(std::path::Path::new(path), usize::MAX).unwrap();
    let g = grid([-0.6, -0.8, -0.7], 0.1, [13, 18, 18]);
    let (n, uncrossed) = check(&spot, &g, Fill::Parity);
    assert!(n > 500 && uncrossed == 0, "{n} {uncrossed}");
    // An open mesh (spot without a band of triangles) filled by winding: edges the hole
    // leaves uncrossed are reported as such.
    let tris: Vec<[u32; 3]> = spot
        .triangles()
        .iter()
        .enumerate()
        .filter(|(i, _)| i % 7 != 3)
        .map(|(_, t)| *t)
        .collect();
    let holed = Mesh::new(spot.positions().to_vec(), tris).unwrap();
    let (n, uncrossed) = check(&holed, &g, Fill::Winding);
    assert!(n > 500 && uncrossed > 0, "{n} {uncrossed}");
}

#[test]
fn a_canceled_control_stops_the_work() {
    let g = grid([0.0; 3], 0.1, [10, 10, 10]);
    let m = ellipsoid(&mut Rng(7), &g);
    let solid = BitVolume::new(g);
    let tris = crate::engine::sdf::lattice_triangles(&m, &g, Some(FIXED_ONE)).unwrap();
    let ctl = Control::new();
    ctl.cancel();
    assert!(hermite(&tris, &solid, &ctl).is_err());
}
