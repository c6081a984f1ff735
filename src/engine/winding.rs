//! `fill=winding`: a voxel is solid iff |w| ≥ ½ at its centre, w the generalised winding number of
//! the mesh (the sum of the signed solid angles of its triangles over 4π; Barill et al. 2018).
//! |w| rather than w, so that a mesh whose triangles all face inwards gives the same solid.
//!
//! Three parts make it fast without giving up the definition:
//!
//! 1. **Exact integer part.** The boundary of the mesh, taken as a chain (each edge counted +1 in
//!    the direction a triangle uses it, −1 in the other, on positions merged by exact equality), is
//!    a set of closed cycles. A fan of *cap* triangles from each cycle's centroid closes it, so the
//!    mesh plus its caps is a closed chain, whose winding number at a voxel centre is an integer N:
//!    the signed count of crossings of the ray towards −z, computed by the `solid` kernel with signs
//!    (same lattice, same tie rules; [`crate::engine::cpu`]). The mesh's own winding number is
//!    `w = N − w_caps`. A watertight mesh has no caps: every voxel is decided by N, exactly.
//! 2. **Intervals over blocks.** Super-blocks of 32×32×32 voxels are tried whole by the caps'
//!    interval (below), then, where that fails, blocks of 8×8×8 voxels (split into eight, down to 2×2×2
//!    blocks, which go voxel by voxel, below, where that fails) get an interval for w_caps: the hierarchy's value at the block's centre
//!    plus a bound on how far w_caps can move over the block (below) and a margin of
//!    `MARGIN` for the hierarchy's error. If it holds no half-integer, k − ½ < w_caps < k + ½
//!    for one integer k and, N being an integer, |w| ≥ ½ ⇔ N ≠ k for every voxel of the block
//!    (k = 0 where the cheap bound Σ area / (distance − radius)² alone proves |w_caps| < 0.45:
//!    "exact"). An 8³ or 4³ block that cuts a cap but misses the mesh's own triangles gets the same
//!    kind of interval for w itself (from the hierarchy over the mesh); if it excludes ±½ the whole block
//!    is inside or outside. The variation bounds: wherever a surface's winding number is smooth
//!    (off its triangles), its gradient is the Biot–Savart field of its boundary over 4π, and
//!    the mesh and its caps share one boundary chain, so |∇w| ≤ ∮ |dl| / 4πr² over the chain's
//!    edges (`EdgeTree`: near segments by their exact field, summed as vectors so that the two
//!    sides of a crack cancel; far clusters by a first-order expansion bound); where that is too
//!    coarse, per triangle, |∇Ω| ≤ 2·area/r³ (`WindingTree::spread`).
//! 3. **Fast winding numbers per voxel.** The voxels left (near a cap where the interval is
//!    too wide: the rims of holes, and where w_caps is close to a half-integer) get w_caps from
//!    Barill et al.'s hierarchy: a bounding volume hierarchy over the triangles, each node
//!    carrying the Taylor expansion of its triangles' dipole field about its area-weighted centre
//!    up to second order (the area-weighted normal sum, the first moment matrix and the second
//!    moment tensor); a node is used through its expansion when the query is farther than β = 2
//!    node radii from its centre, and its triangles are summed exactly (Van Oosterom–Strackee
//!    solid angles) otherwise; nodes proven to subtend less than `SMALL` enter as ± that
//!    bound (re-evaluated in full where that leaves the voxel open). A voxel within 1/100 voxel
//!    of a cap triangle gets the mesh's own winding number.
//!
//!    Most such voxels (the shell around the caps of a mesh with many holes) are decided first,
//!    2×2×2 at a time, by a Taylor model (`Certifier::taylor_voxels`): the cap triangles within
//!    `TAYLOR_NEAR` block radii are summed exactly per voxel, the rest enter through their
//!    value at the block's centre (the hierarchy), their gradient there (the Biot–Savart field
//!    of their boundary: the chain's, less the near triangles' edges) and a bound on the
//!    second-order remainder (|∇∇Ω| ≤ 6·area/r⁴ per triangle); a voxel whose interval, widened
//!    by `MARGIN`, holds no half-integer gets its k from it, the others the evaluation above.
//!
//! Decisions are kept per block (one code: N ≠ k, all in, all out, or per-voxel codes for that
//! block only), so memory grows with the blocks near caps, not with the grid. A block's decision
//! can differ from the exact winding number's only where the hierarchy's error at its centre
//! exceeds the margin; a voxel's only where |w| is within the hierarchy's error of ½.
//!
//! The eight 2³ blocks of a 4³ block left open are taken together: one traversal of the caps'
//! tree gives all eight intervals (`WindingTree::spread_lanes`), one more the Taylor models of
//! those still open (`WindingTree::taylor_lanes`), one of the chain their fields
//! (`EdgeTree::field_lanes`); a node is opened for the balls that need it and taken through
//! its children by the others, which bounds them as well. The eight 4³ blocks of an open 8³
//! block get their caps' intervals the same way. The solid angles, distances, expansions and
//! the bounds built on them are computed eight at a time ([`super::lanes`]).
//!
//! Both parts run on the CPU; the signed counts use the same integer crossing rule as `solid`.

use std::f64::consts::PI;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::lanes::{self, Far, LANES};
use super::snap::snapped_world;
use super::{EngineError, GridMesh};
use crate::cancel::{Canceled, Control};
use crate::grid::Grid;
use crate::mesh::{Mesh, merged_ids};
use crate::volume::BitVolume;

/// Barill et al.'s accuracy parameter: expansions are used beyond β node radii.
pub const BETA: f64 = 2.0;
/// Leaves hold at most this many triangles.
const LEAF: usize = 8;
const _: () = assert!(LEAF <= LANES, "a leaf's triangles fit the lanes");
/// Voxels are decided by the integer part where |w_caps| is proven below this.
const CAP_LIMIT: f64 = 0.45;
/// Edge of the voxel blocks certified at once.
const BLOCK: u32 = 8;
/// Blocks are first tried `SUPER`³ at a time (32³ voxels): most of a grid lies far from the
/// caps, where one interval decides them all.
const SUPER: u32 = 4;
/// Added to every block's interval (in units of w) for the hierarchy's approximation error at
/// the block's centre (about 10⁻³; see the tests).
const MARGIN: f64 = 0.02;
/// A node (or triangle) whose solid angle is proven below this (in units of w) anywhere in a
/// block or at a voxel enters as ± that bound instead of being evaluated, up to `SMALL_BUDGET`
/// in all per query.
const SMALL: f64 = 1e-3;
const SMALL_BUDGET: f64 = 0.05;
/// Voxels within this many voxel sizes of a cap triangle are ties (decided by the mesh's own
/// winding number), and blocks that near a triangle are split.
const TIE: f64 = 0.01;
/// The Taylor model of a 2³ block ([`WindingTree::taylor`]) sums the cap triangles within this
/// many block radii of the block exactly at each voxel.
const TAYLOR_NEAR: f64 = 10.0;
/// Boundary clusters farther than this many radii from a query enter the field by their
/// expansion ([`EdgeTree::field`]).
const FIELD_OPEN: f64 = 4.0;

/// How the voxels of a winding fill were decided.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct WindingStats {
    /// Triangles added to close the mesh's boundary cycles.
    pub cap_triangles: u64,
    /// Voxels decided by the exact crossing count alone (|w_caps| < 0.45 proven by the bound
    /// Σ area / (distance − radius)² over the block or voxel).
    pub exact_voxels: u64,
    /// Voxels decided a block at a time by the crossing count against an integer k: the
    /// interval of the caps' winding number over the block (the hierarchy at its centre ± a
    /// bound on its variation and a margin) contains no half-integer, and inside ⇔ N ≠ k.
    #[serde(default)]
    pub cap_block_voxels: u64,
    /// Voxels decided a block at a time by the mesh's own winding number: its interval over the
    /// block (away from the mesh's triangles) excludes ±½.
    #[serde(default)]
    pub mesh_block_voxels: u64,
    /// Voxels decided one by one by the crossing count minus the caps' winding number
    /// (hierarchy).
    pub cap_evaluated_voxels: u64,
    /// Voxels within a hundredth of a voxel of a cap triangle, decided by the mesh's own winding
    /// number (exact sums, or the hierarchy over the mesh when there are many).
    pub mesh_evaluated_voxels: u64,
    /// Voxels decided one by one by the crossing count minus the caps' winding number as the
    /// exact sum over the cap triangles near their small block plus an interval for the rest.
    #[serde(default)]
    pub near_evaluated_voxels: u64,
}

impl WindingStats {
    /// Every voxel is counted once.
    pub fn voxels(&self) -> u64 {
        self.exact_voxels
            + self.cap_block_voxels
            + self.mesh_block_voxels
            + self.cap_evaluated_voxels
            + self.mesh_evaluated_voxels
            + self.near_evaluated_voxels
    }
}

/// The solid of `mesh` on `grid` under `fill=winding`.
pub fn solid(mesh: &Mesh, grid: &Grid) -> Result<(BitVolume, WindingStats), EngineError> {
    solid_with(mesh, grid, &Control::none())
}

/// [`solid`], checking `ctl` per column of blocks while certifying, per tie voxel after, and per
/// band and x-row while counting, and reporting progress there.
pub fn solid_with(
    mesh: &Mesh,
    grid: &Grid,
    ctl: &Control,
) -> Result<(BitVolume, WindingStats), EngineError> {
    solid_impl(mesh, grid, ctl, true)
}

/// How the voxels of one `BLOCK`³ block are decided.
#[derive(Clone, Copy, Debug)]
enum Block {
    /// Inside ⇔ N ≠ k.
    Ne(i32),
    /// All inside, or all outside.
    Is(bool),
    /// Per voxel: the codes of `mixed[i]`.
    Mixed(u32),
}

/// Codes of the voxels of a mixed block, x-major: a value k means inside ⇔ N ≠ k, else one of
/// these three.
type Codes = [i8; (BLOCK * BLOCK * BLOCK) as usize];
const V_OUT: i8 = i8::MIN;
const V_IN: i8 = i8::MIN + 1;
/// A tie, to be replaced by `V_IN` or `V_OUT` from the mesh's own winding number.
const V_TIE: i8 = i8::MIN + 2;
/// The largest |k| a code holds (larger ones are ties).
const K_MAX: f64 = 100.0;

/// Indices of the statistics' voxel counts.
const EXACT: usize = 0;
const CAP_BLOCK: usize = 1;
const MESH_BLOCK: usize = 2;
const CAP_EVAL: usize = 3;
const MESH_EVAL: usize = 4;
const NEAR_EVAL: usize = 5;

/// The certification of blocks: trees, grid, and what a column of blocks found.
struct Certifier<'a> {
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
struct Column {
    blocks: Vec<Block>,
    mixed: Vec<Codes>,
    ties: Vec<[u32; 3]>,
    counts: [u64; 6],
}

/// A block's or voxel's decision.
#[derive(Clone, Copy)]
enum Decision {
    Ne(i32, usize),
    Is(bool),
    Tie,
}

impl<'a> Certifier<'a> {
    fn new(grid: &'a Grid, trees: &'a Trees, blocks: bool) -> Certifier<'a> {
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
    fn decide_super(&self, lo: [u32; 3]) -> Option<Decision> {
        self.super_interval(lo).and_then(caps_decision)
    }

    /// The caps' interval ([`bounded`]) over the `SUPER`³ blocks at voxel `lo`.
    fn super_interval(&self, lo: [u32; 3]) -> Option<(f64, f64, f64)> {
        let (c, rb) = self.ball(lo, SUPER * BLOCK);
        self.interval(self.caps, self.cap_edges, c, rb).0
    }

    /// Decides the block column `(bx, by)`'s blocks `bz0..bz1` into `col`, each as `decision`
    /// where a super-block's decision is given, else one by one ([`Self::block`]).
    fn blocks(
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
    fn super_blocks(
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

/// Bit j set where `inside(j, run[j])`, for the (at most 64) counts of `run`.
#[inline(always)]
fn run_bits(run: &[i32], inside: impl Fn(usize, i32) -> bool) -> u64 {
    run.iter()
        .enumerate()
        .fold(0, |m, (j, &n)| m | (u64::from(inside(j, n)) << j))
}

/// A voxel's index in its block's codes.
fn local([x, y, z]: [u32; 3]) -> usize {
    (((x % BLOCK) * BLOCK + y % BLOCK) * BLOCK + z % BLOCK) as usize
}

/// The mesh closed by its caps ([`closing_caps`]: their apexes follow the mesh's positions, their
/// triangles its triangles), and the caps.
fn closed_by_caps(mesh: &Mesh) -> (Mesh, Vec<[u32; 3]>) {
    let (apexes, caps) = closing_caps(mesh);
    let mut positions = mesh.positions().to_vec();
    positions.extend_from_slice(&apexes);
    let mut triangles = mesh.triangles().to_vec();
    triangles.extend_from_slice(&caps);
    let closed = Mesh::new(positions, triangles).expect("caps index the mesh's own positions");
    (closed, caps)
}

/// The hierarchies the certification reads: over the caps and over the mesh, and over the
/// boundary chain on each one's positions.
struct Trees {
    caps: WindingTree,
    mesh: WindingTree,
    cap_edges: EdgeTree,
    mesh_edges: EdgeTree,
}

impl Trees {
    /// `closed` and `caps` from [`closed_by_caps`].
    fn new(mesh: &Mesh, closed: &Mesh, caps: &[[u32; 3]], grid: &Grid) -> Trees {
        // The caps exactly as the crossing count sees them: on the 1/256-voxel lattice.
        let cap_positions: Vec<[f64; 3]> = closed
            .positions()
            .iter()
            .map(|&p| snapped_world(grid, p))
            .collect();
        // Degenerate caps (fans over collinear edges; many where the mesh has degenerate
        // triangles) subtend nothing and their boundaries add nothing to the Biot–Savart field
        // (a closed path along a line), so neither the tree nor the bound needs them. The
        // crossing count has none either: they cover no column.
        let live = |p: &[[f64; 3]]| -> Vec<[u32; 3]> {
            caps.iter()
                .filter(|t| norm(area_normal(&t.map(|i| p[i as usize]))) > 0.0)
                .copied()
                .collect()
        };
        let snapped_caps = live(&cap_positions);
        let (cap_tree, mesh_tree) = rayon::join(
            || WindingTree::new(&cap_positions, &snapped_caps),
            || WindingTree::new(mesh.positions(), mesh.triangles()),
        );
        let segments = |p: &[[f64; 3]], caps: &[[u32; 3]]| {
            let segs = chain_boundary(caps)
                .iter()
                .map(|e| e.map(|i| p[i as usize]))
                .collect();
            EdgeTree::new(segs)
        };
        Trees {
            caps: cap_tree,
            mesh: mesh_tree,
            cap_edges: segments(&cap_positions, &snapped_caps),
            mesh_edges: segments(closed.positions(), &live(closed.positions())),
        }
    }
}

/// [`solid_with`]; `blocks` off decides every voxel near the caps one by one (the tests compare).
fn solid_impl(
    mesh: &Mesh,
    grid: &Grid,
    ctl: &Control,
    blocks: bool,
) -> Result<(BitVolume, WindingStats), EngineError> {
    // Shares of the progress: certifying blocks (and evaluating the voxels that need it), the
    // tie voxels, the counting pass.
    let (certify, ties, count) = (
        ctl.stage(0.0, 0.8),
        ctl.stage(0.8, 0.85),
        ctl.stage(0.85, 1.0),
    );
    let (closed, caps) = closed_by_caps(mesh);
    let gm = GridMesh::new(&closed, grid)?;
    let centre = |[x, y, z]: [u32; 3]| grid.voxel_center(x, y, z);
    let nb = grid.dims.map(|d| d.div_ceil(BLOCK));
    let mut counts = [0u64; 6];
    let mut block_codes: Vec<Block> = Vec::new();
    let mut mixed: Vec<Codes> = Vec::new();
    ctl.check()?;
    if caps.is_empty() {
        // Closed: N is the winding number.
        counts[EXACT] = grid.voxel_count();
    } else {
        let trees = Trees::new(mesh, &closed, &caps, grid);
        let mesh_tree = &trees.mesh;
        let cert = Certifier::new(grid, &trees, blocks);
        let block_columns = nb[0] * nb[1];
        let certified = certify.counter(block_columns as u64);
        // Super-blocks (with `blocks` on): columns of them in parallel, each deciding its
        // columns of blocks, which are then put in order (x-major, as the counting pass reads
        // them).
        let sup = if blocks { SUPER } else { 1 };
        let ns = nb.map(|n| n.div_ceil(sup));
        let supers: Vec<Vec<([u32; 2], Column)>> = (0..ns[0] * ns[1])
            .into_par_iter()
            .map(|c| {
                certified.check()?;
                let (sx, sy) = (c / ns[1], c % ns[1]);
                let bxs = sx * sup..((sx + 1) * sup).min(nb[0]);
                let bys = sy * sup..((sy + 1) * sup).min(nb[1]);
                let mut cols: Vec<([u32; 2], Column)> = bxs
                    .clone()
                    .flat_map(|bx| bys.clone().map(move |by| ([bx, by], Column::default())))
                    .collect();
                for sz in 0..ns[2] {
                    let bz = sz * sup..((sz + 1) * sup).min(nb[2]);
                    let decision = (sup > 1)
                        .then(|| cert.decide_super([sx, sy, sz].map(|v| v * sup * BLOCK)))
                        .flatten();
                    if decision.is_none() && sup > 1 {
                        cert.super_blocks(bxs.clone(), bys.clone(), bz, &mut cols);
                        continue;
                    }
                    for (b, col) in &mut cols {
                        cert.blocks(*b, bz.clone(), decision, col);
                    }
                }
                certified.add(cols.len() as u64);
                Ok(cols)
            })
            .collect::<Result<_, Canceled>>()?;
        let mut columns: Vec<Column> = (0..block_columns).map(|_| Column::default()).collect();
        for ([bx, by], col) in supers.into_iter().flatten() {
            columns[(bx * nb[1] + by) as usize] = col;
        }
        certify.complete();
        block_codes.reserve(nb.iter().map(|&n| n as usize).product());
        let mut deferred = Vec::new();
        for col in columns {
            let base = mixed.len() as u32;
            block_codes.extend(col.blocks.iter().map(|&b| match b {
                Block::Mixed(i) => Block::Mixed(base + i),
                b => b,
            }));
            mixed.extend(col.mixed);
            deferred.extend(col.ties);
            for (t, c) in counts.iter_mut().zip(col.counts) {
                *t += c;
            }
        }
        // Voxels at a cap's tie: the mesh's own winding number. A few: exact sums over the mesh;
        // many: the hierarchy over it, eight neighbours (in the order the blocks found them) at a
        // time.
        let tris = mesh.triangles().len();
        let tied = ties.counter(deferred.len() as u64);
        let exact = (deferred.len() as u64) * (tris as u64) < 2_000_000;
        let winding: Vec<f64> = deferred
            .par_chunks(LANES)
            .map(|chunk| {
                tied.check()?;
                let w: Vec<f64> = if exact {
                    chunk
                        .iter()
                        .map(|&v| {
                            exact_winding_number((0..tris).map(|t| mesh.triangle(t)), centre(v))
                        })
                        .collect()
                } else {
                    let qs = std::array::from_fn(|i| centre(chunk[i.min(chunk.len() - 1)]));
                    mesh_tree.winding_numbers(&qs)[..chunk.len()].to_vec()
                };
                tied.add(chunk.len() as u64);
                Ok(w)
            })
            .collect::<Result<Vec<_>, Canceled>>()?
            .concat();
        for (&v, w) in deferred.iter().zip(winding) {
            let b = v.map(|c| c / BLOCK);
            let Block::Mixed(i) = block_codes[((b[0] * nb[1] + b[1]) * nb[2] + b[2]) as usize]
            else {
                unreachable!("a tie lies in a mixed block");
            };
            mixed[i as usize][local(v)] = if w.abs() >= 0.5 { V_IN } else { V_OUT };
        }
    }
    ties.complete();
    let [_, ny, nz] = grid.dims;
    let wpc = nz.div_ceil(64) as usize;
    let vol = crate::engine::cpu::signed_crossings(&gm, &count, |x, crossings, words| {
        // Stopped: the row is left empty and the pass fails below.
        if count.check().is_err() {
            return;
        }
        let bx = x / BLOCK;
        let mut run = [0i32; BLOCK as usize];
        for y in 0..ny {
            let out = &mut words[y as usize * wpc..(y as usize + 1) * wpc];
            let row = ((bx * nb[1] + y / BLOCK) * nb[2]) as usize;
            let mut col = crossings.column(y).iter().peekable();
            // The signed count N at the voxel being looked at.
            let mut n = 0;
            // A block's voxels of one column at a time: one code, and (64 being a multiple of
            // BLOCK) one word.
            for z0 in (0..nz).step_by(BLOCK as usize) {
                let len = (nz - z0).min(BLOCK) as usize;
                let all = u64::MAX >> (64 - len);
                while let Some(&(_, s)) = col.next_if(|&&(k, _)| k as u32 <= z0) {
                    n += s;
                }
                // No crossing within the block: N is the same at all its voxels.
                let flat = col
                    .peek()
                    .is_none_or(|&&(k, _)| k as u32 >= z0 + len as u32);
                let code = block_codes.get(row + (z0 / BLOCK) as usize);
                let bits = match (flat, code) {
                    (true, None) => all * u64::from(n != 0),
                    (true, Some(&Block::Ne(k))) => all * u64::from(n != k),
                    (_, Some(&Block::Is(inside))) => all * u64::from(inside),
                    _ => {
                        let run = &mut run[..len];
                        for (z, count) in (z0..).zip(run.iter_mut()) {
                            while let Some(&(_, s)) = col.next_if(|&&(k, _)| k as u32 <= z) {
                                n += s;
                            }
                            *count = n;
                        }
                        let run = &*run;
                        match code {
                            None => run_bits(run, |_, n| n != 0),
                            Some(&Block::Ne(k)) => run_bits(run, |_, n| n != k),
                            Some(&Block::Is(_)) => unreachable!("decided above"),
                            Some(&Block::Mixed(i)) => {
                                let codes = &mixed[i as usize];
                                run_bits(run, |j, n| match codes[local([x, y, z0 + j as u32])] {
                                    V_OUT => false,
                                    V_IN => true,
                                    k => n != k as i32,
                                })
                            }
                        }
                    }
                };
                out[z0 as usize / 64] |= bits << (z0 % 64);
            }
        }
    })?;
    // A row skipped because the work was stopped must not pass for a finished one.
    ctl.check()?;
    ctl.complete();
    Ok((
        vol,
        WindingStats {
            cap_triangles: caps.len() as u64,
            exact_voxels: counts[EXACT],
            cap_block_voxels: counts[CAP_BLOCK],
            mesh_block_voxels: counts[MESH_BLOCK],
            cap_evaluated_voxels: counts[CAP_EVAL],
            mesh_evaluated_voxels: counts[MESH_EVAL],
            near_evaluated_voxels: counts[NEAR_EVAL],
        },
    ))
}

/// Triangles (and their apex positions, to be appended after the mesh's positions) whose boundary
/// is minus the mesh's boundary chain: each boundary cycle is capped by [`cap_cycle`].
pub fn closing_caps(mesh: &Mesh) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let ids = merged_ids(mesh);
    // One representative position index per merged id.
    let mut rep = vec![u32::MAX; ids.iter().copied().max().map_or(0, |m| m as usize + 1)];
    for (i, &id) in ids.iter().enumerate() {
        if rep[id as usize] == u32::MAX {
            rep[id as usize] = i as u32;
        }
    }
    // Directed edges as (low, high, ±1), summed per undirected edge.
    let mut edges: Vec<(u64, i32)> = mesh
        .triangles()
        .par_iter()
        .flat_map_iter(|t| {
            let m = t.map(|i| ids[i as usize]);
            [(m[0], m[1]), (m[1], m[2]), (m[2], m[0])]
                .into_iter()
                .filter(|(a, b)| a != b)
                .map(|(a, b)| {
                    let key = ((a.min(b) as u64) << 32) | a.max(b) as u64;
                    (key, if a < b { 1 } else { -1 })
                })
        })
        .collect();
    edges.par_sort_unstable_by_key(|e| e.0);
    // The boundary chain as directed edges with multiplicity, in an adjacency list.
    let mut out: std::collections::HashMap<u32, Vec<u32>> = std::collections::HashMap::new();
    let mut remaining = 0usize;
    for run in edges.chunk_by(|a, b| a.0 == b.0) {
        let net: i32 = run.iter().map(|e| e.1).sum();
        let (lo, hi) = ((run[0].0 >> 32) as u32, run[0].0 as u32);
        let (from, to) = if net > 0 { (lo, hi) } else { (hi, lo) };
        for _ in 0..net.unsigned_abs() {
            out.entry(from).or_default().push(to);
            remaining += 1;
        }
    }
    let positions = mesh.positions();
    let (mut apexes, mut caps) = (Vec::new(), Vec::new());
    let mut starts: Vec<u32> = out.keys().copied().collect();
    starts.sort_unstable();
    // Every vertex of a cycle (a chain's boundary) has as many edges in as out, so a walk along
    // unused edges from a vertex always returns to it.
    for s in starts {
        while out.get(&s).is_some_and(|v| !v.is_empty()) {
            let mut cycle = vec![s];
            let mut v = s;
            loop {
                let next = out
                    .get_mut(&v)
                    .and_then(|e| e.pop())
                    .expect("balanced cycle");
                remaining -= 1;
                if next == s {
                    break;
                }
                cycle.push(next);
                v = next;
            }
            let cycle: Vec<u32> = cycle.iter().map(|&v| rep[v as usize]).collect();
            cap_cycle(&cycle, positions, &mut apexes, &mut caps);
        }
    }
    debug_assert_eq!(remaining, 0);
    (apexes, caps)
}

/// Caps a cycle of position indices (edges `cycle[i] → cycle[i + 1]`, the last back to the
/// first) with triangles whose boundary is minus the cycle. A long cycle is not fanned from one
/// point (its long, thin triangles would make every nearby query expensive): it is cut into chunks
/// of `CHUNK` consecutive edges, each chunk plus the chord back to its start is fanned from its
/// own centroid, and the cycle of chords (`CHUNK` times shorter) is capped the same way. The fans
/// give −(chunk edges) + (chords), the chords' cap −(chords): −(cycle) in total, with triangles
/// about as large as the features they span.
fn cap_cycle(
    cycle: &[u32],
    positions: &[[f64; 3]],
    apexes: &mut Vec<[f64; 3]>,
    caps: &mut Vec<[u32; 3]>,
) {
    const CHUNK: usize = 8;
    let n = cycle.len();
    let mut fan = |poly: &[u32], apexes: &mut Vec<[f64; 3]>| {
        // A cycle of two vertices (a→b→a) bounds nothing.
        if poly.len() < 3 {
            return;
        }
        let mut c = [0.0; 3];
        for &v in poly {
            let p = positions[v as usize];
            for a in 0..3 {
                c[a] += p[a] / poly.len() as f64;
            }
        }
        let apex = (positions.len() + apexes.len()) as u32;
        apexes.push(c);
        for (i, &a) in poly.iter().enumerate() {
            let b = poly[(i + 1) % poly.len()];
            // Edge a→b closed by the cap triangle (apex, b, a).
            caps.push([apex, b, a]);
        }
    };
    if n <= CHUNK {
        fan(cycle, apexes);
        return;
    }
    let mut coarse = Vec::with_capacity(n.div_ceil(CHUNK));
    for start in (0..n).step_by(CHUNK) {
        let end = (start + CHUNK).min(n);
        let poly: Vec<u32> = (start..=end).map(|i| cycle[i % n]).collect();
        fan(&poly, apexes);
        coarse.push(cycle[start]);
    }
    cap_cycle(&coarse, positions, apexes, caps);
}

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

/// Barill et al.'s hierarchy over a triangle set.
pub struct WindingTree {
    nodes: Vec<Node>,
    /// Triangles in leaf order.
    tris: Vec<[[f64; 3]; 3]>,
    /// Their areas.
    areas: Vec<f64>,
    /// Each leaf's triangles lane by lane (a leaf node's `right`).
    leaves: Vec<lanes::Leaf>,
}

#[derive(Clone, Debug)]
struct Node {
    /// Area-weighted centroid of the node's triangles (the expansion point).
    centre: [f64; 3],
    /// Every point of every triangle of the node lies within this distance of `centre`.
    radius: f64,
    /// Σ triangle areas.
    area: f64,
    /// Leaf: triangle range; inner node: `first` is the left child, `count` 0 and `right` the
    /// right child.
    first: u32,
    count: u32,
    right: u32,
    /// The moments as [`far_field`] uses them.
    far: Far,
}

/// A node's moments about its centre, kept while the tree is built (a parent's are its
/// children's, moved).
#[derive(Clone, Debug, Default)]
struct Moments {
    /// Σ area·normal.
    n1: [f64; 3],
    /// Σ_t (area·normal)_i (centroid − centre)_j.
    m: [[f64; 3]; 3],
    /// Σ_t normal_i ∫_t (x − centre)_j (x − centre)_k dA, (j, k) in order xx yy zz xy xz yz.
    c: [[f64; 6]; 3],
}

/// A node's moments folded for evaluation ([`lanes::Far`]).
#[allow(clippy::needless_range_loop)] // index notation of the moment formulas
fn folded(moments: &Moments) -> Far {
    let Moments { n1, m, c } = moments;
    let n1 = *n1;
    let mut far = Far {
        n1,
        tr: m[0][0] + m[1][1] + m[2][2],
        ..Far::default()
    };
    for (e, &(i, j)) in SYM.iter().enumerate() {
        let sym = if i == j { m[i][i] } else { m[i][j] + m[j][i] };
        far.m[e] = 3.0 * sym;
    }
    for i in 0..3 {
        let full = sym_full(&c[i]);
        for k in 0..3 {
            far.w[k] += 1.5 * (2.0 * full[i][k]);
        }
        far.w[i] += 1.5 * (full[0][0] + full[1][1] + full[2][2]);
        for e in 0..6 {
            far.c[i][e] = 7.5 * if e < 3 { c[i][e] } else { 2.0 * c[i][e] };
        }
    }
    far
}

const SYM: [(usize, usize); 6] = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)];

impl WindingTree {
    pub fn new(positions: &[[f64; 3]], triangles: &[[u32; 3]]) -> WindingTree {
        let mut tris: Vec<[[f64; 3]; 3]> = triangles
            .par_iter()
            .map(|t| t.map(|i| positions[i as usize]))
            .collect();
        let mut nodes = Vec::with_capacity(2 * tris.len() / LEAF + 2);
        if !tris.is_empty() {
            build(&mut nodes, &mut Vec::new(), &mut tris, 0);
        }
        let areas: Vec<f64> = tris.iter().map(|t| norm(area_normal(t))).collect();
        let mut leaves = Vec::new();
        for n in nodes.iter_mut().filter(|n| n.count > 0) {
            n.right = leaves.len() as u32;
            let range = n.first as usize..(n.first + n.count) as usize;
            leaves.push(lanes::Leaf::new(&tris[range.clone()], &areas[range]));
        }
        WindingTree {
            nodes,
            tris,
            areas,
            leaves,
        }
    }

    /// The generalised winding number at q, exact near q and expanded far from it.
    pub fn winding_number(&self, q: [f64; 3]) -> f64 {
        self.evaluate(q, -1.0).expect("no plane check")
    }

    /// [`Self::winding_number`] at eight points, from one traversal ([`spread_lanes`] over
    /// balls of radius 0, which opens and expands each point's nodes as `winding_number` does).
    fn winding_numbers(&self, qs: &[[f64; 3]; LANES]) -> [f64; LANES] {
        let at = spread_lanes(
            self,
            qs,
            0.0,
            f64::NEG_INFINITY,
            &[f64::INFINITY; LANES],
            0.0,
            &[false; LANES],
        );
        std::array::from_fn(|i| match at[i] {
            Some(t) => t.value / (4.0 * PI),
            // Only where a distance came out NaN: the plain traversal.
            None => self.winding_number(qs[i]),
        })
    }

    /// [`Self::winding_number`], or `None` when q lies within `eps` of a triangle summed exactly
    /// (where the sign of its solid angle is a tie to break by other means).
    pub fn winding_number_off_planes(&self, q: [f64; 3], eps: f64) -> Option<f64> {
        self.evaluate(q, eps)
    }

    fn evaluate(&self, q: [f64; 3], eps: f64) -> Option<f64> {
        if self.nodes.is_empty() {
            return Some(0.0);
        }
        let mut sum = 0.0;
        let mut stack = [0u32; 64];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let n = &self.nodes[stack[top] as usize];
            let r = sub(n.centre, q);
            let d2 = dot(r, r);
            if d2 > (BETA * n.radius).powi(2) {
                sum += far_field(n, r, d2);
            } else if n.count > 0 {
                let (angles, dist2) = lanes::leaf(&self.leaves[n.right as usize], q);
                for j in 0..n.count as usize {
                    if eps >= 0.0 && dist2[j] <= eps * eps {
                        return None;
                    }
                    sum += angles[j];
                }
            } else {
                stack[top] = n.first;
                stack[top + 1] = n.right;
                top += 2;
            }
        }
        Some(sum / (4.0 * PI))
    }

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
    fn spread(
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

    /// [`Self::spread`] over eight balls of radius `rq` at once (centres `qs`, each with its own
    /// `limit` and `by_area`), in one traversal: a node is opened for the balls that need it
    /// opened, and the others take it as `spread` would. A ball for which some other ball's need
    /// opens a node takes the node's children instead, which bound it as well; and the nodes
    /// left out as small are a different set, within the same budget. So each ball's result is a
    /// bound of the same kind, though not always the same numbers as its own traversal's.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn spread_lanes_body(
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
            let at = lanes::node_body::<true>(&n.far, n.centre, n.radius, n.area, rq, reach2, &q);
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
    fn taylor(
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

    /// [`Self::taylor`] for the balls of radius `rq` about `qs[i]`, for the lanes i in `lanes`,
    /// in one traversal (as [`spread_lanes`]: a node opened for one ball is taken through
    /// its children by the others, which model them as well).
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn taylor_lanes_body(
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
            let at = lanes::node_body::<false>(&n.far, n.centre, n.radius, n.area, rq, reach2, &q);
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

    /// Σ exact solid angles at q of the triangles `near` (with twice their areas), or `None`
    /// when one lies within `gap` of q.
    fn near_sum(&self, near: &[(u32, f64)], q: [f64; 3], gap: f64) -> Option<f64> {
        let mut sum = 0.0;
        for &(i, twice_area) in near {
            let t = &self.tris[i as usize];
            let [a, b, c] = t.map(|v| sub(v, q));
            let (det, den) = lanes::det_den(a, b, c);
            // det = twice the area × the signed distance from q to the triangle's plane, which
            // is at most the distance to the triangle: beyond twice gap (a factor 2 for
            // rounding), no tie. A NaN is a tie, as in `spread`.
            if det.abs() <= 2.0 * gap * twice_area || det.is_nan() {
                let d2 = dist2_to_triangle(q, t);
                if d2 <= gap * gap || d2.is_nan() {
                    return None;
                }
            }
            sum += 2.0 * lanes::atan2(det, den);
        }
        Some(sum)
    }

    /// Pushes the children of inner node `n`, the nearer to q on top (a triangle touching the
    /// query's ball is found soonest); a leaf's triangles are handled by the caller.
    fn open(&self, n: &Node, stack: &mut [u32; 64], top: &mut usize, q: [f64; 3]) {
        let (a, b) = (n.first, n.right);
        let dist2 = |i: u32| {
            let v = sub(self.nodes[i as usize].centre, q);
            dot(v, v)
        };
        let (near, far) = if dist2(a) <= dist2(b) { (a, b) } else { (b, a) };
        stack[*top] = far;
        stack[*top + 1] = near;
        *top += 2;
    }
}

// The traversals over eight points, each compiled for AVX-512, AVX2 and the baseline target
// with its kernels inlined (see [`super::lanes`]): the same operations in the same order on
// every path, so the same bits.
lanes::dispatch! {
    /// [`WindingTree::spread_lanes_body`], on the widest instruction set.
    #[allow(clippy::too_many_arguments)]
    fn spread_lanes(
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
    fn taylor_lanes(
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

lanes::dispatch! {
    /// [`EdgeTree::field_lanes_body`], on the widest instruction set.
    fn field_lanes(
        tree: &EdgeTree,
        qs: &[[f64; 3]; LANES],
        lanes: u32,
    ) -> [Option<([f64; 3], f64)>; LANES]
        = EdgeTree::field_lanes_body, field_lanes_avx512, field_lanes_avx2;
}

/// The lanes whose bits are set in `mask`, in order.
#[inline(always)]
fn lanes_of(mut mask: u32) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        (mask != 0).then(|| {
            let i = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            i
        })
    })
}

/// See [`WindingTree::taylor`]; in steradians.
#[derive(Clone, Copy, Debug, Default)]
struct Taylor {
    value: f64,
    /// Σ area/g⁴ over the triangles of the model.
    hessian: f64,
    /// Σ area/g² over the nodes left out of `value` as small.
    left_out: f64,
}

/// See [`WindingTree::spread`].
#[derive(Clone, Copy, Debug, Default)]
struct Spread {
    value: f64,
    spread: f64,
    crude: f64,
    /// The part of `spread` from nodes entered as ± their magnitude alone (left out of `value`).
    left_out: f64,
}

/// A hierarchy over segments (a boundary chain's edges, each as often as its multiplicity) that
/// bounds ∮ |dl| / r², the Biot–Savart bound on the gradient of the solid angle of any surface
/// the chain bounds: off the surface, ∇Ω(q) = ∮ dl × (x − q) / |x − q|³ over its boundary (the
/// edges inside cancel), so |∇Ω| ≤ ∮ |dl| / r². For the mesh and for its caps, whose boundaries
/// are the same chain, this bounds the gradient of their winding numbers wherever they are
/// smooth, however large or curved the surfaces.
struct EdgeTree {
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
    /// As [`Node`]: a leaf's range, or `first` the left child and `right` the right one.
    first: u32,
    count: u32,
    right: u32,
}

impl EdgeTree {
    fn new(segs: Vec<[[f64; 3]; 2]>) -> EdgeTree {
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
    fn bound(&self, q: [f64; 3], rq: f64, limit: f64) -> f64 {
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
    fn field(&self, q: [f64; 3]) -> Option<([f64; 3], f64)> {
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
    fn field_lanes_body(
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

/// The gradient of [`solid_angle`] at q: the Biot–Savart field of the triangle's boundary.
fn solid_angle_gradient(t: &[[f64; 3]; 3], q: [f64; 3]) -> [f64; 3] {
    let mut g = [0.0; 3];
    for i in 0..3 {
        g = add3(g, segment_field(&[t[i], t[(i + 1) % 3]], q));
    }
    g.map(|v| GRADIENT_SIGN * v)
}

/// ∇Ω = GRADIENT_SIGN × the Biot–Savart field of the boundary, for [`solid_angle`]'s sign.
const GRADIENT_SIGN: f64 = -1.0;

/// [`segment_field`], or `None` when q lies on the segment (where the field is infinite).
fn segment_field_off(s: &[[f64; 3]; 2], q: [f64; 3]) -> Option<[f64; 3]> {
    let (r1, r2) = (sub(s[0], q), sub(s[1], q));
    let (l1, l2) = (norm(r1), norm(r2));
    let den = l1 * l2 * (l1 * l2 + dot(r1, r2));
    (den > 0.0).then_some(())?;
    Some(segment_field(s, q))
}

/// ∫ dl × (x − q)/|x − q|³ along the segment (the Biot–Savart field of a straight piece).
fn segment_field(s: &[[f64; 3]; 2], q: [f64; 3]) -> [f64; 3] {
    let (r1, r2) = (sub(s[0], q), sub(s[1], q));
    let (l1, l2) = (norm(r1), norm(r2));
    let den = l1 * l2 * (l1 * l2 + dot(r1, r2));
    if den <= 0.0 {
        return [0.0; 3];
    }
    let f = (l1 + l2) / den;
    cross(r2, r1).map(|v| v * f)
}

/// The directed edges of the chain boundary of `tris` (indices into one position list, each
/// edge as often as its multiplicity).
fn chain_boundary(tris: &[[u32; 3]]) -> Vec<[u32; 2]> {
    let mut edges: Vec<(u64, i32)> = tris
        .iter()
        .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
        .filter(|(a, b)| a != b)
        .map(|(a, b)| {
            let key = ((a.min(b) as u64) << 32) | a.max(b) as u64;
            (key, if a < b { 1 } else { -1 })
        })
        .collect();
    edges.sort_unstable_by_key(|e| e.0);
    let mut out = Vec::new();
    for run in edges.chunk_by(|a, b| a.0 == b.0) {
        let net: i32 = run.iter().map(|e| e.1).sum();
        let (lo, hi) = ((run[0].0 >> 32) as u32, run[0].0 as u32);
        for _ in 0..net.unsigned_abs() {
            out.push(if net > 0 { [lo, hi] } else { [hi, lo] });
        }
    }
    out
}

/// Squared distance from p to the segment s.
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

/// 4π × the node's expanded winding number at q, with r = centre − q and d2 = |r|².
#[allow(clippy::needless_range_loop)] // index notation of the moment formulas
fn far_field(n: &Node, r: [f64; 3], d2: f64) -> f64 {
    lanes::far_one(&n.far, r, d2)
}

fn sym_full(c: &[f64; 6]) -> [[f64; 3]; 3] {
    [[c[0], c[3], c[4]], [c[3], c[1], c[5]], [c[4], c[5], c[2]]]
}

/// Builds the subtree over `tris` (which it reorders), its triangles starting at `offset`;
/// returns the node's index.
/// Builds the subtree over `tris` (their first index `offset`) into `nodes`, with each node's
/// moments at the same index of `moments`; returns its root's index.
fn build(
    nodes: &mut Vec<Node>,
    moments: &mut Vec<Moments>,
    tris: &mut [[[f64; 3]; 3]],
    offset: u32,
) -> u32 {
    let index = nodes.len() as u32;
    if tris.len() <= LEAF {
        let (node, m) = leaf(tris, offset);
        nodes.push(node);
        moments.push(m);
        return index;
    }
    // Median split of the centroids along the longest axis of their box.
    let cen = |t: &[[f64; 3]; 3]| [0, 1, 2].map(|a| (t[0][a] + t[1][a] + t[2][a]) / 3.0);
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for t in tris.iter() {
        let c = cen(t);
        for a in 0..3 {
            lo[a] = lo[a].min(c[a]);
            hi[a] = hi[a].max(c[a]);
        }
    }
    let axis = (0..3)
        .max_by(|&a, &b| (hi[a] - lo[a]).total_cmp(&(hi[b] - lo[b])))
        .unwrap_or(0);
    let mid = tris.len() / 2;
    tris.select_nth_unstable_by(mid, |a, b| cen(a)[axis].total_cmp(&cen(b)[axis]));
    // Placeholders, filled below.
    let (node, m) = leaf(&[], 0);
    nodes.push(node);
    moments.push(m);
    let (left, right) = tris.split_at_mut(mid);
    let l = build(nodes, moments, left, offset);
    let r = build(nodes, moments, right, offset + mid as u32);
    let (li, ri) = (l as usize, r as usize);
    let (node, m) = combine(
        [(&nodes[li], &moments[li]), (&nodes[ri], &moments[ri])],
        l,
        r,
    );
    nodes[index as usize] = node;
    moments[index as usize] = m;
    index
}

#[allow(clippy::needless_range_loop)] // index notation of the moment formulas
fn leaf(tris: &[[[f64; 3]; 3]], offset: u32) -> (Node, Moments) {
    let mut area = 0.0;
    let mut n1 = [0.0; 3];
    let mut weighted = [0.0; 3];
    let mut mean = [0.0; 3];
    for t in tris {
        let an = area_normal(t);
        let a = norm(an);
        area += a;
        for k in 0..3 {
            n1[k] += an[k];
            let c = (t[0][k] + t[1][k] + t[2][k]) / 3.0;
            weighted[k] += a * c;
            mean[k] += c / tris.len() as f64;
        }
    }
    let centre = if area > 0.0 {
        weighted.map(|w| w / area)
    } else {
        mean
    };
    let mut m = [[0.0; 3]; 3];
    let mut c = [[0.0; 6]; 3];
    let mut radius: f64 = 0.0;
    for t in tris {
        let an = area_normal(t);
        let y = t.map(|v| sub(v, centre));
        for v in &y {
            radius = radius.max(norm(*v));
        }
        let s = [0, 1, 2].map(|k| y[0][k] + y[1][k] + y[2][k]);
        for i in 0..3 {
            for j in 0..3 {
                m[i][j] += an[i] * s[j] / 3.0;
            }
            // n_i ∫ y_j y_k dA = (area·n)_i / 12 · (Σ_v y_v,j y_v,k + s_j s_k).
            for (e, &(j, k)) in SYM.iter().enumerate() {
                let second: f64 = y.iter().map(|v| v[j] * v[k]).sum::<f64>() + s[j] * s[k];
                c[i][e] += an[i] * second / 12.0;
            }
        }
    }
    let moments = Moments { n1, m, c };
    let node = Node {
        centre,
        radius,
        area,
        first: offset,
        count: tris.len() as u32,
        right: 0,
        far: folded(&moments),
    };
    (node, moments)
}

/// The parent of two nodes: moments moved to the parent's centre (d = child centre − centre):
/// M += n1 ⊗ d, C_ijk += d_j M_ik + d_k M_ij + d_j d_k n1_i.
#[allow(clippy::needless_range_loop)] // index notation of the moment formulas
fn combine(children: [(&Node, &Moments); 2], li: u32, ri: u32) -> (Node, Moments) {
    let [(l, _), (r, _)] = children;
    let area = l.area + r.area;
    let centre = if area > 0.0 {
        [0, 1, 2].map(|k| (l.centre[k] * l.area + r.centre[k] * r.area) / area)
    } else {
        [0, 1, 2].map(|k| 0.5 * (l.centre[k] + r.centre[k]))
    };
    let mut radius: f64 = 0.0;
    let mut out = Moments::default();
    for (ch, chm) in children {
        let d = sub(ch.centre, centre);
        radius = radius.max(norm(d) + ch.radius);
        for i in 0..3 {
            out.n1[i] += chm.n1[i];
            for j in 0..3 {
                out.m[i][j] += chm.m[i][j] + chm.n1[i] * d[j];
            }
            for (e, &(j, k)) in SYM.iter().enumerate() {
                out.c[i][e] +=
                    chm.c[i][e] + d[j] * chm.m[i][k] + d[k] * chm.m[i][j] + d[j] * d[k] * chm.n1[i];
            }
        }
    }
    let node = Node {
        centre,
        radius,
        area,
        first: li,
        count: 0,
        right: ri,
        far: folded(&out),
    };
    (node, out)
}

/// Area × unit normal (half the cross product).
fn area_normal(t: &[[f64; 3]; 3]) -> [f64; 3] {
    cross(sub(t[1], t[0]), sub(t[2], t[0])).map(|v| 0.5 * v)
}

/// Squared distance from p to a triangle (Ericson, *Real-Time Collision Detection*, 5.1.5).
pub(crate) fn dist2_to_triangle(p: [f64; 3], t: &[[f64; 3]; 3]) -> f64 {
    let [a, b, c] = *t;
    let at = |u: f64, v: f64| [0, 1, 2].map(|i| a[i] + u * (b[i] - a[i]) + v * (c[i] - a[i]));
    let d = |q: [f64; 3]| dot(sub(p, q), sub(p, q));
    let (ab, ac, ap) = (sub(b, a), sub(c, a), sub(p, a));
    let (d1, d2) = (dot(ab, ap), dot(ac, ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return d(a);
    }
    let bp = sub(p, b);
    let (d3, d4) = (dot(ab, bp), dot(ac, bp));
    if d3 >= 0.0 && d4 <= d3 {
        return d(b);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return d(at(d1 / (d1 - d3), 0.0));
    }
    let cp = sub(p, c);
    let (d5, d6) = (dot(ab, cp), dot(ac, cp));
    if d6 >= 0.0 && d5 <= d6 {
        return d(c);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return d(at(0.0, d2 / (d2 - d6)));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return d([0, 1, 2].map(|i| b[i] + w * (c[i] - b[i])));
    }
    let den = 1.0 / (va + vb + vc);
    d(at(vb * den, vc * den))
}

fn add3(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn octahedron() -> Mesh {
        let p = vec![
            [1.0, 0.0, 0.0],
            [-1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, -1.0, 0.0],
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
        ];
        let t = vec![
            [0, 2, 4],
            [2, 1, 4],
            [1, 3, 4],
            [3, 0, 4],
            [2, 0, 5],
            [1, 2, 5],
            [3, 1, 5],
            [0, 3, 5],
        ];
        Mesh::new(p, t).unwrap()
    }

    /// A bumpy open surface of many triangles: a height field over [0, 1]².
    fn sheet(n: u32) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
        let mut p = Vec::new();
        for i in 0..=n {
            for j in 0..=n {
                let (x, y) = (i as f64 / n as f64, j as f64 / n as f64);
                p.push([x, y, 0.1 * (7.0 * x).sin() * (5.0 * y).cos()]);
            }
        }
        let mut t = Vec::new();
        let id = |i: u32, j: u32| i * (n + 1) + j;
        for i in 0..n {
            for j in 0..n {
                t.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
                t.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
        (p, t)
    }

    #[test]
    fn exact_winding_of_a_closed_mesh() {
        let m = octahedron();
        let tris = || (0..m.triangles().len()).map(|t| m.triangle(t));
        assert!((exact_winding_number(tris(), [0.1, 0.2, 0.1]) - 1.0).abs() < 1e-12);
        assert!(exact_winding_number(tris(), [1.1, 0.2, 0.1]).abs() < 1e-12);
        assert!(
            (exact_winding_number(
                m.flipped()
                    .triangles()
                    .iter()
                    .enumerate()
                    .map(|(t, _)| m.flipped().triangle(t)),
                [0.0; 3]
            ) + 1.0)
                .abs()
                < 1e-12
        );
    }

    #[test]
    fn hierarchy_matches_the_exact_sum() {
        let (p, t) = sheet(40);
        let tree = WindingTree::new(&p, &t);
        let tris: Vec<_> = t.iter().map(|t| t.map(|i| p[i as usize])).collect();
        let mut worst: f64 = 0.0;
        let mut far_used = false;
        for i in 0..300 {
            let f = i as f64;
            let q = [
                (f * 0.618).fract() * 3.0 - 1.0,
                (f * 0.414).fract() * 3.0 - 1.0,
                (f * 0.732).fract() * 2.0 - 1.0,
            ];
            let exact = exact_winding_number(tris.iter().copied(), q);
            let fast = tree.winding_number(q);
            worst = worst.max((exact - fast).abs());
            far_used |= exact != fast;
        }
        assert!(far_used, "no query used an expansion");
        eprintln!("worst {worst}");
        assert!(worst < 2e-3, "largest error {worst}");
    }

    #[test]
    fn expansion_error_falls_with_the_order() {
        // One node over a patch, evaluated from ever farther: the error of the second-order
        // expansion must fall faster than the distance cubed (a wrong moment would stall it).
        let (p, t) = sheet(6);
        let tris: Vec<_> = t.iter().map(|t| t.map(|i| p[i as usize])).collect();
        let mut all = tris.clone();
        let mut nodes = Vec::new();
        build(&mut nodes, &mut Vec::new(), &mut all, 0);
        let root = &nodes[0];
        let mut errs = Vec::new();
        for d in [4.0, 8.0, 16.0] {
            let q = [0.5 + d * 0.6, 0.5 - d * 0.3, d * 0.74];
            let r = sub(root.centre, q);
            let approx = far_field(root, r, dot(r, r));
            let exact: f64 = tris.iter().map(|t| solid_angle(t, q)).sum();
            errs.push((approx - exact).abs() / exact.abs());
        }
        // Relative error of an order-2 expansion falls like (size / d)³: × 8 per doubling.
        eprintln!("{errs:?}");
        assert!(
            errs[0] / errs[1] > 6.0 && errs[1] / errs[2] > 6.0,
            "{errs:?}"
        );
    }

    #[test]
    fn caps_close_the_boundary() {
        // An octahedron without two faces: caps make it closed again (every edge balanced).
        let m = octahedron();
        let open = Mesh::new(m.positions().to_vec(), m.triangles()[2..].to_vec()).unwrap();
        let (apexes, caps) = closing_caps(&open);
        assert_eq!(apexes.len(), 1);
        assert_eq!(caps.len(), 4);
        let mut p = open.positions().to_vec();
        p.extend(apexes);
        let mut t = open.triangles().to_vec();
        t.extend(caps);
        let closed = Mesh::new(p, t).unwrap();
        let d = closed.diagnostics();
        assert_eq!((d.boundary_edges, d.non_manifold_edges), (0, 0));
    }

    #[test]
    fn long_cycles_are_capped_in_chunks() {
        // A bumpy sheet has one boundary cycle of 160 edges: capped in 20 chunks of 8, then the
        // 20 chords in 3, then those 3; the result is closed, and its winding number is an integer
        // everywhere.
        let (p, t) = sheet(40);
        let open = Mesh::new(p, t).unwrap();
        let (apexes, caps) = closing_caps(&open);
        assert_eq!(apexes.len(), 20 + 3 + 1);
        let mut p = open.positions().to_vec();
        p.extend(apexes);
        let mut t = open.triangles().to_vec();
        t.extend(caps);
        let closed = Mesh::new(p, t).unwrap();
        // Closed as a chain (collinear chunks make degenerate, non-manifold fans): no boundary.
        assert_eq!(closing_caps(&closed).1.len(), 0);
        let tris: Vec<_> = (0..closed.triangles().len())
            .map(|i| closed.triangle(i))
            .collect();
        for q in [
            [0.3, 0.6, 0.05],
            [0.5, 0.5, -0.3],
            [2.0, 0.1, 0.0],
            [0.2, 0.9, 0.4],
        ] {
            let w = exact_winding_number(tris.iter().copied(), q);
            assert!((w - w.round()).abs() < 1e-9, "{q:?}: {w}");
        }
    }

    /// Positions and triangles.
    type Soup = (Vec<[f64; 3]>, Vec<[u32; 3]>);

    /// xorshift64*: reproducible test inputs.
    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> f64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
        }
        fn range(&mut self, lo: f64, hi: f64) -> f64 {
            lo + (hi - lo) * self.next()
        }
        fn point(&mut self, lo: f64, hi: f64) -> [f64; 3] {
            [0, 1, 2].map(|_| self.range(lo, hi))
        }
        /// A uniformly random unit vector.
        fn direction(&mut self) -> [f64; 3] {
            loop {
                let v = self.point(-1.0, 1.0);
                let l = norm(v);
                if l > 0.1 && l <= 1.0 {
                    return v.map(|c| c / l);
                }
            }
        }
    }

    fn add(a: [f64; 3], b: [f64; 3], t: f64) -> [f64; 3] {
        [0, 1, 2].map(|k| a[k] + t * b[k])
    }

    /// A random triangle in [-1, 1]³ (`None` when its area is below 10⁻³), its area and unit
    /// normal, and a query point at a distance of `near`–1 times 1–100 from its centroid, along
    /// the normal or in a random direction.
    #[allow(clippy::type_complexity)]
    fn triangle_and_query(
        rng: &mut Rng,
        along_normal: bool,
        near: f64,
    ) -> Option<([[f64; 3]; 3], f64, [f64; 3], [f64; 3])> {
        let t = [0; 3].map(|_| rng.point(-1.0, 1.0));
        let area = norm(area_normal(&t));
        if area < 1e-3 {
            return None;
        }
        let centroid = [0, 1, 2].map(|k| (t[0][k] + t[1][k] + t[2][k]) / 3.0);
        let normal = area_normal(&t).map(|v| v / area);
        let dir = if along_normal {
            normal
        } else {
            rng.direction()
        };
        let q = add(
            centroid,
            dir,
            rng.range(near, 1.0) * 10f64.powf(rng.range(0.0, 2.0)),
        );
        Some((t, area, normal, q))
    }

    /// The gradient of `solid_angle` by central differences.
    fn gradient(t: &[[f64; 3]; 3], q: [f64; 3], h: f64) -> [f64; 3] {
        [0, 1, 2].map(|k| {
            let mut e = [0.0; 3];
            e[k] = h;
            (solid_angle(t, add(q, e, 1.0)) - solid_angle(t, add(q, e, -1.0))) / (2.0 * h)
        })
    }

    #[test]
    fn solid_angle_gradient_is_at_most_twice_the_area_over_the_cubed_distance() {
        let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
        let mut tightest: f64 = 0.0;
        for i in 0..4000 {
            // Near and far, from all sides; every fourth along the normal, where the bound is
            // attained in the limit.
            let Some((t, area, _, q)) = triangle_and_query(&mut rng, i % 4 == 0, 0.05) else {
                continue;
            };
            let d = dist2_to_triangle(q, &t).sqrt();
            if d < 1e-2 {
                continue;
            }
            let g = norm(gradient(&t, q, 1e-5 * d));
            let bound = 2.0 * area / d.powi(3);
            let ratio = g / bound;
            assert!(ratio <= 1.0 + 1e-4, "{t:?} {q:?}: |∇Ω| {g} > bound {bound}");
            tightest = tightest.max(ratio);
        }
        // The bound is nearly attained: half of it would be wrong.
        assert!(tightest > 0.95, "{tightest}");
    }

    #[test]
    fn solid_angle_gradient_is_the_boundary_field() {
        let mut rng = Rng(0x1234_5678);
        for _ in 0..500 {
            let t = [0; 3].map(|_| rng.point(-1.0, 1.0));
            let q = rng.point(-2.0, 2.0);
            let d = dist2_to_triangle(q, &t).sqrt();
            if d < 0.05 || norm(area_normal(&t)) < 1e-3 {
                continue;
            }
            let want = gradient(&t, q, 1e-6 * d);
            let got = solid_angle_gradient(&t, q);
            assert!(
                norm(sub(got, want)) <= 1e-5 * norm(want) + 1e-7,
                "{t:?} {q:?}: {got:?} vs {want:?}"
            );
        }
    }

    #[test]
    fn boundary_field_expansion_error_is_bounded() {
        // The sheet's boundary: the tree's field (clusters by their first-order expansion) is
        // within its error bound of the exact sum of the segments' fields.
        let (p, t) = sheet(40);
        let segs: Vec<[[f64; 3]; 2]> = chain_boundary(&t)
            .iter()
            .map(|e| e.map(|i| p[i as usize]))
            .collect();
        let edges = EdgeTree::new(segs.clone());
        let mut rng = Rng(99);
        let (mut used, mut tightest): (u32, f64) = (0, 0.0);
        for _ in 0..400 {
            let q = add(
                [0.5, 0.5, 0.0],
                rng.direction(),
                10f64.powf(rng.range(-1.0, 1.0)),
            );
            let exact = segs
                .iter()
                .fold([0.0; 3], |f, s| add3(f, segment_field(s, q)));
            let Some((got, error)) = edges.field(q) else {
                continue;
            };
            let off = norm(sub(got, exact));
            assert!(
                off <= error * (1.0 + 1e-9) + 1e-12,
                "{q:?}: {off} > {error}"
            );
            if error > 0.0 {
                used += 1;
                tightest = tightest.max(off / error);
            }
        }
        eprintln!("tightest {tightest}");
        assert!(used > 100, "{used}");
    }

    #[test]
    fn taylor_model_holds_the_exact_sum_over_the_ball() {
        // A bumpy sheet as the caps: near triangles exact, the rest by value, boundary-field
        // gradient and remainder bound, against the exact sum at points of the ball.
        let (tree, edges, tris) = sheet_trees();
        let exact = |q: [f64; 3]| tris.iter().map(|t| solid_angle(t, q)).sum::<f64>();
        let mut rng = Rng(2718);
        let (mut checked, mut tightest, mut with_near): (u32, f64, u32) = (0, 0.0, 0);
        for _ in 0..300 {
            let c = add(
                [0.5, 0.5, 0.0],
                rng.direction(),
                10f64.powf(rng.range(-1.5, 0.5)),
            );
            let rq = 10f64.powf(rng.range(-2.5, -1.0));
            let mut near = Vec::new();
            let Some(m) = tree.taylor(c, rq, 10.0 * rq, 1e-9, SMALL * 4.0 * PI, &mut near) else {
                continue;
            };
            let Some((field, error)) = edges.field(c) else {
                continue;
            };
            let mut grad = field.map(|v| GRADIENT_SIGN * v);
            for &(i, _) in &near {
                grad = sub(grad, solid_angle_gradient(&tree.tris[i as usize], c));
            }
            with_near += u32::from(!near.is_empty());
            // The rest at c exactly; the model's value is the hierarchy's (less small nodes).
            let Some(near_c) = tree.near_sum(&near, c, 1e-9) else {
                continue;
            };
            let rest_c = exact(c) - near_c;
            assert!((m.value - rest_c).abs() <= m.left_out + 2e-3 * 4.0 * PI);
            for _ in 0..8 {
                let x = add(c, rng.direction(), rq * rng.next().sqrt());
                let Some(n) = tree.near_sum(&near, x, 1e-9) else {
                    continue;
                };
                let d = sub(x, c);
                let dd = dot(d, d);
                let model = n + rest_c + dot(grad, d);
                let bound = 3.0 * dd * m.hessian + error * dd.sqrt();
                let off = (exact(x) - model).abs();
                assert!(
                    off <= bound * (1.0 + 1e-6) + 1e-11,
                    "{c:?} r {rq}: {off} > {bound}"
                );
                checked += 1;
                if bound > 0.0 {
                    tightest = tightest.max(off / bound);
                }
            }
        }
        eprintln!("checked {checked}, with near {with_near}, tightest {tightest}");
        assert!(checked > 1000 && with_near > 50, "{checked} {with_near}");
    }

    #[test]
    fn solid_angle_hessian_is_at_most_six_times_the_area_over_the_fourth_power() {
        // Along segments from q, the solid angle departs from its first-order model by at most
        // 3|δ|² area/g⁴ (g the distance from the segment to the triangle); nearly attained
        // somewhere, so a smaller constant would fail.
        let mut rng = Rng(0xfeed_beef);
        let mut tightest: f64 = 0.0;
        for i in 0..6000 {
            let Some((t, area, normal, q)) = triangle_and_query(&mut rng, i % 3 == 0, 0.1) else {
                continue;
            };
            let dist = dist2_to_triangle(q, &t).sqrt();
            let step = if i % 3 == 0 { normal } else { rng.direction() };
            let len = dist * rng.range(0.01, 0.5);
            let x = add(q, step, len);
            let g = dist - len;
            let model = solid_angle(&t, q) + dot(solid_angle_gradient(&t, q), sub(x, q));
            let off = (solid_angle(&t, x) - model).abs();
            let bound = 3.0 * len * len * area / g.powi(4);
            assert!(
                off <= bound * (1.0 + 1e-6) + 1e-13,
                "{t:?} {q:?} {x:?}: {off} > {bound}"
            );
            tightest = tightest.max(off / bound);
        }
        eprintln!("tightest {tightest}");
        assert!(tightest > 0.5, "{tightest}");
    }

    /// A bumpy sheet's hierarchy, its boundary's, and its triangles.
    fn sheet_trees() -> (WindingTree, EdgeTree, Vec<[[f64; 3]; 3]>) {
        let (p, t) = sheet(30);
        let tris = t.iter().map(|t| t.map(|i| p[i as usize])).collect();
        let segs: Vec<[[f64; 3]; 2]> = chain_boundary(&t)
            .iter()
            .map(|e| e.map(|i| p[i as usize]))
            .collect();
        (WindingTree::new(&p, &t), EdgeTree::new(segs), tris)
    }

    /// Eight balls at the centres of a small block's eight sub-blocks near the sheet, and their
    /// radius.
    fn eight_balls(rng: &mut Rng) -> ([[f64; 3]; LANES], f64) {
        let centre = add(
            [0.5, 0.5, 0.0],
            rng.direction(),
            10f64.powf(rng.range(-1.3, 0.3)),
        );
        let step = 10f64.powf(rng.range(-2.5, -1.3));
        let qs = std::array::from_fn(|d| {
            [0, 1, 2].map(|a| centre[a] + step * (((d >> a) & 1) as f64 - 0.5))
        });
        (qs, 0.5 * step * 3f64.sqrt())
    }

    #[test]
    fn lane_traversals_give_the_same_bits_on_every_instruction_set() {
        // The traversals over eight points are compiled per instruction set with their kernels
        // inlined, bookkeeping and all: every path must give the baseline's bits, and
        // `winding_numbers` the one-point traversal's values.
        let (tree, edges, _) = sheet_trees();
        let mut rng = Rng(2718);
        let small = SMALL * 4.0 * PI;
        let (mut compared, mut open) = (0, 0);
        for case in 0..60 {
            let (qs, rq) = eight_balls(&mut rng);
            let by_area: [bool; LANES] = std::array::from_fn(|i| (i + case) % 3 != 0);
            let limit: [f64; LANES] =
                std::array::from_fn(|i| if i % 2 == 0 { f64::INFINITY } else { 2.0 });
            let lanes = if case % 4 == 0 { 0b1010_0110 } else { 0xff };
            // Each traversal's results as bits, by one path (0 the baseline, 1 AVX2, 2 AVX-512).
            let run = |path: u32| -> Vec<u64> {
                let mut near: [Vec<(u32, f64)>; LANES] = Default::default();
                // The three traversals by the functions given.
                macro_rules! traverse {
                    ($spread:path, $taylor:path, $field:path) => {
                        (
                            $spread(&tree, &qs, rq, 1e-9, &limit, small, &by_area),
                            $taylor(&tree, &qs, lanes, rq, 10.0 * rq, 1e-9, small, &mut near),
                            $field(&edges, &qs, lanes),
                        )
                    };
                }
                let (sp, ts, fs) = match path {
                    // SAFETY: each path is run only where the processor has its instructions.
                    #[cfg(target_arch = "x86_64")]
                    1 => unsafe {
                        traverse!(spread_lanes_avx2, taylor_lanes_avx2, field_lanes_avx2)
                    },
                    // SAFETY: as above.
                    #[cfg(target_arch = "x86_64")]
                    2 => unsafe {
                        traverse!(spread_lanes_avx512, taylor_lanes_avx512, field_lanes_avx512)
                    },
                    _ => traverse!(
                        WindingTree::spread_lanes_body,
                        WindingTree::taylor_lanes_body,
                        EdgeTree::field_lanes_body
                    ),
                };
                let mut v = Vec::new();
                for i in 0..LANES {
                    match sp[i] {
                        Some(s) => v.extend([s.value, s.spread, s.crude, s.left_out]),
                        None => v.push(f64::NAN),
                    }
                    match ts[i] {
                        Some(t) => v.extend([t.value, t.hessian, t.left_out]),
                        None => v.push(f64::NAN),
                    }
                    match fs[i] {
                        Some((f, e)) => v.extend(f.into_iter().chain([e])),
                        None => v.push(f64::NAN),
                    }
                    v.extend(near[i].iter().flat_map(|&(t, a)| [t as f64, a]));
                }
                v.into_iter().map(f64::to_bits).collect()
            };
            let base = run(0);
            open += nones(&base);
            #[cfg(target_arch = "x86_64")]
            {
                if std::arch::is_x86_feature_detected!("avx2") {
                    assert_eq!(run(1), base, "case {case}: AVX2");
                    compared += 1;
                }
                if std::arch::is_x86_feature_detected!("avx512f") {
                    assert_eq!(run(2), base, "case {case}: AVX-512");
                    compared += 1;
                }
            }
            // Points: the hierarchy's winding numbers, eight at a time as one at a time.
            let w = tree.winding_numbers(&qs);
            for i in 0..LANES {
                let one = tree.winding_number(qs[i]);
                assert!((w[i] - one).abs() < 1e-12, "case {case}: {} {one}", w[i]);
            }
        }
        eprintln!("instruction sets compared {compared}, lanes left open {open}");
        assert!(open > 0, "no lane was stopped by its limit or a gap");
    }

    /// The lanes a traversal's bits (from the test above) mark as `None`.
    fn nones(bits: &[u64]) -> u32 {
        bits.iter().filter(|&&b| f64::from_bits(b).is_nan()).count() as u32
    }

    #[test]
    fn lane_traversals_bound_as_one_ball_at_a_time_does() {
        // Eight balls at the centres of a 4³ block's 2³ blocks, near a bumpy sheet (the caps):
        // each lane's interval (`spread_lanes`) must hold the exact sum over its ball, its model
        // (`taylor_lanes`, `field_lanes`) the exact sum at each point, as the one-ball versions.
        let (tree, edges, tris) = sheet_trees();
        let exact = |q: [f64; 3]| tris.iter().map(|t| solid_angle(t, q)).sum::<f64>();
        let mut rng = Rng(31415);
        let (mut intervals, mut models, mut near_lanes) = (0u32, 0u32, 0u32);
        for case in 0..120 {
            let (qs, rq) = eight_balls(&mut rng);
            let by_area: [bool; LANES] = std::array::from_fn(|i| (i + case) % 3 != 0);
            let small = SMALL * 4.0 * PI;
            let spreads = spread_lanes(
                &tree,
                &qs,
                rq,
                1e-9,
                &[f64::INFINITY; LANES],
                small,
                &by_area,
            );
            // Some lanes only: the others' traversal must not be disturbed by them.
            let lanes = if case % 4 == 0 { 0b1010_0110 } else { 0xff };
            let mut near: [Vec<(u32, f64)>; LANES] = Default::default();
            let ts = taylor_lanes(&tree, &qs, lanes, rq, 10.0 * rq, 1e-9, small, &mut near);
            let fields = field_lanes(&edges, &qs, lanes);
            for (i, &c) in qs.iter().enumerate() {
                let points: Vec<[f64; 3]> = (0..6)
                    .map(|_| add(c, rng.direction(), rq * rng.next().sqrt()))
                    .collect();
                if let Some(sp) = spreads[i] {
                    intervals += 1;
                    for &x in &points {
                        let off = (exact(x) - sp.value).abs();
                        assert!(
                            off <= sp.spread + 1e-3 * 4.0 * PI,
                            "case {case} lane {i}: {off} > {}",
                            sp.spread
                        );
                        let magnitude: f64 = tris.iter().map(|t| solid_angle(t, x).abs()).sum();
                        assert!(magnitude <= sp.crude * (1.0 + 1e-9) + 1e-12);
                    }
                }
                if lanes >> i & 1 == 0 {
                    assert!(ts[i].is_none() && fields[i].is_none() && near[i].is_empty());
                    continue;
                }
                let (Some(m), Some((field, error))) = (ts[i], fields[i]) else {
                    continue;
                };
                // The field as the one-point traversal finds it, within both error bounds.
                let (one, one_error) = edges.field(c).expect("no segment at the centre");
                assert!(
                    norm(sub(field, one)) <= error + one_error + 1e-9,
                    "case {case} lane {i}"
                );
                let mut grad = field.map(|v| GRADIENT_SIGN * v);
                for &(t, _) in &near[i] {
                    grad = sub(grad, solid_angle_gradient(&tree.tris[t as usize], c));
                }
                near_lanes += u32::from(!near[i].is_empty());
                let Some(near_c) = tree.near_sum(&near[i], c, 1e-9) else {
                    continue;
                };
                let rest_c = exact(c) - near_c;
                assert!((m.value - rest_c).abs() <= m.left_out + 2e-3 * 4.0 * PI);
                for &x in &points {
                    let Some(n) = tree.near_sum(&near[i], x, 1e-9) else {
                        continue;
                    };
                    let d = sub(x, c);
                    let dd = dot(d, d);
                    let bound = 3.0 * dd * m.hessian + error * dd.sqrt();
                    let off = (exact(x) - (n + rest_c + dot(grad, d))).abs();
                    assert!(
                        off <= bound * (1.0 + 1e-6) + 1e-11,
                        "case {case} lane {i}: {off} > {bound}"
                    );
                    models += 1;
                }
            }
        }
        eprintln!(
            "intervals {intervals}, model points {models}, lanes with near caps {near_lanes}"
        );
        assert!(
            intervals > 500 && models > 2000 && near_lanes > 100,
            "{intervals} {models} {near_lanes}"
        );
    }

    #[test]
    fn spread_bounds_the_variation_over_the_ball() {
        let mut rng = Rng(12345);
        let (p, t) = sheet(12);
        let one = vec![[0.2, 0.1, 0.0], [0.9, 0.3, 0.05], [0.4, 0.8, -0.1]];
        let sets: [Soup; 3] = [(p.clone(), t.clone()), (one, vec![[0, 1, 2]]), sheet(3)];
        let (mut tightest, mut checked, mut worst_value): (f64, u32, f64) = (0.0, 0, 0.0);
        for (p, t) in &sets {
            let tree = WindingTree::new(p, t);
            let tris: Vec<_> = t.iter().map(|t| t.map(|i| p[i as usize])).collect();
            let exact = |q: [f64; 3]| tris.iter().map(|t| solid_angle(t, q)).sum::<f64>();
            for i in 0..600 {
                let q = add(
                    [0.5, 0.5, 0.0],
                    rng.direction(),
                    10f64.powf(rng.range(-0.7, 1.3)),
                );
                let rq = if i % 5 == 0 {
                    0.0
                } else {
                    norm(sub(q, [0.5, 0.5, 0.0])) * 10f64.powf(rng.range(-3.0, -0.3))
                };
                let Some(s) = tree.spread(q, rq, 0.0, f64::INFINITY, 0.0, true) else {
                    continue;
                };
                // With small nodes bounded instead of summed: the interval still holds the
                // exact sum (up to the expansions' error).
                let bounded = tree
                    .spread(q, rq, 0.0, f64::INFINITY, SMALL * 4.0 * PI, true)
                    .expect("the same nodes come near");
                checked += 1;
                let at_q = exact(q);
                // Where no node was left out, `value` is the hierarchy's value at q and `spread`
                // bounds the variation; otherwise `value ± spread` holds every exact sum.
                let whole = s.left_out == 0.0;
                if whole {
                    worst_value = worst_value.max((s.value - at_q).abs() / (4.0 * PI));
                }
                // Points of the ball: random ones, and the two along the gradient at q.
                let grad = {
                    let g: [f64; 3] = (0..3)
                        .map(|k| {
                            let h = 1e-6 * (1.0 + norm(q));
                            let mut e = [0.0; 3];
                            e[k] = h;
                            (exact(add(q, e, 1.0)) - exact(add(q, e, -1.0))) / (2.0 * h)
                        })
                        .collect::<Vec<_>>()
                        .try_into()
                        .unwrap();
                    let l = norm(g);
                    if l > 0.0 {
                        g.map(|v| v / l)
                    } else {
                        [1.0, 0.0, 0.0]
                    }
                };
                let mut points = vec![add(q, grad, rq), add(q, grad, -rq)];
                for _ in 0..6 {
                    points.push(add(q, rng.direction(), rq * rng.next().sqrt()));
                }
                for x in points {
                    let change = (exact(x) - if whole { at_q } else { s.value }).abs();
                    let allowed = if whole { 0.0 } else { 1e-3 * 4.0 * PI };
                    assert!(
                        change <= s.spread * (1.0 + 1e-9) + 1e-12 + allowed,
                        "{q:?} r {rq}: change {change} > spread {}",
                        s.spread
                    );
                    let off = (exact(x) - bounded.value).abs();
                    assert!(
                        off <= bounded.spread + 1e-3 * 4.0 * PI,
                        "{q:?} r {rq}: {off} off > {}",
                        bounded.spread
                    );
                    let magnitude: f64 = tris.iter().map(|t| solid_angle(t, x).abs()).sum();
                    assert!(magnitude <= s.crude * (1.0 + 1e-9) + 1e-12);
                    if whole && s.spread > 1e-9 {
                        tightest = tightest.max(change / s.spread);
                    }
                }
            }
        }
        assert!(checked > 1000, "{checked}");
        // The variation bound is close to attained somewhere (half of it would be wrong), and the
        // hierarchy's value at the centre is well within the margin added for it.
        assert!(tightest > 0.8, "{tightest}");
        assert!(worst_value < MARGIN / 4.0, "{worst_value}");
    }

    /// A UV sphere: positions and outward triangles.
    fn uv_sphere(c: [f64; 3], r: f64, n: u32) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
        let (rings, segs) = (n, 2 * n);
        let mut p = vec![[c[0], c[1], c[2] + r], [c[0], c[1], c[2] - r]];
        for i in 1..rings {
            let th = PI * i as f64 / rings as f64;
            for j in 0..segs {
                let ph = 2.0 * PI * j as f64 / segs as f64;
                p.push([
                    c[0] + r * th.sin() * ph.cos(),
                    c[1] + r * th.sin() * ph.sin(),
                    c[2] + r * th.cos(),
                ]);
            }
        }
        let id = |i: u32, j: u32| 2 + (i - 1) * segs + j % segs;
        let mut t = Vec::new();
        for j in 0..segs {
            t.push([0, id(1, j), id(1, j + 1)]);
            t.push([1, id(rings - 1, j + 1), id(rings - 1, j)]);
            for i in 1..rings - 1 {
                t.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
                t.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
        (p, t)
    }

    /// Meshes with holes on a 32³ unit grid: a sphere with triangles missing, an open bowl, a
    /// patch left of a sphere (where the caps' winding number is near ±1), two overlapping
    /// spheres (w = 2) with holes, and a bumpy sheet.
    fn holey_meshes() -> Vec<Mesh> {
        let mut rng = Rng(777);
        let mut out = Vec::new();
        let (p, mut t) = uv_sphere([15.7, 16.2, 16.1], 11.3, 14);
        for _ in 0..6 {
            t.remove((rng.next() * t.len() as f64) as usize);
        }
        out.push(Mesh::new(p, t).unwrap());
        let (p, mut t) = uv_sphere([16.2, 15.9, 15.4], 12.1, 16);
        t.retain(|tri| tri.iter().map(|&v| p[v as usize][2]).sum::<f64>() / 3.0 < 22.0);
        out.push(Mesh::new(p, t).unwrap().flipped());
        let (p, mut t) = uv_sphere([16.1, 16.3, 15.8], 12.4, 16);
        t.retain(|tri| tri.iter().map(|&v| p[v as usize][0]).sum::<f64>() / 3.0 > 9.0);
        out.push(Mesh::new(p, t).unwrap());
        let (mut p, mut t) = uv_sphere([13.1, 14.2, 15.3], 8.7, 12);
        let (p2, t2) = uv_sphere([18.4, 17.9, 16.6], 9.2, 12);
        let off = p.len() as u32;
        p.extend(p2);
        t.extend(t2.iter().map(|tri| tri.map(|v| v + off)));
        for _ in 0..8 {
            t.remove((rng.next() * t.len() as f64) as usize);
        }
        out.push(Mesh::new(p, t).unwrap());
        let (p, t) = sheet(24);
        let p = p
            .iter()
            .map(|v| [3.3 + 25.0 * v[0], 4.1 + 24.0 * v[1], 15.2 + 60.0 * v[2]]);
        out.push(Mesh::new(p.collect(), t).unwrap());
        out
    }

    /// A grid around [`holey_meshes`] with room for `SUPER`³ blocks of blocks beside them.
    const SUPER_GRID: Grid = Grid {
        origin: [-37.5, -21.0, -40.25],
        voxel_size: 1.0,
        dims: [100, 71, 97],
    };

    #[test]
    fn blocks_decide_as_voxel_by_voxel_evaluation_does() {
        // The meshes fill the first grid; in the second they lie among `SUPER`³ blocks of
        // blocks, which the caps' interval decides whole.
        let grids = [
            Grid {
                origin: [0.0; 3],
                voxel_size: 1.0,
                dims: [32, 31, 33],
            },
            SUPER_GRID,
        ];
        let mut total = WindingStats::default();
        let cases = grids
            .iter()
            .flat_map(|&g| holey_meshes().into_iter().map(move |m| (g, m)));
        for (i, (grid, mesh)) in cases.enumerate() {
            let (a, sa) = solid_impl(&mesh, &grid, &Control::none(), true).unwrap();
            let (b, sb) = solid_impl(&mesh, &grid, &Control::none(), false).unwrap();
            assert_eq!(sa.voxels(), grid.voxel_count());
            assert_eq!(sb.voxels(), grid.voxel_count());
            assert_eq!(sb.cap_block_voxels + sb.mesh_block_voxels, 0);
            let tris: Vec<_> = (0..mesh.triangles().len())
                .map(|t| mesh.triangle(t))
                .collect();
            let [nx, ny, nz] = grid.dims;
            let differ: Vec<[u32; 3]> = (0..nx)
                .flat_map(|x| (0..ny).flat_map(move |y| (0..nz).map(move |z| [x, y, z])))
                .filter(|&[x, y, z]| a.get(x, y, z) != b.get(x, y, z))
                .collect();
            for &[x, y, z] in &differ {
                let w = exact_winding_number(tris.iter().copied(), grid.voxel_center(x, y, z));
                assert!(
                    (w.abs() - 0.5).abs() <= 0.05,
                    "mesh {i}: voxel {:?} differs, w = {w}",
                    [x, y, z]
                );
            }
            eprintln!("mesh {i}: {sa:?}; {} differ", differ.len());
            assert_eq!(sb.near_evaluated_voxels, 0);
            total.cap_block_voxels += sa.cap_block_voxels;
            total.mesh_block_voxels += sa.mesh_block_voxels;
            total.cap_evaluated_voxels += sa.cap_evaluated_voxels;
            total.near_evaluated_voxels += sa.near_evaluated_voxels;
        }
        assert!(
            total.cap_block_voxels > 10_000
                && total.mesh_block_voxels > 200
                && total.cap_evaluated_voxels > 100
                && total.near_evaluated_voxels > 1_000,
            "{total:?}"
        );
    }

    /// Every voxel of a `SUPER`³ block of blocks that the caps' interval decides: the exact sum
    /// over the (snapped) caps lies in the interval, and within ½ of the block's k.
    #[test]
    fn super_block_intervals_hold_every_voxel() {
        let grid = SUPER_GRID;
        let size = SUPER * BLOCK;
        let (mut decided, mut nonzero, mut widest) = (0, 0, 0f64);
        // And a bowl: a hemisphere whose one cap is a disc across the grid's middle.
        let mut meshes = holey_meshes();
        let (p, mut t) = uv_sphere([12.3, 14.1, 8.2], 29.0, 24);
        t.retain(|tri| tri.iter().map(|&v| p[v as usize][2]).sum::<f64>() / 3.0 < 8.2);
        meshes.push(Mesh::new(p, t).unwrap());
        for (i, mesh) in meshes.iter().enumerate() {
            let (closed, caps) = closed_by_caps(mesh);
            let trees = Trees::new(mesh, &closed, &caps, &grid);
            let cert = Certifier::new(&grid, &trees, true);
            let cap_tris: Vec<[[f64; 3]; 3]> = caps
                .iter()
                .map(|t| t.map(|v| snapped_world(&grid, closed.positions()[v as usize])))
                .collect();
            let ns = grid.dims.map(|d| d.div_ceil(size));
            for s in (0..ns[0])
                .flat_map(|x| (0..ns[1]).flat_map(move |y| (0..ns[2]).map(move |z| [x, y, z])))
            {
                let lo = s.map(|v| v * size);
                let interval = cert.super_interval(lo);
                let decision = cert.decide_super(lo);
                let Some(Decision::Ne(k, _)) = decision else {
                    assert!(decision.is_none(), "mesh {i} block {s:?}: only Ne is made");
                    continue;
                };
                let (v, e, crude) = interval.expect("a decision comes from an interval");
                decided += 1;
                nonzero += u32::from(crude >= CAP_LIMIT * 4.0 * PI);
                let hi = [0, 1, 2].map(|a| (lo[a] + size).min(grid.dims[a]));
                // The block's faces: off the caps w_caps is harmonic, so its extremes over the
                // block lie there (and the interior is checked by the other tests' blocks).
                let on_face = |p: [u32; 3]| (0..3).any(|a| p[a] == lo[a] || p[a] + 1 == hi[a]);
                for x in lo[0]..hi[0] {
                    for y in lo[1]..hi[1] {
                        for z in lo[2]..hi[2] {
                            if !on_face([x, y, z]) {
                                continue;
                            }
                            let q = grid.voxel_center(x, y, z);
                            let w = exact_winding_number(cap_tris.iter().copied(), q);
                            widest = widest.max((w - v).abs());
                            assert!(
                                (w - v).abs() <= e && (w - k as f64).abs() < 0.5,
                                "mesh {i} block {s:?} voxel {:?}: w_caps {w}, interval {v} ± {e}, k {k}",
                                [x, y, z]
                            );
                        }
                    }
                }
            }
        }
        eprintln!("{decided} blocks decided, {nonzero} past the crude bound, widest {widest}");
        // Blocks were decided whole, some of them near enough to the caps that the crude bound
        // did not do it, and their caps' winding number varies over them.
        assert!(
            decided > 100 && nonzero > 10 && widest > 0.015,
            "{decided} {nonzero} {widest}"
        );
    }

    #[test]
    fn boundary_field_bounds_the_variation_off_the_surface() {
        // An open bumpy sheet: its solid angle varies over a ball that misses it by at most
        // rq × the Biot–Savart bound of its boundary.
        let (p, t) = sheet(10);
        let tris: Vec<_> = t.iter().map(|t| t.map(|i| p[i as usize])).collect();
        let segs: Vec<[[f64; 3]; 2]> = chain_boundary(&t)
            .iter()
            .map(|e| e.map(|i| p[i as usize]))
            .collect();
        assert_eq!(segs.len(), 40);
        let edges = EdgeTree::new(segs.clone());
        let exact = |q: [f64; 3]| tris.iter().map(|t| solid_angle(t, q)).sum::<f64>();
        let mut rng = Rng(4242);
        let (mut checked, mut tightest): (u32, f64) = (0, 0.0);
        for i in 0..400 {
            let q = add(
                [0.5, 0.5, 0.0],
                rng.direction(),
                10f64.powf(rng.range(-1.0, 1.0)),
            );
            // The segment's field against a quadrature of dl × (x − q)/|x − q|³.
            if i % 10 == 0 {
                let s = &segs[i % segs.len()];
                let n = 2000;
                let mut sum = [0.0; 3];
                for k in 0..n {
                    let x = add(s[0], sub(s[1], s[0]), (k as f64 + 0.5) / n as f64);
                    let r = sub(x, q);
                    let f = cross(sub(s[1], s[0]), r).map(|v| v / (n as f64 * norm(r).powi(3)));
                    sum = add3(sum, f);
                }
                let got = segment_field(s, q);
                assert!(
                    norm(sub(got, sum)) <= 1e-4 * norm(sum) + 1e-9,
                    "{got:?} {sum:?}"
                );
            }
            let gap = tris
                .iter()
                .map(|t| dist2_to_triangle(q, t).sqrt())
                .fold(f64::INFINITY, f64::min);
            let rq = gap * rng.range(0.05, 0.95);
            let b = edges.bound(q, rq, f64::INFINITY);
            if !b.is_finite() {
                continue;
            }
            checked += 1;
            let at_q = exact(q);
            for _ in 0..8 {
                let x = add(q, rng.direction(), rq * rng.next().sqrt());
                let change = (exact(x) - at_q).abs();
                assert!(
                    change <= rq * b * (1.0 + 1e-9),
                    "{q:?} r {rq}: {change} > {}",
                    rq * b
                );
                tightest = tightest.max(change / (rq * b));
            }
        }
        assert!(checked > 300, "{checked}");
        eprintln!("tightest {tightest}");
    }
}
