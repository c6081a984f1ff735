//! MagicaVoxel `.vox`, version 150 (the format of ephtracy's `voxel-model` repository: RIFF-like
//! chunks `MAIN` ⊃ `SIZE`/`XYZI` per model, the scene graph `nTRN`/`nGRP`/`nSHP`, and `RGBA`),
//! written a model at a time, never read back.
//!
//! * **Models.** A model is at most 256 voxels along each axis, so the grid is cut into blocks
//!   of 256³ (the last ones smaller), one model each, in the order x-block, y-block, z-block
//!   (z fastest); a model's voxels are its block's set voxels, listed x, then y, then z. Its
//!   `SIZE` is the block's size rounded up to even, so the model's centre is a whole voxel.
//! * **Scene.** Node 0, a transform, holds node 1, a group of one transform (node 2 + 2i)
//!   per model i, each holding a shape (node 3 + 2i) of model i. A model's transform puts its
//!   centre at `_t` = its lower corner + its `SIZE` / 2, in MagicaVoxel's world, where voxel
//!   (x, y, z) of the grid lies at (x − ⌊X/2⌋, y − ⌊Y/2⌋, z): the grid centred over the
//!   ground, standing on it. Axes are voxd's (MagicaVoxel's z is up).
//! * **World.** MagicaVoxel's world is ±1000 voxels about the ground's centre, rendered above
//!   the ground: a grid beyond 2000 × 2000 × 1000 voxels is refused with its numbers
//!   ([`check_world`]).
//! * **Colour.** A volume with a colour channel gets a palette of at most 255 entries
//!   (`palette.rs`: exact when there are at most 255 colours, else median cut seeded k-means
//!   in CIELAB) and each voxel its nearest entry; without one every voxel is palette index 1,
//!   light grey ([`GREY`]). The `RGBA` chunk holds the 256 entries (entry k is index k + 1).
//!
//! The file's length is known before it is written ([`Plan::len`]): the voxels of each model
//! are counted first (a model's `XYZI` chunk starts with its count).

use super::palette::{self, Quantized};
use crate::volume::{Attributed, BitVolume, Volume};

pub const MAGIC: &[u8; 4] = b"VOX ";
/// The version written.
pub const VERSION: u32 = 150;
/// A model's largest side.
pub const MODEL: u32 = 256;
/// MagicaVoxel's world, in voxels along x, y and z (z from the ground up).
pub const WORLD: [u32; 3] = [2000, 2000, 1000];
/// The colour of every voxel of a volume without colours (palette index 1).
pub const GREY: [u8; 4] = [200, 200, 200, 255];

/// Refuses a grid MagicaVoxel's world cannot hold, with the numbers.
pub fn check_world(dims: [u32; 3]) -> Result<(), String> {
    if (0..3).all(|a| dims[a] <= WORLD[a]) {
        return Ok(());
    }
    Err(format!(
        "MagicaVoxel's world holds at most {}x{}x{} voxels (x and y within ±1000 of its centre, z from the ground up to 1000); this grid is {}x{}x{}",
        WORLD[0], WORLD[1], WORLD[2], dims[0], dims[1], dims[2]
    ))
}

/// What is written, decided before the first byte: the models and their voxel counts.
pub struct Plan<'a> {
    bits: &'a BitVolume,
    /// Models along each axis.
    blocks: [u32; 3],
    /// Set voxels per model, in model order.
    counts: Vec<u64>,
    /// Each model's `_t` (its centre in the world), as written.
    centres: Vec<String>,
    /// For a volume with colours: the palette and each set voxel's entry (by rank), and the
    /// volume (its columns' ranks).
    colours: Option<(Quantized, &'a Attributed)>,
}

/// Model `i`'s block: its lower corner and size (before rounding up to even).
fn block(blocks: [u32; 3], dims: [u32; 3], i: usize) -> ([u32; 3], [u32; 3]) {
    let i = i as u32;
    let b = [
        i / (blocks[1] * blocks[2]),
        i / blocks[2] % blocks[1],
        i % blocks[2],
    ];
    let lo = b.map(|k| k * MODEL);
    let size = [0, 1, 2].map(|a| (dims[a] - lo[a]).min(MODEL));
    (lo, size)
}

/// A model's `SIZE`: its block's size rounded up to even (at most 256).
fn padded(size: [u32; 3]) -> [u32; 3] {
    size.map(|s| s.next_multiple_of(2).max(2))
}

/// The bytes of a `.vox` `STRING`.
fn string_len(s: &str) -> u64 {
    4 + s.len() as u64
}

impl<'a> Plan<'a> {
    /// The plan for `v` (a bit volume within [`WORLD`]); counts the voxels of each model.
    pub fn new(v: &'a Volume) -> std::io::Result<Plan<'a>> {
        let Some(bits) = v.bits() else {
            return Err(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                format!("vox holds bit volumes, not {}", v.kind()),
            ));
        };
        let coloured = match v {
            Volume::Channels(a) => a.colours().map(|c| (c, a)),
            _ => None,
        };
        let dims = bits.dims();
        check_world(dims).map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidInput, e))?;
        let blocks = dims.map(|d| d.div_ceil(MODEL).max(1));
        let n = (blocks[0] * blocks[1] * blocks[2]) as usize;
        let mut counts = vec![0u64; n];
        // A z-block is 4 whole column words (256 = 4 · 64).
        let per = (MODEL / 64) as usize;
        for x in 0..dims[0] {
            for y in 0..dims[1] {
                let col = bits.column(x, y);
                for (bz, words) in col.chunks(per).enumerate() {
                    let i = ((x / MODEL * blocks[1] + y / MODEL) * blocks[2]) as usize + bz;
                    counts[i] += words.iter().map(|w| u64::from(w.count_ones())).sum::<u64>();
                }
            }
        }
        let half = [dims[0] / 2, dims[1] / 2, 0];
        let centres = (0..n)
            .map(|i| {
                let (lo, size) = block(blocks, dims, i);
                let p = padded(size);
                let c = [0, 1, 2].map(|a| i64::from(lo[a] + p[a] / 2) - i64::from(half[a]));
                format!("{} {} {}", c[0], c[1], c[2])
            })
            .collect();
        let colours = coloured.map(|(c, a)| (palette::quantize(c), a));
        if let Some((q, _)) = &colours {
            tracing::info!(
                colours = q.palette.len(),
                mean_delta_e = q.mean_de,
                p99_delta_e = q.p99_de,
                "vox palette"
            );
        }
        Ok(Plan {
            bits,
            blocks,
            counts,
            centres,
            colours,
        })
    }

    /// The number of models.
    pub fn models(&self) -> usize {
        self.counts.len()
    }

    /// The length of the file (never empty: at least the header, one model and the palette).
    #[allow(clippy::len_without_is_empty)]
    pub fn len(&self) -> u64 {
        8 + 12 + self.children()
    }

    /// The bytes of `MAIN`'s children.
    fn children(&self) -> u64 {
        let models: u64 = self.counts.iter().map(|n| 24 + 16 + 4 * n).sum();
        let root = 12 + 28;
        let group = 12 + 12 + 4 * self.models() as u64;
        let transforms: u64 = self
            .centres
            .iter()
            .map(|t| 12 + 24 + 4 + string_len("_t") + string_len(t))
            .sum();
        let shapes = (12 + 20) * self.models() as u64;
        models + root + group + transforms + shapes + 12 + 1024
    }

    /// Writes the file, a model at a time (pieces of at most 64 KiB).
    pub fn write(&self, out: &mut impl std::io::Write) -> std::io::Result<()> {
        let mut buf: Vec<u8> = Vec::with_capacity(PIECE + 64);
        let put = |buf: &mut Vec<u8>, v: u32| buf.extend_from_slice(&v.to_le_bytes());
        buf.extend_from_slice(MAGIC);
        put(&mut buf, VERSION);
        chunk(&mut buf, b"MAIN", 0, self.children());
        let dims = self.bits.dims();
        for (i, &n) in self.counts.iter().enumerate() {
            let (lo, size) = block(self.blocks, dims, i);
            chunk(&mut buf, b"SIZE", 12, 0);
            for s in padded(size) {
                put(&mut buf, s);
            }
            chunk(&mut buf, b"XYZI", 4 + 4 * n, 0);
            put(&mut buf, n as u32);
            let per = (MODEL / 64) as usize;
            let bz = (lo[2] / MODEL) as usize;
            for x in lo[0]..lo[0] + size[0] {
                for y in lo[1]..lo[1] + size[1] {
                    let col = self.bits.column(x, y);
                    let words = col.get(bz * per..).unwrap_or(&[]);
                    // The rank of the block's first voxel in this column.
                    let mut rank = match &self.colours {
                        Some((_, a)) => {
                            a.column_start(x, y)
                                + col[..(bz * per).min(col.len())]
                                    .iter()
                                    .map(|w| u64::from(w.count_ones()))
                                    .sum::<u64>()
                        }
                        None => 0,
                    };
                    for (w, &word) in words.iter().take(per).enumerate() {
                        let mut t = word;
                        while t != 0 {
                            let z = (w * 64) as u32 + t.trailing_zeros();
                            t &= t - 1;
                            let entry = match &self.colours {
                                Some((q, _)) => q.index[rank as usize] + 1,
                                None => 1,
                            };
                            rank += 1;
                            buf.extend_from_slice(&[
                                (x - lo[0]) as u8,
                                (y - lo[1]) as u8,
                                z as u8,
                                entry,
                            ]);
                        }
                    }
                    if buf.len() >= PIECE {
                        out.write_all(&buf)?;
                        buf.clear();
                    }
                }
            }
        }
        // The scene graph.
        let dict = |buf: &mut Vec<u8>, pairs: &[(&str, &str)]| {
            put(buf, pairs.len() as u32);
            for (k, v) in pairs {
                for s in [k, v] {
                    put(buf, s.len() as u32);
                    buf.extend_from_slice(s.as_bytes());
                }
            }
        };
        let m = self.models() as u32;
        chunk(&mut buf, b"nTRN", 28, 0);
        for v in [0, 0, 1, u32::MAX, u32::MAX, 1, 0] {
            // id, no attributes, child 1, reserved −1, layer −1, one frame, no frame attributes
            put(&mut buf, v);
        }
        chunk(&mut buf, b"nGRP", 12 + 4 * u64::from(m), 0);
        put(&mut buf, 1);
        put(&mut buf, 0);
        put(&mut buf, m);
        for i in 0..m {
            put(&mut buf, 2 + 2 * i);
        }
        for (i, t) in self.centres.iter().enumerate() {
            let i = i as u32;
            chunk(
                &mut buf,
                b"nTRN",
                24 + 4 + string_len("_t") + string_len(t),
                0,
            );
            for v in [2 + 2 * i, 0, 3 + 2 * i, u32::MAX, 0, 1] {
                // id, no attributes, its shape, reserved −1, layer 0, one frame
                put(&mut buf, v);
            }
            dict(&mut buf, &[("_t", t)]);
            chunk(&mut buf, b"nSHP", 20, 0);
            for v in [3 + 2 * i, 0, 1, i, 0] {
                // id, no attributes, one model: model i, no model attributes
                put(&mut buf, v);
            }
            if buf.len() >= PIECE {
                out.write_all(&buf)?;
                buf.clear();
            }
        }
        chunk(&mut buf, b"RGBA", 1024, 0);
        let entries: &[[u8; 4]] = match &self.colours {
            Some((q, _)) => &q.palette,
            None => &[GREY],
        };
        for k in 0..256 {
            buf.extend_from_slice(entries.get(k).unwrap_or(&[0, 0, 0, 255]));
        }
        out.write_all(&buf)
    }
}

/// Bytes gathered before a write.
const PIECE: usize = 64 * 1024;

/// A chunk's header: its id, the bytes of its content and of its children.
fn chunk(buf: &mut Vec<u8>, id: &[u8; 4], content: u64, children: u64) {
    buf.extend_from_slice(id);
    buf.extend_from_slice(&(content as u32).to_le_bytes());
    buf.extend_from_slice(&(children as u32).to_le_bytes());
}

/// Streams the `.vox` of `v` (a bit volume within [`WORLD`]; `InvalidInput` otherwise).
pub fn write(v: &Volume, out: &mut impl std::io::Write) -> std::io::Result<()> {
    Plan::new(v)?.write(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::Grid;
    use crate::testkit::Rng;

    fn bits(dims: [u32; 3], rng: &mut Rng, p: f64) -> BitVolume {
        let grid = Grid {
            origin: [0.0; 3],
            voxel_size: 1.0,
            dims,
        };
        crate::testkit::random_bit_volume(rng, grid, p)
    }

    /// dot_vox (an independent reader) reads every model, its voxels and its place in the
    /// scene; the voxels put back where the scene says give the volume.
    #[test]
    fn dot_vox_reads_every_voxel_back_in_place() {
        let mut rng = Rng::new(34);
        for (dims, p) in [
            ([1, 1, 1], 1.0),
            ([3, 5, 7], 0.4),
            ([600, 40, 300], 0.002),
            ([257, 2, 513], 0.01),
            ([10, 10, 10], 0.0),
        ] {
            let b = bits(dims, &mut rng, p);
            let v = Volume::Bits(b.clone());
            let plan = Plan::new(&v).unwrap();
            let mut out = Vec::new();
            plan.write(&mut out).unwrap();
            assert_eq!(out.len() as u64, plan.len(), "{dims:?}");
            let data = dot_vox::load_bytes(&out).expect("dot_vox reads it");
            assert_eq!(data.version, VERSION);
            assert_eq!(data.models.len(), plan.models());
            assert_eq!(
                data.palette[0],
                dot_vox::Color {
                    r: 200,
                    g: 200,
                    b: 200,
                    a: 255
                }
            );
            // Walk the scene: root transform → group → (transform → shape) per model.
            let mut got = BitVolume::new(*b.grid());
            let dot_vox::SceneNode::Transform { child, .. } = &data.scenes[0] else {
                panic!("root is a transform")
            };
            let dot_vox::SceneNode::Group { children, .. } = &data.scenes[*child as usize] else {
                panic!("a group under the root")
            };
            assert_eq!(children.len(), plan.models());
            let mut seen = 0;
            for &t in children {
                let dot_vox::SceneNode::Transform { child, frames, .. } = &data.scenes[t as usize]
                else {
                    panic!("a transform per model")
                };
                let dot_vox::SceneNode::Shape { models, .. } = &data.scenes[*child as usize] else {
                    panic!("a shape under each transform")
                };
                let model = &data.models[models[0].model_id as usize];
                let c: Vec<i64> = frames[0].attributes["_t"]
                    .split(' ')
                    .map(|s| s.parse().unwrap())
                    .collect();
                let s = [model.size.x, model.size.y, model.size.z].map(i64::from);
                for vx in &model.voxels {
                    // dot_vox counts palette entries from 0: file index 1 is 0.
                    assert_eq!(vx.i, 0);
                    // World = centre − size/2 + local; grid = world + (⌊X/2⌋, ⌊Y/2⌋, 0).
                    let local = [vx.x, vx.y, vx.z].map(i64::from);
                    let shift = [i64::from(dims[0] / 2), i64::from(dims[1] / 2), 0];
                    let g = [0, 1, 2].map(|a| c[a] - s[a] / 2 + local[a] + shift[a]);
                    assert!((0..3).all(|a| g[a] >= 0 && g[a] < i64::from(dims[a])));
                    assert!(!got.get(g[0] as u32, g[1] as u32, g[2] as u32), "twice");
                    got.set(g[0] as u32, g[1] as u32, g[2] as u32, true);
                    seen += 1;
                }
                assert!(s.iter().all(|&k| k % 2 == 0 && k <= 256));
            }
            assert_eq!(seen, b.count_ones());
            assert!(got == b, "{dims:?}: the voxels differ");
        }
    }

    #[test]
    fn a_grid_beyond_the_world_is_refused_with_its_numbers() {
        assert!(check_world([2000, 2000, 1000]).is_ok());
        let e = check_world([2001, 5, 5]).unwrap_err();
        assert!(
            e.contains("2000x2000x1000") && e.contains("2001x5x5"),
            "{e}"
        );
        let b = BitVolume::new(Grid {
            origin: [0.0; 3],
            voxel_size: 1.0,
            dims: [4, 4, 1001],
        });
        let e = write(&Volume::Bits(b), &mut Vec::new()).unwrap_err();
        assert_eq!(e.kind(), std::io::ErrorKind::InvalidInput);
    }
}
