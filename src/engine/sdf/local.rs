//! A triangle seen from one brick: its vertices relative to the brick's first voxel centre, with
//! what the distance to it needs precomputed, so the 512 centres of the brick take
//! [`lattice::distance2`]'s value in plain `f64` arithmetic.
//!
//! Why the bits are the same: `lattice::distance2` computes exact integers (i64/i128) and rounds
//! only the final products and quotient to f64. When every coordinate difference among the
//! brick's centres and the triangle's vertices is at most D = 2¹², every one of those integers
//! is below 2⁵³ (|w|, |e| ≤ D; cross products ≤ 2D²; dot products of them ≤ 12D⁴ = 3·2⁵⁰; the
//! plane's n·w ≤ 6D³), so f64 holds it exactly and the same roundings follow. The inside-the-
//! triangle test n·(e × w) ≥ 0 is computed as w·(n × e), n × e ≤ 4D³, the dot ≤ 12D⁴: exact too.
//! A triangle that spans more than D with the brick ([`Local::exact`] false) takes
//! `lattice::distance2` itself.

use crate::engine::geom::lattice;
use crate::engine::snap::{FIXED_HALF, FIXED_ONE};
use crate::volume::sparse::BRICK;

/// The largest coordinate difference for which f64 arithmetic is exact here.
const D: i64 = 1 << 12;

#[inline(always)]
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
#[inline(always)]
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
#[inline(always)]
fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// A triangle relative to a brick's first voxel centre `origin` (lattice units).
pub struct Local<'a> {
    pub tri: &'a [[i32; 3]; 3],
    pub origin: [i64; 3],
    /// Vertices, relative.
    v: [[f64; 3]; 3],
    /// Edges v[i+1] − v[i], their squared lengths, and n × e (n the integer normal).
    e: [[f64; 3]; 3],
    ee: [f64; 3],
    ne: [[f64; 3]; 3],
    n: [f64; 3],
    nn: f64,
    /// The bounding box, relative.
    pub lo: [f64; 3],
    pub hi: [f64; 3],
    /// The unit normal (one rounding per component), for the plane's lower bound; zeros for
    /// a degenerate triangle.
    pub unit: [f64; 3],
    /// Every difference within D: [`Local::distance2`] is exact-then-rounded like
    /// `lattice::distance2`.
    pub exact: bool,
}

/// What a triangle's distance needs that does not depend on the brick it is seen from: its
/// integer normal (rounded once per component to f64, as `lattice::distance2` has it), the
/// normal's squared length and the unit normal. Computed once per triangle rather than once
/// per (brick, triangle) pair: the normal is a cross product of edges, the same integers from
/// any origin.
#[derive(Clone, Copy, Debug)]
pub struct Plane {
    n: [f64; 3],
    nn: f64,
    /// All zeros for a degenerate triangle (a bound that culls nothing).
    unit: [f64; 3],
}

impl Plane {
    pub fn new(tri: &[[i32; 3]; 3]) -> Plane {
        let ie =
            |i: usize, j: usize| [0, 1, 2].map(|a| i64::from(tri[j][a]) - i64::from(tri[i][a]));
        let (e1, e2) = (ie(0, 1), ie(0, 2));
        let ni = [
            e1[1] as i128 * e2[2] as i128 - e1[2] as i128 * e2[1] as i128,
            e1[2] as i128 * e2[0] as i128 - e1[0] as i128 * e2[2] as i128,
            e1[0] as i128 * e2[1] as i128 - e1[1] as i128 * e2[0] as i128,
        ];
        let n = ni.map(|c| c as f64);
        let nn = dot(n, n);
        let len = nn.sqrt();
        let unit = if len > 0.0 {
            n.map(|c| c / len)
        } else {
            [0.0; 3]
        };
        Plane { n, nn, unit }
    }
}

impl<'a> Local<'a> {
    /// Triangle `tri` (whose [`Plane`] is `plane`) seen from brick `at` (origin: the centre of
    /// voxel `8·at`).
    #[inline(always)]
    pub fn new(tri: &'a [[i32; 3]; 3], plane: &Plane, at: [u32; 3]) -> Local<'a> {
        // Written out with loops rather than nested `map`s: the compiler left those as calls,
        // and this runs once per (brick, triangle) pair (millions of them).
        let mut origin = [0i64; 3];
        let mut rel = [[0i64; 3]; 3];
        let mut v = [[0.0f64; 3]; 3];
        for a in 0..3 {
            origin[a] = i64::from(at[a] * BRICK) * FIXED_ONE + FIXED_HALF;
            for c in 0..3 {
                rel[c][a] = i64::from(tri[c][a]) - origin[a];
                v[c][a] = rel[c][a] as f64;
            }
        }
        let span = (i64::from(BRICK) - 1) * FIXED_ONE;
        let (mut lo, mut hi) = ([0.0f64; 3], [0.0f64; 3]);
        let mut exact = true;
        for a in 0..3 {
            let rlo = rel[0][a].min(rel[1][a]).min(rel[2][a]);
            let rhi = rel[0][a].max(rel[1][a]).max(rel[2][a]);
            exact &= rhi.max(span) - rlo.min(0) <= D;
            lo[a] = v[0][a].min(v[1][a]).min(v[2][a]);
            hi[a] = v[0][a].max(v[1][a]).max(v[2][a]);
        }
        let nf = plane.n;
        let mut e = [[0.0f64; 3]; 3];
        let (mut ee, mut ne) = ([0.0f64; 3], [[0.0f64; 3]; 3]);
        for i in 0..3 {
            e[i] = sub(v[(i + 1) % 3], v[i]);
            ee[i] = dot(e[i], e[i]);
            ne[i] = cross(nf, e[i]);
        }
        Local {
            tri,
            origin,
            v,
            e,
            ee,
            ne,
            n: nf,
            nn: plane.nn,
            lo,
            hi,
            unit: plane.unit,
            exact,
        }
    }

    /// Vertex `i`, relative.
    #[inline]
    pub fn vertex(&self, i: usize) -> [f64; 3] {
        self.v[i]
    }

    /// The squared lattice distance from local point `p` (relative to the origin, lattice
    /// units), with exactly [`lattice::distance2`]'s value.
    #[inline(always)]
    pub fn distance2(&self, p: [f64; 3]) -> f64 {
        if !self.exact {
            let g = [0, 1, 2].map(|a| p[a] as i64 + self.origin[a]);
            return lattice::distance2(g, self.tri);
        }
        self.distance2_lanes(&[[p[0]], [p[1]], [p[2]]])[0]
    }

    /// [`Local::distance2`] at `L` points (`p[a][k]`: coordinate a of point k) of an exact
    /// triangle ([`Local::exact`]), in the shape that vectorizes: every candidate computed and
    /// the valid ones selected without a branch (which feature is nearest does not predict
    /// well); the same operations on the same values as `lattice::distance2`, lane by lane, so
    /// the same bits.
    #[inline(always)]
    pub fn distance2_lanes<const L: usize>(&self, p: &[[f64; L]; 3]) -> [f64; L] {
        debug_assert!(self.exact);
        let mut best = [f64::INFINITY; L];
        let mut inside = [self.nn > 0.0; L];
        for i in 0..3 {
            let (v, e, ne) = (self.v[i], self.e[i], self.ne[i]);
            for k in 0..L {
                let w = [p[0][k] - v[0], p[1][k] - v[1], p[2][k] - v[2]];
                let d = dot(w, w);
                let wd = dot(w, e);
                let c = cross(w, e);
                let edge = dot(c, c) / self.ee[i];
                let on_edge = (wd > 0.0) & (wd < self.ee[i]);
                let m = if d < best[k] { d } else { best[k] };
                best[k] = if on_edge & (edge < m) { edge } else { m };
                inside[k] &= dot(w, ne) >= 0.0;
            }
        }
        let v0 = self.v[0];
        for k in 0..L {
            let q = dot(self.n, [p[0][k] - v0[0], p[1][k] - v0[1], p[2][k] - v0[2]]);
            let plane = q * q / self.nn;
            best[k] = if inside[k] & (plane < best[k]) {
                plane
            } else {
                best[k]
            };
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The local evaluation has lattice::distance2's bits, for triangles that qualify and for
    /// those that do not (which take it directly).
    #[test]
    fn local_distance_has_the_lattice_bits() {
        let mut s = 0x9e3779b97f4a7c15u64;
        let mut rnd = |m: i64| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s % (2 * m as u64 + 1)) as i64 - m
        };
        let at = [3u32, 5, 7];
        let base = at.map(|c| i64::from(c * BRICK) * FIXED_ONE);
        let (mut exact, mut not) = (0, 0);
        for case in 0..4000 {
            // Small, medium, degenerate and huge triangles about the brick.
            let m = [40, 700, 1500, 1 << 20][case % 4];
            let c = [0, 1, 2].map(|a| base[a] + 1000 + rnd(1500));
            let mut tri = [[0i32; 3]; 3];
            for p in tri.iter_mut() {
                *p = [0, 1, 2].map(|a| (c[a] + rnd(m)) as i32);
            }
            if case % 17 == 0 {
                tri[2] = tri[0]; // a segment
            }
            let l = Local::new(&tri, &Plane::new(&tri), at);
            if l.exact {
                exact += 1;
            } else {
                not += 1;
            }
            for i in 0..512 {
                let o = [i / 64, i / 8 % 8, i % 8];
                let p = [0, 1, 2].map(|a| (o[a] * FIXED_ONE) as f64);
                let g = [0, 1, 2].map(|a| o[a] * FIXED_ONE + l.origin[a]);
                let want = lattice::distance2(g, &tri);
                assert_eq!(l.distance2(p).to_bits(), want.to_bits(), "{tri:?} at {g:?}");
            }
            // Eight lanes at a time, on scattered centres, have the same bits too.
            if l.exact {
                for first in (0..512).step_by(8) {
                    let at = |k: i64| (first + k * 67) % 512;
                    let p: [[f64; 8]; 3] = std::array::from_fn(|a| {
                        std::array::from_fn(|k| {
                            let i = at(k as i64);
                            ([i / 64, i / 8 % 8, i % 8][a] * FIXED_ONE) as f64
                        })
                    });
                    let got = l.distance2_lanes(&p);
                    for (k, d) in got.iter().enumerate() {
                        let g = [0, 1, 2].map(|a| p[a][k] as i64 + l.origin[a]);
                        let want = lattice::distance2(g, &tri);
                        assert_eq!(d.to_bits(), want.to_bits(), "{tri:?} lane {k}");
                    }
                }
            }
        }
        assert!(exact > 2000 && not > 500, "{exact} exact, {not} not");
    }
}
