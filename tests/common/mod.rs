//! Test helpers: independent oracles written as plainly as possible (no binning, no prefix
//! scans, no pruning), random mesh generators and access to `../shared/meshes`. The oracles
//! share no code with the library: where the library has a function for the same quantity
//! (point-triangle distance, solid angle), the one here is a different formulation, itself
//! checked against brute force in `checks`.

mod checks;
pub mod nginx;
pub mod redis_server;
pub mod s3;

use std::io::Write;
use std::path::PathBuf;

use voxd::engine::cpu::CpuEngine;
use voxd::engine::{Engine, GridMesh, Method};
use voxd::grid::{Grid, GridSpec};
use voxd::mesh::Mesh;
use voxd::volume::BitVolume;

/// `../shared/meshes`, or `None` with a printed notice.
pub fn shared_meshes() -> Option<PathBuf> {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/meshes");
    if p.join("README.md").exists() {
        Some(p)
    } else {
        eprintln!(
            "NOTICE: {} is absent; skipping tests on the shared real meshes",
            p.display()
        );
        None
    }
}

pub fn data(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name)
}

/// A fresh, empty scratch directory `$TMPDIR/voxd-tests-<pid>/<name>`; `name` keeps the tests'
/// directories apart (they all run in one process).
pub fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir()
        .join(format!("voxd-tests-{}", std::process::id()))
        .join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// `b` gzipped.
pub fn gz(b: &[u8]) -> Vec<u8> {
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    e.write_all(b).unwrap();
    e.finish().unwrap()
}

/// xorshift64*: deterministic, dependency-free.
pub struct Rng(u64);
impl Rng {
    pub fn new(seed: u64) -> Rng {
        Rng(seed.wrapping_mul(0x9E3779B97F4A7C15) | 1)
    }
    pub fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545F4914F6CDD1D)
    }
    pub fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
    /// A coordinate in [lo, hi] on the half-voxel lattice (on voxel faces and column centres).
    pub fn half(&mut self, lo: f64, hi: f64) -> f64 {
        let n = ((hi - lo) * 2.0) as u64;
        lo + self.below(n + 1) as f64 / 2.0
    }
}

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

/// The closed, outward-oriented box [lo, hi] as a mesh.
pub fn box_mesh(lo: [f64; 3], hi: [f64; 3]) -> Mesh {
    let (mut p, mut t) = (vec![], vec![]);
    push_box(&mut p, &mut t, lo, hi);
    Mesh::new(p, t).unwrap()
}

/// Appends a closed, outward-oriented box [lo, hi] to a triangle list.
pub fn push_box(p: &mut Vec<[f64; 3]>, t: &mut Vec<[u32; 3]>, lo: [f64; 3], hi: [f64; 3]) {
    let b = p.len() as u32;
    for i in 0..8 {
        p.push([
            if i & 1 == 0 { lo[0] } else { hi[0] },
            if i & 2 == 0 { lo[1] } else { hi[1] },
            if i & 4 == 0 { lo[2] } else { hi[2] },
        ]);
    }
    for f in [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ] {
        t.push([b + f[0], b + f[1], b + f[2]]);
        t.push([b + f[0], b + f[2], b + f[3]]);
    }
}

/// Appends a closed, outward-oriented octahedron.
pub fn push_octahedron(p: &mut Vec<[f64; 3]>, t: &mut Vec<[u32; 3]>, c: [f64; 3], r: [f64; 3]) {
    let b = p.len() as u32;
    for (a, s) in [
        (0, 1.0),
        (0, -1.0),
        (1, 1.0),
        (1, -1.0),
        (2, 1.0),
        (2, -1.0),
    ] {
        let mut q = c;
        q[a] += s * r[a];
        p.push(q);
    }
    // +x 0, -x 1, +y 2, -y 3, +z 4, -z 5
    for f in [
        [0, 2, 4],
        [2, 1, 4],
        [1, 3, 4],
        [3, 0, 4],
        [2, 0, 5],
        [1, 2, 5],
        [3, 1, 5],
        [0, 3, 5],
    ] {
        t.push([b + f[0], b + f[1], b + f[2]]);
    }
}

/// Appends a closed, outward-oriented tetrahedron with the given corners.
pub fn push_tetrahedron(p: &mut Vec<[f64; 3]>, t: &mut Vec<[u32; 3]>, v: [[f64; 3]; 4]) {
    let b = p.len() as u32;
    let s = |u: [f64; 3], w: [f64; 3]| [u[0] - w[0], u[1] - w[1], u[2] - w[2]];
    let (e1, e2, e3) = (s(v[1], v[0]), s(v[2], v[0]), s(v[3], v[0]));
    let vol = e1[0] * (e2[1] * e3[2] - e2[2] * e3[1]) - e1[1] * (e2[0] * e3[2] - e2[2] * e3[0])
        + e1[2] * (e2[0] * e3[1] - e2[1] * e3[0]);
    let v = if vol < 0.0 {
        [v[0], v[2], v[1], v[3]]
    } else {
        v
    };
    p.extend_from_slice(&v);
    for f in [[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]] {
        t.push([b + f[0], b + f[1], b + f[2]]);
    }
}

/// Random closed solids (boxes, octahedra, tetrahedra; overlapping) with vertices on the
/// half-voxel lattice of a unit grid at the origin, so many vertices sit on column centres and
/// faces on voxel faces. Some reach outside the grid and below it.
pub fn random_closed(rng: &mut Rng, dims: [u32; 3]) -> Mesh {
    let (mut p, mut t) = (vec![], vec![]);
    let d = dims.map(|d| d as f64);
    for _ in 0..1 + rng.below(4) {
        match rng.below(3) {
            0 => {
                let lo = [0, 1, 2].map(|a| rng.half(-1.5, d[a]));
                let hi =
                    [0, 1, 2].map(|a| lo[a] + rng.half(0.5, d[a] + 1.0 - lo[a].max(0.0)).max(0.5));
                push_box(&mut p, &mut t, lo, hi);
            }
            1 => {
                let c = [0, 1, 2].map(|a| rng.half(0.0, d[a]));
                let r = [0, 1, 2].map(|a| rng.half(0.5, (d[a] / 2.0).max(1.0)));
                push_octahedron(&mut p, &mut t, c, r);
            }
            _ => {
                let v = [0; 4].map(|_| [0, 1, 2].map(|a| rng.half(-1.0, d[a] + 1.0)));
                push_tetrahedron(&mut p, &mut t, v);
            }
        }
    }
    Mesh::new(p, t).unwrap()
}

/// A random triangle soup: lattice and off-lattice vertices, degenerate and vertical triangles,
/// triangles outside the grid, below it and above it.
pub fn random_soup(rng: &mut Rng, dims: [u32; 3]) -> Mesh {
    let d = dims.map(|d| d as f64);
    let mut p = vec![];
    let mut t = vec![];
    for _ in 0..1 + rng.below(12) {
        let b = p.len() as u32;
        let mut v = [0; 3].map(|_| {
            [0, 1, 2].map(|a| {
                if rng.below(2) == 0 {
                    rng.half(-2.0, d[a] + 2.0)
                } else {
                    rng.range(-2.0, d[a] + 2.0)
                }
            })
        });
        match rng.below(6) {
            0 => v[2] = v[1],                                         // two corners coincide
            1 => v[2] = [0, 1, 2].map(|a| (v[0][a] + v[1][a]) / 2.0), // collinear
            2 => v[2] = [v[0][0], v[0][1], v[1][2] + 1.5],            // vertical
            3 => v.iter_mut().for_each(|q| q[2] -= d[2] + 5.0),       // below the grid
            _ => {}
        }
        p.extend_from_slice(&v);
        t.push([b, b + 1, b + 2]);
    }
    Mesh::new(p, t).unwrap()
}

pub fn unit_grid(dims: [u32; 3]) -> Grid {
    Grid {
        origin: [0.0; 3],
        voxel_size: 1.0,
        dims,
    }
}

/// Describes the first difference between two volumes, for assertion messages.
pub fn first_difference(a: &BitVolume, b: &BitVolume) -> Option<String> {
    let [nx, ny, nz] = a.dims();
    for x in 0..nx {
        for y in 0..ny {
            for z in 0..nz {
                if a.get(x, y, z) != b.get(x, y, z) {
                    let n = a
                        .words()
                        .iter()
                        .zip(b.words())
                        .map(|(p, q)| (p ^ q).count_ones() as u64)
                        .sum::<u64>();
                    return Some(format!(
                        "voxel ({x},{y},{z}): {} vs {}; {n} voxels differ",
                        a.get(x, y, z),
                        b.get(x, y, z)
                    ));
                }
            }
        }
    }
    None
}

/// A volume on `g` with each voxel set with a random probability chosen per volume.
pub fn random_fill(rng: &mut Rng, g: Grid) -> BitVolume {
    let mut v = BitVolume::new(g);
    let fill = rng.below(100);
    for x in 0..g.dims[0] {
        for y in 0..g.dims[1] {
            for z in 0..g.dims[2] {
                if rng.below(100) < fill {
                    v.set(x, y, z, true);
                }
            }
        }
    }
    v
}

/// "X Y Z count Σx Σy Σz" of a volume: what the Python checks print for it.
pub fn summary(v: &BitVolume) -> String {
    let s = v.iter_ones().fold([0u64; 3], |a, p| {
        [a[0] + p[0] as u64, a[1] + p[1] as u64, a[2] + p[2] as u64]
    });
    let d = v.dims();
    format!(
        "{} {} {} {} {} {} {}",
        d[0],
        d[1],
        d[2],
        v.count_ones(),
        s[0],
        s[1],
        s[2]
    )
}

/// A random closed mesh on even seeds, a random triangle soup on odd ones.
pub fn random_mesh(rng: &mut Rng, dims: [u32; 3], seed: u64) -> Mesh {
    if seed.is_multiple_of(2) {
        random_closed(rng, dims)
    } else {
        random_soup(rng, dims)
    }
}

/// An octahedron subdivided `levels` times onto the sphere of `radius` around `centre`.
pub fn sphere(centre: [f64; 3], radius: f64, levels: u32) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let (mut p, mut t) = (vec![], vec![]);
    push_octahedron(&mut p, &mut t, [0.0; 3], [1.0; 3]);
    for _ in 0..levels {
        let mut nt = vec![];
        for tri in &t {
            let [a, b, c]: [u32; 3] = *tri;
            let mut mid = |i: u32, j: u32| {
                let (u, v) = (p[i as usize], p[j as usize]);
                p.push([0, 1, 2].map(|k| (u[k] + v[k]) / 2.0));
                p.len() as u32 - 1
            };
            let (ab, bc, ca) = (mid(a, b), mid(b, c), mid(c, a));
            nt.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        t = nt;
    }
    let p = p
        .iter()
        .map(|q| {
            let l = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt();
            [0, 1, 2].map(|k| centre[k] + radius * q[k] / l)
        })
        .collect();
    (p, t)
}

/// A mesh file and the grid `spec` (plus `padding`) fits to it.
pub fn mesh_and_grid(path: &std::path::Path, spec: GridSpec, padding: u32) -> (Mesh, Grid) {
    let mesh = voxd::mesh::load_file(path, usize::MAX).unwrap();
    let (lo, hi) = mesh.bounds();
    let g = Grid::fit(lo, hi, spec, padding, Default::default()).unwrap();
    (mesh, g)
}

/// What the library (and so the CLI and the service) gives for a mesh file, grid and method.
pub fn voxelize_file(path: &std::path::Path, spec: GridSpec, padding: u32, m: Method) -> BitVolume {
    let (mesh, g) = mesh_and_grid(path, spec, padding);
    CpuEngine
        .voxelize(&GridMesh::new(&mesh, &g).unwrap(), m)
        .unwrap()
}

/// The mesh as OBJ text.
pub fn to_obj(mesh: &Mesh) -> Vec<u8> {
    let mut s = String::new();
    for p in mesh.positions() {
        s += &format!("v {} {} {}\n", p[0], p[1], p[2]);
    }
    for t in mesh.triangles() {
        s += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    s.into_bytes()
}

/// A sphere with its top cut off (an open bowl) and one more triangle missing: not watertight,
/// and parity streaks on it.
pub fn open_bowl() -> Mesh {
    let (p, mut t) = sphere([0.1, -0.2, 0.05], 1.0, 3);
    t.retain(|tri| tri.iter().map(|&v| p[v as usize][2]).sum::<f64>() / 3.0 < 0.6);
    t.remove(7);
    Mesh::new(p, t).unwrap()
}

/// One HTTP/1.1 exchange over a fresh connection (`Connection: close`): the status, the headers
/// (names lowercased) and the body (chunked or not). Any failure, such as a server killed
/// mid-way, is an error, never a panic.
pub fn http_exchange(
    addr: &str,
    method: &str,
    path: &str,
    headers: &[(&str, &str)],
    body: &[u8],
) -> std::io::Result<(u16, std::collections::BTreeMap<String, String>, Vec<u8>)> {
    use std::collections::BTreeMap;
    use std::io::{Read, Write};
    let bad = |m: &str| std::io::Error::new(std::io::ErrorKind::InvalidData, m.to_string());
    let mut s = std::net::TcpStream::connect(addr)?;
    s.set_read_timeout(Some(std::time::Duration::from_secs(120)))?;
    s.set_write_timeout(Some(std::time::Duration::from_secs(120)))?;
    let mut head = format!(
        "{method} {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\nContent-Length: {}\r\n",
        body.len()
    );
    for (k, v) in headers {
        head += &format!("{k}: {v}\r\n");
    }
    head += "\r\n";
    s.write_all(head.as_bytes())?;
    s.write_all(body)?;
    let mut raw = Vec::new();
    s.read_to_end(&mut raw)?;
    let split = raw
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .ok_or_else(|| bad("no response head"))?;
    let head = String::from_utf8_lossy(&raw[..split]).to_string();
    let mut lines = head.split("\r\n");
    let status = lines
        .next()
        .and_then(|l| l.split(' ').nth(1))
        .and_then(|s| s.parse().ok())
        .ok_or_else(|| bad("no status"))?;
    let headers: BTreeMap<String, String> = lines
        .filter_map(|l| l.split_once(':'))
        .map(|(k, v)| (k.trim().to_ascii_lowercase(), v.trim().to_string()))
        .collect();
    let mut body = raw[split + 4..].to_vec();
    if headers
        .get("transfer-encoding")
        .is_some_and(|t| t == "chunked")
    {
        let mut out = Vec::new();
        let mut rest = &body[..];
        loop {
            let eol = rest
                .windows(2)
                .position(|w| w == b"\r\n")
                .ok_or_else(|| bad("torn chunk"))?;
            let n = std::str::from_utf8(&rest[..eol])
                .ok()
                .and_then(|n| usize::from_str_radix(n.trim(), 16).ok())
                .ok_or_else(|| bad("bad chunk size"))?;
            if n == 0 {
                break;
            }
            let chunk = rest
                .get(eol + 2..eol + 2 + n)
                .ok_or_else(|| bad("torn chunk"))?;
            out.extend_from_slice(chunk);
            rest = rest.get(eol + 4 + n..).ok_or_else(|| bad("torn chunk"))?;
        }
        body = out;
    } else if headers
        .get("content-length")
        .and_then(|n| n.parse::<usize>().ok())
        .is_some_and(|n| n != body.len())
    {
        return Err(bad("torn body"));
    }
    Ok((status, headers, body))
}

/// A response, as [`http_exchange`] reads it.
#[derive(Debug)]
pub struct Resp {
    pub status: u16,
    pub headers: std::collections::BTreeMap<String, String>,
    pub body: Vec<u8>,
}

impl Resp {
    /// The body as JSON (a panic showing the body when it is not).
    pub fn json(&self) -> serde_json::Value {
        serde_json::from_slice(&self.body)
            .unwrap_or_else(|e| panic!("{e}: {}", String::from_utf8_lossy(&self.body)))
    }
    pub fn header(&self, h: &str) -> Option<&str> {
        self.headers.get(h).map(String::as_str)
    }
    /// Itself, once its status is `status`.
    pub fn ok(self, status: u16) -> Resp {
        assert_eq!(
            self.status,
            status,
            "{}",
            String::from_utf8_lossy(&self.body)
        );
        self
    }
    /// The problem document, once it is one of `slug` with `status`.
    pub fn problem(&self, status: u16, slug: &str) -> serde_json::Value {
        assert_eq!(
            self.status,
            status,
            "{}",
            String::from_utf8_lossy(&self.body)
        );
        assert_eq!(
            self.header("content-type"),
            Some("application/problem+json")
        );
        let p = self.json();
        assert_eq!(
            p["type"],
            format!("https://voxd.dev/problems/{slug}"),
            "{p}"
        );
        p
    }
}

/// Spawns `cmd` (a `voxd serve`; its stdout is piped here) and waits, 120 s at most, for its
/// `voxd listening on` line: the child and the address it listens on.
pub fn spawn_serve(cmd: &mut std::process::Command) -> (std::process::Child, String) {
    use std::io::BufRead;
    let mut child = cmd
        .stdout(std::process::Stdio::piped())
        .spawn()
        .expect("voxd starts");
    let stdout = child.stdout.take().unwrap();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let mut line = String::new();
        let _ = std::io::BufReader::new(stdout).read_line(&mut line);
        let _ = tx.send(line);
    });
    let line = rx
        .recv_timeout(std::time::Duration::from_secs(120))
        .expect("voxd listens within 120 s");
    let addr = line
        .trim()
        .strip_prefix("voxd listening on http://")
        .unwrap_or_else(|| panic!("voxd did not start: {line:?}"))
        .to_string();
    (child, addr)
}
