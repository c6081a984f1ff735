//! Hermite data (issue 33; docs/methods.md, "Hermite data"): for every grid edge between two
//! neighbouring voxel centres whose voxels differ in a solid made from the mesh, where the
//! surface crosses it and the unit normal of the triangle it crosses — what dual contouring
//! places its vertices from.
//!
//! The rules, all on the 1/256-voxel lattice of [`GridMesh`] (integer arithmetic until the one
//! division that gives the fraction):
//! * An edge along axis `a` from voxel `k` to `k + 1` is the segment between their centres.
//!   Seen along `a`, a triangle covers the edge's line when the line's point lies in the
//!   triangle's projection: *strictly* by the solid's tie rule (rotated so that `a` plays the
//!   part of z: `(a + 1, a + 2, a)` is a right-handed frame), or *closed* (on an edge or vertex of
//!   the projection). Its crossing is the plane's depth `c` there, an exact rational.
//! * A crossing belongs to the edge when `centre_k ≤ c < centre_k+1` (the solid's "strictly
//!   above" rule, so along z the strict crossings of an edge are exactly the ones the solid
//!   counted), or closed, `centre_k ≤ c ≤ centre_k+1`.
//! * Each edge takes one crossing: a strict one if it has any, else a closed one; among those
//!   the lowest fraction, then the lowest triangle. Triangles whose projection along `a` has
//!   zero area (parallel to the edge) cross nothing.
//! * An edge that differs in solid without any crossing (an open mesh filled by winding or
//!   flood, or a solid from another fill) is kept with `crossed = false`, the fraction ½ and a
//!   zero normal. For a watertight mesh filled by parity every differing edge is crossed
//!   (the segment joins a point inside and one outside, or starts on the surface).
//! * The normal is the triangle's (snapped), `(v1 − v0) × (v2 − v0)` normalised: outward for an
//!   outward-oriented mesh.

use rayon::prelude::*;

use super::snap::{FIXED_HALF, FIXED_ONE};
use super::{axis_bounds, centre_range};
use crate::cancel::{Canceled, Control};
use crate::grid::Grid;
use crate::volume::BitVolume;

/// One edge of the Hermite data.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HermiteEdge {
    /// The edge's lower voxel; the other is one step along `axis`.
    pub voxel: [u32; 3],
    pub axis: u8,
    /// The lower voxel is inside the solid (so the upper one is outside).
    pub lower_inside: bool,
    /// Where the surface crosses, as a fraction of the edge from the lower voxel's centre, in
    /// [0, 1]: the exact rational rounded (numerator and denominator each rounded to f64,
    /// then divided: within 2⁻⁵¹ relative).
    pub t: f64,
    /// The crossed triangle's unit normal (zero when not crossed).
    pub normal: [f64; 3],
    /// A triangle crosses the edge.
    pub crossed: bool,
}

impl HermiteEdge {
    /// The crossing point in lattice units (voxel (i, j, k) spans [i, i + 1] × …).
    pub fn point(&self) -> [f64; 3] {
        let mut p = self.voxel.map(|c| f64::from(c) + 0.5);
        p[self.axis as usize] += self.t;
        p
    }
}

/// The Hermite data of a solid: its differing edges in order of (axis, x, y, z).
#[derive(Clone, Debug)]
pub struct Hermite {
    pub grid: Grid,
    pub edges: Vec<HermiteEdge>,
}

impl Hermite {
    /// Edges no triangle crosses.
    pub fn uncrossed(&self) -> usize {
        self.edges.iter().filter(|e| !e.crossed).count()
    }

    /// The edge from `voxel` along `axis`, if it differs in solid.
    pub fn find(&self, voxel: [u32; 3], axis: usize) -> Option<&HermiteEdge> {
        let key = (axis as u8, voxel);
        self.edges
            .binary_search_by(|e| (e.axis, e.voxel).cmp(&key))
            .ok()
            .map(|i| &self.edges[i])
    }
}

/// Bytes per edge of [`Hermite`] while it is built (the candidate list and the edges).
pub const BYTES_PER_EDGE: u64 = 96;

/// A crossing found for an edge: its key, rank (0 strict, 1 closed), fraction and triangle.
#[derive(Clone, Copy)]
struct Candidate {
    key: u64,
    rank: u8,
    t: f64,
    tri: u32,
}

/// The Hermite data of `solid` from `triangles` (lattice coordinates of [`GridMesh`] on
/// `solid`'s grid; every triangle within a voxel of the grid must be there).
///
/// [`GridMesh`]: super::GridMesh
pub fn hermite(
    triangles: &[[[i32; 3]; 3]],
    solid: &BitVolume,
    ctl: &Control,
) -> Result<Hermite, Canceled> {
    let grid = *solid.grid();
    let d = grid.dims;
    let key = |axis: usize, v: [u32; 3]| -> u64 {
        let n = u64::from(d[0]) * u64::from(d[1]) * u64::from(d[2]);
        axis as u64 * n
            + (u64::from(v[0]) * u64::from(d[1]) + u64::from(v[1])) * u64::from(d[2])
            + u64::from(v[2])
    };
    let differs = |v: [u32; 3], a: usize| -> bool {
        let mut w = v;
        w[a] += 1;
        solid.get(v[0], v[1], v[2]) != solid.get(w[0], w[1], w[2])
    };
    let counter = ctl.counter(3 * triangles.len() as u64);
    let mut cands: Vec<Candidate> = Vec::new();
    for a in 0..3 {
        let found: Result<Vec<Vec<Candidate>>, Canceled> = triangles
            .par_chunks(4096)
            .enumerate()
            .map(|(ci, chunk)| {
                counter.check()?;
                let mut out = Vec::new();
                for (i, t) in chunk.iter().enumerate() {
                    let tri = (ci * 4096 + i) as u32;
                    crossings(t, a, d, |v, rank, t| {
                        if differs(v, a) {
                            out.push(Candidate {
                                key: key(a, v),
                                rank,
                                t,
                                tri,
                            });
                        }
                    });
                }
                counter.add(chunk.len() as u64);
                Ok(out)
            })
            .collect();
        for v in found? {
            cands.extend(v);
        }
    }
    cands.par_sort_unstable_by(|x, y| {
        (x.key, x.rank)
            .cmp(&(y.key, y.rank))
            .then(x.t.total_cmp(&y.t))
            .then(x.tri.cmp(&y.tri))
    });
    cands.dedup_by_key(|c| c.key);
    ctl.check()?;
    // Every differing edge, in key order, with its candidate when it has one.
    let mut edges = Vec::with_capacity(cands.len());
    let mut next = cands.iter().peekable();
    for a in 0..3 {
        let mut hi = d;
        hi[a] -= 1;
        for x in 0..hi[0] {
            for y in 0..hi[1] {
                for z in 0..hi[2] {
                    let v = [x, y, z];
                    if !differs(v, a) {
                        continue;
                    }
                    let k = key(a, v);
                    while next.peek().is_some_and(|c| c.key < k) {
                        next.next();
                    }
                    let lower_inside = solid.get(x, y, z);
                    let c = next.peek().filter(|c| c.key == k);
                    edges.push(match c {
                        Some(c) => HermiteEdge {
                            voxel: v,
                            axis: a as u8,
                            lower_inside,
                            t: c.t,
                            normal: unit_normal(&triangles[c.tri as usize]),
                            crossed: true,
                        },
                        None => HermiteEdge {
                            voxel: v,
                            axis: a as u8,
                            lower_inside,
                            t: 0.5,
                            normal: [0.0; 3],
                            crossed: false,
                        },
                    });
                }
            }
        }
        ctl.check()?;
    }
    ctl.complete();
    Ok(Hermite { grid, edges })
}

/// The triangle's unit normal, `(v1 − v0) × (v2 − v0)` normalised (zero when degenerate).
pub fn unit_normal(t: &[[i32; 3]; 3]) -> [f64; 3] {
    let e = |i: usize| [0, 1, 2].map(|a| i64::from(t[i][a]) - i64::from(t[0][a]));
    let (u, v) = (e(1), e(2));
    let n = [
        (u[1] as i128 * v[2] as i128 - u[2] as i128 * v[1] as i128) as f64,
        (u[2] as i128 * v[0] as i128 - u[0] as i128 * v[2] as i128) as f64,
        (u[0] as i128 * v[1] as i128 - u[1] as i128 * v[0] as i128) as f64,
    ];
    let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    if len == 0.0 {
        [0.0; 3]
    } else {
        n.map(|c| c / len)
    }
}

/// Calls `f(lower voxel, rank, t)` for every edge along axis `a` of a `d` grid that triangle
/// `t` crosses (module rules; rank 0 strict, 1 closed only).
fn crossings(t: &[[i32; 3]; 3], a: usize, d: [u32; 3], mut f: impl FnMut([u32; 3], u8, f64)) {
    let (p, q) = ((a + 1) % 3, (a + 2) % 3);
    // Rotated so that (p, q, a) is (x, y, z).
    let mut v = t.map(|c| [i64::from(c[p]), i64::from(c[q]), i64::from(c[a])]);
    let area2 =
        (v[1][0] - v[0][0]) * (v[2][1] - v[0][1]) - (v[1][1] - v[0][1]) * (v[2][0] - v[0][0]);
    if area2 == 0 {
        return;
    }
    let area2 = if area2 < 0 {
        v.swap(1, 2);
        -area2
    } else {
        area2
    };
    let (Some((x0, x1)), Some((y0, y1))) = (
        {
            let (lo, hi) = axis_bounds(&v, 0);
            centre_range(lo, hi, d[p])
        },
        {
            let (lo, hi) = axis_bounds(&v, 1);
            centre_range(lo, hi, d[q])
        },
    ) else {
        return;
    };
    if d[a] < 2 {
        return;
    }
    // Edge i (opposite vertex i): w_i = ex·(py − a.y) − ey·(px − a.x), the solid's tie bias.
    let edge = |s: [i64; 3], e: [i64; 3]| {
        let (ex, ey) = (e[0] - s[0], e[1] - s[1]);
        let bias = if ey > 0 || (ey == 0 && ex < 0) { 0 } else { 1 };
        (s, ex, ey, bias)
    };
    let edges = [edge(v[1], v[2]), edge(v[2], v[0]), edge(v[0], v[1])];
    let a2 = i128::from(area2);
    let step = i128::from(FIXED_ONE) * a2;
    for x in x0..=x1 {
        let px = i64::from(x) * FIXED_ONE + FIXED_HALF;
        for y in y0..=y1 {
            let py = i64::from(y) * FIXED_ONE + FIXED_HALF;
            let w = edges.map(|(s, ex, ey, _)| ex * (py - s[1]) - ey * (px - s[0]));
            if w.iter().any(|&w| w < 0) {
                continue;
            }
            let strict = (0..3).all(|i| w[i] >= edges[i].3);
            // Depth c = num / A; from the first centre: c − 128 = (num − 128·A) / A.
            let num: i128 = (0..3).map(|i| i128::from(w[i]) * i128::from(v[i][2])).sum();
            let rel = num - i128::from(FIXED_HALF) * a2;
            let k = rel.div_euclid(step);
            let rem = rel.rem_euclid(step);
            let mut voxel = |k: i128, rank: u8, t: f64| {
                if k >= 0 && k + 1 < i128::from(d[a]) {
                    let mut c = [0u32; 3];
                    c[p] = x;
                    c[q] = y;
                    c[a] = k as u32;
                    f(c, rank, t);
                }
            };
            voxel(k, if strict { 0 } else { 1 }, rem as f64 / step as f64);
            if rem == 0 {
                // On the centre of voxel k: also the top end of edge k − 1 (closed only).
                voxel(k - 1, 1, 1.0);
            }
        }
    }
}

#[cfg(test)]
#[path = "hermite_tests.rs"]
mod tests;
