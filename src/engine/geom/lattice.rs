//! Exact distance from a lattice point to a snapped triangle: the one closest-point routine of
//! the distance methods (`distance`'s threshold test, `sdf`'s band and values). Points and
//! vertices are on the 1/256-voxel lattice of [`crate::engine::snap`] (|coordinate| ≤
//! [`MAX_FIXED`](crate::engine::snap::MAX_FIXED)), distances in lattice units.
//!
//! The distance from p to triangle T is the least of: the distance to each vertex; to each edge
//! whose interior holds p's foot (0 < w·d < |d|²); and to the plane when T has an area and p's
//! projection lies in the closed triangle. Every one of these is the distance to a point of T,
//! and the least of them is the distance to T, so no Voronoi region has to be named. Degenerate
//! triangles (zero area: a segment or a point) are their edges and vertices.
//!
//! [`compare`] decides `dist(p, T)` against a threshold with integers only (squared values; the
//! plane's case in 256-bit products), so a threshold test is exact and the same on every engine;
//! [`distance2`] gives the squared value in `f64` from the same exact integers with a few roundings
//! (relative error below 2⁻⁵⁰).
//!
//! Magnitudes, with coordinates ≤ 2²⁹ (differences ≤ 2³⁰): edge and cross products ≤ 2⁶¹ (i64);
//! n·w ≤ 3·2⁹¹ and |n|², n·(e×w) ≤ 3·2¹²² (i128); (n·w)² and t²·|n|² need 256 bits.

use std::cmp::Ordering;

type V = [i64; 3];

#[inline]
fn sub(a: V, b: V) -> V {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
#[inline]
fn dot(a: V, b: V) -> i128 {
    a[0] as i128 * b[0] as i128 + a[1] as i128 * b[1] as i128 + a[2] as i128 * b[2] as i128
}
#[inline]
fn cross(a: V, b: V) -> V {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// a·b as (high, low) halves of the 256-bit product.
#[inline]
fn mul_wide(a: u128, b: u128) -> (u128, u128) {
    const M: u128 = u64::MAX as u128;
    let (a0, a1, b0, b1) = (a & M, a >> 64, b & M, b >> 64);
    let (p00, p01, p10, p11) = (a0 * b0, a0 * b1, a1 * b0, a1 * b1);
    let mid = (p00 >> 64) + (p01 & M) + (p10 & M);
    let lo = (p00 & M) | (mid << 64);
    let hi = p11 + (p01 >> 64) + (p10 >> 64) + (mid >> 64);
    (hi, lo)
}

/// The triangle's vertices as lattice points.
#[inline]
pub fn vertices(t: &[[i32; 3]; 3]) -> [V; 3] {
    t.map(|v| v.map(i64::from))
}

/// `dist(p, T)` against `t` (lattice units, 0 ≤ t ≤ 2³²): `Less`, `Equal` or `Greater`, exactly.
pub fn compare(p: V, tri: &[[i32; 3]; 3], t: i64) -> Ordering {
    debug_assert!((0..=1 << 32).contains(&t));
    let v = vertices(tri);
    let t2 = (t as i128 * t as i128) as u128;
    let mut best = Ordering::Greater;
    for i in 0..3 {
        let (a, b) = (v[i], v[(i + 1) % 3]);
        let w = sub(p, a);
        best = best.min((dot(w, w) as u128).cmp(&t2));
        let d = sub(b, a);
        let (wd, dd) = (dot(w, d), dot(d, d));
        if wd > 0 && wd < dd {
            // |w × d|² / |d|² against t².
            let c = cross(w, d);
            best = best.min((dot(c, c) as u128).cmp(&(t2 * dd as u128)));
        }
        if best == Ordering::Less {
            return best;
        }
    }
    let n = cross(sub(v[1], v[0]), sub(v[2], v[0]));
    if n != [0; 3] && projects_inside(p, &v, n) {
        let q = dot(n, sub(p, v[0])).unsigned_abs();
        best = best.min(mul_wide(q, q).cmp(&mul_wide(t2, dot(n, n) as u128)));
    }
    best
}

/// Does p's projection along `n` (the triangle's nonzero normal) lie in the closed triangle?
#[inline]
fn projects_inside(p: V, v: &[V; 3], n: V) -> bool {
    (0..3).all(|i| {
        let (a, b) = (v[i], v[(i + 1) % 3]);
        dot(n, cross(sub(b, a), sub(p, a))) >= 0
    })
}

/// `dist(p, T) ≤ t`, exactly: p's voxel is within `t` of the triangle.
#[inline]
pub fn within(p: V, tri: &[[i32; 3]; 3], t: i64) -> bool {
    compare(p, tri, t) != Ordering::Greater
}

/// `dist(p, T)²` in lattice units² (relative error below 2⁻⁵¹): vertices exactly (below 2⁵³,
/// else one rounding), edges and the plane as one division of two exact integers.
pub fn distance2(p: V, tri: &[[i32; 3]; 3]) -> f64 {
    let v = vertices(tri);
    let mut best = f64::INFINITY;
    for i in 0..3 {
        let (a, b) = (v[i], v[(i + 1) % 3]);
        let w = sub(p, a);
        best = best.min(dot(w, w) as f64);
        let d = sub(b, a);
        let (wd, dd) = (dot(w, d), dot(d, d));
        if wd > 0 && wd < dd {
            let c = cross(w, d);
            best = best.min(dot(c, c) as f64 / dd as f64);
        }
    }
    let n = cross(sub(v[1], v[0]), sub(v[2], v[0]));
    if n != [0; 3] && projects_inside(p, &v, n) {
        let q = dot(n, sub(p, v[0])) as f64;
        best = best.min(q * q / dot(n, n) as f64);
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wide_products_are_exact() {
        let m = u128::MAX;
        assert_eq!(mul_wide(m, m), (m - 1, 1));
        assert_eq!(mul_wide(1 << 100, 1 << 100), (1 << 72, 0));
        assert_eq!(mul_wide(3, 5), (0, 15));
    }

    #[test]
    fn features_decide_the_distance() {
        // Triangle in z = 0: (0,0,0), (8,0,0), (0,8,0).
        let t = [[0, 0, 0], [8, 0, 0], [0, 8, 0]];
        // Above the face: the plane.
        assert_eq!(distance2([1, 1, 5], &t), 25.0);
        assert_eq!(compare([1, 1, 5], &t, 5), Ordering::Equal);
        assert_eq!(compare([1, 1, 5], &t, 4), Ordering::Greater);
        // Beyond the hypotenuse: its edge, distance √2·… : p = (6,6,0) → foot (4,4,0).
        assert_eq!(distance2([6, 6, 0], &t), 8.0);
        assert_eq!(compare([6, 6, 0], &t, 3), Ordering::Less);
        assert_eq!(compare([6, 6, 0], &t, 2), Ordering::Greater);
        // Past a vertex.
        assert_eq!(distance2([-3, -4, 0], &t), 25.0);
        assert!(within([-3, -4, 0], &t, 5) && !within([-3, -4, 0], &t, 4));
        // Degenerate: a segment, and a point.
        let seg = [[0, 0, 0], [10, 0, 0], [5, 0, 0]];
        assert_eq!(distance2([5, 3, 4], &seg), 25.0);
        let pt = [[2, 2, 2]; 3];
        assert_eq!(distance2([2, 2, 5], &pt), 9.0);
        assert_eq!(compare([2, 2, 5], &pt, 3), Ordering::Equal);
    }

    #[test]
    fn the_largest_coordinates_do_not_overflow() {
        let m = crate::engine::snap::MAX_FIXED as i32;
        let t = [[-m, -m, -m], [m, -m, m], [-m, m, m]];
        let p = [m as i64, m as i64, -m as i64];
        let d = distance2(p, &t).sqrt();
        assert!(d.is_finite() && d > 0.0);
        let ti = d as i64;
        assert_eq!(compare(p, &t, (ti - 1).min(1 << 32)), Ordering::Greater);
    }
}
