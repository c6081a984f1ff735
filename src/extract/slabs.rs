//! The vertices of a [`Net`](super::surface_nets::Net) numbered lattice slab by lattice slab:
//! every lattice point whose 2×2×2 block of voxels is mixed gets one vertex per sheet of the
//! boundary around it (`cubes::sheets_for`, with the pinched edges `pinches::Joins` joined),
//! numbered in (x, y, z, sheet) order. The blocks are read from the column words 64 lattice
//! points at a time, and the numbers are kept for two slabs only (the faces are visited in
//! order of their lowest lattice x, and a face's corners lie in its slab and the next), so a
//! face's four vertices are found by table lookups instead of a hash map keyed by point.

use std::sync::OnceLock;

use super::cubes::sheets_for;
use super::pinches::Joins;
use super::surface_nets::Face;
use crate::volume::BitVolume;

/// For each block occupancy with no pinch joined: each internal face's sheet as 0..count (in
/// the order of the sheets' names; `u8::MAX` for a face that is not a boundary face), and the
/// count.
static COMPACT: OnceLock<Vec<([u8; 12], u8)>> = OnceLock::new();

/// Is internal face `f` (0..12, `cubes::face_index`) of block occupancy `set` a boundary face?
fn boundary(set: u8, f: usize) -> bool {
    let a = f / 4;
    let o = ((f & 1) << ((a + 1) % 3)) | ((f >> 1 & 1) << ((a + 2) % 3));
    (set >> o & 1) != (set >> (o | 1 << a) & 1)
}

/// The sheets of `set` (named as `cubes::sheets_for` names them) numbered 0..count.
fn compact(set: u8, names: &[u8; 12]) -> ([u8; 12], u8) {
    let mut rank = [u8::MAX; 12];
    let mut out = [u8::MAX; 12];
    let mut n = 0;
    for f in (0..12).filter(|&f| boundary(set, f)) {
        let s = usize::from(names[f]);
        if rank[s] == u8::MAX {
            rank[s] = n;
            n += 1;
        }
        out[f] = rank[s];
    }
    (out, n)
}

/// Sheets a block has at most: each is a cycle of at least three of its 12 internal faces.
const MAX_SHEETS: usize = 4;

/// Each sheet's vertex before relaxation, for the numbering `compact` gives (`nums`, `n`): the
/// mean of the centres of its faces, as an offset from the block's lattice point (lane 3 zero).
/// Internal face `f` across axis `a` = f / 4 lies in the lattice point's plane of `a`, its
/// centre half a voxel from the point along the other two axes, towards the octants named by
/// its bits (`face_index`).
fn sheet_offsets(nums: &[u8; 12], n: u8) -> [[f32; 4]; MAX_SHEETS] {
    let mut sum = [[0.0f64; 4]; MAX_SHEETS];
    for (f, &s) in nums.iter().enumerate() {
        if s == u8::MAX {
            continue;
        }
        let a = f / 4;
        let s = &mut sum[usize::from(s)];
        s[(a + 1) % 3] += (f & 1) as f64 - 0.5;
        s[(a + 2) % 3] += (f >> 1 & 1) as f64 - 0.5;
        s[3] += 1.0;
    }
    let mut out = [[0.0f32; 4]; MAX_SHEETS];
    for (o, s) in out.iter_mut().zip(&sum).take(usize::from(n)) {
        *o = [
            (s[0] / s[3]) as f32,
            (s[1] / s[3]) as f32,
            (s[2] / s[3]) as f32,
            0.0,
        ];
    }
    out
}

/// Room for every vertex of the slabs that the faces of lattice planes `from ..= upto` — the
/// faces with a corner in them — touch (`faces`: their count): each vertex is a sheet of at
/// least three of its block's faces, and each face is a corner of four blocks. A surface has
/// about as many vertices as faces, so three quarters of the room are used, and the rest is
/// never touched (no memory behind it).
pub(super) fn room(faces: usize) -> usize {
    (4 * faces).div_ceil(3)
}

/// The offset of a vertex of shape `code` ([`Slabs::shapes`]): its [`sheet_offsets`] entry.
#[inline]
pub(super) fn shape_offset(code: u32) -> [f32; 4] {
    let (set, flags, sheet) = (code as u8, (code >> 8) as u8, (code >> 16) as usize);
    if flags == 0 {
        offsets_table()[usize::from(set)][sheet]
    } else {
        let (nums, n) = compact(set, &sheets_for(set, flags));
        sheet_offsets(&nums, n)[sheet]
    }
}

/// [`sheet_offsets`] of each block occupancy with no pinch joined.
static OFFSETS: OnceLock<Vec<[[f32; 4]; MAX_SHEETS]>> = OnceLock::new();

fn offsets_table() -> &'static [[[f32; 4]; MAX_SHEETS]] {
    OFFSETS.get_or_init(|| {
        compact_table()
            .iter()
            .map(|(nums, n)| sheet_offsets(nums, *n))
            .collect()
    })
}

fn compact_table() -> &'static [([u8; 12], u8)] {
    COMPACT.get_or_init(|| {
        (0..=255u8)
            .map(|set| compact(set, &sheets_for(set, 0)))
            .collect()
    })
}

/// [`compact`] numbering of a block with joined half-edges (rare: out of line).
#[cold]
#[inline(never)]
fn joined(set: u8, flags: u8) -> ([u8; 12], u8) {
    compact(set, &sheets_for(set, flags))
}

/// A lattice point's first vertex, block occupancy and joined half-edges (one load per
/// corner: the two slabs' tables are larger than a core's cache).
#[derive(Clone, Copy, Default)]
struct Block {
    base: u32,
    set: u8,
    flags: u8,
}

/// Two slabs of lattice-point vertex numbers, advanced as the faces are visited.
pub(super) struct Slabs<'a> {
    bits: &'a BitVolume,
    joins: &'a Joins,
    table: &'static [([u8; 12], u8)],
    zero: Vec<u64>,
    /// Lattice points per slab row (dims z + 1).
    stride: usize,
    /// By slab parity, by (y, z): the lattice point's block.
    blocks: [Vec<Block>; 2],
    /// The first slab not numbered yet.
    next: u32,
    /// Each vertex numbered so far: its lattice point (the first `count` entries).
    points: &'a mut [[u32; 3]],
    /// Vertices numbered so far.
    pub count: usize,
    /// The first vertex of the last slab numbered.
    pub last_start: usize,
    /// Each vertex numbered so far: its block occupancy, joined half-edges and sheet, as
    /// `set | flags << 8 | sheet << 16` ([`shape_offset`] gives its offset; filled only when
    /// asked for: 4 bytes a vertex while the runs are held, where its offset takes 16).
    shapes: &'a mut [u32],
    with_offsets: bool,
}

impl<'a> Slabs<'a> {
    /// Slabs numbered from slab `from` on (its first vertex numbered 0), each vertex's lattice
    /// point written to `points` and, when `with_offsets`, its shape to `shapes` (both with
    /// room for every vertex numbered: [`room`]).
    pub(super) fn new(
        bits: &'a BitVolume,
        joins: &'a Joins,
        from: u32,
        with_offsets: bool,
        points: &'a mut [[u32; 3]],
        shapes: &'a mut [u32],
    ) -> Slabs<'a> {
        let d = bits.dims();
        let n = (d[1] as usize + 1) * (d[2] as usize + 1);
        Slabs {
            bits,
            joins,
            table: compact_table(),
            zero: vec![0; bits.words_per_column()],
            stride: d[2] as usize + 1,
            blocks: [vec![Block::default(); n], vec![Block::default(); n]],
            next: from,
            last_start: 0,
            points,
            count: 0,
            shapes,
            with_offsets,
        }
    }

    /// Numbers the slabs up to `x` (at most the last lattice slab, dims x), those before it
    /// first; only the last two numbered are kept.
    pub(super) fn reach(&mut self, x: u32) {
        let last = x.min(self.bits.dims()[0]);
        while self.next <= last {
            self.number(self.next);
            self.next += 1;
        }
    }

    /// The quad of face `f`: the vertices of its four corners, counter-clockwise seen from
    /// outside (from +a when `f.plus`). At corner (u + du, v + dv) the face is the block's
    /// internal face across a between the octants with bits (1 − du, 1 − dv).
    #[inline(always)]
    pub(super) fn quad(&self, f: &Face) -> [u32; 4] {
        let p = f.point(0, 0);
        // A step along axis 0 is the other slab's table, along 1 a row, along 2 an entry.
        let step = |axis: usize| match axis {
            0 => (1, 0),
            1 => (0, self.stride),
            _ => (0, 1),
        };
        let ((pu, iu), (pv, iv)) = (step((f.a + 1) % 3), step((f.a + 2) % 3));
        let (par, i) = (
            (p[0] & 1) as usize,
            p[1] as usize * self.stride + p[2] as usize,
        );
        // The four corners' blocks loaded first, then their sheets (no call per corner).
        let corners = [(0, 0), (1, 0), (1, 1), (0, 1)];
        let at = |(du, dv): (usize, usize)| {
            self.blocks[par ^ (pu * du) ^ (pv * dv)][i + iu * du + iv * dv]
        };
        let blocks = [
            at(corners[0]),
            at(corners[1]),
            at(corners[2]),
            at(corners[3]),
        ];
        let mut ring = [0u32; 4];
        for c in 0..4 {
            let (du, dv) = corners[c];
            let Block { base, set, flags } = blocks[c];
            let face = f.a * 4 + (1 - du) + 2 * (1 - dv);
            let r = self.numbering(set, flags).0[face];
            debug_assert!(r != u8::MAX, "a boundary face of the block");
            ring[c] = base + u32::from(r);
        }
        if !f.plus {
            ring.reverse();
        }
        ring
    }

    /// The [`compact`] numbering of a block's sheets: from the table when no half-edge is
    /// joined (nearly always), else computed.
    #[inline(always)]
    fn numbering(&self, set: u8, flags: u8) -> ([u8; 12], u8) {
        if flags == 0 {
            self.table[usize::from(set)]
        } else {
            joined(set, flags)
        }
    }

    fn number(&mut self, x: u32) {
        let bits = self.bits;
        let d = bits.dims();
        let par = (x & 1) as usize;
        // Words of lattice z: 64w..64w + 64, up to dims z.
        let nw = d[2] as usize / 64 + 1;
        self.last_start = self.count;
        for y in 0..=d[1] {
            // The four columns around the lattice row, k = dx + 2·dy (voxel x − 1 + dx,
            // y − 1 + dy).
            let cols: [&[u64]; 4] = std::array::from_fn(|k| {
                let (cx, cy) = (
                    i64::from(x) - 1 + (k & 1) as i64,
                    i64::from(y) - 1 + (k >> 1) as i64,
                );
                if cx < 0 || cy < 0 || cx >= i64::from(d[0]) || cy >= i64::from(d[1]) {
                    &self.zero[..]
                } else {
                    bits.column(cx as u32, cy as u32)
                }
            });
            let mut carry = [0u64; 4];
            for w in 0..nw {
                // Bit t: the voxel at z = 64w + t (up) and at z − 1 (lo).
                let words: [u64; 4] = std::array::from_fn(|k| cols[k].get(w).copied().unwrap_or(0));
                // Empty, and the voxels below them too (seven in ten words at igea-subdiv4
                // 518³): no mixed block, and the carries stay zero.
                if words.iter().chain(&carry).all(|&b| b == 0) {
                    continue;
                }
                let mut up = [0u64; 4];
                let mut lo = [0u64; 4];
                for (k, &word) in words.iter().enumerate() {
                    up[k] = word;
                    lo[k] = word << 1 | carry[k];
                    carry[k] = word >> 63;
                }
                let any = up.iter().chain(&lo).fold(0, |a, &b| a | b);
                let all = up.iter().chain(&lo).fold(u64::MAX, |a, &b| a & b);
                let mut mixed = any & !all;
                let room = i64::from(d[2]) - 64 * w as i64;
                if room < 63 {
                    mixed &= (1u64 << (room + 1)) - 1;
                }
                while mixed != 0 {
                    let t = mixed.trailing_zeros();
                    mixed &= mixed - 1;
                    let mut set = 0u8;
                    for k in 0..4 {
                        set |= ((lo[k] >> t & 1) as u8) << k;
                        set |= ((up[k] >> t & 1) as u8) << (k + 4);
                    }
                    let z = 64 * w as u32 + t;
                    let flags = self.joins.flags([x, y, z], set);
                    let n = self.numbering(set, flags).1;
                    let first = self.count;
                    let code = u32::from(set) | u32::from(flags) << 8;
                    for sheet in 0..usize::from(n) {
                        self.points[first + sheet] = [x, y, z];
                        if self.with_offsets {
                            self.shapes[first + sheet] = code | (sheet as u32) << 16;
                        }
                    }
                    self.count += usize::from(n);
                    let i = y as usize * self.stride + z as usize;
                    self.blocks[par][i] = Block {
                        base: first as u32,
                        set,
                        flags,
                    };
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::extract::cubes::{SHEETS, sheets};

    #[test]
    fn compact_numbers_keep_the_sheets_apart_and_together() {
        // Independent of the numbering: two boundary faces share a number iff `sheets` names
        // the same sheet for them, and the count is the number of distinct names.
        for set in 0..=255u8 {
            let names = SHEETS.get_or_init(sheets)[usize::from(set)];
            let (nums, n) = compact_table()[usize::from(set)];
            let faces: Vec<usize> = (0..12).filter(|&f| boundary(set, f)).collect();
            let mut distinct: Vec<u8> = faces.iter().map(|&f| names[f]).collect();
            distinct.sort_unstable();
            distinct.dedup();
            assert_eq!(usize::from(n), distinct.len(), "set {set:08b}");
            for &f in &faces {
                assert!(nums[f] < n);
                for &g in &faces {
                    assert_eq!(names[f] == names[g], nums[f] == nums[g], "set {set:08b}");
                }
            }
            // No boundary face at all exactly when the block is all in or all out.
            assert_eq!(faces.is_empty(), set == 0 || set == 255);
        }
    }
}
