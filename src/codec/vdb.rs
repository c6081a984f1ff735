//! OpenVDB `.vdb` files, written (never read): a sparse distance volume as a `FloatGrid` (tree
//! `Tree_float_5_4_3`, grid class `level set` when every inactive value is ±background) and a
//! bit volume as a `BoolGrid` (`Tree_bool_5_4_3`), one grid a file, file format version 224
//! (OpenVDB 10), no compression but OpenVDB's active-mask one (level sets: only the active
//! values of a node, its inactive ones ±background). `docs/format.md` ("OpenVDB") lists what is
//! written and what is not; the layout follows OpenVDB's `io/Archive.cc`, `tree/RootNode.h`,
//! `InternalNode.h`, `LeafNode.h`, `LeafNodeBool.h` and `io/Compression.h`.
//!
//! Everything is little-endian. A voxd brick is an OpenVDB leaf: brick (bx, by, bz) is the leaf
//! at index (8bx, 8by, 8bz), its 512 values in the same order (`((x%8)·8 + y%8)·8 + z%8`).
//! Leaves hang from internal nodes of 16³ children (128³ voxels), which hang from internal nodes
//! of 32³ children (4096³ voxels), which hang from the root. Index (i, j, k) is voxel (i, j, k)'s
//! centre: the transform maps it to `origin + (i + ½)·s`. A voxel is active when it is in the
//! band, `|v| < background`; a tile of a sparse volume is a tile of its 16³ node (inactive when
//! its value is out of the band) unless its brick sticks out of the grid, where it is written as
//! a leaf holding the tile value inside the grid and the background past it.
//!
//! The file is made whole in memory; its bytes depend on the volume alone (the header's UUID is
//! taken from a SHA-256 of the rest), so a download's ETag stays true.

use std::collections::BTreeMap;

use sha2::{Digest, Sha256};

use crate::grid::Grid;
use crate::volume::sparse::{BRICK, BRICK_VOXELS, Sparse};
use crate::volume::{BitVolume, Volume};

/// OpenVDB's magic number, `0x56444220` as a little-endian `i64`.
pub const MAGIC: &[u8; 8] = b"\x20\x42\x44\x56\0\0\0\0";
/// The file format version written (`OPENVDB_FILE_VERSION_MULTIPASS_IO`, OpenVDB 6 to 10).
pub const FILE_VERSION: u32 = 224;
/// The library version the header names.
const LIBRARY_VERSION: (u32, u32) = (10, 0);
/// `io::COMPRESS_NONE`, and `io::COMPRESS_ACTIVE_MASK` (only the active values of a node are
/// written, its inactive ones being ±background).
const COMPRESS_NONE: u32 = 0;
const COMPRESS_ACTIVE_MASK: u32 = 2;
/// The per-node flags of `io::writeCompressedValues`: every inactive value is +background
/// (`NO_MASK_OR_INACTIVE_VALS`), −background (`NO_MASK_AND_MINUS_BG`), or one of the two as a
/// selection mask says (`MASK_AND_NO_INACTIVE_VALS`, set: +background), and only the active
/// values follow; or every value follows (`NO_MASK_AND_ALL_VALS`).
const NO_MASK_OR_INACTIVE_VALS: u8 = 0;
const NO_MASK_AND_MINUS_BG: u8 = 1;
const MASK_AND_NO_INACTIVE_VALS: u8 = 3;
const NO_MASK_AND_ALL_VALS: u8 = 6;
/// Bytes of the file header: magic, versions, the offsets flag, the UUID.
const HEADER_BYTES: usize = 8 + 4 * 3 + 1 + 36;

/// Log2 of the children along an edge of the lower internal node (16) and the upper (32).
const LOWER_LOG2: u32 = 4;
const UPPER_LOG2: u32 = 5;

/// A value OpenVDB stores: its bytes, the zero written at a child's slot, its negation and
/// equality by bits (for mask compression).
trait VdbValue: Copy {
    const ZERO: Self;
    fn put(self, out: &mut Vec<u8>);
    fn neg(self) -> Self;
    fn same(self, other: Self) -> bool;
}

impl VdbValue for f32 {
    const ZERO: f32 = 0.0;
    fn put(self, out: &mut Vec<u8>) {
        out.extend_from_slice(&self.to_le_bytes());
    }
    fn neg(self) -> f32 {
        -self
    }
    fn same(self, other: f32) -> bool {
        self.to_bits() == other.to_bits()
    }
}

impl VdbValue for bool {
    const ZERO: bool = false;
    fn put(self, out: &mut Vec<u8>) {
        out.push(self as u8);
    }
    fn neg(self) -> bool {
        self
    }
    fn same(self, other: bool) -> bool {
        self == other
    }
}

/// A node's values as `io::writeCompressedValues` writes them: without mask compression the
/// flag `NO_MASK_AND_ALL_VALS` and every value; with it, the flag that says what the inactive
/// values are (a selection mask when both ±background occur) and the active values alone, or
/// every value when an inactive one is neither. `active` is the value mask; `skip` marks slots
/// whose value does not matter (children), taken as +background.
fn put_values<V: VdbValue>(
    out: &mut Vec<u8>,
    values: &[V],
    active: &[u64],
    skip: &[u64],
    background: V,
    compress: bool,
) {
    let on = |m: &[u64], i: usize| m.get(i / 64).is_some_and(|w| w >> (i % 64) & 1 == 1);
    if !compress {
        out.push(NO_MASK_AND_ALL_VALS);
        values.iter().for_each(|v| v.put(out));
        return;
    }
    let (mut plus, mut minus, mut other) = (false, false, false);
    for (i, v) in values.iter().enumerate() {
        if on(active, i) || on(skip, i) {
            continue;
        }
        if v.same(background) {
            plus = true;
        } else if v.same(background.neg()) {
            minus = true;
        } else {
            other = true;
        }
    }
    let flag = match (other, plus, minus) {
        (true, _, _) => NO_MASK_AND_ALL_VALS,
        (false, _, false) => NO_MASK_OR_INACTIVE_VALS,
        (false, false, true) => NO_MASK_AND_MINUS_BG,
        (false, true, true) => MASK_AND_NO_INACTIVE_VALS,
    };
    out.push(flag);
    if flag == NO_MASK_AND_ALL_VALS {
        values.iter().for_each(|v| v.put(out));
        return;
    }
    if flag == MASK_AND_NO_INACTIVE_VALS {
        let mut selection = vec![0u64; values.len().div_ceil(64)];
        for (i, v) in values.iter().enumerate() {
            let inactive = !on(active, i);
            if inactive && (on(skip, i) || v.same(background)) {
                selection[i / 64] |= 1 << (i % 64);
            }
        }
        put_words(out, &selection);
    }
    for (i, v) in values.iter().enumerate() {
        if on(active, i) {
            v.put(out);
        }
    }
}

/// A leaf's two sections: its topology (the value mask) and its buffers.
trait Leaf {
    fn topology(&self, out: &mut Vec<u8>);
    fn buffers(&self, out: &mut Vec<u8>, compress: bool);
}

/// A float leaf: the active mask and the 512 values (a brick's, or a tile's made into a leaf).
struct FloatLeaf<'a> {
    background: f32,
    active: [u64; 8],
    values: std::borrow::Cow<'a, [f32; BRICK_VOXELS]>,
}

impl Leaf for FloatLeaf<'_> {
    fn topology(&self, out: &mut Vec<u8>) {
        put_words(out, &self.active);
    }
    fn buffers(&self, out: &mut Vec<u8>, compress: bool) {
        put_words(out, &self.active);
        put_values(
            out,
            &self.values[..],
            &self.active,
            &[],
            self.background,
            compress,
        );
    }
}

/// A bool leaf: the set voxels, active and true; its buffers repeat its origin.
struct BoolLeaf {
    origin: [i32; 3],
    bits: [u64; 8],
}

impl Leaf for BoolLeaf {
    fn topology(&self, out: &mut Vec<u8>) {
        put_words(out, &self.bits);
    }
    fn buffers(&self, out: &mut Vec<u8>, _compress: bool) {
        put_words(out, &self.bits);
        for c in self.origin {
            out.extend_from_slice(&c.to_le_bytes());
        }
        put_words(out, &self.bits);
    }
}

/// A lower internal node (16³ slots of 8³): its leaves and tiles by slot.
struct Lower<L> {
    leaves: BTreeMap<u32, L>,
    tiles: Vec<u32>,
}

/// The tree below the root: root key (the upper node's origin) → upper slot → lower node.
type Roots<L> = BTreeMap<[i32; 3], BTreeMap<u32, Lower<L>>>;

/// Where brick `b` goes: its root key, upper slot and lower slot.
fn place(b: [u32; 3]) -> ([i32; 3], u32, u32) {
    let key = b.map(|c| ((c >> (UPPER_LOG2 + LOWER_LOG2)) << 12) as i32);
    let slot = |shift: u32, log2: u32| {
        let m = (1 << log2) - 1;
        ((b[0] >> shift & m) << (2 * log2)) | ((b[1] >> shift & m) << log2) | (b[2] >> shift & m)
    };
    (key, slot(LOWER_LOG2, UPPER_LOG2), slot(0, LOWER_LOG2))
}

fn lower_of<L>(roots: &mut Roots<L>, b: [u32; 3]) -> (&mut Lower<L>, u32) {
    let (key, upper, lower) = place(b);
    let node = roots
        .entry(key)
        .or_default()
        .entry(upper)
        .or_insert_with(|| Lower {
            leaves: BTreeMap::new(),
            tiles: Vec::new(),
        });
    (node, lower)
}

fn put_words(out: &mut Vec<u8>, words: &[u64]) {
    for w in words {
        out.extend_from_slice(&w.to_le_bytes());
    }
}

fn put_string(out: &mut Vec<u8>, s: &str) {
    out.extend_from_slice(&(s.len() as u32).to_le_bytes());
    out.extend_from_slice(s.as_bytes());
}

/// A node mask of `bits` bits with `on` set.
fn mask(bits: usize, on: impl Iterator<Item = u32>) -> Vec<u64> {
    let mut w = vec![0u64; bits / 64];
    for i in on {
        w[i as usize / 64] |= 1 << (i % 64);
    }
    w
}

/// The tree's topology then its buffers (`Tree::writeTopology`, `Tree::writeBuffers`): the
/// root with no tiles, each internal node's child mask, value mask and values, each leaf's;
/// `compress`: mask compression (see [`put_values`]). Returns the offset of the buffers.
fn write_tree<V: VdbValue, L: Leaf>(
    out: &mut Vec<u8>,
    background: V,
    tile: V,
    tile_active: bool,
    roots: &Roots<L>,
    compress: bool,
) -> usize {
    out.extend_from_slice(&1i32.to_le_bytes()); // buffer count
    background.put(out);
    out.extend_from_slice(&0u32.to_le_bytes()); // root tiles
    out.extend_from_slice(&(roots.len() as u32).to_le_bytes());
    let on = |m: &[u64], i: usize| m[i / 64] >> (i % 64) & 1 == 1;
    for (key, uppers) in roots {
        for c in key {
            out.extend_from_slice(&c.to_le_bytes());
        }
        let n = 1usize << (3 * UPPER_LOG2);
        let children = mask(n, uppers.keys().copied());
        let none = vec![0u64; n / 64];
        put_words(out, &children);
        put_words(out, &none);
        let values: Vec<V> = (0..n)
            .map(|i| {
                if on(&children, i) {
                    V::ZERO
                } else {
                    background
                }
            })
            .collect();
        put_values(out, &values, &none, &children, background, compress);
        for lower in uppers.values() {
            let n = 1usize << (3 * LOWER_LOG2);
            let children = mask(n, lower.leaves.keys().copied());
            let tiles = mask(n, lower.tiles.iter().copied());
            let active = if tile_active {
                tiles.clone()
            } else {
                vec![0u64; n / 64]
            };
            put_words(out, &children);
            put_words(out, &active);
            let values: Vec<V> = (0..n)
                .map(|i| {
                    if on(&children, i) {
                        V::ZERO
                    } else if on(&tiles, i) {
                        tile
                    } else {
                        background
                    }
                })
                .collect();
            put_values(out, &values, &active, &children, background, compress);
            for leaf in lower.leaves.values() {
                leaf.topology(out);
            }
        }
    }
    let buffers = out.len();
    for uppers in roots.values() {
        for lower in uppers.values() {
            for leaf in lower.leaves.values() {
                leaf.buffers(out, compress);
            }
        }
    }
    buffers
}

/// The grid's description: name, tree type, class and the volume's transform.
struct GridHead<'a> {
    name: &'a str,
    tree_type: &'a str,
    class: &'a str,
    grid: &'a Grid,
    /// `COMPRESS_NONE` or `COMPRESS_ACTIVE_MASK`.
    compression: u32,
}

/// The whole file around a tree written by `tree` (which returns the buffers' offset).
fn file(head: &GridHead, tree: impl FnOnce(&mut Vec<u8>) -> usize) -> Vec<u8> {
    let mut out = Vec::new();
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&FILE_VERSION.to_le_bytes());
    out.extend_from_slice(&LIBRARY_VERSION.0.to_le_bytes());
    out.extend_from_slice(&LIBRARY_VERSION.1.to_le_bytes());
    out.push(1); // has grid offsets
    out.extend_from_slice(&[b'0'; 36]); // the UUID, filled in at the end
    debug_assert_eq!(out.len(), HEADER_BYTES);
    out.extend_from_slice(&0u32.to_le_bytes()); // file metadata: none
    out.extend_from_slice(&1i32.to_le_bytes()); // grids
    // The grid descriptor: unique name, type, instance parent, then three offsets.
    put_string(&mut out, head.name);
    put_string(&mut out, head.tree_type);
    put_string(&mut out, "");
    let offsets = out.len();
    out.extend_from_slice(&[0; 24]);
    let grid_pos = out.len();
    out.extend_from_slice(&head.compression.to_le_bytes());
    // Metadata, by name: each a name, a type name, a byte count and the bytes.
    let meta = [
        ("class", head.class),
        ("creator", "voxd"),
        ("name", head.name),
    ];
    out.extend_from_slice(&(meta.len() as u32).to_le_bytes());
    for (k, v) in meta {
        put_string(&mut out, k);
        put_string(&mut out, "string");
        put_string(&mut out, v);
    }
    // The transform: index (i, j, k) → origin + (i + ½, j + ½, k + ½)·s.
    let s = head.grid.voxel_size;
    put_string(&mut out, "UniformScaleTranslateMap");
    let translation = head.grid.origin.map(|o| o + 0.5 * s);
    for v in [
        translation,
        [s; 3],
        [s; 3],
        [1.0 / s; 3],
        [1.0 / (s * s); 3],
        [0.5 / s; 3],
    ] {
        for c in v {
            out.extend_from_slice(&c.to_le_bytes());
        }
    }
    let block_pos = tree(&mut out);
    let end_pos = out.len();
    for (i, p) in [grid_pos, block_pos, end_pos].into_iter().enumerate() {
        out[offsets + 8 * i..offsets + 8 * i + 8].copy_from_slice(&(p as i64).to_le_bytes());
    }
    let digest = Sha256::digest(&out[HEADER_BYTES..]);
    out[HEADER_BYTES - 36..HEADER_BYTES].copy_from_slice(uuid(&digest).as_bytes());
    out
}

/// A UUID-shaped string (8-4-4-4-12 upper-case hex digits) from the first 16 bytes of `d`.
fn uuid(d: &[u8]) -> String {
    let hex: String = d[..16].iter().map(|b| format!("{b:02X}")).collect();
    format!(
        "{}-{}-{}-{}-{}",
        &hex[..8],
        &hex[8..12],
        &hex[12..16],
        &hex[16..20],
        &hex[20..32]
    )
}

/// Is brick `at` wholly inside a grid of `dims`?
fn inside(at: [u32; 3], dims: [u32; 3]) -> bool {
    (0..3).all(|a| (at[a] + 1) * BRICK <= dims[a])
}

fn float_mask(values: &[f32; BRICK_VOXELS], background: f32) -> [u64; 8] {
    let mut m = [0u64; 8];
    for (i, v) in values.iter().enumerate() {
        if v.abs() < background {
            m[i / 64] |= 1 << (i % 64);
        }
    }
    m
}

/// A sparse distance volume as an OpenVDB FloatGrid named `sdf`.
pub fn encode_sparse(s: &Sparse<f32>) -> Vec<u8> {
    let bg = s.background();
    let tile = s.tile_value();
    let dims = s.grid().dims;
    let mut roots: Roots<FloatLeaf> = BTreeMap::new();
    // A level set's inactive values are ±background; anything else is said to be of no class.
    let outside = |v: &f32| v.abs() >= bg;
    let pm = |v: f32| v.to_bits() == bg.to_bits() || v.to_bits() == (-bg).to_bits();
    let mut level_set = s.tile_count() == 0 || pm(tile) || !outside(&tile);
    for (at, values) in s.bricks() {
        level_set &= values.iter().filter(|v| outside(v)).all(|&v| pm(v));
        let (lower, slot) = lower_of(&mut roots, at);
        lower.leaves.insert(
            slot,
            FloatLeaf {
                background: bg,
                active: float_mask(values, bg),
                values: std::borrow::Cow::Borrowed(values),
            },
        );
    }
    for at in s.tiles() {
        let (lower, slot) = lower_of(&mut roots, at);
        if inside(at, dims) {
            lower.tiles.push(slot);
            continue;
        }
        let mut values = Box::new([bg; BRICK_VOXELS]);
        for (i, v) in values.iter_mut().enumerate() {
            let p = [i / 64, i / 8 % 8, i % 8].map(|c| c as u32);
            if (0..3).all(|a| at[a] * BRICK + p[a] < dims[a]) {
                *v = tile;
            }
        }
        lower.leaves.insert(
            slot,
            FloatLeaf {
                background: bg,
                active: float_mask(&values, bg),
                values: std::borrow::Cow::Owned(*values),
            },
        );
    }
    for uppers in roots.values_mut() {
        for lower in uppers.values_mut() {
            lower.tiles.sort_unstable();
        }
    }
    let head = GridHead {
        name: "sdf",
        tree_type: "Tree_float_5_4_3",
        class: if level_set { "level set" } else { "unknown" },
        grid: s.grid(),
        compression: COMPRESS_ACTIVE_MASK,
    };
    let tile_active = !outside(&tile);
    file(&head, |out| {
        write_tree(out, bg, tile, tile_active, &roots, true)
    })
}

/// A bit volume as an OpenVDB BoolGrid named `mask`: the set voxels active and true.
pub fn encode_bits(b: &BitVolume) -> Vec<u8> {
    let mut roots: Roots<BoolLeaf> = BTreeMap::new();
    for [x, y, z] in b.iter_ones() {
        let at = [x / BRICK, y / BRICK, z / BRICK];
        let (lower, slot) = lower_of(&mut roots, at);
        let leaf = lower.leaves.entry(slot).or_insert_with(|| BoolLeaf {
            origin: at.map(|c| (c * BRICK) as i32),
            bits: [0; 8],
        });
        let i = (((x % BRICK) * BRICK + y % BRICK) * BRICK + z % BRICK) as usize;
        leaf.bits[i / 64] |= 1 << (i % 64);
    }
    let head = GridHead {
        name: "mask",
        tree_type: "Tree_bool_5_4_3",
        class: "unknown",
        grid: b.grid(),
        compression: COMPRESS_NONE,
    };
    file(&head, |out| {
        write_tree(out, false, false, false, &roots, false)
    })
}

/// `v` as a `.vdb`: sparse distance volumes and bit volumes (the format's row says which).
pub fn encode(v: &Volume) -> Option<Vec<u8>> {
    match v {
        Volume::SparseDistance(s) => Some(encode_sparse(s)),
        other => other.bits().map(encode_bits),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(dims: [u32; 3]) -> Grid {
        Grid {
            origin: [-1.5, 0.25, 3.0],
            voxel_size: 0.5,
            dims,
        }
    }

    /// Slots by OpenVDB's `coordToOffset`, spelt out for voxel coordinates.
    #[test]
    #[allow(clippy::identity_op)] // the slots spelt out axis by axis
    fn bricks_go_to_openvdbs_slots() {
        // Voxel (4100, 130, 9): root key (4096, 0, 0); upper slot ((4100 & 4095) >> 7 = 0,
        // 130 >> 7 = 1, 0); lower slot ((4100 & 127) >> 3 = 0, (130 & 127) >> 3 = 0, 9 >> 3 = 1).
        let (key, upper, lower) = place([4100 / 8, 130 / 8, 9 / 8]);
        assert_eq!(key, [4096, 0, 0]);
        assert_eq!(upper, (0 << 10) | (1 << 5));
        assert_eq!(lower, 1);
        let (key, upper, lower) = place([(4095 - 7) / 8, 127 / 8, 255 / 8]);
        assert_eq!(key, [0, 0, 0]);
        assert_eq!(upper, (31 << 10) | (0 << 5) | 1);
        assert_eq!(lower, (15 << 8) | (15 << 4) | 15);
    }

    /// The fixed parts of the file, at the offsets OpenVDB reads them from.
    #[test]
    fn the_header_and_descriptor_are_openvdbs() {
        let mut b = BitVolume::new(grid([9, 9, 9]));
        b.set(8, 0, 3, true);
        let f = encode_bits(&b);
        assert_eq!(&f[..8], &0x56444220i64.to_le_bytes());
        let u = |at: usize| u32::from_le_bytes(f[at..at + 4].try_into().unwrap());
        assert_eq!((u(8), u(12), u(16), f[20]), (224, 10, 0, 1));
        let id = std::str::from_utf8(&f[21..57]).unwrap();
        assert_eq!(
            id.split('-').map(str::len).collect::<Vec<_>>(),
            [8, 4, 4, 4, 12]
        );
        assert_eq!((u(57), u(61)), (0, 1));
        assert_eq!(u(65), 4);
        assert_eq!(&f[69..73], b"mask");
        assert_eq!(u(73), 15);
        assert_eq!(&f[77..92], b"Tree_bool_5_4_3");
        assert_eq!(u(92), 0);
        let i = |at: usize| i64::from_le_bytes(f[at..at + 8].try_into().unwrap()) as usize;
        assert_eq!(i(96), 120);
        assert_eq!(i(112), f.len());
        // Encoding is deterministic, UUID included.
        assert_eq!(encode_bits(&b), f);
    }
}
