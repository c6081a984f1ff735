//! Dual contouring's crossing triangles undone: a vertex the QEF placed far from its mass point
//! (on a sharp edge or corner) can fold its triangles through their neighbours'. The triangles
//! around such vertices are tested against every triangle near them; where two cross, the
//! vertices of both move halfway back to their mass points and the quads around them are split
//! again, until none cross (surface nets' mass-point mesh is what they tend to).
//!
//! * **Tested**: each triangle with a vertex over [`FAR`] from its mass point, then each
//!   triangle a repair re-split, against every triangle that can reach it. Every vertex lies
//!   in its dual cell (the unit cube about its lattice point) and a quad's four lattice points
//!   differ by at most one on each axis, so a triangle meeting triangle `t`'s bounding box has
//!   its lattice points within 1.5 of that box on every axis: those are found through the
//!   vertices' lattice points (sorted: the net numbers vertices in (x, y, z) order), and
//!   tested when their boxes overlap.
//! * **Crossing**: `measure::triangles_cross` (an edge of one through the other's interior,
//!   by exact orientation signs: with plain f64 ones, nearly coplanar neighbours that do not
//!   meet were reported crossing, and their sharp vertices pulled back for nothing).
//! * **Bounded**: at most [`ROUNDS`] rounds; in the last a vertex goes to its mass point.
//!   What still crosses after it is left and logged (not met on the test meshes).

use rayon::prelude::*;

use super::measure::triangles_cross;
use super::vec3::{dot, sub};

/// A vertex farther than this (voxels) from its mass point makes its triangles suspects.
pub const FAR: f64 = 0.25;
/// A group of suspects' box is at most this wide (voxels) on every axis, and holds at most
/// `GROUP_LEN` of them ([`crossings`]).
const GROUP_SPAN: f64 = 3.0;
const GROUP_LEN: usize = 32;
/// Rounds of halving at most (the last puts the vertices on their mass points).
pub const ROUNDS: usize = 8;

/// The mesh being untangled: vertices (with their lattice points, mass points and QEF
/// positions), quads and their triangles (two a quad, `2q` and `2q + 1`).
pub(super) struct Tangle<'a> {
    pub cells: &'a [[u32; 3]],
    pub mass: &'a [[f64; 3]],
    /// The QEF position (kept in the cell).
    pub solved: &'a [[f64; 3]],
    pub quads: &'a [[u32; 4]],
    pub positions: &'a mut [[f64; 3]],
    pub triangles: &'a mut [[u32; 3]],
}

/// Untangles `t` (module docs), re-splitting a quad with `split(quad index, positions)`;
/// returns the crossing pairs left (0 when untangled) and the vertices moved.
pub(super) fn untangle(
    t: &mut Tangle<'_>,
    split: impl Fn(usize, &[[f64; 3]]) -> [[u32; 3]; 2],
) -> (usize, usize) {
    let n = t.positions.len();
    let far: Vec<usize> = (0..n)
        .filter(|&v| {
            let d = sub(t.positions[v], t.mass[v]);
            dot(d, d).sqrt() > FAR
        })
        .collect();
    tracing::debug!(far = far.len(), "untangle suspects");
    if far.is_empty() {
        return (0, 0);
    }
    // Each vertex's quads.
    let (start, corners) = super::surface_nets::corners_by_vertex(n, t.quads);
    let of: Vec<u32> = corners.iter().map(|c| c / 4).collect();
    let quads_of = |v: u32| &of[start[v as usize] as usize..start[v as usize + 1] as usize];
    let triangles_at = |vs: &mut dyn Iterator<Item = u32>| {
        let mut out: Vec<u32> = vs
            .flat_map(|v| quads_of(v).iter().flat_map(|&q| [2 * q, 2 * q + 1]))
            .collect();
        out.sort_unstable();
        out.dedup();
        out
    };
    // The halving step each vertex has reached (0: at its QEF position).
    let mut step = vec![0u8; n];
    let mut suspects = triangles_at(&mut far.iter().map(|&v| v as u32));
    let mut moved = 0;
    for round in 0..=ROUNDS {
        let pairs = crossings(t, &suspects, &triangles_at);
        if pairs.is_empty() || round == ROUNDS {
            if !pairs.is_empty() {
                tracing::warn!(
                    pairs = pairs.len(),
                    "dual contouring: crossing triangles left"
                );
            }
            return (pairs.len(), moved);
        }
        let mut vs: Vec<u32> = pairs
            .iter()
            .flat_map(|&(a, b)| {
                let (ta, tb) = (t.triangles[a as usize], t.triangles[b as usize]);
                ta.into_iter().chain(tb)
            })
            .collect();
        vs.sort_unstable();
        vs.dedup();
        for &v in &vs {
            let v = v as usize;
            moved += usize::from(step[v] == 0);
            step[v] += 1;
            // Halfway to the mass point each round; on it in the last.
            let s = if round + 1 == ROUNDS {
                0.0
            } else {
                0.5f64.powi(i32::from(step[v]))
            };
            t.positions[v] = [0, 1, 2].map(|a| t.mass[v][a] + s * (t.solved[v][a] - t.mass[v][a]));
        }
        let mut touched: Vec<u32> = vs.iter().flat_map(|&v| quads_of(v).to_vec()).collect();
        touched.sort_unstable();
        touched.dedup();
        for &q in &touched {
            let [a, b] = split(q as usize, t.positions);
            t.triangles[2 * q as usize] = a;
            t.triangles[2 * q as usize + 1] = b;
        }
        suspects = touched.iter().flat_map(|&q| [2 * q, 2 * q + 1]).collect();
    }
    unreachable!("the last round returns")
}

/// A triangle (a suspect, or one near a group of them): its number, corners and bounding box.
type Candidate = (u32, [[f64; 3]; 3], [f64; 3], [f64; 3]);

/// The pairs (lower first) of a suspect and any triangle that crosses it.
fn crossings(
    t: &Tangle<'_>,
    suspects: &[u32],
    triangles_at: &(dyn Fn(&mut dyn Iterator<Item = u32>) -> Vec<u32> + Sync),
) -> Vec<(u32, u32)> {
    let corners = |i: u32| t.triangles[i as usize].map(|v| t.positions[v as usize]);
    let bbox = |p: &[[f64; 3]; 3]| -> ([f64; 3], [f64; 3]) {
        (
            std::array::from_fn(|k| p[0][k].min(p[1][k]).min(p[2][k])),
            std::array::from_fn(|k| p[0][k].max(p[1][k]).max(p[2][k])),
        )
    };
    let shape = |a: u32| -> Candidate {
        let p = corners(a);
        let (lo, hi) = bbox(&p);
        (a, p, lo, hi)
    };
    // Each suspect's corners and box, found once for the grouping and the tests.
    let shapes: Vec<Candidate> = suspects.iter().map(|&a| shape(a)).collect();
    // The suspects in groups of neighbours (consecutive in number, their boxes' union at most
    // GROUP_SPAN a side, at most GROUP_LEN of them), each group's neighbourhood looked up once:
    // the lookup (a search of the lattice points per column, the neighbours' triangles sorted)
    // cost more than the tests, and a suspect's neighbours are mostly its group's too.
    let mut groups: Vec<(&[Candidate], [f64; 3], [f64; 3])> = vec![];
    let mut i = 0;
    while i < shapes.len() {
        let (_, _, mut lo, mut hi) = shapes[i];
        let mut j = i + 1;
        while j < shapes.len() && j - i < GROUP_LEN {
            let (_, _, l, h) = shapes[j];
            let (nl, nh): ([f64; 3], [f64; 3]) = (
                std::array::from_fn(|k| lo[k].min(l[k])),
                std::array::from_fn(|k| hi[k].max(h[k])),
            );
            if (0..3).any(|k| nh[k] - nl[k] > GROUP_SPAN) {
                break;
            }
            (lo, hi) = (nl, nh);
            j += 1;
        }
        groups.push((&shapes[i..j], lo, hi));
        i = j;
    }
    let mut pairs: Vec<(u32, u32)> = groups
        .par_iter()
        .flat_map_iter(|&(group, lo, hi)| {
            // A triangle meeting the group's box has its lattice points within 1.5 of the box
            // on every axis (its vertices are within ½ of theirs, which differ by at most 1).
            let from: [u32; 3] = std::array::from_fn(|k| (lo[k] - 1.5).ceil().max(0.0) as u32);
            let to: [u32; 3] = std::array::from_fn(|k| (hi[k] + 1.5).floor().max(0.0) as u32);
            let mut near = vec![];
            for x in from[0]..=to[0] {
                for y in from[1]..=to[1] {
                    let i = t
                        .cells
                        .partition_point(|c| (c[0], c[1], c[2]) < (x, y, from[2]));
                    let j =
                        i + t.cells[i..].partition_point(|c| (c[0], c[1], c[2]) <= (x, y, to[2]));
                    near.extend(i as u32..j as u32);
                }
            }
            let candidates: Vec<Candidate> = triangles_at(&mut near.into_iter())
                .into_iter()
                .map(shape)
                .collect();
            let mut out = vec![];
            for &(a, pa, lo, hi) in group {
                let ta = t.triangles[a as usize];
                for &(b, pb, blo, bhi) in &candidates {
                    if b != a
                        && (0..3).all(|k| blo[k] <= hi[k] && bhi[k] >= lo[k])
                        && triangles_cross(ta, pa, t.triangles[b as usize], pb)
                    {
                        out.push((a.min(b), a.max(b)));
                    }
                }
            }
            out
        })
        .collect();
    pairs.sort_unstable();
    pairs.dedup();
    pairs
}
