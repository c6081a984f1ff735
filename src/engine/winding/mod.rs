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
//! tree gives all eight intervals (`traverse::spread_lanes`), one more the Taylor models of
//! those still open (`traverse::taylor_lanes`), one of the chain their fields
//! (`edges::field_lanes`); a node is opened for the balls that need it and taken through
//! its children by the others, which bounds them as well. The eight 4³ blocks of an open 8³
//! block get their caps' intervals the same way. The solid angles, distances, expansions and
//! the bounds built on them are computed eight at a time (`lanes`).
//!
//! Both parts run on the CPU; the signed counts use the same integer crossing rule as `solid`.
//!
//! The files: this one drives a fill through its phases (`solid_impl`: close the mesh, certify
//! the blocks, settle the ties, count the crossings); `caps` closes the boundary;
//! `certifier` decides blocks and voxels; `trees` holds the hierarchies, `bounds` their
//! intervals and Taylor models over a ball, `traverse` the same for eight balls at once,
//! `edges` the boundary chain's tree and fields, `lanes` the eight-lane kernels. The
//! geometry of triangles and the bounding-volume hierarchy come from `crate::engine::geom`.
//!
//! Not here: the other fills (parity, vote, flood: [`super::fill`]), or the crossing count
//! itself ([`crate::engine::cpu`]), which the last phase calls with its own decision per block.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

mod bounds;
mod caps;
mod certifier;
mod edges;
pub(crate) mod lanes;
#[cfg(test)]
mod tests;
mod traverse;
mod trees;

pub use crate::engine::geom::{exact_winding_number, solid_angle};
pub use caps::closing_caps;
pub use trees::WindingTree;

use super::{EngineError, GridMesh};
use crate::cancel::{Canceled, Control};
use crate::grid::Grid;
use crate::mesh::Mesh;
use crate::volume::BitVolume;
use caps::closed_by_caps;
use certifier::{Certifier, Column};
use lanes::LANES;
use trees::{Trees, WindingTree as Tree};

/// Barill et al.'s accuracy parameter: expansions are used beyond β node radii.
pub const BETA: f64 = 2.0;
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
/// expansion ([`edges::EdgeTree::field`]).
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
    solid_impl(mesh, grid, ctl, true, false)
}

/// [`solid_with`] for a mesh known to need no caps (its diagnosis counts no unoriented edge:
/// closed, every edge used as often in each direction), which skips looking for them.
pub fn solid_of_closed_with(
    mesh: &Mesh,
    grid: &Grid,
    ctl: &Control,
) -> Result<(BitVolume, WindingStats), EngineError> {
    solid_impl(mesh, grid, ctl, true, true)
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

/// Bit j set where `inside(j, run[j])`, for the (at most 64) counts of `run`.
#[inline(always)]
fn run_bits(run: &[i32], inside: impl Fn(usize, i32) -> bool) -> u64 {
    run.iter()
        .enumerate()
        .fold(0, |m, (j, &n)| m | (u64::from(inside(j, n)) << j))
}

/// A voxel's index in its block's codes.
#[inline]
fn local([x, y, z]: [u32; 3]) -> usize {
    (((x % BLOCK) * BLOCK + y % BLOCK) * BLOCK + z % BLOCK) as usize
}

/// What the certification decided, block by block, in the order the counting pass reads them
/// (x-major): one code per block, the voxel codes of the mixed blocks, and how many voxels were
/// decided each way (indexed by `EXACT` … `NEAR_EVAL`). No blocks at all for a closed mesh,
/// where the crossing count alone decides.
#[derive(Default)]
struct Decided {
    blocks: Vec<Block>,
    mixed: Vec<Codes>,
    counts: [u64; 6],
}

/// [`solid_with`]; `blocks` off decides every voxel near the caps one by one (the tests compare);
/// `known_closed`: the mesh needs no caps (not looked for).
/// The phases, in order: close the mesh by its caps, certify the blocks ([`certify_blocks`]),
/// settle the voxels at a cap's tie by the mesh's own winding number ([`settle_ties`]), count
/// the crossings and apply the decisions ([`count_crossings`]).
fn solid_impl(
    mesh: &Mesh,
    grid: &Grid,
    ctl: &Control,
    blocks: bool,
    known_closed: bool,
) -> Result<(BitVolume, WindingStats), EngineError> {
    // Shares of the progress: certifying blocks (and evaluating the voxels that need it), the
    // tie voxels, the counting pass.
    let (certify_ctl, ties_ctl, count_ctl) = (
        ctl.stage(0.0, 0.8),
        ctl.stage(0.8, 0.85),
        ctl.stage(0.85, 1.0),
    );
    let (closed, caps) = if known_closed {
        (std::borrow::Cow::Borrowed(mesh), Vec::new())
    } else {
        closed_by_caps(mesh)
    };
    let gm = GridMesh::new(&closed, grid)?;
    let nb = grid.dims.map(|d| d.div_ceil(BLOCK));
    let mut decided = Decided::default();
    ctl.check()?;
    if caps.is_empty() {
        // Closed: N is the winding number.
        decided.counts[EXACT] = grid.voxel_count();
    } else {
        let trees = Trees::new(mesh, &closed, &caps, grid);
        let deferred = certify_blocks(grid, &trees, blocks, nb, &certify_ctl, &mut decided)?;
        settle_ties(
            mesh,
            grid,
            &trees.mesh,
            nb,
            &deferred,
            &ties_ctl,
            &mut decided,
        )?;
    }
    ties_ctl.complete();
    let vol = count_crossings(&gm, grid, nb, &decided, &count_ctl)?;
    // A row skipped because the work was stopped must not pass for a finished one.
    ctl.check()?;
    ctl.complete();
    let counts = decided.counts;
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

/// Certifies every block of the grid (`nb` blocks a side) into `decided`, and returns the
/// voxels left at a cap's tie, in the order the blocks found them.
fn certify_blocks(
    grid: &Grid,
    trees: &Trees,
    blocks: bool,
    nb: [u32; 3],
    certify: &Control,
    decided: &mut Decided,
) -> Result<Vec<[u32; 3]>, Canceled> {
    let cert = Certifier::new(grid, trees, blocks);
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
    let Decided {
        blocks: block_codes,
        mixed,
        counts,
    } = decided;
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
    Ok(deferred)
}

/// Voxels at a cap's tie (`deferred`): the mesh's own winding number decides them, into their
/// mixed blocks' codes. A few: exact sums over the mesh; many: the hierarchy over it
/// (`mesh_tree`), eight neighbours (in the order the blocks found them) at a time.
fn settle_ties(
    mesh: &Mesh,
    grid: &Grid,
    mesh_tree: &Tree,
    nb: [u32; 3],
    deferred: &[[u32; 3]],
    ties: &Control,
    decided: &mut Decided,
) -> Result<(), Canceled> {
    let centre = |[x, y, z]: [u32; 3]| grid.voxel_center(x, y, z);
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
                    .map(|&v| exact_winding_number((0..tris).map(|t| mesh.triangle(t)), centre(v)))
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
        let Block::Mixed(i) = decided.blocks[((b[0] * nb[1] + b[1]) * nb[2] + b[2]) as usize]
        else {
            unreachable!("a tie lies in a mixed block");
        };
        decided.mixed[i as usize][local(v)] = if w.abs() >= 0.5 { V_IN } else { V_OUT };
    }
    Ok(())
}

/// The counting pass: the signed crossing count N along each column, turned into bits by each
/// block's decision (`decided`; inside ⇔ N ≠ 0 where there is none).
fn count_crossings(
    gm: &GridMesh,
    grid: &Grid,
    nb: [u32; 3],
    decided: &Decided,
    count: &Control,
) -> Result<BitVolume, Canceled> {
    let Decided {
        blocks: block_codes,
        mixed,
        ..
    } = decided;
    let [_, ny, nz] = grid.dims;
    let wpc = nz.div_ceil(64) as usize;
    crate::engine::cpu::signed_crossings(gm, count, |x, crossings, words| {
        // Stopped: the row is left empty and the pass fails below.
        if count.check().is_err() {
            return;
        }
        if block_codes.is_empty() {
            // Nothing decided by blocks (a closed mesh): inside ⇔ N ≠ 0, set a run of voxels
            // between two crossings at a time.
            for y in 0..ny {
                let out = &mut words[y as usize * wpc..(y as usize + 1) * wpc];
                let (mut n, mut from) = (0, 0);
                for &(k, s) in crossings.column(y) {
                    if n != 0 {
                        set_run(out, from, k as u32);
                    }
                    n += s;
                    from = k as u32;
                }
                if n != 0 {
                    set_run(out, from, nz);
                }
            }
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
    })
}

/// Sets bits `lo..hi` of a column's words.
fn set_run(words: &mut [u64], lo: u32, hi: u32) {
    if lo >= hi {
        return;
    }
    let (lo, hi) = (lo as usize, hi as usize);
    let (first, last) = (lo / 64, (hi - 1) / 64);
    let head = u64::MAX << (lo % 64);
    let tail = u64::MAX >> (63 - (hi - 1) % 64);
    if first == last {
        words[first] |= head & tail;
    } else {
        words[first] |= head;
        words[first + 1..last].fill(u64::MAX);
        words[last] |= tail;
    }
}
