//! The bounds that let the winding fill decide whole blocks and balls: over a ball, the
//! hierarchy's value at its centre with a bound on how far the exact sum strays from it anywhere
//! in the ball ([`WindingTree::spread`]), and a first-order Taylor model of the caps' solid angle
//! with a bound on its remainder ([`WindingTree::taylor`]). One ball at a time; the proofs of the
//! bounds are in the methods' docs.
//!
//! Not here: the same for eight balls in one traversal ([`super::traverse`]), the boundary
//! chain's Biot–Savart bound ([`super::edges`]), or what the certifier makes of the intervals
//! ([`super::certifier`]).

use std::f64::consts::PI;

use super::lanes;
use super::trees::{WindingTree, far_field};
use super::{BETA, SMALL_BUDGET};
use crate::engine::geom::{dot, sub};

impl WindingTree {
    /// Over the ball (q, rq), in steradians: the hierarchy's Σ solid angles at q (less the
    /// nodes left out, below), a bound on how far the exact sum anywhere in the ball lies from
    /// that value, and a bound on Σ |solid angle| anywhere in the ball. `None` when a triangle
    /// comes within `gap` of the ball, or when the bound reaches `limit`.
    ///
    /// The bounds, for a node (or triangle) at distance g from the ball: its solid angle is at
    /// most its area over g² (`magnitude`), and the gradient of a triangle's solid angle at a
    /// point at distance ≥ g from it is at most 2·area/g³ (∇(n·r/|r|³) = (n − 3(n·r̂)r̂)/|r|³,
    /// of magnitude √(1 + 3(n·r̂)²)/|r|³), so along a segment from q of length ≤ rq it changes by
    /// at most rq · 2·area/g³ (`variation`). A node whose magnitude is at most `small` (and
    /// within a budget of `SMALL_BUDGET` in all) or below its variation enters as ± its
    /// magnitude alone; one farther than β radii from q (Barill et al.'s rule; with rq = 0 and
    /// `small` 0 this is [`Self::winding_number`]) through its expansion at q ± its variation;
    /// any other is opened, nearer child first, and a leaf's triangles are taken one by one, the
    /// same way, with exact solid angles. Without `by_area`, nodes enter alone only when small (the
    /// caller bounds the variation otherwise, by `EdgeTree::bound`).
    pub(super) fn spread(
        &self,
        q: [f64; 3],
        rq: f64,
        gap: f64,
        limit: f64,
        small: f64,
        by_area: bool,
    ) -> Option<Spread> {
        let mut out = Spread::default();
        if self.nodes.is_empty() {
            return Some(out);
        }
        // What the nodes left out by `small` may add up to.
        let mut budget = SMALL_BUDGET * 4.0 * PI;
        let mut stack = [0u32; 64];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let n = &self.nodes[stack[top] as usize];
            let r = sub(n.centre, q);
            let d2 = dot(r, r);
            let g = d2.sqrt() - n.radius - rq;
            if g > gap {
                let ig = 1.0 / g;
                let magnitude = n.area * ig * ig;
                let variation = rq * 2.0 * magnitude * ig;
                let expanded = d2 > (BETA * n.radius).powi(2);
                // Wherever in the ball, the node adds at most ±magnitude: that alone, when small
                // (out of a budget) or when tighter than the gradient bound.
                let alone = if magnitude <= small && magnitude <= budget {
                    budget -= magnitude;
                    true
                } else {
                    by_area && expanded && variation >= magnitude
                };
                if alone {
                    out.spread += magnitude;
                    out.left_out += magnitude;
                    out.crude += magnitude;
                    continue;
                }
                if expanded {
                    out.value += far_field(n, r, d2);
                    out.spread += variation;
                    out.crude += magnitude;
                    if out.spread >= limit {
                        return None;
                    }
                    continue;
                }
            }
            if n.count > 0 {
                let (s, e) = (n.first as usize, (n.first + n.count) as usize);
                let at = lanes::leaf_spread(&self.leaves[n.right as usize], q, rq);
                for (j, &area) in self.areas[s..e].iter().enumerate() {
                    // A degenerate triangle (of a fan over collinear edges) subtends nothing.
                    if area == 0.0 {
                        continue;
                    }
                    let g = at.g[j];
                    if g.is_nan() || g <= gap {
                        return None;
                    }
                    let (magnitude, variation) = (at.magnitude[j], at.variation[j]);
                    if (magnitude <= small && magnitude <= budget)
                        || (by_area && variation >= magnitude)
                    {
                        if magnitude <= small && magnitude <= budget {
                            budget -= magnitude;
                        }
                        out.spread += magnitude;
                        out.left_out += magnitude;
                    } else {
                        out.value += at.angle[j];
                        out.spread += variation;
                    }
                    out.crude += magnitude;
                }
            } else {
                self.open(n, &mut stack, &mut top, q);
            }
            if out.spread >= limit {
                return None;
            }
        }
        Some(out)
    }

    /// A first-order model of the caps' solid angle over the ball (c, rq), less the triangles
    /// that come within `near_dist` of the ball, which go to `near` (with twice their areas):
    /// the rest's value at c (the hierarchy's, less the nodes left out as small) and Σ area/g⁴
    /// over the rest (g the distance from the ball). `None` where c lies within `gap` of a near
    /// triangle.
    ///
    /// The bound: the Hessian of a triangle's solid angle at a point p at distance ≥ g from it is
    /// ∫ ∇∇(n·r/|r|³) dA (r = x − p), and for unit u, uᵀ∇∇(n·r/|r|³)u = (15ab² − 6bc − 3a)/|r|⁴
    /// with a = n·r̂, b = u·r̂, c = n·u; writing n and u along and across r̂,
    /// |15ab² − 6bc − 3a| ≤ 3|a|·|3b² − 1| + 6|b|√(1 − a²)√(1 − b²) ≤ √(45b⁴ − 18b² + 9) ≤ 6.
    /// So along a segment from c of length |δ| ≤ rq the rest differs from its value at c plus its
    /// gradient at c times δ by at most ½|δ|² · 6 Σ area/g⁴ = 3|δ|² Σ area/g⁴ (Taylor, the
    /// rest being smooth on the ball).
    pub(super) fn taylor(
        &self,
        c: [f64; 3],
        rq: f64,
        near_dist: f64,
        gap: f64,
        small: f64,
        near: &mut Vec<(u32, f64)>,
    ) -> Option<Taylor> {
        let mut out = Taylor::default();
        if self.nodes.is_empty() {
            return Some(out);
        }
        let near_dist = near_dist.max(gap);
        let mut budget = SMALL_BUDGET * 4.0 * PI;
        let mut stack = [0u32; 64];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let n = &self.nodes[stack[top] as usize];
            let r = sub(n.centre, c);
            let d2 = dot(r, r);
            let g = d2.sqrt() - n.radius - rq;
            if g > near_dist {
                let ig2 = 1.0 / (g * g);
                // Within the ball, a node adds at most area/g² (at c in particular).
                let magnitude = n.area * ig2;
                if magnitude <= small && magnitude <= budget {
                    budget -= magnitude;
                    out.left_out += magnitude;
                    out.hessian += magnitude * ig2;
                    continue;
                }
                if d2 > (BETA * n.radius).powi(2) {
                    out.value += far_field(n, r, d2);
                    out.hessian += magnitude * ig2;
                    continue;
                }
            }
            if n.count > 0 {
                let at = lanes::leaf_taylor(&self.leaves[n.right as usize], c, rq);
                for (j, i) in (n.first..n.first + n.count).enumerate() {
                    let area = self.areas[i as usize];
                    if area == 0.0 {
                        continue;
                    }
                    let dist = at.dist[j];
                    if dist.is_nan() || dist <= gap {
                        return None;
                    }
                    if dist - rq > near_dist {
                        out.value += at.angle[j];
                        out.hessian += at.hessian[j];
                    } else {
                        near.push((i, 2.0 * area));
                    }
                }
            } else {
                self.open(n, &mut stack, &mut top, c);
            }
        }
        Some(out)
    }
}

/// See [`WindingTree::taylor`]; in steradians.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Taylor {
    pub(super) value: f64,
    /// Σ area/g⁴ over the triangles of the model.
    pub(super) hessian: f64,
    /// Σ area/g² over the nodes left out of `value` as small.
    pub(super) left_out: f64,
}

/// See [`WindingTree::spread`].
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Spread {
    pub(super) value: f64,
    pub(super) spread: f64,
    pub(super) crude: f64,
    /// The part of `spread` from nodes entered as ± their magnitude alone (left out of `value`).
    pub(super) left_out: f64,
}
