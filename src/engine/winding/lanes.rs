//! The winding fill's inner loops, eight at a time: solid angles and squared distances of up to
//! eight triangles seen from one point (a leaf of the hierarchy), and the solid angles of a list
//! of triangles seen from eight points (the voxels of a 2×2×2 block).
//!
//! The same code is compiled three times, for AVX-512, for AVX2 and for the baseline target,
//! and the widest the processor has is chosen at run time. Every path does the same IEEE
//! operations in the same order (no fused multiply-adds: Rust never contracts `a * b + c`), so
//! all three give the same bits; `atan2` is Cephes' (as Go's `math.Atan`), written without
//! branches so that it vectorizes, within a few ulps of the C library's.
//!
//! Not here: the traversals that call the kernels for a node or a leaf and keep the sums
//! ([`super::traverse`], [`super::edges`], [`super::trees`]), or the scalar geometry they must
//! agree with ([`crate::engine::geom`]; the tests compare). The small vector helpers at the end
//! are this file's own, marked `#[inline(always)]`, so that they are inlined into every
//! instruction set's copy of a kernel.

// Loops run over lane indices on purpose: that is the shape that vectorizes.
#![allow(clippy::needless_range_loop)]

use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI};

/// `pub fn NAME(args) -> R` that runs `BODY` (a function's path, generic arguments and all) compiled for AVX-512 (as `AVX512`), for AVX2 (as
/// `AVX2`) or for the baseline target, the widest the processor has.
macro_rules! dispatch {
    ($(#[$m:meta])* $vis:vis fn $name:ident($($arg:ident: $ty:ty),* $(,)?) -> $ret:ty
        = $body:path, $avx512:ident, $avx2:ident;) => {
        $(#[$m])*
        $vis fn $name($($arg: $ty),*) -> $ret {
            #[cfg(target_arch = "x86_64")]
            {
                match $crate::engine::winding::lanes::simd() {
                    // SAFETY: the processor has AVX-512F (`simd` checked).
                    $crate::engine::winding::lanes::Simd::Avx512 => return unsafe { $avx512($($arg),*) },
                    // SAFETY: the processor has AVX2 (`simd` checked).
                    $crate::engine::winding::lanes::Simd::Avx2 => return unsafe { $avx2($($arg),*) },
                    $crate::engine::winding::lanes::Simd::Baseline => {}
                }
            }
            $body($($arg),*)
        }

        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx512f")]
        $(#[$m])*
        $vis fn $avx512($($arg: $ty),*) -> $ret {
            $body($($arg),*)
        }

        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx2")]
        $(#[$m])*
        $vis fn $avx2($($arg: $ty),*) -> $ret {
            $body($($arg),*)
        }
    };
}

/// The instruction sets the kernels are compiled for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Simd {
    Baseline,
    Avx2,
    Avx512,
}

/// The widest instruction set this processor has, or narrower where `VOXD_SIMD` (`baseline`,
/// `avx2`) asks for it: every path gives the same bits, so this only changes the speed (for
/// benchmarks of the narrower paths on a wide machine). Decided once.
pub fn simd() -> Simd {
    static SIMD: std::sync::OnceLock<Simd> = std::sync::OnceLock::new();
    *SIMD.get_or_init(|| {
        #[allow(unused_mut)]
        let mut has = Simd::Baseline;
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx512f") {
                has = Simd::Avx512;
            } else if std::arch::is_x86_feature_detected!("avx2") {
                has = Simd::Avx2;
            }
        }
        let cap = match std::env::var("VOXD_SIMD").as_deref() {
            Ok("baseline") => Simd::Baseline,
            Ok("avx2") => Simd::Avx2,
            _ => Simd::Avx512,
        };
        has.min(cap)
    })
}

/// For the winding fill's traversals, which run these kernels inlined: the bookkeeping between
/// them is compiled for the same wide registers.
pub(crate) use dispatch;

/// Lanes per call.
pub const LANES: usize = 8;

/// Up to [`LANES`] triangles, coordinate by coordinate, with what the distance needs. Lanes past
/// the leaf's triangles repeat its last one (their results are not read).
#[derive(Clone, Debug)]
pub struct Leaf {
    /// Vertex k's coordinate a is `v[3 * k + a]`.
    v: [[f64; LANES]; 9],
    /// The edges' reciprocal squared lengths (ab, bc, ca), 0 for a zero-length edge.
    inv_len2: [[f64; LANES]; 3],
    /// The (unnormalised) normal (b − a) × (c − a) and the reciprocal of its squared length.
    n: [[f64; LANES]; 3],
    inv_n2: [f64; LANES],
    /// The triangles' areas (as the hierarchy holds them), for the bounds of [`leaf_spread`]
    /// and [`leaf_taylor`].
    area: [f64; LANES],
}

impl Leaf {
    /// The leaf of `tris` (1 to [`LANES`] of them), of areas `areas`.
    pub fn new(tris: &[[[f64; 3]; 3]], areas: &[f64]) -> Leaf {
        assert!(
            !tris.is_empty() && tris.len() <= LANES && areas.len() == tris.len(),
            "a leaf holds 1 to 8 triangles, each with its area"
        );
        let mut l = Leaf {
            v: [[0.0; LANES]; 9],
            inv_len2: [[0.0; LANES]; 3],
            n: [[0.0; LANES]; 3],
            inv_n2: [0.0; LANES],
            area: [0.0; LANES],
        };
        for i in 0..LANES {
            let t = tris[i.min(tris.len() - 1)];
            l.area[i] = areas[i.min(tris.len() - 1)];
            for (k, p) in t.iter().enumerate() {
                for a in 0..3 {
                    l.v[3 * k + a][i] = p[a];
                }
            }
            for e in 0..3 {
                let d = sub(t[(e + 1) % 3], t[e]);
                let len2 = dot(d, d);
                l.inv_len2[e][i] = if len2 > 0.0 { 1.0 / len2 } else { 0.0 };
            }
            let n = cross(sub(t[1], t[0]), sub(t[2], t[0]));
            for a in 0..3 {
                l.n[a][i] = n[a];
            }
            let n2 = dot(n, n);
            l.inv_n2[i] = if n2 > 0.0 { 1.0 / n2 } else { 0.0 };
        }
        l
    }
}

dispatch! {
    /// For each lane's triangle: its solid angle seen from q (as
    /// [`crate::engine::geom::solid_angle`]) and q's squared distance to it (of a degenerate
    /// triangle: to its edges).
    pub fn leaf(
        l: &Leaf,
        q: [f64; 3],
    ) -> ([f64; LANES], [f64; LANES])
        = leaf_body, leaf_avx512, leaf_avx2;
}

dispatch! {
    /// [`leaf`] with `spread`'s bounds over the ball (q, rq): for each lane's triangle of area
    /// A, g = its distance − rq, by_distance = A/g², magnitude = min(by_distance, 2π) and
    /// variation = 2 rq · by_distance/g.
    pub fn leaf_spread(
        l: &Leaf,
        q: [f64; 3],
        rq: f64,
    ) -> LeafSpread
        = leaf_spread_body, leaf_spread_avx512, leaf_spread_avx2;
}

/// See [`leaf_spread`].
#[derive(Clone, Copy, Debug)]
pub struct LeafSpread {
    pub angle: [f64; LANES],
    pub g: [f64; LANES],
    pub magnitude: [f64; LANES],
    pub variation: [f64; LANES],
}

dispatch! {
    /// [`leaf`] with `taylor`'s bounds over the ball (q, rq): for each lane's triangle of area
    /// A, its distance and A/g⁴, g = the distance − rq.
    pub fn leaf_taylor(
        l: &Leaf,
        q: [f64; 3],
        rq: f64,
    ) -> LeafTaylor
        = leaf_taylor_body, leaf_taylor_avx512, leaf_taylor_avx2;
}

/// See [`leaf_taylor`].
#[derive(Clone, Copy, Debug)]
pub struct LeafTaylor {
    pub angle: [f64; LANES],
    pub dist: [f64; LANES],
    pub hessian: [f64; LANES],
}

dispatch! {
    /// For each of eight points q (`q[a][lane]`): Σ over `tris` of their solid angles seen from it,
    /// and whether some triangle's plane passes within `2 · gap` of it (by twice its area, `det`
    /// against `2 · gap · twice_area`; NaN counts as near). Where it does, the caller decides
    /// whether that is a tie.
    pub fn point_sums(
        tris: &[[[f64; 3]; 3]],
        near: &[(u32, f64)],
        q: &[[f64; LANES]; 3],
        gap: f64,
    ) -> ([f64; LANES], [bool; LANES])
        = point_sums_body, point_sums_avx512, point_sums_avx2;
}

/// A hierarchy node's expansion folded for evaluation: with r the offset from the query to the
/// node's centre and d = |r|, 4π × its winding number is about
/// (n1·r + tr)/d³ − (rᵀ M r + w·r)/d⁵ + Σ_i r_i (rᵀ C_i r)/d⁷ (see `trees::folded`).
#[derive(Clone, Copy, Debug, Default)]
pub struct Far {
    pub n1: [f64; 3],
    /// The first moment's trace.
    pub tr: f64,
    /// 3 × the first moment's symmetric part, xx yy zz and the doubled xy xz yz.
    pub m: [f64; 6],
    /// 1.5 × (2 Σ_i C_i,ik + Σ_j C_k,jj), by k.
    pub w: [f64; 3],
    /// 7.5 × the second moments, xx yy zz and the doubled xy xz yz.
    pub c: [[f64; 6]; 3],
}

/// One node's expansion at offset r (|r|² = d2).
#[inline(always)]
pub fn far_one(f: &Far, r: [f64; 3], d2: f64) -> f64 {
    // Order 0 (dipoles at the centre): n1·r/d³.
    // Order 1: Σ M_ij ∂_j K_i with ∂_j K_i = δ_ij/d³ − 3 r_i r_j/d⁵.
    // Order 2: ½ Σ C_ijk ∂_j ∂_k K_i with
    // ∂_j ∂_k K_i = −3 (δ_ij r_k + δ_ik r_j + δ_jk r_i)/d⁵ + 15 r_i r_j r_k/d⁷.
    // Collected by power of d (the factors folded into `Far`).
    let id2 = 1.0 / d2;
    let i3 = d2.sqrt() * id2 * id2;
    let (i5, i7) = (i3 * id2, i3 * id2 * id2);
    let [x, y, z] = r;
    let rr = [x * x, y * y, z * z, x * y, x * z, y * z];
    let rrr = x * form(&f.c[0], &rr) + y * form(&f.c[1], &rr) + z * form(&f.c[2], &rr);
    (dot(f.n1, r) + f.tr) * i3 - (form(&f.m, &rr) + dot(f.w, r)) * i5 + rrr * i7
}

#[inline(always)]
fn form(c: &[f64; 6], rr: &[f64; 6]) -> f64 {
    c[0] * rr[0] + c[1] * rr[1] + c[2] * rr[2] + c[3] * rr[3] + c[4] * rr[4] + c[5] * rr[5]
}

/// See [`node_body`].
#[derive(Clone, Copy, Debug)]
pub struct NodeLanes {
    pub d2: [f64; LANES],
    pub far: [f64; LANES],
    pub g: [f64; LANES],
    pub magnitude: [f64; LANES],
    pub extra: [f64; LANES],
}

/// One node (centre, radius, area) seen from eight points q, over the balls of radius `rq`
/// about them: d² = |centre − q|², the node's expansion at q (as [`far_one`]; 0 unless
/// d² > `reach2` for some point),
/// g = d − radius − rq, magnitude = area/g², and extra: for `spread` (`SPREAD`) the variation
/// 2 rq · magnitude/g, for `taylor` area/g⁴ (by 1/g² as `taylor` takes them). Inlined into the
/// winding fill's traversals, which are compiled per instruction set (`dispatch!`).
#[inline(always)]
pub(super) fn node_body<const SPREAD: bool>(
    f: &Far,
    centre: [f64; 3],
    radius: f64,
    area: f64,
    rq: f64,
    reach2: f64,
    q: &[[f64; LANES]; 3],
) -> NodeLanes {
    let mut out = NodeLanes {
        d2: [0.0; LANES],
        far: [0.0; LANES],
        g: [0.0; LANES],
        magnitude: [0.0; LANES],
        extra: [0.0; LANES],
    };
    let r = |i: usize| {
        [
            centre[0] - q[0][i],
            centre[1] - q[1][i],
            centre[2] - q[2][i],
        ]
    };
    for i in 0..LANES {
        out.d2[i] = dot(r(i), r(i));
    }
    // The expansion only where some point is beyond reach (the only lanes that read it); a node
    // that every point opens (about half of those visited) skips it.
    if out.d2.iter().any(|&d2| d2 > reach2) {
        for i in 0..LANES {
            out.far[i] = far_one(f, r(i), out.d2[i]);
        }
    }
    for i in 0..LANES {
        let d2 = out.d2[i];
        let g = d2.sqrt() - radius - rq;
        out.g[i] = g;
        if SPREAD {
            let ig = 1.0 / g;
            let magnitude = area * ig * ig;
            out.magnitude[i] = magnitude;
            out.extra[i] = rq * 2.0 * magnitude * ig;
        } else {
            let ig2 = 1.0 / (g * g);
            let magnitude = area * ig2;
            out.magnitude[i] = magnitude;
            out.extra[i] = magnitude * ig2;
        }
    }
    out
}

/// See [`edge_node_body`].
#[derive(Clone, Copy, Debug)]
pub struct EdgeLanes {
    pub d: [f64; LANES],
    pub field: [[f64; LANES]; 3],
}

/// The segments `segs` of a leaf of the boundary chain's hierarchy, seen from eight points q:
/// `acc` plus their Biot–Savart fields ∫ dl × (x − q)/|x − q|³ (as `edges::segment_field`,
/// added one by one in order), and whether q lies on one of them (where the field is
/// infinite; NaN counts as on), lane by lane.
#[inline(always)]
pub(super) fn edge_leaf_body(
    segs: &[[[f64; 3]; 2]],
    q: &[[f64; LANES]; 3],
    mut acc: [[f64; LANES]; 3],
) -> ([[f64; LANES]; 3], [bool; LANES]) {
    let mut on = [false; LANES];
    for [s, t] in segs {
        for i in 0..LANES {
            let r1 = [s[0] - q[0][i], s[1] - q[1][i], s[2] - q[2][i]];
            let r2 = [t[0] - q[0][i], t[1] - q[1][i], t[2] - q[2][i]];
            let (l1, l2) = (norm(r1), norm(r2));
            let den = l1 * l2 * (l1 * l2 + dot(r1, r2));
            // Not positive, or NaN: on.
            on[i] |= (den <= 0.0) | den.is_nan();
            let f = (l1 + l2) / den;
            let c = cross(r2, r1);
            for a in 0..3 {
                acc[a][i] += c[a] * f;
            }
        }
    }
    (acc, on)
}

/// One cluster of the boundary chain seen from eight points q: the distances from q to its
/// centre m, and the first-order expansion of its Biot–Savart field at each
/// (`net × K + anti/d³ − 3 (M r) × r/d⁵`, r = m − q, K = r/d³; see `edges::EdgeTree::field`).
#[inline(always)]
pub(super) fn edge_node_body(
    centre: [f64; 3],
    net: [f64; 3],
    moment: &[[f64; 3]; 3],
    anti: [f64; 3],
    q: &[[f64; LANES]; 3],
) -> EdgeLanes {
    let mut out = EdgeLanes {
        d: [0.0; LANES],
        field: [[0.0; LANES]; 3],
    };
    for i in 0..LANES {
        let r = [
            centre[0] - q[0][i],
            centre[1] - q[1][i],
            centre[2] - q[2][i],
        ];
        let d = norm(r);
        let id2 = 1.0 / (d * d);
        let i3 = d * id2 * id2;
        let i5 = i3 * id2;
        let k = [r[0] * i3, r[1] * i3, r[2] * i3];
        let mr = [dot(moment[0], r), dot(moment[1], r), dot(moment[2], r)];
        let turn = cross(mr, r);
        let nk = cross(net, k);
        out.d[i] = d;
        for a in 0..3 {
            out.field[a][i] = nk[a] + (anti[a] * i3 - 3.0 * turn[a] * i5);
        }
    }
    out
}

#[inline(always)]
pub(super) fn leaf_body(l: &Leaf, q: [f64; 3]) -> ([f64; LANES], [f64; LANES]) {
    let mut angle = [0.0; LANES];
    let mut dist2 = [0.0; LANES];
    for i in 0..LANES {
        (angle[i], dist2[i]) = leaf_lane(l, q, i);
    }
    (angle, dist2)
}

#[inline(always)]
pub(super) fn leaf_spread_body(l: &Leaf, q: [f64; 3], rq: f64) -> LeafSpread {
    let mut out = LeafSpread {
        angle: [0.0; LANES],
        g: [0.0; LANES],
        magnitude: [0.0; LANES],
        variation: [0.0; LANES],
    };
    for i in 0..LANES {
        let (angle, dist2) = leaf_lane(l, q, i);
        let g = dist2.sqrt() - rq;
        let ig = 1.0 / g;
        let by_distance = l.area[i] * ig * ig;
        out.angle[i] = angle;
        out.g[i] = g;
        out.magnitude[i] = min(by_distance, 2.0 * PI);
        out.variation[i] = rq * 2.0 * by_distance * ig;
    }
    out
}

#[inline(always)]
pub(super) fn leaf_taylor_body(l: &Leaf, q: [f64; 3], rq: f64) -> LeafTaylor {
    let mut out = LeafTaylor {
        angle: [0.0; LANES],
        dist: [0.0; LANES],
        hessian: [0.0; LANES],
    };
    for i in 0..LANES {
        let (angle, dist2) = leaf_lane(l, q, i);
        let dist = dist2.sqrt();
        let g = dist - rq;
        out.angle[i] = angle;
        out.dist[i] = dist;
        out.hessian[i] = l.area[i] / (g * g * g * g);
    }
    out
}

/// Lane i of [`leaf`]: written with plain locals (no closures), so that the loops that call it
/// vectorize.
#[inline(always)]
fn leaf_lane(l: &Leaf, q: [f64; 3], i: usize) -> (f64, f64) {
    let a = [l.v[0][i] - q[0], l.v[1][i] - q[1], l.v[2][i] - q[2]];
    let b = [l.v[3][i] - q[0], l.v[4][i] - q[1], l.v[5][i] - q[2]];
    let c = [l.v[6][i] - q[0], l.v[7][i] - q[1], l.v[8][i] - q[2]];
    let angle = solid_angle_of(a, b, c);
    // Off the triangle's prism: the nearest of its edges; on it: the plane.
    let ab = edge_dist2(a, b, l.inv_len2[0][i]);
    let bc = edge_dist2(b, c, l.inv_len2[1][i]);
    let ca = edge_dist2(c, a, l.inv_len2[2][i]);
    let best = min(min(ab, bc), ca);
    let n = [l.n[0][i], l.n[1][i], l.n[2][i]];
    // q inside the prism over the triangle: on the inner side of each edge's plane along n.
    let inside = (dot(cross(sub(b, a), a), n) <= 0.0)
        & (dot(cross(sub(c, b), b), n) <= 0.0)
        & (dot(cross(sub(a, c), c), n) <= 0.0);
    let h = dot(a, n);
    let plane = h * h * l.inv_n2[i];
    let dist2 = if inside & (l.inv_n2[i] > 0.0) & (plane < best) {
        plane
    } else {
        best
    };
    (angle, dist2)
}

/// The squared distance from the origin to the segment s–t (`inv_len2` = 1/|t − s|², or 0).
#[inline(always)]
fn edge_dist2(s: [f64; 3], t: [f64; 3], inv_len2: f64) -> f64 {
    let d = sub(t, s);
    let u = -dot(s, d) * inv_len2;
    let u = if u < 0.0 { 0.0 } else { u };
    let u = if u > 1.0 { 1.0 } else { u };
    let r = [s[0] + u * d[0], s[1] + u * d[1], s[2] + u * d[2]];
    dot(r, r)
}

#[inline(always)]
fn min(a: f64, b: f64) -> f64 {
    if a < b { a } else { b }
}

#[inline(always)]
pub(super) fn point_sums_body(
    tris: &[[[f64; 3]; 3]],
    near: &[(u32, f64)],
    q: &[[f64; LANES]; 3],
    gap: f64,
) -> ([f64; LANES], [bool; LANES]) {
    let mut sum = [0.0; LANES];
    let mut close = [false; LANES];
    for &(t, twice_area) in near {
        let [ta, tb, tc] = tris[t as usize];
        let bound = 2.0 * gap * twice_area;
        for i in 0..LANES {
            let p = [q[0][i], q[1][i], q[2][i]];
            let (det, den) = det_den(sub(ta, p), sub(tb, p), sub(tc, p));
            // NaN: close.
            close[i] |= det.abs() <= bound || det.is_nan();
            sum[i] += 2.0 * atan2(det, den);
        }
    }
    (sum, close)
}

/// Van Oosterom & Strackee's solid angle of the triangle (a, b, c) seen from the origin.
#[inline(always)]
fn solid_angle_of(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> f64 {
    let (det, den) = det_den(a, b, c);
    2.0 * atan2(det, den)
}

/// The solid angle of (a, b, c) seen from the origin is 2 atan2(det, den): det = a·(b × c)
/// (twice the area times the signed distance to the plane), den as Van Oosterom & Strackee.
#[inline(always)]
pub fn det_den(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> (f64, f64) {
    let det = dot(a, cross(b, c));
    let (la, lb, lc) = (norm(a), norm(b), norm(c));
    let den = la * lb * lc + dot(a, b) * lc + dot(b, c) * la + dot(c, a) * lb;
    (det, den)
}

/// atan(x) for 0 ≤ x ≤ 0.66 (Cephes' rational approximation, relative error ~1e-16).
#[inline(always)]
fn atan_small(x: f64) -> f64 {
    const P: [f64; 5] = [
        -8.750_608_600_031_904e-1,
        -1.615_753_718_733_365e1,
        -7.500_855_792_314_705e1,
        -1.228_866_684_490_136_2e2,
        -6.485_021_904_942_025e1,
    ];
    const Q: [f64; 5] = [
        2.485_846_490_142_306_3e1,
        1.650_270_098_316_988_6e2,
        4.328_810_604_912_903e2,
        4.853_903_996_359_137e2,
        1.945_506_571_482_614e2,
    ];
    let z = x * x;
    let p = (((P[0] * z + P[1]) * z + P[2]) * z + P[3]) * z + P[4];
    let r = ((((z + Q[0]) * z + Q[1]) * z + Q[2]) * z + Q[3]) * z + Q[4];
    x * (z * p / r) + x
}

/// atan2(y, x) without branches (each `if` a select), as Cephes reduces it: |y/x| above
/// tan(3π/8) through π/2 − atan(x/y), above 0.66 through π/4 + atan((y − x)/(y + x)).
#[inline(always)]
pub fn atan2(y: f64, x: f64) -> f64 {
    let (ay, ax) = (y.abs(), x.abs());
    let big = ay > 2.414_213_562_373_095 * ax;
    let mid = ay > 0.66 * ax;
    let num = if big {
        -ax
    } else if mid {
        ay - ax
    } else {
        ay
    };
    let den = if big {
        ay
    } else if mid {
        ay + ax
    } else {
        ax
    };
    let base = if big {
        FRAC_PI_2
    } else if mid {
        FRAC_PI_4
    } else {
        0.0
    };
    let r = base + atan_small(num / den);
    // 0/0 (y = x = 0) is NaN here; the C library gives 0 or ±π. Either way the point lies on
    // the triangle's plane, which every caller treats as a tie beforehand.
    let r = if x < 0.0 { PI - r } else { r };
    if y.is_sign_negative() { -r } else { r }
}

#[inline(always)]
fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

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
fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}
