//! The hierarchy's traversals for eight balls at once: [`spread_lanes`] (eight intervals) and
//! [`taylor_lanes`] (eight Taylor models), what [`WindingTree::spread`] and
//! [`WindingTree::taylor`] give one ball at a time. A node is opened for the balls that need it
//! and taken through its children by the others, which bounds them as well. Each is compiled
//! for AVX-512, AVX2 and the baseline target with its kernels ([`super::lanes`]) inlined, and
//! the widest the processor has runs: the same operations in the same order on every path, so
//! the same bits.
//!
//! Not here: the kernels themselves ([`super::lanes`]), the boundary chain's traversal of eight
//! points ([`super::edges`]), or the one-ball bounds and their proofs ([`super::bounds`]).

use std::f64::consts::PI;

use super::bounds::{Spread, Taylor};
use super::lanes::{self, LANES};
use super::trees::WindingTree;
use super::{BETA, SMALL_BUDGET};
use crate::engine::geom::{dot, sub};

impl WindingTree {
    /// [`Self::spread`] over eight balls of radius `rq` at once (centres `qs`, each with its own
    /// `limit` and `by_area`), in one traversal: a node is opened for the balls that need it
    /// opened, and the others take it as `spread` would. A ball for which some other ball's need
    /// opens a node takes the node's children instead, which bound it as well; and the nodes
    /// left out as small are a different set, within the same budget. So each ball's result is a
    /// bound of the same kind, though not always the same numbers as its own traversal's.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub(super) fn spread_lanes_body(
        &self,
        qs: &[[f64; 3]; LANES],
        rq: f64,
        gap: f64,
        limit: &[f64; LANES],
        small: f64,
        by_area: &[bool; LANES],
    ) -> [Option<Spread>; LANES] {
        if self.nodes.is_empty() {
            return [Some(Spread::default()); LANES];
        }
        // The balls' sums, one array per quantity, so that a node's bookkeeping for all eight
        // runs without branches (and in vector registers): a lane that does not take a node adds
        // zero.
        let mut value = [0.0; LANES];
        let mut spread = [0.0; LANES];
        let mut crude = [0.0; LANES];
        let mut left_out = [0.0; LANES];
        let q = [0, 1, 2].map(|a| qs.map(|p| p[a]));
        // Children are taken nearer to the balls' mean centre first.
        let mean = [0, 1, 2].map(|a| q[a].iter().sum::<f64>() / LANES as f64);
        let mut budget = [SMALL_BUDGET * 4.0 * PI; LANES];
        let all = (1u32 << LANES) - 1;
        let mut alive = all;
        let mut stack = [(0u32, 0u32); 64];
        stack[0] = (0, all);
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let (index, mask) = stack[top];
            let mask = mask & alive;
            if mask == 0 {
                continue;
            }
            let n = &self.nodes[index as usize];
            let reach2 = (BETA * n.radius).powi(2);
            let at =
                lanes::node_body::<true>(&n.summary, n.centre, n.radius, n.area, rq, reach2, &q);
            let mut open = 0;
            for i in 0..LANES {
                let on = mask >> i & 1 == 1 && at.g[i] > gap;
                let (magnitude, variation) = (at.magnitude[i], at.extra[i]);
                let expanded = at.d2[i] > reach2;
                // Wherever in the ball, the node adds at most ±magnitude: that alone, when
                // small (out of a budget) or when tighter than the gradient bound.
                let small_enough = on && magnitude <= small && magnitude <= budget[i];
                let alone =
                    small_enough || (on && by_area[i] && expanded && variation >= magnitude);
                let far = on && !alone && expanded;
                budget[i] -= if small_enough { magnitude } else { 0.0 };
                spread[i] += if alone {
                    magnitude
                } else if far {
                    variation
                } else {
                    0.0
                };
                left_out[i] += if alone { magnitude } else { 0.0 };
                crude[i] += if alone || far { magnitude } else { 0.0 };
                value[i] += if far { at.far[i] } else { 0.0 };
                open |= ((mask >> i & 1 == 1 && !alone && !far) as u32) << i;
            }
            if open != 0 && n.count > 0 {
                let (s, e) = (n.first as usize, (n.first + n.count) as usize);
                for i in lanes_of(open) {
                    let at = lanes::leaf_spread_body(&self.leaves[n.right as usize], qs[i], rq);
                    for (j, &area) in self.areas[s..e].iter().enumerate() {
                        if area == 0.0 {
                            continue;
                        }
                        let g = at.g[j];
                        if g.is_nan() || g <= gap {
                            alive &= !(1 << i);
                            break;
                        }
                        let (magnitude, variation) = (at.magnitude[j], at.variation[j]);
                        let small_enough = magnitude <= small && magnitude <= budget[i];
                        if small_enough || (by_area[i] && variation >= magnitude) {
                            if small_enough {
                                budget[i] -= magnitude;
                            }
                            spread[i] += magnitude;
                            left_out[i] += magnitude;
                        } else {
                            value[i] += at.angle[j];
                            spread[i] += variation;
                        }
                        crude[i] += magnitude;
                    }
                }
            } else if open != 0 {
                let (a, b) = (n.first, n.right);
                let dist2 = |c: u32| {
                    let v = sub(self.nodes[c as usize].centre, mean);
                    dot(v, v)
                };
                let (near, far) = if dist2(a) <= dist2(b) { (a, b) } else { (b, a) };
                stack[top] = (far, open);
                stack[top + 1] = (near, open);
                top += 2;
            }
            // A lane's spread only grows, and was below its limit when last checked.
            let mut over = 0;
            for i in 0..LANES {
                over |= ((spread[i] >= limit[i]) as u32) << i;
            }
            alive &= !over;
            if alive == 0 {
                break;
            }
        }
        std::array::from_fn(|i| {
            (alive >> i & 1 == 1).then_some(Spread {
                value: value[i],
                spread: spread[i],
                crude: crude[i],
                left_out: left_out[i],
            })
        })
    }

    /// [`Self::taylor`] for the balls of radius `rq` about `qs[i]`, for the lanes i in `lanes`,
    /// in one traversal (as [`spread_lanes`]: a node opened for one ball is taken through
    /// its children by the others, which model them as well).
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub(super) fn taylor_lanes_body(
        &self,
        qs: &[[f64; 3]; LANES],
        lanes: u32,
        rq: f64,
        near_dist: f64,
        gap: f64,
        small: f64,
        near: &mut [Vec<(u32, f64)>; LANES],
    ) -> [Option<Taylor>; LANES] {
        let mut out = [Taylor::default(); LANES];
        if self.nodes.is_empty() {
            return std::array::from_fn(|i| (lanes >> i & 1 == 1).then_some(out[i]));
        }
        let q = [0, 1, 2].map(|a| qs.map(|p| p[a]));
        let mean = [0, 1, 2].map(|a| {
            (0..LANES)
                .filter(|i| lanes >> i & 1 == 1)
                .map(|i| q[a][i])
                .sum::<f64>()
                / lanes.count_ones() as f64
        });
        let near_dist = near_dist.max(gap);
        let mut budget = [SMALL_BUDGET * 4.0 * PI; LANES];
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
            let reach2 = (BETA * n.radius).powi(2);
            let at =
                lanes::node_body::<false>(&n.summary, n.centre, n.radius, n.area, rq, reach2, &q);
            let mut open = 0;
            for i in lanes_of(mask) {
                let o = &mut out[i];
                if at.g[i] > near_dist {
                    let magnitude = at.magnitude[i];
                    if magnitude <= small && magnitude <= budget[i] {
                        budget[i] -= magnitude;
                        o.left_out += magnitude;
                        o.hessian += at.extra[i];
                        continue;
                    }
                    if at.d2[i] > reach2 {
                        o.value += at.far[i];
                        o.hessian += at.extra[i];
                        continue;
                    }
                }
                open |= 1 << i;
            }
            if open != 0 && n.count > 0 {
                for i in lanes_of(open) {
                    let o = &mut out[i];
                    let at = lanes::leaf_taylor_body(&self.leaves[n.right as usize], qs[i], rq);
                    for (j, t) in (n.first..n.first + n.count).enumerate() {
                        let area = self.areas[t as usize];
                        if area == 0.0 {
                            continue;
                        }
                        let dist = at.dist[j];
                        if dist.is_nan() || dist <= gap {
                            alive &= !(1 << i);
                            break;
                        }
                        if dist - rq > near_dist {
                            o.value += at.angle[j];
                            o.hessian += at.hessian[j];
                        } else {
                            near[i].push((t, 2.0 * area));
                        }
                    }
                }
            } else if open != 0 {
                let (a, b) = (n.first, n.right);
                let dist2 = |c: u32| {
                    let v = sub(self.nodes[c as usize].centre, mean);
                    dot(v, v)
                };
                let (nearer, farther) = if dist2(a) <= dist2(b) { (a, b) } else { (b, a) };
                stack[top] = (farther, open);
                stack[top + 1] = (nearer, open);
                top += 2;
            }
        }
        std::array::from_fn(|i| (alive >> i & 1 == 1).then_some(out[i]))
    }
}

// The traversals over eight points, each compiled for AVX-512, AVX2 and the baseline target
// with its kernels inlined (see [`super::lanes`]): the same operations in the same order on
// every path, so the same bits.
lanes::dispatch! {
    /// [`WindingTree::spread_lanes_body`], on the widest instruction set.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn spread_lanes(
        tree: &WindingTree,
        qs: &[[f64; 3]; LANES],
        rq: f64,
        gap: f64,
        limit: &[f64; LANES],
        small: f64,
        by_area: &[bool; LANES],
    ) -> [Option<Spread>; LANES]
        = WindingTree::spread_lanes_body, spread_lanes_avx512, spread_lanes_avx2;
}

lanes::dispatch! {
    /// [`WindingTree::taylor_lanes_body`], on the widest instruction set.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn taylor_lanes(
        tree: &WindingTree,
        qs: &[[f64; 3]; LANES],
        lanes: u32,
        rq: f64,
        near_dist: f64,
        gap: f64,
        small: f64,
        near: &mut [Vec<(u32, f64)>; LANES],
    ) -> [Option<Taylor>; LANES]
        = WindingTree::taylor_lanes_body, taylor_lanes_avx512, taylor_lanes_avx2;
}

/// The lanes whose bits are set in `mask`, in order.
#[inline(always)]
pub(super) fn lanes_of(mut mask: u32) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        (mask != 0).then(|| {
            let i = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            i
        })
    })
}
