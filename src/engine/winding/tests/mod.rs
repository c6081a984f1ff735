//! The winding fill's tests, by what they check: the geometry and the hierarchy's values
//! ([`hierarchy`]), the caps ([`caps`]), the bounds against exact sums ([`bounds`]), the
//! eight-lane traversals ([`traversal`]) and kernels ([`lanes`]), and whole fills decided by
//! blocks against voxel by voxel ([`blocks`]). Here: the meshes, random inputs and trees they
//! share.
//!
//! Not here: the fills compared with the other fills and with the exact winding number on real
//! meshes (`tests/fill.rs`, `tests/oracles.rs`).

mod blocks;
mod bounds;
mod caps;
mod hierarchy;
mod lanes;
mod traversal;

use std::f64::consts::PI;

use super::caps::{chain_boundary, closed_by_caps};
use super::certifier::{Certifier, Decision};
use super::edges::{EdgeTree, GRADIENT_SIGN, field_lanes, segment_field, solid_angle_gradient};
use super::lanes::{Far, LANES};
use super::traverse::{spread_lanes, taylor_lanes};
use super::trees::{Trees, far_field};
use super::*;
use crate::engine::geom::bvh::build;
use crate::engine::geom::{add3, area_normal, cross, dist2_to_triangle, dot, norm, sub};
use crate::engine::snap::snapped_world;
use crate::testkit::Rng;

fn octahedron() -> Mesh {
    let (p, t) = crate::testkit::octahedron();
    Mesh::new(p, t).unwrap()
}

/// A bumpy open surface of many triangles: a height field over [0, 1]².
fn sheet(n: u32) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let mut p = Vec::new();
    for i in 0..=n {
        for j in 0..=n {
            let (x, y) = (i as f64 / n as f64, j as f64 / n as f64);
            p.push([x, y, 0.1 * (7.0 * x).sin() * (5.0 * y).cos()]);
        }
    }
    let mut t = Vec::new();
    let id = |i: u32, j: u32| i * (n + 1) + j;
    for i in 0..n {
        for j in 0..n {
            t.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            t.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    (p, t)
}

/// Positions and triangles.
type Soup = (Vec<[f64; 3]>, Vec<[u32; 3]>);

fn add(a: [f64; 3], b: [f64; 3], t: f64) -> [f64; 3] {
    [0, 1, 2].map(|k| a[k] + t * b[k])
}

/// A random triangle in [-1, 1]³ (`None` when its area is below 10⁻³), its area and unit
/// normal, and a query point at a distance of `near`–1 times 1–100 from its centroid, along
/// the normal or in a random direction.
#[allow(clippy::type_complexity)]
fn triangle_and_query(
    rng: &mut Rng,
    along_normal: bool,
    near: f64,
) -> Option<([[f64; 3]; 3], f64, [f64; 3], [f64; 3])> {
    let t = [0; 3].map(|_| rng.point(-1.0, 1.0));
    let area = norm(area_normal(&t));
    if area < 1e-3 {
        return None;
    }
    let centroid = [0, 1, 2].map(|k| (t[0][k] + t[1][k] + t[2][k]) / 3.0);
    let normal = area_normal(&t).map(|v| v / area);
    let dir = if along_normal {
        normal
    } else {
        rng.direction()
    };
    let q = add(
        centroid,
        dir,
        rng.range(near, 1.0) * 10f64.powf(rng.range(0.0, 2.0)),
    );
    Some((t, area, normal, q))
}

/// The gradient of `solid_angle` by central differences.
fn gradient(t: &[[f64; 3]; 3], q: [f64; 3], h: f64) -> [f64; 3] {
    [0, 1, 2].map(|k| {
        let mut e = [0.0; 3];
        e[k] = h;
        (solid_angle(t, add(q, e, 1.0)) - solid_angle(t, add(q, e, -1.0))) / (2.0 * h)
    })
}

/// A bumpy sheet's hierarchy, its boundary's, and its triangles.
fn sheet_trees() -> (WindingTree, EdgeTree, Vec<[[f64; 3]; 3]>) {
    let (p, t) = sheet(30);
    let tris = t.iter().map(|t| t.map(|i| p[i as usize])).collect();
    let segs: Vec<[[f64; 3]; 2]> = chain_boundary(&t)
        .iter()
        .map(|e| e.map(|i| p[i as usize]))
        .collect();
    (WindingTree::new(&p, &t), EdgeTree::new(segs), tris)
}

/// Eight balls at the centres of a small block's eight sub-blocks near the sheet, and their
/// radius.
fn eight_balls(rng: &mut Rng) -> ([[f64; 3]; LANES], f64) {
    let centre = add(
        [0.5, 0.5, 0.0],
        rng.direction(),
        10f64.powf(rng.range(-1.3, 0.3)),
    );
    let step = 10f64.powf(rng.range(-2.5, -1.3));
    let qs = std::array::from_fn(|d| {
        [0, 1, 2].map(|a| centre[a] + step * (((d >> a) & 1) as f64 - 0.5))
    });
    (qs, 0.5 * step * 3f64.sqrt())
}

/// The lanes a traversal's bits (from the test above) mark as `None`.
fn nones(bits: &[u64]) -> u32 {
    bits.iter().filter(|&&b| f64::from_bits(b).is_nan()).count() as u32
}

/// A UV sphere: positions and outward triangles.
fn uv_sphere(c: [f64; 3], r: f64, n: u32) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let (rings, segs) = (n, 2 * n);
    let mut p = vec![[c[0], c[1], c[2] + r], [c[0], c[1], c[2] - r]];
    for i in 1..rings {
        let th = PI * i as f64 / rings as f64;
        for j in 0..segs {
            let ph = 2.0 * PI * j as f64 / segs as f64;
            p.push([
                c[0] + r * th.sin() * ph.cos(),
                c[1] + r * th.sin() * ph.sin(),
                c[2] + r * th.cos(),
            ]);
        }
    }
    let id = |i: u32, j: u32| 2 + (i - 1) * segs + j % segs;
    let mut t = Vec::new();
    for j in 0..segs {
        t.push([0, id(1, j), id(1, j + 1)]);
        t.push([1, id(rings - 1, j + 1), id(rings - 1, j)]);
        for i in 1..rings - 1 {
            t.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            t.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    (p, t)
}

/// Meshes with holes on a 32³ unit grid: a sphere with triangles missing, an open bowl, a
/// patch left of a sphere (where the caps' winding number is near ±1), two overlapping
/// spheres (w = 2) with holes, and a bumpy sheet.
fn holey_meshes() -> Vec<Mesh> {
    let mut rng = Rng::new(777);
    let mut out = Vec::new();
    let (p, mut t) = uv_sphere([15.7, 16.2, 16.1], 11.3, 14);
    for _ in 0..6 {
        t.remove((rng.unit() * t.len() as f64) as usize);
    }
    out.push(Mesh::new(p, t).unwrap());
    let (p, mut t) = uv_sphere([16.2, 15.9, 15.4], 12.1, 16);
    t.retain(|tri| tri.iter().map(|&v| p[v as usize][2]).sum::<f64>() / 3.0 < 22.0);
    out.push(Mesh::new(p, t).unwrap().flipped());
    let (p, mut t) = uv_sphere([16.1, 16.3, 15.8], 12.4, 16);
    t.retain(|tri| tri.iter().map(|&v| p[v as usize][0]).sum::<f64>() / 3.0 > 9.0);
    out.push(Mesh::new(p, t).unwrap());
    let (mut p, mut t) = uv_sphere([13.1, 14.2, 15.3], 8.7, 12);
    let (p2, t2) = uv_sphere([18.4, 17.9, 16.6], 9.2, 12);
    let off = p.len() as u32;
    p.extend(p2);
    t.extend(t2.iter().map(|tri| tri.map(|v| v + off)));
    for _ in 0..8 {
        t.remove((rng.unit() * t.len() as f64) as usize);
    }
    out.push(Mesh::new(p, t).unwrap());
    let (p, t) = sheet(24);
    let p = p
        .iter()
        .map(|v| [3.3 + 25.0 * v[0], 4.1 + 24.0 * v[1], 15.2 + 60.0 * v[2]]);
    out.push(Mesh::new(p.collect(), t).unwrap());
    out
}

/// A grid around [`holey_meshes`] with room for `SUPER`³ blocks of blocks beside them.
const SUPER_GRID: Grid = Grid {
    origin: [-37.5, -21.0, -40.25],
    voxel_size: 1.0,
    dims: [100, 71, 97],
};
