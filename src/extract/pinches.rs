//! Which pinched edges surface nets joins. A lattice edge is *pinched* when, of the four voxels
//! around it, the two inside ones are diagonal. The boundary's faces around it are linked in
//! pairs at each of its two ends: by inside voxel (the two voxels kept apart, the rule of
//! `cubes`) unless that would let a sheet at *both* ends hold faces of both voxels — the two
//! voxels joined through the other voxels of both blocks — which would make the two dual cells'
//! vertices share two quad edges (an edge of four triangles). Such an edge is linked by
//! outside voxel instead (the two voxels joined). Joining only ever adds inside connections, so
//! an edge that is joined never needs to be undone; the edges are decided again until none
//! changes (at most one pass per pinched edge, in practice one or two).

use std::collections::HashSet;
use std::sync::OnceLock;

use super::cubes::{SHEETS, block, face_index, sheets, sheets_for};
use crate::volume::BitVolume;

use super::faces::Edge;

/// The pinched edges surface nets joins.
#[derive(Default)]
pub(super) struct Joins(HashSet<Edge, foldhash::fast::RandomState>);

/// The near voxels of half-edge (e, side) of a block, as octants: (set, set, unset, unset).
fn around(set: u8, e: usize, side: u8) -> Option<[u8; 4]> {
    let (b, c) = ((e + 1) % 3, (e + 2) % 3);
    let q = |i: u8, j: u8| side << e | i << b | j << c;
    let on = |o: u8| set >> o & 1 == 1;
    let (q00, q10, q01, q11) = (q(0, 0), q(1, 0), q(0, 1), q(1, 1));
    if !(on(q00) == on(q11) && on(q10) == on(q01) && on(q00) != on(q10)) {
        return None;
    }
    Some(if on(q00) {
        [q00, q11, q10, q01]
    } else {
        [q10, q01, q00, q11]
    })
}

/// For each block occupancy, its pinched half-edges (bit e·2 + side: [`around`] is some).
/// Most mixed blocks have none, and [`Joins::flags`] looks nothing up for them.
fn pinched() -> &'static [u8; 256] {
    static PINCHED: OnceLock<[u8; 256]> = OnceLock::new();
    PINCHED.get_or_init(|| {
        std::array::from_fn(|set| {
            let mut m = 0;
            for e in 0..3 {
                for side in 0..2u8 {
                    if around(set as u8, e, side).is_some() {
                        m |= 1 << (e * 2 + usize::from(side));
                    }
                }
            }
            m
        })
    })
}

/// The face between octants `x` and `y` (one bit apart).
fn face(x: u8, y: u8) -> usize {
    let a = (x ^ y).trailing_zeros() as usize;
    face_index(a, x & !(1 << a))
}

impl Joins {
    /// The joined half-edges of the block at `p` with occupancy `set` (bit e·2 + side).
    /// Inlined: a block with no pinched edge (nearly every one) or no edge joined at all is
    /// answered by one table lookup; the rest are looked up out of line.
    #[inline]
    pub(super) fn flags(&self, p: [u32; 3], set: u8) -> u8 {
        let half_edges = pinched()[usize::from(set)];
        if half_edges == 0 || self.0.is_empty() {
            return 0;
        }
        self.looked_up(p, half_edges)
    }

    /// [`Joins::flags`] of the block at `p` with pinched half-edges `half_edges`: each looked
    /// up.
    #[inline(never)]
    fn looked_up(&self, p: [u32; 3], mut half_edges: u8) -> u8 {
        let mut flags = 0;
        while half_edges != 0 {
            let bit = half_edges.trailing_zeros() as usize;
            half_edges &= half_edges - 1;
            let (e, side) = (bit / 2, bit % 2);
            let mut lo = p;
            if side == 0 {
                lo[e] -= 1;
            }
            if self.0.contains(&(lo, e as u8)) {
                flags |= 1 << bit;
            }
        }
        flags
    }

    /// Decides every pinched edge of `bits` (`edges`: all of them, from
    /// `faces::plane_counts_and_pinches`).
    pub(super) fn decide(bits: &BitVolume, edges: &[Edge]) -> Joins {
        let d = bits.dims();
        let occ = |p: [i64; 3]| {
            (0..3).all(|a| p[a] >= 0 && p[a] < i64::from(d[a]))
                && bits.get(p[0] as u32, p[1] as u32, p[2] as u32)
        };
        let mut joins = Joins::default();
        // Do the sheets at the block of `p` join the inside voxels of its half-edge (e, side)?
        let joined_at = |joins: &Joins, p: [u32; 3], e: usize, side: u8| {
            let set = block(&occ, p);
            let [a, b, c, _] = around(set, e, side).expect("a pinched edge");
            let sheet = match joins.flags(p, set) {
                0 => SHEETS.get_or_init(sheets)[set as usize],
                j => sheets_for(set, j),
            };
            sheet[face(a, c)] == sheet[face(b, c)]
        };
        for _ in 0..=edges.len() {
            let mut changed = false;
            for &(lo, e) in edges {
                if joins.0.contains(&(lo, e)) {
                    continue;
                }
                let mut hi = lo;
                hi[e as usize] += 1;
                if joined_at(&joins, lo, e as usize, 1) && joined_at(&joins, hi, e as usize, 0) {
                    joins.0.insert((lo, e));
                    changed = true;
                }
            }
            if !changed {
                break;
            }
        }
        joins
    }
}
