//! Geometry of points, segments and triangles in world coordinates (`f64`), for the methods that
//! measure a mesh from a point rather than count crossings on the lattice: the winding fill
//! today ([`super::winding`]), a distance field next. Here: the vector arithmetic they share, the
//! exact solid angle and winding number of triangles, the closest point on (and squared
//! distance to) a triangle or a segment, and the bounding-volume hierarchy over triangles
//! ([`bvh`]) that makes "the triangles near q" cheap.
//!
//! [`lattice`]: the exact distance from a lattice point to a snapped triangle (integers), which
//! the distance methods share. Not here: the snap itself (`snap`) and the voxelizers' exact
//! integer rules, which they must follow bit for bit; the winding fill's expansions, bounds and eight-lane kernels (in
//! [`super::winding`], which builds them on [`bvh`]); anything about grids or volumes.
//!
//! Every function computes exactly what it did where it was written for the winding fill (same
//! operations in the same order): the fill's output depends on these bits.

pub mod bvh;
pub mod lattice;

use std::f64::consts::PI;

/// Exact signed solid angle of triangle (a, b, c) seen from q (Van Oosterom & Strackee), in
/// steradians: positive when q is on the side its normal (right hand, a→b→c) points away from.
pub fn solid_angle(t: &[[f64; 3]; 3], q: [f64; 3]) -> f64 {
    let [a, b, c] = t.map(|v| sub(v, q));
    let (la, lb, lc) = (norm(a), norm(b), norm(c));
    let det = dot(a, cross(b, c));
    let den = la * lb * lc + dot(a, b) * lc + dot(b, c) * la + dot(c, a) * lb;
    2.0 * det.atan2(den)
}

/// The exact generalised winding number of a triangle set at q: Σ solid angles / 4π.
pub fn exact_winding_number(tris: impl IntoIterator<Item = [[f64; 3]; 3]>, q: [f64; 3]) -> f64 {
    tris.into_iter().map(|t| solid_angle(&t, q)).sum::<f64>() / (4.0 * PI)
}

/// Area × unit normal (half the cross product).
#[inline]
pub(crate) fn area_normal(t: &[[f64; 3]; 3]) -> [f64; 3] {
    cross(sub(t[1], t[0]), sub(t[2], t[0])).map(|v| 0.5 * v)
}

/// Squared distance from p to the segment s.
#[inline]
pub(crate) fn dist2_to_segment(p: [f64; 3], s: &[[f64; 3]; 2]) -> f64 {
    let (d, w) = (sub(s[1], s[0]), sub(p, s[0]));
    let l2 = dot(d, d);
    let t = if l2 > 0.0 {
        (dot(w, d) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let e = sub(w, d.map(|v| v * t));
    dot(e, e)
}

/// Squared distance from p to a triangle: to its [`closest_on_triangle`].
#[inline]
pub(crate) fn dist2_to_triangle(p: [f64; 3], t: &[[f64; 3]; 3]) -> f64 {
    let q = closest_on_triangle(p, t);
    dot(sub(p, q), sub(p, q))
}

/// The point of triangle t closest to p (Ericson, *Real-Time Collision Detection*, 5.1.5): a
/// vertex, a point of an edge, or of the face, by the Voronoi region p lies in. For a triangle
/// whose area is zero or lost to rounding the point can be off the triangle, or NaN: callers that
/// meet such triangles take the least of this and the edges' distances (as the winding fill's
/// leaf kernel does).
#[inline]
pub(crate) fn closest_on_triangle(p: [f64; 3], t: &[[f64; 3]; 3]) -> [f64; 3] {
    let [a, b, c] = *t;
    let at = |u: f64, v: f64| [0, 1, 2].map(|i| a[i] + u * (b[i] - a[i]) + v * (c[i] - a[i]));
    let (ab, ac, ap) = (sub(b, a), sub(c, a), sub(p, a));
    let (d1, d2) = (dot(ab, ap), dot(ac, ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = sub(p, b);
    let (d3, d4) = (dot(ab, bp), dot(ac, bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return at(d1 / (d1 - d3), 0.0);
    }
    let cp = sub(p, c);
    let (d5, d6) = (dot(ab, cp), dot(ac, cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return at(0.0, d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return [0, 1, 2].map(|i| b[i] + w * (c[i] - b[i]));
    }
    let den = 1.0 / (va + vb + vc);
    at(vb * den, vc * den)
}

// `#[inline]` on the small helpers: their callers live in other modules (other codegen units),
// where they were inlined when they shared a file with them.
#[inline]
pub(crate) fn add3(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
#[inline]
pub(crate) fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
#[inline]
pub(crate) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
#[inline]
pub(crate) fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
#[inline]
pub(crate) fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}
