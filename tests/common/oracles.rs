//! The independent oracles: what each voxelization method and query should give, written as
//! plainly as possible (no binning, no prefix scans, no pruning). They share no code with the
//! library: where the library has a function for the same quantity (point–triangle distance,
//! solid angle), the one here is a different formulation, itself checked against brute force in
//! `checks`. Not for meshes or fixtures (`meshes`, `fixtures`).

use voxd::grid::Grid;
use voxd::mesh::Mesh;
use voxd::volume::BitVolume;

mod checks;

pub type Tri = [[i128; 3]; 3];

/// Snaps exactly as docs/methods.md defines (grid units × 256, rounded), without culling.
pub fn snap(mesh: &Mesh, g: &Grid) -> Vec<Tri> {
    let scale = 256.0 / g.voxel_size;
    mesh.triangles()
        .iter()
        .map(|t| {
            t.map(|i| {
                let p = mesh.positions()[i as usize];
                [0, 1, 2].map(|a| ((p[a] - g.origin[a]) * scale).round() as i128)
            })
        })
        .collect()
}

fn orient(p: [i128; 3], q: [i128; 3], r: [i128; 2]) -> i128 {
    (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0])
}

/// Does the ray from the fixed-point centre `c` towards −z cross `t`? Column-in-triangle with the
/// top-left tie rule, then "centre strictly above the plane".
pub fn crosses(t: &Tri, c: [i128; 3]) -> bool {
    match column_depth(t, [c[0], c[1]]) {
        Some((num, area)) => c[2] * area > num,
        None => false,
    }
}

/// If the column centre `p` is inside `t`'s projection: (Σ w_i z_i, A), the plane depth being
/// num / A with A > 0.
pub fn column_depth(t: &Tri, p: [i128; 2]) -> Option<(i128, i128)> {
    let [a, mut b, mut c] = *t;
    let mut area = orient(a, b, [c[0], c[1]]);
    if area == 0 {
        return None;
    }
    if area < 0 {
        std::mem::swap(&mut b, &mut c);
        area = -area;
    }
    for (u, v) in [(a, b), (b, c), (c, a)] {
        let s = orient(u, v, p);
        let (dx, dy) = (v[0] - u[0], v[1] - u[1]);
        if s < 0 || (s == 0 && !(dy > 0 || (dy == 0 && dx < 0))) {
            return None;
        }
    }
    let (wa, wb, wc) = (orient(b, c, p), orient(c, a, p), orient(a, b, p));
    Some((wa * a[2] + wb * b[2] + wc * c[2], area))
}

pub fn centre(i: u32) -> i128 {
    i as i128 * 256 + 128
}

/// Brute force parity: every voxel against every triangle.
pub fn solid_brute(mesh: &Mesh, g: &Grid) -> BitVolume {
    let tris = snap(mesh, g);
    let mut v = BitVolume::new(*g);
    let [nx, ny, nz] = g.dims;
    for x in 0..nx {
        for y in 0..ny {
            for z in 0..nz {
                let c = [centre(x), centre(y), centre(z)];
                let n = tris.iter().filter(|t| crosses(t, c)).count();
                v.set(x, y, z, n % 2 == 1);
            }
        }
    }
    v
}

/// Per-column gather: triangles binned by the columns their bbox covers, then every voxel of the
/// column compared with every crossing (no floor division, no prefix scan).
pub fn solid_binned(mesh: &Mesh, g: &Grid) -> BitVolume {
    let tris = snap(mesh, g);
    let [nx, ny, nz] = g.dims;
    let mut bins: Vec<Vec<u32>> = vec![Vec::new(); nx as usize * ny as usize];
    for (i, t) in tris.iter().enumerate() {
        let lo = [0, 1].map(|a| t.iter().map(|p| p[a]).min().unwrap());
        let hi = [0, 1].map(|a| t.iter().map(|p| p[a]).max().unwrap());
        let r =
            |a: usize, n: u32| (0..n).filter(move |&k| centre(k) >= lo[a] && centre(k) <= hi[a]);
        for x in r(0, nx) {
            for y in r(1, ny) {
                bins[(x * ny + y) as usize].push(i as u32);
            }
        }
    }
    let mut v = BitVolume::new(*g);
    for x in 0..nx {
        for y in 0..ny {
            let depths: Vec<(i128, i128)> = bins[(x * ny + y) as usize]
                .iter()
                .filter_map(|&t| column_depth(&tris[t as usize], [centre(x), centre(y)]))
                .collect();
            for z in 0..nz {
                let n = depths
                    .iter()
                    .filter(|(num, a)| centre(z) * a > *num)
                    .count();
                if n % 2 == 1 {
                    v.set(x, y, z, true);
                }
            }
        }
    }
    v
}

fn sub(a: [i128; 3], b: [i128; 3]) -> [i128; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn cross(a: [i128; 3], b: [i128; 3]) -> [i128; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn dot(a: [i128; 3], b: [i128; 3]) -> i128 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Plain 13-axis separating-axis test of a triangle against the closed box with centre `c` and
/// half-size 128 (fixed point).
pub fn tri_box(t: &Tri, c: [i128; 3]) -> bool {
    let v = t.map(|p| sub(p, c));
    let e = [sub(v[1], v[0]), sub(v[2], v[1]), sub(v[0], v[2])];
    let units = [[1, 0, 0], [0, 1, 0], [0, 0, 1]];
    let mut axes = units.to_vec();
    axes.push(cross(e[0], e[1]));
    for ei in e {
        for u in units {
            axes.push(cross(ei, u));
        }
    }
    axes.iter().all(|a| {
        let p = v.map(|x| dot(*a, x));
        let r = 128 * (a[0].abs() + a[1].abs() + a[2].abs());
        !(p.iter().min().unwrap() > &r || p.iter().max().unwrap() < &-r)
    })
}

/// Brute force surface: every voxel against every triangle.
pub fn surface_brute(mesh: &Mesh, g: &Grid) -> BitVolume {
    let tris = snap(mesh, g);
    let mut v = BitVolume::new(*g);
    let [nx, ny, nz] = g.dims;
    for x in 0..nx {
        for y in 0..ny {
            for z in 0..nz {
                let c = [centre(x), centre(y), centre(z)];
                if tris.iter().any(|t| tri_box(t, c)) {
                    v.set(x, y, z, true);
                }
            }
        }
    }
    v
}

/// Surface by SAT on every voxel whose box meets the triangle's bounding box.
pub fn surface_bbox(mesh: &Mesh, g: &Grid) -> BitVolume {
    let tris = snap(mesh, g);
    let mut v = BitVolume::new(*g);
    for t in &tris {
        let r: [(u32, u32); 3] = [0, 1, 2].map(|a| {
            let lo = t.iter().map(|p| p[a]).min().unwrap();
            let hi = t.iter().map(|p| p[a]).max().unwrap();
            let first = (0..g.dims[a])
                .find(|&i| i as i128 * 256 + 256 >= lo)
                .unwrap_or(g.dims[a]);
            let last = (0..g.dims[a]).rev().find(|&i| i as i128 * 256 <= hi);
            match last {
                Some(l) if first <= l => (first, l + 1),
                _ => (0, 0),
            }
        });
        for x in r[0].0..r[0].1 {
            for y in r[1].0..r[1].1 {
                for z in r[2].0..r[2].1 {
                    if tri_box(t, [centre(x), centre(y), centre(z)]) {
                        v.set(x, y, z, true);
                    }
                }
            }
        }
    }
    v
}

/// Generalised winding number of the (unsnapped) mesh at `p`, and the distance from `p` to the
/// nearest triangle.
pub fn winding_and_distance(mesh: &Mesh, p: [f64; 3]) -> (f64, f64) {
    let mut w = 0.0;
    let mut d2 = f64::INFINITY;
    for t in 0..mesh.triangles().len() {
        let [a, b, c] = mesh.triangle(t);
        w += solid_angle(p, a, b, c);
        // The distance to the triangle's bounding box is a lower bound of the distance to it:
        // where that is no nearer than the nearest so far, the triangle cannot be the nearest.
        let to_box: f64 = (0..3)
            .map(|i| {
                let (lo, hi) = (a[i].min(b[i]).min(c[i]), a[i].max(b[i]).max(c[i]));
                (lo - p[i]).max(p[i] - hi).max(0.0).powi(2)
            })
            .sum();
        if to_box < d2 {
            d2 = d2.min(dist2_to_triangle(p, a, b, c));
        }
    }
    (w / (4.0 * std::f64::consts::PI), d2.sqrt())
}

fn subf(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn dotf(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn crossf(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// Signed solid angle of triangle abc seen from `p`: the area E of the spherical triangle its
/// corners project to, by L'Huilier's theorem on the three side arcs θ (semiperimeter s),
/// `tan(E/4)² = tan(s/2) · tan((s − θ₁)/2) · tan((s − θ₂)/2) · tan((s − θ₃)/2)`, with each
/// tangent a sum of ± quarter arcs and so, by the tangent addition formula, a rational function of
/// the quarter-arc tangents `tan(θ/4) = |û − v̂| / (2 + |û + v̂|)` (û, v̂: unit vectors to two
/// corners). Its sign is that of `(a − p) · ((b − p) × (c − p))`. (The library uses Van Oosterom
/// and Strackee's formula.)
pub fn solid_angle(p: [f64; 3], a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> f64 {
    let [a, b, c] = [a, b, c].map(|q| subf(q, p));
    let det = dotf(a, crossf(b, c));
    let len = |u: [f64; 3]| dotf(u, u).sqrt();
    let l = [a, b, c].map(len);
    if det == 0.0 || l.contains(&0.0) {
        // p in the triangle's plane: 0 unless p is on the triangle (where it is undefined).
        return 0.0;
    }
    let [a, b, c] = [(a, l[0]), (b, l[1]), (c, l[2])].map(|(u, l)| u.map(|x| x / l));
    let quarter = |u: [f64; 3], v: [f64; 3]| {
        len(subf(u, v)) / (2.0 + len([u[0] + v[0], u[1] + v[1], u[2] + v[2]]))
    };
    let [t1, t2, t3] = [quarter(b, c), quarter(c, a), quarter(a, b)];
    // tan(x + y + z) from tan x, tan y, tan z.
    let tan_sum = |x: f64, y: f64, z: f64| (x + y + z - x * y * z) / (1.0 - x * y - y * z - z * x);
    let product =
        tan_sum(t1, t2, t3) * tan_sum(-t1, t2, t3) * tan_sum(t1, -t2, t3) * tan_sum(t1, t2, -t3);
    // The product is ≥ 0 (the clamp only undoes rounding on flat spherical triangles).
    4.0 * product.max(0.0).sqrt().atan() * det.signum()
}

/// Squared distance from p to triangle abc: to its plane where p is over the triangle (p is on
/// the inner side of all three edges, by the sign of (v − u) × (p − u) against the normal), else
/// to the nearest of the edges that p is outside of (the nearest point of the triangle is on one
/// of them). A triangle of (next to) zero area, whose normal is rounding noise, is its three
/// edges. (The library uses Ericson's walk of the Voronoi regions.)
pub fn dist2_to_triangle(p: [f64; 3], a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> f64 {
    let (ab, ac) = (subf(b, a), subf(c, a));
    let n = crossf(ab, ac);
    let nn = dotf(n, n);
    // |n|² = |ab|² |ac|² sin²(angle at a): flat below sin = 1e-10.
    let flat = nn <= 1e-20 * dotf(ab, ab) * dotf(ac, ac);
    let edges = [(a, b), (b, c), (c, a)];
    let side = edges.map(|(u, v)| dotf(crossf(subf(v, u), subf(p, u)), n));
    if !flat && side.iter().all(|&s| s >= 0.0) {
        let h = dotf(subf(p, a), n);
        return h * h / nn;
    }
    (0..3)
        .filter(|&i| flat || side[i] < 0.0)
        .map(|i| dist2_to_segment(p, edges[i].0, edges[i].1))
        .fold(f64::INFINITY, f64::min)
}

/// Squared distance from p to the segment uv (a point when u = v).
pub fn dist2_to_segment(p: [f64; 3], u: [f64; 3], v: [f64; 3]) -> f64 {
    let d = subf(v, u);
    let dd = dotf(d, d);
    let s = if dd > 0.0 {
        (dotf(subf(p, u), d) / dd).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let q = [0, 1, 2].map(|i| u[i] + s * d[i]);
    dotf(subf(p, q), subf(p, q))
}
