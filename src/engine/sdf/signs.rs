//! The sign of every voxel, brick by brick: what `sdf` keeps of the `solid` volume that signs
//! it. Per brick position two bits (some voxel inside, every voxel inside), and the 512 bits of
//! the bricks that hold both (the surface's bricks), so a 2048³ grid's signs take a few tens of
//! MB instead of the solid's 1 GB, which is dropped before the distances are computed.

use rayon::prelude::*;

use super::bins;
use crate::volume::BitVolume;
use crate::volume::sparse::BRICK;

/// A mixed brick's voxels, bit `((x%8)·8 + y%8)·8 + z%8` (the brick's voxel order) as word
/// `x%8`, bit `(y%8)·8 + z%8`.
pub type Mask = [u64; 8];

/// One brick row's codes (by bz: 0 none inside, 1 mixed, 2 all) and its mixed bricks' masks.
type RowSigns = (Vec<u8>, Vec<(u32, Mask)>);

/// The signs of a solid, by brick.
pub struct Signs {
    bd: [u32; 3],
    /// Bit per brick position (by [`bins::key`]): some voxel inside.
    any: Vec<u64>,
    /// Bit per brick position: every voxel (inside the grid) inside.
    all: Vec<u64>,
    /// The bricks with voxels of both signs, by key, and their voxels.
    mixed: Vec<(u64, Mask)>,
}

fn bit(v: &[u64], i: u64) -> bool {
    v[(i / 64) as usize] >> (i % 64) & 1 == 1
}

impl Signs {
    /// The signs of `solid`, brick row by brick row in parallel.
    pub fn new(solid: &BitVolume) -> Signs {
        let dims = solid.grid().dims;
        let bd = dims.map(|d| d.div_ceil(BRICK));
        let bz_n = bd[2] as usize;
        // The grid's voxels in a brick's z byte.
        let zmask = |bz: usize| -> u8 {
            let left = dims[2] as usize - bz * 8;
            if left >= 8 { 0xff } else { (1u8 << left) - 1 }
        };
        let rows: Vec<(u32, u32)> = (0..bd[0])
            .flat_map(|bx| (0..bd[1]).map(move |by| (bx, by)))
            .collect();
        // Per brick row: a code per bz (0 no voxel inside, 1 both, 2 every voxel inside) and
        // the masks of the mixed ones.
        let found: Vec<RowSigns> = rows
            .par_iter()
            .map(|&(bx, by)| {
                let mut masks = vec![[0u64; 8]; bz_n];
                let mut all = vec![true; bz_n];
                for x in bx * BRICK..(bx * BRICK + BRICK).min(dims[0]) {
                    for y in by * BRICK..(by * BRICK + BRICK).min(dims[1]) {
                        let col = solid.column(x, y);
                        for bz in 0..bz_n {
                            let byte = (col[bz / 8] >> ((bz % 8) * 8)) as u8 & zmask(bz);
                            masks[bz][(x % BRICK) as usize] |= u64::from(byte) << (8 * (y % BRICK));
                            all[bz] &= byte == zmask(bz);
                        }
                    }
                }
                let mut codes = vec![0u8; bz_n];
                let mut mixed = Vec::new();
                for bz in 0..bz_n {
                    if all[bz] {
                        codes[bz] = 2;
                    } else if masks[bz] != [0; 8] {
                        codes[bz] = 1;
                        mixed.push((bz as u32, masks[bz]));
                    }
                }
                (codes, mixed)
            })
            .collect();
        let n = bd.iter().map(|&d| d as u64).product::<u64>();
        let words = n.div_ceil(64) as usize;
        let (mut any, mut all) = (vec![0u64; words], vec![0u64; words]);
        let mut mixed = Vec::new();
        for (&(bx, by), (codes, masks)) in rows.iter().zip(found) {
            let k0 = bins::key([bx, by, 0], bd);
            for (bz, &c) in codes.iter().enumerate() {
                let k = k0 + bz as u64;
                if c > 0 {
                    any[(k / 64) as usize] |= 1 << (k % 64);
                }
                if c == 2 {
                    all[(k / 64) as usize] |= 1 << (k % 64);
                }
            }
            mixed.extend(masks.into_iter().map(|(bz, m)| (k0 + u64::from(bz), m)));
        }
        Signs {
            bd,
            any,
            all,
            mixed,
        }
    }

    /// Brick `at`: (some voxel inside, every voxel inside).
    pub fn brick(&self, at: [u32; 3]) -> (bool, bool) {
        let k = bins::key(at, self.bd);
        (bit(&self.any, k), bit(&self.all, k))
    }

    /// Brick `at`'s voxels (all zero when none is inside, all ones — past the grid too — when
    /// every voxel is).
    pub fn mask(&self, at: [u32; 3]) -> Mask {
        match self.brick(at) {
            (false, _) => [0; 8],
            (true, true) => [u64::MAX; 8],
            (true, false) => {
                let k = bins::key(at, self.bd);
                let i = self
                    .mixed
                    .binary_search_by_key(&k, |m| m.0)
                    .expect("a mixed brick has its mask");
                self.mixed[i].1
            }
        }
    }

    /// Voxel `i` (the brick's voxel order) of `mask`.
    #[inline]
    pub fn inside(mask: &Mask, i: usize) -> bool {
        mask[i / 64] >> (i % 64) & 1 == 1
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        (self.any.len() + self.all.len()) * 8
            + self.mixed.len() * std::mem::size_of::<(u64, Mask)>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::Grid;

    /// Every voxel's sign from the brick codes and masks is the solid's, on a grid whose edges
    /// cut bricks, with empty, full and mixed bricks.
    #[test]
    fn signs_are_the_solids_voxel_by_voxel() {
        let grid = Grid {
            origin: [0.0; 3],
            voxel_size: 1.0,
            dims: [21, 17, 30],
        };
        let mut solid = BitVolume::new(grid);
        let mut s = 12345u64;
        for x in 0..21 {
            for y in 0..17 {
                for z in 0..30 {
                    s = s
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    // Bricks with x < 8: full; 8..16: random; 16..: empty but for a few.
                    let v = match x / 8 {
                        0 => true,
                        1 => s >> 60 < 7,
                        _ => s >> 58 == 0,
                    };
                    solid.set(x, y, z, v);
                }
            }
        }
        let signs = Signs::new(&solid);
        let (mut full, mut mixed, mut empty) = (0, 0, 0);
        for bx in 0..3 {
            for by in 0..3 {
                for bz in 0..4 {
                    let at = [bx, by, bz];
                    let mask = signs.mask(at);
                    let (mut any, mut all) = (false, true);
                    for i in 0..512 {
                        let v = [
                            bx * 8 + i as u32 / 64,
                            by * 8 + i as u32 / 8 % 8,
                            bz * 8 + i as u32 % 8,
                        ];
                        if (0..3).any(|a| v[a] >= grid.dims[a]) {
                            continue;
                        }
                        let want = solid.get(v[0], v[1], v[2]);
                        assert_eq!(Signs::inside(&mask, i), want, "voxel {v:?}");
                        any |= want;
                        all &= want;
                    }
                    assert_eq!(signs.brick(at), (any, all), "brick {at:?}");
                    match (any, all) {
                        (true, true) => full += 1,
                        (true, false) => mixed += 1,
                        _ => empty += 1,
                    }
                }
            }
        }
        assert!(full > 0 && mixed > 0 && empty > 0, "{full} {mixed} {empty}");
    }
}
