//! The certifier: decides the voxels of a column of blocks without evaluating each. A block (a
//! super-block of `SUPER`³ blocks, a `BLOCK`³ block, its 4³ and 2³ sub-blocks) gets an interval
//! for the caps' winding number from the hierarchy at its centre and the bounds on its
//! variation; where that holds no half-integer, inside ⇔ N ≠ k for all its voxels, and where it
//! fails, the mesh's own interval, the Taylor model of a 2³ block, or the voxel by voxel
//! evaluation decides. What it finds goes to a [`Column`]: one code per block, voxel codes for
//! the mixed ones, the ties to settle by the mesh's winding number, and the counts.
//!
//! Not here: the driver that runs it over the grid and counts the crossings (`super`), the trees
//! and bounds it reads ([`super::trees`], [`super::bounds`], [`super::traverse`],
//! [`super::edges`]).

use std::f64::consts::PI;

use super::bounds::{Spread, Taylor};
use super::edges::{EdgeTree, GRADIENT_SIGN, field_lanes, solid_angle_gradient};
use super::lanes::{self, LANES};
use super::traverse::{spread_lanes, taylor_lanes};
use super::trees::{Trees, WindingTree};
use super::{
    BLOCK, Block, CAP_BLOCK, CAP_EVAL, CAP_LIMIT, Codes, EXACT, K_MAX, MARGIN, MESH_BLOCK,
    MESH_EVAL, NEAR_EVAL, SMALL, SUPER, TAYLOR_NEAR, TIE, V_IN, V_OUT, V_TIE, local,
};
use crate::engine::geom::{dot, sub};
use crate::grid::Grid;

/// The certification of blocks: trees, grid, and what a column of blocks found.
pub(super) struct Certifier<'a> {
    grid: &'a Grid,
    caps: &'a WindingTree,
    mesh: &'a WindingTree,
    /// The boundary chain on the caps' positions (on the lattice) and on the mesh's.
    cap_edges: &'a EdgeTree,
    mesh_edges: &'a EdgeTree,
    /// Whether blocks are decided as wholes (off: every voxel one by one, for the tests).
    blocks: bool,
}

/// What a column of blocks found.
#[derive(Default)]
pub(super) struct Column {
    pub(super) blocks: Vec<Block>,
    pub(super) mixed: Vec<Codes>,
    pub(super) ties: Vec<[u32; 3]>,
    pub(super) counts: [u64; 6],
}

/// A block's or voxel's decision.
#[derive(Clone, Copy)]
pub(super) enum Decision {
    Ne(i32, usize),
    Is(bool),
    Tie,
}

impl<'a> Certifier<'a> {
    pub(super) fn new(grid: &'a Grid, trees: &'a Trees, blocks: bool) -> Certifier<'a> {
        Certifier {
            grid,
            caps: &trees.caps,
            mesh: &trees.mesh,
            cap_edges: &trees.cap_edges,
            mesh_edges: &trees.mesh_edges,
            blocks,
        }
    }

    /// The ball around the voxel centres of `lo..lo + size` clamped to the grid: its centre
    /// and its radius.
    fn ball(&self, lo: [u32; 3], size: u32) -> ([f64; 3], f64) {
        let g = self.grid;
        let hi = [0, 1, 2].map(|a| (lo[a] + size).min(g.dims[a]));
        let c = g.world_of([0, 1, 2].map(|a| (lo[a] as f64 + hi[a] as f64) * 0.5));
        let rb = 0.5
            * g.voxel_size
            * (0..3)
                .map(|a| ((hi[a] - lo[a] - 1) as f64).powi(2))
                .sum::<f64>()
                .sqrt();
        (c, rb)
    }

    /// The decision for the voxels `lo..lo + size` (clamped to the grid) as a whole, if any.
    fn decide(&self, lo: [u32; 3], size: u32) -> Option<Decision> {
        let g = self.grid;
        let s = g.voxel_size;
        let (c, rb) = self.ball(lo, size);
        let four_pi = 4.0 * PI;
        // A block's interval must stay within ½ − MARGIN of its centre's value.
        let limit = (0.5 - MARGIN) * four_pi;
        // Small nodes enter as bounds (not with the reference evaluation of the tests).
        let small = if self.blocks { SMALL * four_pi } else { 0.0 };
        if size == 1 {
            let caps = self.caps.spread(c, rb, TIE * s, limit, small, true);
            // One voxel: the hierarchy's value, as [`WindingTree::winding_number_off_planes`],
            // first with small nodes bounded, then, where that leaves it open, in full.
            let Some(mut caps) = caps else {
                return Some(Decision::Tie);
            };
            if caps.crude < CAP_LIMIT * four_pi {
                return Some(Decision::Ne(0, EXACT));
            }
            let (v, e) = (caps.value / four_pi, caps.spread / four_pi);
            if caps.left_out > 0.0 && (v - v.round()).abs() + e >= 0.5 {
                caps = self
                    .caps
                    .spread(c, rb, TIE * s, limit, 0.0, true)
                    .expect("no tie where there was none");
            }
            let v = caps.value / four_pi;
            let k = v.round();
            return Some(if k.abs() > K_MAX {
                Decision::Tie
            } else if (v - k).abs() + caps.spread / four_pi < 0.5 {
                Decision::Ne(k as i32, CAP_EVAL)
            } else {
                // |N − v| ≥ ½ for every integer N.
                Decision::Is(true)
            });
        }
        if !self.blocks {
            return match self.caps.spread(c, rb, TIE * s, limit, 0.0, true) {
                Some(caps) if caps.crude < CAP_LIMIT * four_pi => Some(Decision::Ne(0, EXACT)),
                _ => None,
            };
        }
        let (caps, by_edges) = self.interval(self.caps, self.cap_edges, c, rb);
        if let Some(d) = caps.and_then(caps_decision) {
            return Some(d);
        }
        // A 2³ block left open by the caps' interval goes straight to the Taylor model
        // (`Self::taylor_voxels`) and, per voxel, the evaluation: both decide every voxel, so
        // the mesh's interval is not needed here, and at 2³ it rarely holds (a block this close
        // to a cap is close to the mesh's boundary, which the cap shares) while it costs a
        // traversal of the mesh (2CylinderEngine 256³: it held for no block at any size).
        if size == 2 {
            return None;
        }
        self.mesh_decision(c, rb, by_edges)
    }

    /// The interval of `tree`'s winding number over the ball (c, rb), in units of w: its value
    /// at c, the bound on how far it strays over the ball (with `MARGIN`), and the crude bound
    /// Σ |solid angle| (in steradians). The variation, wherever a winding number is smooth on
    /// the ball, is rb × the Biot–Savart bound of the boundary; where that is too large, the
    /// triangles' own bounds. Also whether the boundary's bound held (see
    /// [`Self::mesh_decision`]).
    fn interval(
        &self,
        tree: &WindingTree,
        edges: &EdgeTree,
        c: [f64; 3],
        rb: f64,
    ) -> (Option<(f64, f64, f64)>, bool) {
        let s = self.grid.voxel_size;
        let four_pi = 4.0 * PI;
        let limit = (0.5 - MARGIN) * four_pi;
        let bs = rb * edges.bound(c, rb, limit / rb);
        let by_edges = bs < limit;
        let t = tree.spread(
            c,
            rb,
            TIE * s,
            if by_edges { f64::INFINITY } else { limit },
            SMALL * four_pi,
            !by_edges,
        );
        (t.map(|t| bounded(&t, by_edges, bs)), by_edges)
    }

    /// The decision for the ball (c, rb) by the mesh's own winding number: all inside or all
    /// outside where its interval excludes ±½. Tried only where the boundary chain's bound held
    /// for the caps' interval (`chain`): the mesh shares that chain, and where its bound fails
    /// the other way, the mesh's own triangles' bounds, is hopeless for a block this close to a
    /// cap, hence to the mesh's boundary. Measured at 256³: on 2CylinderEngine the mesh's
    /// interval held for none of 56,850 blocks tried, at 5 % of the time; on the teapot every
    /// block it decided had the chain's bound.
    fn mesh_decision(&self, c: [f64; 3], rb: f64, chain: bool) -> Option<Decision> {
        if !chain {
            return None;
        }
        let (v, e, _) = self.interval(self.mesh, self.mesh_edges, c, rb).0?;
        ((v - 0.5).abs() > e && (v + 0.5).abs() > e).then_some(Decision::Is(v.abs() >= 0.5))
    }

    /// [`Self::decide`] for the eight blocks of edge `size` (2 or 4) of the block of edge
    /// 2·size at `lo` (inside the grid, with `blocks` on), by the caps' intervals of all eight
    /// from one traversal ([`spread_lanes`]); where those leave a 4³ block open,
    /// by the mesh's interval, one by one.
    fn decide_lanes(&self, lo: [u32; 3], size: u32) -> [Option<Decision>; LANES] {
        let g = self.grid;
        let s = g.voxel_size;
        let four_pi = 4.0 * PI;
        let limit = (0.5 - MARGIN) * four_pi;
        // As `decide` computes them for a whole block.
        let rb = 0.5 * s * 3f64.sqrt() * (size - 1) as f64;
        let h = size as f64 * 0.5;
        let subs: [[u32; 3]; LANES] =
            std::array::from_fn(|d| [0, 1, 2].map(|a| lo[a] + ((d as u32 >> a) & 1) * size));
        let centres = subs.map(|b| g.world_of(b.map(|v| v as f64 + h)));
        let bs = centres.map(|c| rb * self.cap_edges.bound(c, rb, limit / rb));
        let by_edges = bs.map(|b| b < limit);
        let limits = by_edges.map(|e| if e { f64::INFINITY } else { limit });
        let spreads = spread_lanes(
            self.caps,
            &centres,
            rb,
            TIE * s,
            &limits,
            SMALL * four_pi,
            &by_edges.map(|e| !e),
        );
        std::array::from_fn(|i| {
            let caps = spreads[i].and_then(|t| caps_decision(bounded(&t, by_edges[i], bs[i])));
            // As in `decide`: a 2³ block goes to the Taylor model, a larger one to the mesh.
            caps.or_else(|| (size > 2).then(|| self.mesh_decision(centres[i], rb, by_edges[i]))?)
        })
    }

    /// The decision for the `SUPER`³ blocks of `BLOCK`³ at voxel `lo` (clamped to the grid) as
    /// a whole, by the caps' interval alone ([`Self::decide`] without the mesh's interval, which
    /// at this size hardly ever holds: a block this large that misses the caps' bound is near a
    /// cap, hence near the mesh's boundary).
    pub(super) fn decide_super(&self, lo: [u32; 3]) -> Option<Decision> {
        self.super_interval(lo).and_then(caps_decision)
    }

    /// The caps' interval ([`bounded`]) over the `SUPER`³ blocks at voxel `lo`.
    pub(super) fn super_interval(&self, lo: [u32; 3]) -> Option<(f64, f64, f64)> {
        let (c, rb) = self.ball(lo, SUPER * BLOCK);
        self.interval(self.caps, self.cap_edges, c, rb).0
    }

    /// Decides the block column `(bx, by)`'s blocks `bz0..bz1` into `col`, each as `decision`
    /// where a super-block's decision is given, else one by one ([`Self::block`]).
    pub(super) fn blocks(
        &self,
        [bx, by]: [u32; 2],
        bz: std::ops::Range<u32>,
        decision: Option<Decision>,
        col: &mut Column,
    ) {
        let (block, how) = match decision {
            Some(Decision::Ne(k, how)) => (Block::Ne(k), how),
            Some(Decision::Is(inside)) => (Block::Is(inside), MESH_BLOCK),
            Some(Decision::Tie) | None => {
                for bz in bz {
                    self.block([bx, by, bz], None, col);
                }
                return;
            }
        };
        let lo = [bx, by, bz.start].map(|v| v * BLOCK);
        let hi = [bx + 1, by + 1, bz.end].map(|v| v * BLOCK);
        col.counts[how] += (0..3)
            .map(|a| (hi[a].min(self.grid.dims[a]) - lo[a]) as u64)
            .product::<u64>();
        col.blocks.extend(std::iter::repeat_n(block, bz.len()));
    }

    /// Decides the blocks of a super-block that was not decided whole into its columns `cols`
    /// (x-major, as `bxs` × `bys`): eight (2×2×2) at a time by [`Self::decide_lanes`] where those
    /// lie wholly inside the grid, the others one by one.
    pub(super) fn super_blocks(
        &self,
        bxs: std::ops::Range<u32>,
        bys: std::ops::Range<u32>,
        bzs: std::ops::Range<u32>,
        cols: &mut [([u32; 2], Column)],
    ) {
        let g = self.grid;
        let nby = bys.len();
        for gz in bzs.clone().step_by(2) {
            for gx in bxs.clone().step_by(2) {
                for gy in bys.clone().step_by(2) {
                    let lo = [gx, gy, gz].map(|v| v * BLOCK);
                    let whole = (0..3).all(|a| lo[a] + 2 * BLOCK <= g.dims[a]);
                    let made = whole.then(|| self.decide_lanes(lo, BLOCK));
                    for d in 0..8u32 {
                        let b = [gx + (d & 1), gy + ((d >> 1) & 1), gz + (d >> 2)];
                        // z last, so that each column gets its blocks in order.
                        if b[0] >= bxs.end || b[1] >= bys.end || b[2] >= bzs.end {
                            continue;
                        }
                        let c = (b[0] - bxs.start) as usize * nby + (b[1] - bys.start) as usize;
                        // `decide_lanes` numbers its blocks x-minor.
                        let made = made.map(|m| m[d as usize]);
                        self.block(b, made, &mut cols[c].1);
                    }
                }
            }
        }
    }

    /// Decides the block at block coordinates `b` into `col`, by `made` where its decision was
    /// made already.
    fn block(&self, b: [u32; 3], made: Option<Option<Decision>>, col: &mut Column) {
        let lo = b.map(|v| v * BLOCK);
        let voxels = |lo: [u32; 3], size: u32| -> u64 {
            (0..3)
                .map(|a| ((lo[a] + size).min(self.grid.dims[a]) - lo[a]) as u64)
                .product()
        };
        match made.unwrap_or_else(|| self.decide(lo, BLOCK)) {
            Some(Decision::Ne(k, how)) => {
                col.counts[how] += voxels(lo, BLOCK);
                col.blocks.push(Block::Ne(k));
                return;
            }
            Some(Decision::Is(inside)) => {
                col.counts[MESH_BLOCK] += voxels(lo, BLOCK);
                col.blocks.push(Block::Is(inside));
                return;
            }
            Some(Decision::Tie) | None => {}
        }
        let mut codes: Codes = [V_OUT; (BLOCK * BLOCK * BLOCK) as usize];
        // Sub-blocks still to decide, with their decision where it was made for eight at once.
        let mut stack: Vec<([u32; 3], u32, Option<Option<Decision>>)> = Vec::with_capacity(32);
        let h = BLOCK / 2;
        // A block wholly inside the grid: its eight 4³ blocks' intervals at once.
        let whole = (0..3).all(|a| lo[a] + BLOCK <= self.grid.dims[a]);
        let made = (whole && self.blocks).then(|| self.decide_lanes(lo, h));
        for d in 0..8u32 {
            let child = [0, 1, 2].map(|a| lo[a] + ((d >> a) & 1) * h);
            stack.push((child, h, made.map(|m| m[d as usize])));
        }
        while let Some((sub, size, made)) = stack.pop() {
            if (0..3).any(|a| sub[a] >= self.grid.dims[a]) {
                continue;
            }
            let decision = made.unwrap_or_else(|| self.decide(sub, size));
            // A 2³ block left open: its voxels one by one, by the Taylor model about its centre.
            if decision.is_none() && size == 2 && self.blocks {
                self.taylor_voxels(sub, size, &mut codes, col);
                continue;
            }
            let (code, how) = match decision {
                Some(Decision::Ne(k, how)) => (k as i8, how),
                Some(Decision::Is(inside)) => (
                    if inside { V_IN } else { V_OUT },
                    if size == 1 { CAP_EVAL } else { MESH_BLOCK },
                ),
                Some(Decision::Tie) => (V_TIE, MESH_EVAL),
                None => {
                    let h = size / 2;
                    // A 4³ block wholly inside the grid: its eight 2³ blocks' intervals at once.
                    let whole = (0..3).all(|a| sub[a] + size <= self.grid.dims[a]);
                    if size == 4 && self.blocks && whole {
                        // ... and the models of those they leave open, at once too.
                        let made = self.decide_lanes(sub, h);
                        let mut open = Vec::with_capacity(LANES);
                        for (d, &decision) in made.iter().enumerate() {
                            let child = [0, 1, 2].map(|a| sub[a] + ((d as u32 >> a) & 1) * h);
                            match decision {
                                None => open.push(child),
                                Some(decision) => stack.push((child, h, Some(Some(decision)))),
                            }
                        }
                        if !open.is_empty() {
                            self.taylor_lanes(&open, &mut codes, col);
                        }
                    } else {
                        for d in 0..8u32 {
                            let child = [0, 1, 2].map(|a| sub[a] + ((d >> a) & 1) * h);
                            stack.push((child, h, None));
                        }
                    }
                    continue;
                }
            };
            col.counts[how] += voxels(sub, size);
            let hi = [0, 1, 2].map(|a| (sub[a] + size).min(self.grid.dims[a]));
            for x in sub[0]..hi[0] {
                for y in sub[1]..hi[1] {
                    for z in sub[2]..hi[2] {
                        if code == V_TIE {
                            col.ties.push([x, y, z]);
                        }
                        codes[local([x, y, z])] = code;
                    }
                }
            }
        }
        col.blocks.push(Block::Mixed(col.mixed.len() as u32));
        col.mixed.push(codes);
    }

    /// The voxels of the sub-block `lo..lo + size` one by one: w_caps = (the cap triangles near
    /// the sub-block, summed exactly at each voxel v) + (the rest), and the rest by its
    /// first-order Taylor model about the sub-block's centre c: its value at c from the hierarchy
    /// ([`WindingTree::taylor`]), its gradient at c as the Biot–Savart field of its boundary
    /// (the caps' chain, by [`EdgeTree::field`] within a bound on the error, less the near
    /// triangles' boundaries, exactly), and the remainder bound 3|v − c|² Σ area/g⁴. Where that
    /// interval, widened by `MARGIN` for the hierarchy's error at c, holds no half-integer and
    /// rounds to k, inside ⇔ N ≠ k, as [`Self::decide`] finds for one voxel; the voxels it leaves
    /// open (all of them where c lies on a cap or a boundary segment, and ties) are decided by
    /// [`Self::decide`] alone.
    fn taylor_voxels(&self, lo: [u32; 3], size: u32, codes: &mut Codes, col: &mut Column) {
        let g = self.grid;
        let s = g.voxel_size;
        let four_pi = 4.0 * PI;
        let (c, rb) = self.ball(lo, size);
        let mut near = Vec::new();
        let model = self
            .caps
            .taylor(c, rb, TAYLOR_NEAR * rb, TIE * s, SMALL * four_pi, &mut near)
            .and_then(|t| Some((t, self.cap_edges.field(c)?)));
        self.model_voxels(lo, size, c, model, &near, codes, col);
    }

    /// [`Self::taylor_voxels`] for several whole 2³ blocks (`subs`, at most eight) at once: their
    /// models from one traversal of the caps' tree and one of the chain's.
    fn taylor_lanes(&self, subs: &[[u32; 3]], codes: &mut Codes, col: &mut Column) {
        let g = self.grid;
        let s = g.voxel_size;
        let rb = 0.5 * s * 3f64.sqrt();
        let mut centres = [[0.0; 3]; LANES];
        for (i, c) in centres.iter_mut().enumerate() {
            *c = g.world_of(subs[i.min(subs.len() - 1)].map(|v| v as f64 + 1.0));
        }
        let lanes = (1u32 << subs.len()) - 1;
        let mut near: [Vec<(u32, f64)>; LANES] = Default::default();
        let models = taylor_lanes(
            self.caps,
            &centres,
            lanes,
            rb,
            TAYLOR_NEAR * rb,
            TIE * s,
            SMALL * 4.0 * PI,
            &mut near,
        );
        // The fields only where there is a model.
        let modelled = (0..subs.len())
            .filter(|&i| models[i].is_some())
            .fold(0, |m, i| m | 1 << i);
        let fields = field_lanes(self.cap_edges, &centres, modelled);
        for (i, &sub) in subs.iter().enumerate() {
            let model = models[i].zip(fields[i]);
            self.model_voxels(sub, 2, centres[i], model, &near[i], codes, col);
        }
    }

    /// The voxels of the sub-block `lo..lo + size` by the model about its centre c (the rest's
    /// Taylor data, the chain's field at c and its error; the near triangles in `near`), those
    /// it leaves open by [`Self::decide`]. See [`Self::taylor_voxels`].
    #[allow(clippy::too_many_arguments)]
    fn model_voxels(
        &self,
        lo: [u32; 3],
        size: u32,
        c: [f64; 3],
        model: Option<(Taylor, ([f64; 3], f64))>,
        near: &[(u32, f64)],
        codes: &mut Codes,
        col: &mut Column,
    ) {
        let g = self.grid;
        let s = g.voxel_size;
        let four_pi = 4.0 * PI;
        let hi = [0, 1, 2].map(|a| (lo[a] + size).min(g.dims[a]));
        let model = model.map(|(t, (field, error))| {
            // The rest's gradient: the whole chain's field less the near triangles'.
            let mut grad = field.map(|v| GRADIENT_SIGN * v);
            for &(i, _) in near {
                grad = sub(grad, solid_angle_gradient(&self.caps.tris[i as usize], c));
            }
            (t, grad, error)
        });
        // The block's voxels (up to eight: fewer at the grid's end), and the near caps' exact
        // sums at all of them at once; where a cap's plane passes close to a voxel, the sum is
        // taken again with the tie rule.
        let mut voxels = [[0u32; 3]; LANES];
        let mut count = 0;
        for x in lo[0]..hi[0] {
            for y in lo[1]..hi[1] {
                for z in lo[2]..hi[2] {
                    voxels[count] = [x, y, z];
                    count += 1;
                }
            }
        }
        for i in count..LANES {
            voxels[i] = voxels[0];
        }
        let points = voxels.map(|v| g.world_of(v.map(|i| i as f64 + 0.5)));
        let sums = model.map(|_| {
            let q = [0, 1, 2].map(|a| points.map(|p| p[a]));
            lanes::point_sums(&self.caps.tris, near, &q, TIE * s)
        });
        for (i, &v) in voxels[..count].iter().enumerate() {
            let decided = model
                .zip(sums)
                .and_then(|((t, grad, error), (sum, close))| {
                    let q = points[i];
                    let near_sum = if close[i] {
                        self.caps.near_sum(near, q, TIE * s)?
                    } else {
                        sum[i]
                    };
                    let d = sub(q, c);
                    let dd = dot(d, d);
                    let w = (near_sum + t.value + dot(grad, d)) / four_pi;
                    let e = (3.0 * dd * t.hessian + error * dd.sqrt() + t.left_out) / four_pi;
                    let k = w.round();
                    ((w - k).abs() + e + MARGIN < 0.5 && k.abs() <= K_MAX).then_some(k as i8)
                });
            let (code, how) = match decided {
                Some(k) => (k, NEAR_EVAL),
                None => match self.decide(v, 1).expect("a voxel is decided") {
                    Decision::Ne(k, how) => (k as i8, how),
                    Decision::Is(inside) => (if inside { V_IN } else { V_OUT }, CAP_EVAL),
                    Decision::Tie => {
                        col.ties.push(v);
                        (V_TIE, MESH_EVAL)
                    }
                },
            };
            col.counts[how] += 1;
            codes[local(v)] = code;
        }
    }
}

/// A winding number's interval over a ball from its [`Spread`] there, in units of w: the value
/// at the centre, how far it strays over the ball (with `MARGIN`; by `bs`, rb × the Biot–Savart
/// bound of the boundary, where `by_edges`, else the triangles' own bounds), and the crude bound
/// Σ |solid angle| (in steradians).
fn bounded(t: &Spread, by_edges: bool, bs: f64) -> (f64, f64, f64) {
    let four_pi = 4.0 * PI;
    let e = if by_edges {
        t.spread.min(t.left_out + bs)
    } else {
        t.spread
    };
    (t.value / four_pi, e / four_pi + MARGIN, t.crude)
}

/// The decision for a block by the caps' interval over it ([`bounded`]): |w_caps| < 0.45
/// proven (the exact crossing count alone), or no half-integer in it, so inside ⇔ N ≠ k.
fn caps_decision((v, e, crude): (f64, f64, f64)) -> Option<Decision> {
    if crude < CAP_LIMIT * 4.0 * PI {
        return Some(Decision::Ne(0, EXACT));
    }
    let k = v.round();
    ((v - k).abs() + e < 0.5 && k.abs() <= K_MAX).then_some(Decision::Ne(k as i32, CAP_BLOCK))
}
