//! The boundary chain's hierarchy ([`EdgeTree`]): a tree over the chain's segments that bounds
//! the Biot–Savart field of the chain over a ball ([`EdgeTree::bound`], the bound on how fast
//! the winding number of any surface the chain bounds can vary), and evaluates the field itself
//! at a point with an error bound ([`EdgeTree::field`]; eight points at once, [`field_lanes`]),
//! which is the gradient of the caps' solid angle in the Taylor models. Also the field of one
//! segment and the gradient of one triangle's solid angle, which the models and tests use.
//!
//! Not here: which segments form the chain ([`super::caps::chain_boundary`]), or the triangle
//! hierarchy ([`super::trees`]).

use super::FIELD_OPEN;
use super::lanes::{self, LANES};
use super::traverse::lanes_of;
use crate::engine::geom::bvh::LEAF;
use crate::engine::geom::{add3, cross, dist2_to_segment, dot, norm, sub};

/// A hierarchy over segments (a boundary chain's edges, each as often as its multiplicity) that
/// bounds ∮ |dl| / r², the Biot–Savart bound on the gradient of the solid angle of any surface
/// the chain bounds: off the surface, ∇Ω(q) = ∮ dl × (x − q) / |x − q|³ over its boundary (the
/// edges inside cancel), so |∇Ω| ≤ ∮ |dl| / r². For the mesh and for its caps, whose boundaries
/// are the same chain, this bounds the gradient of their winding numbers wherever they are
/// smooth, however large or curved the surfaces.
pub(super) struct EdgeTree {
    nodes: Vec<EdgeNode>,
    segs: Vec<[[f64; 3]; 2]>,
}

struct EdgeNode {
    centre: [f64; 3],
    radius: f64,
    length: f64,
    /// Σ (end − start): nothing for closed cycles.
    net: [f64; 3],
    /// Σ ∫ dl ⊗ (x − centre) = Σ (end − start) ⊗ (midpoint − centre).
    moment: [[f64; 3]; 3],
    /// Its antisymmetric part as a vector: (M₁₂ − M₂₁, M₂₀ − M₀₂, M₀₁ − M₁₀).
    anti: [f64; 3],
    /// As [`super::trees::Node`]: a leaf's range, or `first` the left child and `right` the right one.
    first: u32,
    count: u32,
    right: u32,
}

impl EdgeTree {
    pub(super) fn new(segs: Vec<[[f64; 3]; 2]>) -> EdgeTree {
        let mut t = EdgeTree {
            nodes: Vec::with_capacity(2 * segs.len() / LEAF + 2),
            segs,
        };
        if !t.segs.is_empty() {
            let mut segs = std::mem::take(&mut t.segs);
            t.build(&mut segs, 0);
            t.segs = segs;
        }
        t
    }

    fn build(&mut self, segs: &mut [[[f64; 3]; 2]], offset: u32) -> u32 {
        let index = self.nodes.len() as u32;
        let mid = |s: &[[f64; 3]; 2]| [0, 1, 2].map(|a| 0.5 * (s[0][a] + s[1][a]));
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for s in segs.iter() {
            for p in s {
                for a in 0..3 {
                    lo[a] = lo[a].min(p[a]);
                    hi[a] = hi[a].max(p[a]);
                }
            }
        }
        let centre = [0, 1, 2].map(|a| 0.5 * (lo[a] + hi[a]));
        let radius = segs
            .iter()
            .flat_map(|s| s.iter())
            .map(|&p| norm(sub(p, centre)))
            .fold(0.0, f64::max);
        let length = segs.iter().map(|s| norm(sub(s[1], s[0]))).sum();
        let mut net = [0.0; 3];
        for s in segs.iter() {
            net = add3(net, sub(s[1], s[0]));
        }
        let mut moment = [[0.0; 3]; 3];
        for s in segs.iter() {
            let (d, m) = (sub(s[1], s[0]), sub(mid(s), centre));
            for (i, row) in moment.iter_mut().enumerate() {
                for (j, v) in row.iter_mut().enumerate() {
                    *v += d[i] * m[j];
                }
            }
        }
        self.nodes.push(EdgeNode {
            centre,
            radius,
            length,
            net,
            moment,
            anti: [
                moment[1][2] - moment[2][1],
                moment[2][0] - moment[0][2],
                moment[0][1] - moment[1][0],
            ],
            first: offset,
            count: segs.len() as u32,
            right: 0,
        });
        if segs.len() > LEAF {
            let axis = (0..3)
                .max_by(|&a, &b| (hi[a] - lo[a]).total_cmp(&(hi[b] - lo[b])))
                .unwrap_or(0);
            let m = segs.len() / 2;
            segs.select_nth_unstable_by(m, |a, b| mid(a)[axis].total_cmp(&mid(b)[axis]));
            let (left, right) = segs.split_at_mut(m);
            let l = self.build(left, offset);
            let r = self.build(right, offset + m as u32);
            let n = &mut self.nodes[index as usize];
            (n.first, n.count, n.right) = (l, 0, r);
        }
        index
    }

    /// A bound on |∮ dl × (x − p)/|x − p|³| over the segments for every p in the ball (q, rq),
    /// or infinity when a segment meets the ball or the bound reaches `limit`. Clusters far away
    /// enter by an expansion bound (or length/g²); the segments of nearer leaves by
    /// their exact field at q, summed as vectors (opposite edges of a crack cancel), plus
    /// rq × the bound 2·length/g³ on its gradient.
    pub(super) fn bound(&self, q: [f64; 3], rq: f64, limit: f64) -> f64 {
        if self.nodes.is_empty() {
            return 0.0;
        }
        let (mut far, mut field, mut slope) = (0.0, [0.0; 3], 0.0);
        let mut stack = [0u32; 64];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let n = &self.nodes[stack[top] as usize];
            let d = norm(sub(n.centre, q));
            let g = d - n.radius - rq;
            if g > n.radius + rq {
                // Each point x of the node's segments is within its radius of the centre m, and
                // K(x) = (x − p)/|x − p|³ has a Jacobian of norm ≤ 2/|x − p|³: so
                // |Σ ∫ dl × K| ≤ |net|·|K(m)| + 2·radius·length/g³; or length/g² outright.
                let near = d - rq;
                let expanded =
                    norm(n.net) / (near * near) + 2.0 * n.radius * n.length / (g * g * g);
                far += (n.length / (g * g)).min(expanded);
            } else if n.count > 0 {
                let (s, e) = (n.first as usize, (n.first + n.count) as usize);
                for seg in &self.segs[s..e] {
                    let g = dist2_to_segment(q, seg).sqrt() - rq;
                    if g.is_nan() || g <= 0.0 {
                        return f64::INFINITY;
                    }
                    field = add3(field, segment_field(seg, q));
                    slope += 2.0 * norm(sub(seg[1], seg[0])) / (g * g * g);
                }
            } else {
                stack[top] = n.first;
                stack[top + 1] = n.right;
                top += 2;
            }
            if far + rq * slope >= limit {
                return f64::INFINITY;
            }
        }
        let total = far + norm(field) + rq * slope;
        if total >= limit { f64::INFINITY } else { total }
    }
}

impl EdgeTree {
    /// The Biot–Savart field Σ ∫ dl × K(x) (K(x) = (x − q)/|x − q|³) of the segments at q, and
    /// a bound on the error of that value, or `None` when q lies on a segment. Leaves near q are
    /// summed exactly; a cluster whose segments all lie farther than `FIELD_OPEN` × its radius ρ
    /// from q enters by the first-order expansion of K about its centre m:
    /// Σ ∫ dl × (K(m) + J(m)(x − m)) = net × K(m) + Σ_{b,c} ε_·bc (M Jᵀ)_bc, with M its
    /// moment. The remainder: K = −∇φ, φ = 1/|x − q|, and for unit h, w,
    /// D³φ[h, h, w] = (−15a²b + 6ac + 3b)/|x − q|⁴ (a = h·r̂, b = w·r̂, c = h·w); writing h, w along
    /// and across r̂, |−15a²b + 6ac + 3b| ≤ |b|·|3 − 9a²| + 6|a|√(1 − a²)√(1 − b²)
    /// ≤ √(45a⁴ − 18a² + 9) ≤ 6, so |K(x) − K(m) − J(m)(x − m)| ≤ 3ρ²/g⁴ (g the distance from q
    /// to the cluster's ball), and the cluster's error is at most 3ρ²·length/g⁴.
    pub(super) fn field(&self, q: [f64; 3]) -> Option<([f64; 3], f64)> {
        let (mut field, mut error) = ([0.0; 3], 0.0);
        if self.nodes.is_empty() {
            return Some((field, error));
        }
        let mut stack = [0u32; 64];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let n = &self.nodes[stack[top] as usize];
            let r = sub(n.centre, q);
            let d = norm(r);
            let g = d - n.radius;
            if g > FIELD_OPEN * n.radius {
                // r = m − q; K(m) = r/d³, J_cj = δ_cj/d³ − 3 r_c r_j/d⁵, so
                // (M Jᵀ)_bc = M_bc/d³ − 3 (M r)_b r_c/d⁵, whose ε-contraction is
                // anti/d³ − 3 (M r) × r/d⁵ (anti: the moment's antisymmetric part).
                let id2 = 1.0 / (d * d);
                let i3 = d * id2 * id2;
                let i5 = i3 * id2;
                let k = r.map(|v| v * i3);
                let mr = n.moment.map(|row| dot(row, r));
                let turn = cross(mr, r);
                let first = [0, 1, 2].map(|a| n.anti[a] * i3 - 3.0 * turn[a] * i5);
                field = add3(field, add3(cross(n.net, k), first));
                error += 3.0 * n.radius * n.radius * n.length / (g * g * g * g);
            } else if n.count > 0 {
                let (s, e) = (n.first as usize, (n.first + n.count) as usize);
                for seg in &self.segs[s..e] {
                    field = add3(field, segment_field_off(seg, q)?);
                }
            } else {
                stack[top] = n.first;
                stack[top + 1] = n.right;
                top += 2;
            }
        }
        Some((field, error))
    }

    /// [`Self::field`] at `qs[i]` for the lanes i in `lanes`, in one traversal (a cluster far
    /// enough from some points and not from others is opened for all of them, whose sums over
    /// its children are as exact).
    #[inline(always)]
    pub(super) fn field_lanes_body(
        &self,
        qs: &[[f64; 3]; LANES],
        lanes: u32,
    ) -> [Option<([f64; 3], f64)>; LANES] {
        let mut out = [([0.0; 3], 0.0); LANES];
        if self.nodes.is_empty() {
            return std::array::from_fn(|i| (lanes >> i & 1 == 1).then_some(out[i]));
        }
        let q = [0, 1, 2].map(|a| qs.map(|p| p[a]));
        let mut alive = lanes;
        let mut stack = [(0u32, 0u32); 64];
        stack[0] = (0, lanes);
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let (index, mask) = stack[top];
            let mask = mask & alive;
            if mask == 0 {
                continue;
            }
            let n = &self.nodes[index as usize];
            let at = lanes::edge_node_body(n.centre, n.net, &n.moment, n.anti, &q);
            let mut open = 0;
            for i in lanes_of(mask) {
                let g = at.d[i] - n.radius;
                if g > FIELD_OPEN * n.radius {
                    let (field, error) = &mut out[i];
                    *field = add3(*field, [at.field[0][i], at.field[1][i], at.field[2][i]]);
                    *error += 3.0 * n.radius * n.radius * n.length / (g * g * g * g);
                } else {
                    open |= 1 << i;
                }
            }
            if open != 0 && n.count > 0 {
                let (s, e) = (n.first as usize, (n.first + n.count) as usize);
                let acc = [0, 1, 2].map(|a| std::array::from_fn(|i| out[i].0[a]));
                let (sum, on) = lanes::edge_leaf_body(&self.segs[s..e], &q, acc);
                for i in lanes_of(open) {
                    if on[i] {
                        alive &= !(1 << i);
                    } else {
                        out[i].0 = [sum[0][i], sum[1][i], sum[2][i]];
                    }
                }
            } else if open != 0 {
                stack[top] = (n.first, open);
                stack[top + 1] = (n.right, open);
                top += 2;
            }
        }
        std::array::from_fn(|i| (alive >> i & 1 == 1).then_some(out[i]))
    }
}

lanes::dispatch! {
    /// [`EdgeTree::field_lanes_body`], on the widest instruction set.
    pub(super) fn field_lanes(
        tree: &EdgeTree,
        qs: &[[f64; 3]; LANES],
        lanes: u32,
    ) -> [Option<([f64; 3], f64)>; LANES]
        = EdgeTree::field_lanes_body, field_lanes_avx512, field_lanes_avx2;
}

/// The gradient of [`solid_angle`](super::solid_angle) at q: the Biot–Savart field of the
/// triangle's boundary.
#[inline]
pub(super) fn solid_angle_gradient(t: &[[f64; 3]; 3], q: [f64; 3]) -> [f64; 3] {
    let mut g = [0.0; 3];
    for i in 0..3 {
        g = add3(g, segment_field(&[t[i], t[(i + 1) % 3]], q));
    }
    g.map(|v| GRADIENT_SIGN * v)
}

/// ∇Ω = GRADIENT_SIGN × the Biot–Savart field of the boundary, for [`super::solid_angle`]'s sign.
pub(super) const GRADIENT_SIGN: f64 = -1.0;

/// [`segment_field`], or `None` when q lies on the segment (where the field is infinite).
#[inline]
fn segment_field_off(s: &[[f64; 3]; 2], q: [f64; 3]) -> Option<[f64; 3]> {
    let (r1, r2) = (sub(s[0], q), sub(s[1], q));
    let (l1, l2) = (norm(r1), norm(r2));
    let den = l1 * l2 * (l1 * l2 + dot(r1, r2));
    (den > 0.0).then_some(())?;
    Some(segment_field(s, q))
}

/// ∫ dl × (x − q)/|x − q|³ along the segment (the Biot–Savart field of a straight piece).
#[inline]
pub(super) fn segment_field(s: &[[f64; 3]; 2], q: [f64; 3]) -> [f64; 3] {
    let (r1, r2) = (sub(s[0], q), sub(s[1], q));
    let (l1, l2) = (norm(r1), norm(r2));
    let den = l1 * l2 * (l1 * l2 + dot(r1, r2));
    if den <= 0.0 {
        return [0.0; 3];
    }
    let f = (l1 + l2) / den;
    cross(r2, r1).map(|v| v * f)
}
