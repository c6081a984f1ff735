//! Measures of an extracted mesh against its source, for the tests and the benchmark (not used
//! by the extraction): two-sided Hausdorff distance (sampled), the dihedral angle across the
//! source's feature edges, and self-intersections. All in the units of the meshes given
//! (lattice units in the tests: a voxel is 1). Brute force over a uniform grid of unit cells.

use std::collections::HashMap;

type Map<K, V> = HashMap<K, V, foldhash::fast::RandomState>;

use super::TriMesh;
use super::dual_contouring::distance2;
use super::vec3::{cross, dot, sub};
use crate::engine::geom::dist2_to_segment;

/// A point's bits: the key of a mesh vertex (a source's shared vertices are the same f64s).
fn key(p: [f64; 3]) -> [u64; 3] {
    p.map(f64::to_bits)
}

fn unit(a: [f64; 3]) -> [f64; 3] {
    let l = dot(a, a).sqrt();
    if l == 0.0 { a } else { a.map(|c| c / l) }
}
fn angle(a: [f64; 3], b: [f64; 3]) -> f64 {
    dot(unit(a), unit(b)).clamp(-1.0, 1.0).acos().to_degrees()
}

/// A mesh's triangles binned into unit cells by their bounding boxes.
pub struct Bins<'a> {
    m: &'a TriMesh,
    cells: Map<[i64; 3], Vec<u32>>,
}

/// The cells a triangle's bounding box meets: its low and high corners (inclusive).
fn box_cells(p: &[[f64; 3]; 3]) -> ([i64; 3], [i64; 3]) {
    (
        [0, 1, 2].map(|a| p[0][a].min(p[1][a]).min(p[2][a]).floor() as i64),
        [0, 1, 2].map(|a| p[0][a].max(p[1][a]).max(p[2][a]).floor() as i64),
    )
}

impl<'a> Bins<'a> {
    pub fn new(m: &'a TriMesh) -> Bins<'a> {
        let mut cells: Map<[i64; 3], Vec<u32>> = Map::default();
        for (i, t) in m.triangles.iter().enumerate() {
            let (lo, hi) = box_cells(&t.map(|v| m.positions[v as usize]));
            for x in lo[0]..=hi[0] {
                for y in lo[1]..=hi[1] {
                    for z in lo[2]..=hi[2] {
                        cells.entry([x, y, z]).or_default().push(i as u32);
                    }
                }
            }
        }
        Bins { m, cells }
    }

    fn tri(&self, i: u32) -> [[f64; 3]; 3] {
        self.m.triangles[i as usize].map(|v| self.m.positions[v as usize])
    }

    /// The nearest triangle to `p` within `reach` cells, and its distance.
    pub fn nearest(&self, p: [f64; 3], reach: i64) -> Option<(u32, f64)> {
        // Within 1 of `p`, a triangle meets a cell within one of p's: look there first.
        let near = self.nearest_in(p, 1);
        if reach <= 1 || near.is_some_and(|(_, d)| d <= 1.0) {
            return near;
        }
        self.nearest_in(p, reach)
    }

    /// The cells within `reach` of cell `c` that hold triangles, with them (x, then y, then
    /// z).
    fn around(&self, c: [i64; 3], reach: i64) -> impl Iterator<Item = ([i64; 3], &[u32])> + '_ {
        let r = move || -reach..=reach;
        r().flat_map(move |dx| {
            r().flat_map(move |dy| r().map(move |dz| [c[0] + dx, c[1] + dy, c[2] + dz]))
        })
        .filter_map(|k| self.cells.get(&k).map(|ts| (k, ts.as_slice())))
    }

    /// Whether some triangle lies within `bound` of `p`: such a triangle meets a cell within
    /// `reach` = ⌈bound⌉ (at least 1) of p's. p's own cell is looked at first.
    fn any_within(&self, p: [f64; 3], bound: f64, reach: i64) -> bool {
        debug_assert!(bound <= reach as f64);
        let c = p.map(|x| x.floor() as i64);
        // Compared as `nearest` reports distances (square roots), so the answer is its.
        let hit = |ts: &[u32]| {
            ts.iter()
                .any(|&t| distance2(p, &self.tri(t)).sqrt() <= bound)
        };
        self.cells.get(&c).is_some_and(|ts| hit(ts))
            || self.around(c, reach).any(|(k, ts)| k != c && hit(ts))
    }

    fn nearest_in(&self, p: [f64; 3], reach: i64) -> Option<(u32, f64)> {
        let c = p.map(|x| x.floor() as i64);
        let mut best: Option<(u32, f64)> = None;
        for (_, ts) in self.around(c, reach) {
            for &t in ts {
                let d = distance2(p, &self.tri(t));
                if best.is_none_or(|b| d < b.1) {
                    best = Some((t, d));
                }
            }
        }
        best.map(|(t, d)| (t, d.sqrt()))
    }

    /// The nearest triangle's normal at `p`.
    pub fn normal_near(&self, p: [f64; 3], reach: i64) -> Option<[f64; 3]> {
        self.nearest(p, reach).map(|(t, _)| {
            let q = self.tri(t);
            unit(cross(sub(q[1], q[0]), sub(q[2], q[0])))
        })
    }
}

/// Points on `m`: its vertices, and points on each triangle spaced about `step` apart.
pub fn samples(m: &TriMesh, step: f64) -> Vec<[f64; 3]> {
    let mut out = m.positions.clone();
    for t in &m.triangles {
        let p = t.map(|v| m.positions[v as usize]);
        let long = (0..3)
            .map(|i| dot(sub(p[(i + 1) % 3], p[i]), sub(p[(i + 1) % 3], p[i])).sqrt())
            .fold(0.0, f64::max);
        let n = ((long / step).ceil() as usize).clamp(1, 64);
        for i in 0..=n {
            for j in 0..=n - i {
                let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
                let w = 1.0 - u - v;
                out.push([0, 1, 2].map(|a| w * p[0][a] + u * p[1][a] + v * p[2][a]));
            }
        }
    }
    out
}

/// The largest distance from a sample of `a` to `b` (∞ when some sample has no triangle of
/// `b` within `reach` cells). A sample with a triangle of `b` no farther than the largest
/// distance so far cannot raise it, so its nearest triangle is not sought (the answer is the
/// same: it only skips work).
pub fn one_sided(a: &TriMesh, b: &Bins<'_>, step: f64, reach: i64) -> f64 {
    let mut worst = 0.0f64;
    for p in samples(a, step) {
        let r = (worst.ceil() as i64).max(1);
        if r <= reach && b.any_within(p, worst, r) {
            continue;
        }
        let d = b.nearest(p, reach).map_or(f64::INFINITY, |(_, d)| d);
        worst = worst.max(d);
    }
    worst
}

/// Two-sided Hausdorff distance between `a` and `b`, sampled every `step`.
pub fn hausdorff(a: &TriMesh, b: &TriMesh, step: f64) -> f64 {
    let (ba, bb) = (Bins::new(a), Bins::new(b));
    one_sided(a, &bb, step, 3).max(one_sided(b, &ba, step, 3))
}

/// A feature edge of a source mesh: its ends and the angle between its two faces' normals.
#[derive(Clone, Copy, Debug)]
pub struct Feature {
    pub a: [f64; 3],
    pub b: [f64; 3],
    pub normals: [[f64; 3]; 2],
    /// The directions into each face, perpendicular to the edge.
    pub into: [[f64; 3]; 2],
    pub angle: f64,
}

/// The edges of `m` whose two triangles' normals differ by more than `min_angle` degrees.
pub fn features(m: &TriMesh, min_angle: f64) -> Vec<Feature> {
    let mut sides: HashMap<(u32, u32), Vec<usize>> = HashMap::new();
    for (i, t) in m.triangles.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            sides.entry((a.min(b), a.max(b))).or_default().push(i);
        }
    }
    let tri = |i: usize| m.triangles[i].map(|v| m.positions[v as usize]);
    let mut out = vec![];
    for ((a, b), ts) in sides {
        if ts.len() != 2 {
            continue;
        }
        let (pa, pb) = (m.positions[a as usize], m.positions[b as usize]);
        let normals = [0, 1].map(|s| {
            let q = tri(ts[s]);
            unit(cross(sub(q[1], q[0]), sub(q[2], q[0])))
        });
        let ang = angle(normals[0], normals[1]);
        if ang <= min_angle {
            continue;
        }
        let e = unit(sub(pb, pa));
        let into = [0, 1].map(|s| {
            let d = unit(cross(normals[s], e));
            // Towards the face's third vertex.
            let third = m.triangles[ts[s]]
                .iter()
                .find(|&&v| v != a && v != b)
                .map(|&v| m.positions[v as usize])
                .unwrap();
            if dot(d, sub(third, pa)) < 0.0 {
                d.map(|c| -c)
            } else {
                d
            }
        });
        out.push(Feature {
            a: pa,
            b: pb,
            normals,
            into,
            angle: ang,
        });
    }
    out.sort_by(|x, y| {
        x.a.partial_cmp(&y.a)
            .unwrap()
            .then(x.b.partial_cmp(&y.b).unwrap())
    });
    out
}

/// Per feature (in order; `None` for one without a probe): |dihedral of `out` − dihedral of
/// `src`| in degrees, averaged over its `probes` ([`probes`], [`isolated`]). At a probe `p`
/// each side's dihedral normal is the normal of the nearest triangle to `p + r·into` (the
/// mesh's at that point of the face, `r` from the edge), in `src` and in `out` alike.
pub fn dihedral_errors(
    src: &TriMesh,
    out: &TriMesh,
    features: &[Feature],
    probes: &[Vec<[f64; 3]>],
    r: f64,
) -> Vec<Option<f64>> {
    let (bs, bo) = (Bins::new(src), Bins::new(out));
    let mut errors = vec![];
    for (f, ps) in features.iter().zip(probes) {
        let mut sum = 0.0;
        let mut n = 0;
        for p in ps {
            let q = [0, 1].map(|i| [0, 1, 2].map(|k| p[k] + r * f.into[i][k]));
            let ns = q.map(|q| bs.normal_near(q, 2));
            let no = q.map(|q| bo.normal_near(q, 2));
            let (Some(s0), Some(s1), Some(o0), Some(o1)) = (ns[0], ns[1], no[0], no[1]) else {
                sum += 180.0;
                n += 1;
                continue;
            };
            sum += (angle(o0, o1) - angle(s0, s1)).abs();
            n += 1;
        }
        errors.push((n > 0).then(|| sum / n as f64));
    }
    errors
}

/// The probes of each feature: points at ¼, ½, ¾ of it, none within `clear` of a corner (an
/// end shared by three or more of `features`).
pub fn probes(features: &[Feature], clear: f64) -> Vec<Vec<[f64; 3]>> {
    let mut degree: HashMap<[u64; 3], usize> = HashMap::new();
    for f in features {
        *degree.entry(key(f.a)).or_default() += 1;
        *degree.entry(key(f.b)).or_default() += 1;
    }
    let corners: Vec<[f64; 3]> = features
        .iter()
        .flat_map(|f| [f.a, f.b])
        .filter(|&p| degree[&key(p)] >= 3)
        .collect();
    features
        .iter()
        .map(|f| {
            [0.25, 0.5, 0.75]
                .iter()
                .map(|s| [0, 1, 2].map(|k| f.a[k] + s * (f.b[k] - f.a[k])))
                .filter(|&p| {
                    !corners
                        .iter()
                        .any(|c| dot(sub(*c, p), sub(*c, p)).sqrt() < clear)
                })
                .collect()
        })
        .collect()
}

/// Source edges whose faces' normals differ by more than this many degrees: the creases a
/// probe of [`isolated`] keeps clear of.
pub const CREASE: f64 = 30.0;

/// `probes` (of `features`, edges of `src`) without those within `clear` of a crease of `src`
/// (an edge over [`CREASE`]) of another chain than their feature's: where a feature is alone
/// on the grid. Two creases closer than a couple of voxels share dual cells, and a cell holds
/// one vertex: dual contouring cannot place it on both, on any grid of that size.
pub fn isolated(
    src: &TriMesh,
    features: &[Feature],
    probes: &[Vec<[f64; 3]>],
    clear: f64,
) -> Vec<Vec<[f64; 3]>> {
    let creases = self::features(src, CREASE);
    let chain = chains(&creases);
    let id: HashMap<([u64; 3], [u64; 3]), usize> = creases
        .iter()
        .enumerate()
        .flat_map(|(i, c)| {
            [
                ((key(c.a), key(c.b)), chain[i]),
                ((key(c.b), key(c.a)), chain[i]),
            ]
        })
        .collect();
    features
        .iter()
        .zip(probes)
        .map(|(f, ps)| {
            // A feature that is no crease (at most CREASE) is in no chain.
            let own = id.get(&(key(f.a), key(f.b))).copied();
            ps.iter()
                .copied()
                .filter(|&p| {
                    creases.iter().zip(&chain).all(|(c, &ch)| {
                        Some(ch) == own || dist2_to_segment(p, &[c.a, c.b]) >= clear * clear
                    })
                })
                .collect()
        })
        .collect()
}

/// Per crease (edges over [`CREASE`], as [`features`] gives them), the id of its chain:
/// creases joined where exactly two meet and the second goes on within 45° of the first's
/// direction (one feature cut into mesh edges).
fn chains(creases: &[Feature]) -> Vec<usize> {
    fn find(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    let mut at: HashMap<[u64; 3], Vec<usize>> = HashMap::new();
    for (i, f) in creases.iter().enumerate() {
        at.entry(key(f.a)).or_default().push(i);
        at.entry(key(f.b)).or_default().push(i);
    }
    let mut parent: Vec<usize> = (0..creases.len()).collect();
    for (v, es) in &at {
        let [e, f] = es[..] else { continue };
        // Each edge's direction away from the shared end.
        let away = |i: usize| {
            let c = &creases[i];
            if key(c.a) == *v {
                sub(c.b, c.a)
            } else {
                sub(c.a, c.b)
            }
        };
        if angle(away(e), away(f)) >= 135.0 {
            let (re, rf) = (find(&mut parent, e), find(&mut parent, f));
            parent[re] = rf;
        }
    }
    (0..creases.len()).map(|i| find(&mut parent, i)).collect()
}

/// Per feature (in order; `None` for one without a probe): the mean distance from its probes
/// to `out` (how far the mesh cuts the edge off; 0 when the edge is on the mesh).
pub fn feature_distances(out: &TriMesh, probes: &[Vec<[f64; 3]>]) -> Vec<Option<f64>> {
    let bo = Bins::new(out);
    probes
        .iter()
        .map(|ps| {
            (!ps.is_empty()).then(|| {
                ps.iter()
                    .map(|&p| bo.nearest(p, 3).map_or(f64::INFINITY, |(_, d)| d))
                    .sum::<f64>()
                    / ps.len() as f64
            })
        })
        .collect()
}

/// Pairs of triangles of `m` that cross each other (an edge of one through the other's
/// interior, by the exact signs of orientation determinants: [`triangles_cross`]; triangles
/// sharing a vertex are tested with the edges away from it, sharing an edge not at all).
pub fn self_intersections(m: &TriMesh) -> usize {
    crossing_pairs(m).len()
}

/// The pairs of triangles [`self_intersections`] counts (lower index first, in no order). A
/// pair whose bounding boxes share cells is tested once, in the first of them (the cell at the
/// larger of the two boxes' low corners, axis by axis).
pub fn crossing_pairs(m: &TriMesh) -> Vec<(u32, u32)> {
    let bins = Bins::new(m);
    let lows: Vec<[i64; 3]> = (0..m.triangles.len() as u32)
        .map(|t| box_cells(&bins.tri(t)).0)
        .collect();
    let mut pairs = vec![];
    for (cell, ts) in &bins.cells {
        for (i, &a) in ts.iter().enumerate() {
            for &b in &ts[i + 1..] {
                let (la, lb) = (lows[a as usize], lows[b as usize]);
                if [0, 1, 2].map(|k| la[k].max(lb[k])) != *cell {
                    continue;
                }
                let (ta, tb) = (m.triangles[a as usize], m.triangles[b as usize]);
                if triangles_cross(ta, bins.tri(a), tb, bins.tri(b)) {
                    pairs.push((a.min(b), a.max(b)));
                }
            }
        }
    }
    pairs
}

/// The sign of the orientation of `d` against the plane through `a`, `b`, `c`, exactly (the
/// sign of the determinant the f64 values define, by Shewchuk's adaptive predicate: plain f64
/// arithmetic got it wrong for nearly coplanar points and reported crossings between triangles
/// that do not touch).
fn orient(a: [f64; 3], b: [f64; 3], c: [f64; 3], d: [f64; 3]) -> i8 {
    let p = |q: [f64; 3]| robust::Coord3D {
        x: q[0],
        y: q[1],
        z: q[2],
    };
    let o = robust::orient3d(p(a), p(b), p(c), p(d));
    if o > 0.0 {
        1
    } else if o < 0.0 {
        -1
    } else {
        0
    }
}

/// Do triangles `ta` and `tb` (vertex ids; corners `pa`, `pb`) cross: an edge of one through
/// the other's interior, decided exactly (the signs of orientation determinants of the f64
/// coordinates, [`orient`])? Sharing an edge: no; sharing a vertex: only the edges away from
/// it are tested. An edge that only touches the other triangle (an end on its plane, or the
/// line through its boundary) does not cross it.
pub(super) fn triangles_cross(
    ta: [u32; 3],
    pa: [[f64; 3]; 3],
    tb: [u32; 3],
    pb: [[f64; 3]; 3],
) -> bool {
    let crosses = |p: [f64; 3], q: [f64; 3], t: [[f64; 3]; 3]| {
        let (s, e) = (orient(t[0], t[1], t[2], p), orient(t[0], t[1], t[2], q));
        if s == 0 || s != -e {
            return false;
        }
        let w = [0, 1, 2].map(|i| orient(p, q, t[i], t[(i + 1) % 3]));
        w.iter().all(|&x| x > 0) || w.iter().all(|&x| x < 0)
    };
    if ta.iter().filter(|v| tb.contains(v)).count() >= 2 {
        return false;
    }
    for (x, tx, y, py) in [(ta, pa, tb, pb), (tb, pb, ta, pa)] {
        for k in 0..3 {
            let (u, v) = (x[k], x[(k + 1) % 3]);
            if y.contains(&u) || y.contains(&v) {
                continue;
            }
            if crosses(tx[k], tx[(k + 1) % 3], py) {
                return true;
            }
        }
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;
    use num_bigint::BigInt;

    type Big3 = [BigInt; 3];

    /// `c` exactly, as an integer count of 2⁻¹²⁰ (every coordinate here is a multiple of it).
    fn big(c: f64) -> BigInt {
        let bits = c.to_bits();
        let exp = ((bits >> 52) & 0x7ff) as i64;
        let frac = bits & ((1u64 << 52) - 1);
        let (m, e) = if exp == 0 {
            (frac, -1074)
        } else {
            (frac | (1u64 << 52), exp - 1075)
        };
        let shift = e + 120;
        assert!(shift >= 0, "{c} is finer than 2^-120");
        let v = BigInt::from(m) << shift as usize;
        if c < 0.0 { -v } else { v }
    }

    fn sub_b(a: &Big3, b: &Big3) -> Big3 {
        [&a[0] - &b[0], &a[1] - &b[1], &a[2] - &b[2]]
    }

    fn cross_b(a: &Big3, b: &Big3) -> Big3 {
        [
            &a[1] * &b[2] - &a[2] * &b[1],
            &a[2] * &b[0] - &a[0] * &b[2],
            &a[0] * &b[1] - &a[1] * &b[0],
        ]
    }

    fn dot_b(a: &Big3, b: &Big3) -> BigInt {
        &a[0] * &b[0] + &a[1] * &b[1] + &a[2] * &b[2]
    }

    fn sign(x: &BigInt) -> i8 {
        match x.sign() {
            num_bigint::Sign::Minus => -1,
            num_bigint::Sign::NoSign => 0,
            num_bigint::Sign::Plus => 1,
        }
    }

    /// The oracle, by another route than `triangles_cross` and in exact integers: segment pq
    /// crosses triangle t when p and q lie strictly on either side of t's plane and the point
    /// where it meets the plane (an exact rational N / D) is strictly inside t, seen along the
    /// normal's largest axis.
    fn segment_crosses(p: &Big3, q: &Big3, t: &[Big3; 3]) -> bool {
        let n = cross_b(&sub_b(&t[1], &t[0]), &sub_b(&t[2], &t[0]));
        if n.iter().all(|c| sign(c) == 0) {
            return false;
        }
        let (s, e) = (dot_b(&n, &sub_b(p, &t[0])), dot_b(&n, &sub_b(q, &t[0])));
        if sign(&s) * sign(&e) != -1 {
            return false;
        }
        // X = p + s / (s − e) · (q − p) = (s·q − e·p) / (s − e).
        let d = &s - &e;
        let num: Big3 = std::array::from_fn(|k| &s * &q[k] - &e * &p[k]);
        let drop = (0..3)
            .max_by_key(|&k| n[k].magnitude().clone())
            .expect("three axes");
        let (u, v) = ((drop + 1) % 3, (drop + 2) % 3);
        // Edge i's side of X, scaled by D (whose sign is the same for all three).
        let side = |i: usize| {
            let (a, b) = (&t[i], &t[(i + 1) % 3]);
            let (ex, ey) = (&b[u] - &a[u], &b[v] - &a[v]);
            let (xx, xy) = (&num[u] - &a[u] * &d, &num[v] - &a[v] * &d);
            sign(&(ex * xy - ey * xx))
        };
        let w = [side(0), side(1), side(2)];
        w.iter().all(|&x| x > 0) || w.iter().all(|&x| x < 0)
    }

    fn oracle(ta: [u32; 3], pa: [[f64; 3]; 3], tb: [u32; 3], pb: [[f64; 3]; 3]) -> bool {
        if ta.iter().filter(|v| tb.contains(v)).count() >= 2 {
            return false;
        }
        let (ia, ib) = (pa.map(|p| p.map(big)), pb.map(|p| p.map(big)));
        let edges = |t: [u32; 3], other: [u32; 3]| {
            (0..3).filter(move |&k| !other.contains(&t[k]) && !other.contains(&t[(k + 1) % 3]))
        };
        edges(ta, tb).any(|k| segment_crosses(&ia[k], &ia[(k + 1) % 3], &ib))
            || edges(tb, ta).any(|k| segment_crosses(&ib[k], &ib[(k + 1) % 3], &ia))
    }

    /// The crossing test as it was, in plain f64: what the cases below must be hard for.
    fn naive(pa: [[f64; 3]; 3], pb: [[f64; 3]; 3]) -> bool {
        let o = |a: [f64; 3], b: [f64; 3], c: [f64; 3], d: [f64; 3]| {
            dot(cross(sub(b, a), sub(c, a)), sub(d, a))
        };
        let crosses = |p: [f64; 3], q: [f64; 3], t: [[f64; 3]; 3]| {
            let (s, e) = (o(t[0], t[1], t[2], p), o(t[0], t[1], t[2], q));
            if !(s > 0.0 && e < 0.0 || s < 0.0 && e > 0.0) {
                return false;
            }
            let w = [0, 1, 2].map(|i| o(p, q, t[i], t[(i + 1) % 3]));
            w.iter().all(|&x| x > 0.0) || w.iter().all(|&x| x < 0.0)
        };
        (0..3).any(|k| crosses(pa[k], pa[(k + 1) % 3], pb))
            || (0..3).any(|k| crosses(pb[k], pb[(k + 1) % 3], pa))
    }

    /// Two neighbouring dual-contouring triangles of rocker-arm at 576 voxels, a unit apart
    /// along x (x ∈ [25, 26] and [26.0002, 27.0002]: they cannot meet), which the plain f64
    /// test reported crossing.
    #[test]
    fn disjoint_nearly_coplanar_triangles_do_not_cross() {
        let a = [
            [25.000195537182375, 259.27073085906875, 553.0025328429148],
            [25.0, 258.9510365413859, 554.0],
            [26.0, 258.92765927204994, 554.0],
        ];
        let b = [
            [26.000195537182375, 259.24735358973277, 553.0025328429148],
            [27.0, 258.90428200271396, 554.0],
            [27.000195537182375, 259.2239763203968, 553.0025328429148],
        ];
        assert!(naive(a, b), "the case the f64 test got wrong");
        assert!(!triangles_cross([0, 1, 2], a, [3, 4, 5], b));
    }

    /// `triangles_cross` agrees with the exact oracle on triangle pairs whose corners were put
    /// on one plane in f64 (off it by the rounding only), on pairs lifted off it by 10⁻⁹ and by
    /// 0.3, and on pairs sharing a vertex; the plain f64 test is wrong on some of them.
    #[test]
    fn crossings_agree_with_an_exact_oracle() {
        let mut seed = 0x9e3779b97f4a7c15u64;
        let mut rnd = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let (mut yes, mut no, mut naive_wrong) = (0, 0, 0);
        for case in 0..20_000 {
            // A plane through o spanned by u and v (random directions), corners on it within
            // two voxels of o, the second triangle's lifted off it by up to `lift`.
            let o = [0, 1, 2].map(|_| 100.0 + 400.0 * rnd());
            let mut dir = || {
                let d = [rnd() - 0.5, rnd() - 0.5, rnd() - 0.5];
                let l = dot(d, d).sqrt().max(1e-9);
                d.map(|c| c / l)
            };
            let (u, v) = (dir(), dir());
            let n = cross(u, v);
            let lift = [0.0, 1e-9, 0.3][case % 3];
            let mut corner = |h: f64| {
                let (a, b) = (4.0 * rnd() - 2.0, 4.0 * rnd() - 2.0);
                let z = h * (2.0 * rnd() - 1.0);
                [0, 1, 2].map(|k| o[k] + a * u[k] + b * v[k] + z * n[k])
            };
            let pa = [corner(0.0), corner(0.0), corner(0.0)];
            let mut pb = [corner(lift), corner(lift), corner(lift)];
            let mut tb = [3, 4, 5];
            if case % 7 == 0 {
                // Sharing a vertex.
                pb[0] = pa[0];
                tb[0] = 0;
            }
            let got = triangles_cross([0, 1, 2], pa, tb, pb);
            assert_eq!(
                got,
                oracle([0, 1, 2], pa, tb, pb),
                "case {case}: {pa:?} {pb:?}"
            );
            if tb[0] != 0 && naive(pa, pb) != got {
                naive_wrong += 1;
            }
            if got { yes += 1 } else { no += 1 }
        }
        assert!(yes > 1000 && no > 1000, "{yes} crossing, {no} not");
        assert!(naive_wrong > 0, "no case was hard for plain f64");
        eprintln!("{yes} crossing, {no} not; plain f64 wrong on {naive_wrong}");
    }
}
