//! Volumes on a grid, of any kind ([`Volume`], [`VolumeKind`]): [`BitVolume`] (one bit per
//! voxel, here), dense typed volumes ([`Dense`], [`DensityVolume`]: `dense.rs`), bit volumes with
//! attribute channels ([`Attributed`]: `channels.rs`) and sparse 8³ bricks ([`Sparse`]:
//! `sparse.rs`). Operations on them live in the sibling modules, each stating which kinds it
//! takes; nothing here reads or writes files (that is `codec`).
//!
//! A `BitVolume` is a set of Z-columns. Column (x, y) is `words_per_column` little-endian `u64`
//! words at `(x * Y + y) * words_per_column`; bit `k % 64` of word `k / 64` is voxel (x, y, k).
//! Bits at `k >= Z` are always zero, so word-wise equality and popcounts are exact. Read as `u32`
//! words on a little-endian machine, the same memory is the GPU's layout (bit `k % 32` of word
//! `k / 32`).

pub mod channels;
pub mod csg;
pub mod dense;
pub mod kind;
pub mod levelset;
pub mod morph;
pub mod normals;
pub mod preview;
pub mod query;
pub mod sparse;
pub mod stats;

pub use channels::{Attributed, Channel, ChannelValues};
pub use dense::{Dense, DensityVolume};
pub use kind::{ValueType, VolumeKind, Voxel, VoxelValue, WrongKind};
pub use sparse::Sparse;

use crate::grid::Grid;

#[derive(Clone, Debug, PartialEq)]
pub struct BitVolume {
    grid: Grid,
    words_per_column: usize,
    words: Vec<u64>,
}

impl BitVolume {
    /// An empty volume on `grid`.
    pub fn new(grid: Grid) -> BitVolume {
        let wpc = words_per_column(grid.dims[2]);
        let n = grid.dims[0] as usize * grid.dims[1] as usize * wpc;
        BitVolume {
            grid,
            words_per_column: wpc,
            words: vec![0; n],
        }
    }

    /// Wraps column words laid out as described in the module docs. Fails when the length is
    /// wrong or a bit beyond Z is set.
    pub fn from_words(grid: Grid, words: Vec<u64>) -> Result<BitVolume, String> {
        let v = BitVolume {
            grid,
            words_per_column: words_per_column(grid.dims[2]),
            words,
        };
        let want = grid.dims[0] as usize * grid.dims[1] as usize * v.words_per_column;
        if v.words.len() != want {
            return Err(format!(
                "expected {want} column words for dims {:?}, got {}",
                grid.dims,
                v.words.len()
            ));
        }
        let tail = v.tail_mask();
        if v.words
            .chunks_exact(v.words_per_column)
            .any(|c| c[c.len() - 1] & !tail != 0)
        {
            return Err("a bit beyond the top of a column is set".into());
        }
        Ok(v)
    }

    pub fn grid(&self) -> &Grid {
        &self.grid
    }
    pub fn dims(&self) -> [u32; 3] {
        self.grid.dims
    }
    pub fn words_per_column(&self) -> usize {
        self.words_per_column
    }
    pub fn words(&self) -> &[u64] {
        &self.words
    }
    pub fn words_mut(&mut self) -> &mut [u64] {
        &mut self.words
    }
    pub fn into_words(self) -> Vec<u64> {
        self.words
    }

    /// Mask of the valid bits of a column's last word.
    pub fn tail_mask(&self) -> u64 {
        tail_mask(self.grid.dims[2])
    }

    fn column_start(&self, x: u32, y: u32) -> usize {
        debug_assert!(x < self.grid.dims[0] && y < self.grid.dims[1]);
        (x as usize * self.grid.dims[1] as usize + y as usize) * self.words_per_column
    }

    pub fn column(&self, x: u32, y: u32) -> &[u64] {
        let s = self.column_start(x, y);
        &self.words[s..s + self.words_per_column]
    }

    pub fn column_mut(&mut self, x: u32, y: u32) -> &mut [u64] {
        let s = self.column_start(x, y);
        let w = self.words_per_column;
        &mut self.words[s..s + w]
    }

    pub fn get(&self, x: u32, y: u32, z: u32) -> bool {
        assert!(z < self.grid.dims[2], "z {z} outside the grid");
        self.column(x, y)[(z / 64) as usize] >> (z % 64) & 1 == 1
    }

    pub fn set(&mut self, x: u32, y: u32, z: u32, value: bool) {
        assert!(z < self.grid.dims[2], "z {z} outside the grid");
        let w = &mut self.column_mut(x, y)[(z / 64) as usize];
        let bit = 1u64 << (z % 64);
        if value { *w |= bit } else { *w &= !bit }
    }

    /// Number of set voxels.
    pub fn count_ones(&self) -> u64 {
        self.words.iter().map(|w| w.count_ones() as u64).sum()
    }

    /// Every set voxel as (x, y, z), in column order.
    pub fn iter_ones(&self) -> impl Iterator<Item = [u32; 3]> + '_ {
        let ny = self.grid.dims[1] as usize;
        let wpc = self.words_per_column;
        self.words
            .iter()
            .enumerate()
            .filter(|(_, w)| **w != 0)
            .flat_map(move |(i, &w)| {
                let col = i / wpc;
                let (x, y) = ((col / ny) as u32, (col % ny) as u32);
                let base = ((i % wpc) * 64) as u32;
                BitIter(w).map(move |b| [x, y, base + b])
            })
    }

    /// Inclusive index bounds (min, max) of the set voxels, or `None` when empty.
    pub fn solid_bounds(&self) -> Option<([u32; 3], [u32; 3])> {
        let mut lo = [u32::MAX; 3];
        let mut hi = [0u32; 3];
        let ny = self.grid.dims[1] as usize;
        let wpc = self.words_per_column;
        let mut any = false;
        for (col, words) in self.words.chunks_exact(wpc).enumerate() {
            let first = words.iter().position(|&w| w != 0);
            let Some(first) = first else { continue };
            let last = words.iter().rposition(|&w| w != 0).unwrap();
            any = true;
            let (x, y) = ((col / ny) as u32, (col % ny) as u32);
            let zlo = first as u32 * 64 + words[first].trailing_zeros();
            let zhi = last as u32 * 64 + 63 - words[last].leading_zeros();
            for (a, v) in [(0, x), (1, y)] {
                lo[a] = lo[a].min(v);
                hi[a] = hi[a].max(v);
            }
            lo[2] = lo[2].min(zlo);
            hi[2] = hi[2].max(zhi);
        }
        any.then_some((lo, hi))
    }

    /// `self |= other`, `self &= other`, `self &= !other` on the same grid.
    pub fn union_with(&mut self, other: &BitVolume) {
        self.zip_words(other, |a, b| a | b)
    }
    pub fn intersect_with(&mut self, other: &BitVolume) {
        self.zip_words(other, |a, b| a & b)
    }
    pub fn subtract(&mut self, other: &BitVolume) {
        self.zip_words(other, |a, b| a & !b)
    }
    pub fn xor_with(&mut self, other: &BitVolume) {
        self.zip_words(other, |a, b| a ^ b)
    }

    fn zip_words(&mut self, other: &BitVolume, f: impl Fn(u64, u64) -> u64) {
        assert_eq!(
            self.grid.dims, other.grid.dims,
            "volumes on different grids"
        );
        for (a, &b) in self.words.iter_mut().zip(&other.words) {
            *a = f(*a, b);
        }
    }
}

/// Word `w` of a column shifted by `shift` bits along z (bit k of the result = bit k − shift of
/// `src`; bits shifted in from outside the column are zero).
pub(crate) fn shifted_word(src: &[u64], w: usize, shift: i64) -> u64 {
    let (q, r) = (shift.div_euclid(64), shift.rem_euclid(64) as u32);
    let get = |i: i64| {
        if i >= 0 && (i as usize) < src.len() {
            src[i as usize]
        } else {
            0
        }
    };
    let i = w as i64 - q;
    if r == 0 {
        get(i)
    } else {
        (get(i) << r) | (get(i - 1) >> (64 - r))
    }
}

/// Words needed for a column of `z` bits: always a whole number of `u64`, so the column is also a
/// whole (even) number of `u32` words for the GPU.
pub fn words_per_column(z: u32) -> usize {
    (z as usize).div_ceil(64)
}

/// Mask of the valid bits in the last word of a column of `z` bits.
pub fn tail_mask(z: u32) -> u64 {
    match z % 64 {
        0 => u64::MAX,
        r => (1u64 << r) - 1,
    }
}

struct BitIter(u64);
impl Iterator for BitIter {
    type Item = u32;
    fn next(&mut self) -> Option<u32> {
        if self.0 == 0 {
            return None;
        }
        let b = self.0.trailing_zeros();
        self.0 &= self.0 - 1;
        Some(b)
    }
}

/// Any stored volume. Code that works on volumes goes through the methods here (the one place
/// that matches every kind) or takes the variant it accepts after [`VolumeKind::require`]; a new
/// kind is a variant, a row of [`VolumeKind`], and an arm in each method below.
#[derive(Clone, Debug, PartialEq)]
pub enum Volume {
    Bits(BitVolume),
    Density(DensityVolume),
    Distance(Dense<f32>),
    Material(Dense<u16>),
    Colour(Dense<[u8; 4]>),
    Channels(Attributed),
    SparseDistance(Sparse<f32>),
    SparseMaterial(Sparse<u16>),
    SparseColour(Sparse<[u8; 4]>),
}

/// One arm per variant: `$t` with `$v` bound to the [`Dense`] or [`Sparse`] inside any typed
/// variant (they share `grid`, `get` and `count_occupied`), and one arm each for the rest.
macro_rules! each {
    ($vol:expr, $v:ident => $t:expr,
     Bits($b:ident) => $bits:expr, Density($d:ident) => $dens:expr, Channels($c:ident) => $ch:expr) => {
        match $vol {
            Volume::Bits($b) => $bits,
            Volume::Density($d) => $dens,
            Volume::Channels($c) => $ch,
            Volume::Distance($v) => $t,
            Volume::Material($v) => $t,
            Volume::Colour($v) => $t,
            Volume::SparseDistance($v) => $t,
            Volume::SparseMaterial($v) => $t,
            Volume::SparseColour($v) => $t,
        }
    };
}

/// The kinds bit-volume operations take.
pub const BITS_ONLY: &[VolumeKind] = &[VolumeKind::Bits];
/// Bit volumes with or without attribute channels: what the formats that list or draw set
/// voxels hold.
pub const BITS_AND_CHANNELS: &[VolumeKind] = &[VolumeKind::Bits, VolumeKind::Channels];

impl Volume {
    pub fn grid(&self) -> &Grid {
        each!(self, v => v.grid(),
            Bits(b) => b.grid(), Density(d) => d.grid(), Channels(c) => c.bits().grid())
    }

    pub fn kind(&self) -> VolumeKind {
        match self {
            Volume::Bits(_) => VolumeKind::Bits,
            Volume::Density(_) => VolumeKind::Density,
            Volume::Distance(_) => VolumeKind::Distance,
            Volume::Material(_) => VolumeKind::Material,
            Volume::Colour(_) => VolumeKind::Colour,
            Volume::Channels(_) => VolumeKind::Channels,
            Volume::SparseDistance(_) => VolumeKind::SparseDistance,
            Volume::SparseMaterial(_) => VolumeKind::SparseMaterial,
            Volume::SparseColour(_) => VolumeKind::SparseColour,
        }
    }

    /// Voxel (x, y, z)'s value in its own type: 0/1 for bits (and a channel volume's bits),
    /// 0..=max for density. Panics outside the grid.
    pub fn value(&self, x: u32, y: u32, z: u32) -> VoxelValue {
        each!(self, v => v.get(x, y, z).value(),
            Bits(b) => VoxelValue::U8(b.get(x, y, z) as u8),
            Density(d) => VoxelValue::U8(d.get(x, y, z)),
            Channels(c) => VoxelValue::U8(c.bits().get(x, y, z) as u8))
    }

    /// The value of every point outside the grid: empty (0; a distance of +∞), or a sparse
    /// volume's background.
    pub fn outside(&self) -> VoxelValue {
        each!(self, v => v.outside().value(),
            Bits(_b) => VoxelValue::U8(0), Density(_d) => VoxelValue::U8(0),
            Channels(_c) => VoxelValue::U8(0))
    }

    /// Is voxel (x, y, z) occupied (set, non-zero, inside: [`Voxel::occupied`])? Panics outside
    /// the grid.
    pub fn occupied(&self, x: u32, y: u32, z: u32) -> bool {
        each!(self, v => v.get(x, y, z).occupied(),
            Bits(b) => b.get(x, y, z),
            Density(d) => d.get(x, y, z) != 0,
            Channels(c) => c.bits().get(x, y, z))
    }

    /// Occupied voxels.
    pub fn count_occupied(&self) -> u64 {
        each!(self, v => v.count_occupied(),
            Bits(b) => b.count_ones(), Density(d) => d.count_nonzero(), Channels(c) => c.len())
    }

    /// The set voxels' colours (rank order) of a volume with a colour channel.
    pub fn colours(&self) -> Option<&[[u8; 4]]> {
        match self {
            Volume::Channels(a) => a.colours(),
            _ => None,
        }
    }

    /// The bits of a bit volume or of a bit volume with channels.
    pub fn bits(&self) -> Option<&BitVolume> {
        match self {
            Volume::Bits(b) => Some(b),
            Volume::Channels(a) => Some(a.bits()),
            _ => None,
        }
    }

    /// The bit volume (a channel volume's bits, its channels dropped: for the operations whose
    /// `ACCEPTS` lists [`BITS_AND_CHANNELS`] and that read only occupancy), or the refusal of
    /// `what`.
    pub fn into_bits(self, what: &str) -> Result<BitVolume, WrongKind> {
        match self {
            Volume::Bits(b) => Ok(b),
            Volume::Channels(a) => Ok(a.into_bits()),
            other => Err(WrongKind {
                given: other.kind(),
                accepts: BITS_ONLY,
                what: what.into(),
            }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(d: [u32; 3]) -> Grid {
        Grid {
            origin: [0.0; 3],
            voxel_size: 1.0,
            dims: d,
        }
    }

    #[test]
    fn set_get_count_iterate() {
        let mut v = BitVolume::new(grid([3, 5, 130]));
        let pts = [[0, 0, 0], [2, 4, 129], [1, 3, 64], [1, 3, 63]];
        for p in pts {
            v.set(p[0], p[1], p[2], true);
        }
        assert_eq!(v.count_ones(), 4);
        assert!(v.get(2, 4, 129) && !v.get(2, 4, 128));
        let mut got: Vec<_> = v.iter_ones().collect();
        got.sort();
        let mut want = pts.to_vec();
        want.sort();
        assert_eq!(got, want);
        assert_eq!(v.solid_bounds(), Some(([0, 0, 0], [2, 4, 129])));
        v.set(2, 4, 129, false);
        assert_eq!(v.count_ones(), 3);
        assert_eq!(BitVolume::new(grid([2, 2, 2])).solid_bounds(), None);
    }

    #[test]
    fn from_words_rejects_stray_bits() {
        let g = grid([1, 1, 10]);
        assert!(BitVolume::from_words(g, vec![1 << 10]).is_err());
        assert!(BitVolume::from_words(g, vec![1 << 9]).is_ok());
        assert!(BitVolume::from_words(g, vec![0, 0]).is_err());
    }

    #[test]
    fn word_ops() {
        let g = grid([2, 2, 70]);
        let mut a = BitVolume::new(g);
        let mut b = BitVolume::new(g);
        a.set(0, 0, 1, true);
        a.set(1, 1, 69, true);
        b.set(1, 1, 69, true);
        b.set(0, 1, 2, true);
        let mut u = a.clone();
        u.union_with(&b);
        assert_eq!(u.count_ones(), 3);
        let mut i = a.clone();
        i.intersect_with(&b);
        assert_eq!(i.iter_ones().collect::<Vec<_>>(), vec![[1, 1, 69]]);
        let mut d = a.clone();
        d.subtract(&b);
        assert_eq!(d.iter_ones().collect::<Vec<_>>(), vec![[0, 0, 1]]);
    }
}
