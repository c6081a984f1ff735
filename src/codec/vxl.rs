//! The native `.vxl` format, documented byte by byte with a Python reader in `docs/format.md`.
//!
//! ```text
//! bytes 0..8     magic  "\x89VXL\r\n\x1a\n"
//! bytes 8..12    format version, u32 little-endian: 1 for bits and density, 2 for the other kinds
//! bytes 12..16   header length H, u32 little-endian
//! bytes 16..16+H header, UTF-8 JSON (see `Header`)
//! rest           one zstd frame (with content checksum) holding the payload, by `layout`:
//!   "x-y-zcolumns-u64le"  (bits) X·Y·W little-endian u64 words, W = ceil(Z/64); column (x, y)
//!                         at word (x·Y + y)·W; bit k%64 of word k/64 is voxel (x, y, k)
//!   "xyz-u8"              (density) X·Y·Z bytes, C order of an (X, Y, Z) array, 0..=max
//!   "xyz-<t>"             (distance f32le, material u16le, colour rgba8) X·Y·Z values of
//!                         type t, little-endian, C order
//!   "x-y-zcolumns-u64le+channels" (channels) the bits' words, then per channel of the header's
//!                         `channels`, in order, `set_voxels` values of its type
//!   "bricks8-<t>"         (sparse-*) the background value; when the header has `tiles`, the
//!                         tile value; then `bricks` brick coordinates (3 × u32 little-endian
//!                         each, strictly increasing in (x, y, z) order), then 512 values per
//!                         brick in the same order; then `tiles` tile coordinates (3 × u32 each,
//!                         strictly increasing, none of them a brick's)
//! ```
//!
//! A sparse file without `tiles` (written before tiles existed, or of a volume whose tile value
//! is its background and that has no tiles) reads as a volume without tiles.
//!
//! Version-1 files (bits and density) are written byte for byte as before the other kinds were
//! added, so the sha256 of a stored volume does not change.

use std::io::Read;

mod sparse;

use serde::{Deserialize, Serialize};

use super::{CodecError, malformed};
use crate::grid::Grid;
use crate::volume::channels::{Attributed, ChannelValues, MAX_CHANNELS};
use crate::volume::kind::{to_le_bytes, valid_from_le_bytes};
use crate::volume::sparse::BRICK_VOXELS;
use crate::volume::{
    BitVolume, Dense, DensityVolume, ValueType, Volume, VolumeKind, Voxel, words_per_column,
};
use sparse::{read_sparse, sparse_counts, sparse_len, sparse_payload, write_sparse};

pub const MAGIC: &[u8; 8] = b"\x89VXL\r\n\x1a\n";
/// The version bits and density volumes are written with (and the oldest read).
pub const VERSION: u32 = 1;
/// The version of every other kind, and the newest read.
pub const VERSION_2: u32 = 2;
const MAX_HEADER: usize = 1 << 20;
/// zstd's level for a payload of `kind`: 3, except for float distances, where level 1 makes
/// smaller frames as well as faster ones (their low mantissa bits are noise to it: igea's
/// band-3 sdf at 512³, 41.4 MB, 14.77 MB in 0.14 s at level 3, 14.69 MB in 0.10 s at level 1,
/// `zstd -T2` here).
fn zstd_level(kind: VolumeKind) -> i32 {
    match kind {
        VolumeKind::Distance | VolumeKind::SparseDistance => 1,
        _ => 3,
    }
}

#[derive(Serialize, Deserialize, Debug)]
struct Header {
    kind: String,
    dims: [u32; 3],
    origin: [f64; 3],
    voxel_size: f64,
    /// "x-y-zcolumns-u64le" for bits, "xyz-u8" for density: the payload layout.
    layout: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    density_max: Option<u8>,
    /// Channels (version 2): the set voxels, each channel's length.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    set_voxels: Option<u64>,
    /// Channels (version 2): name and value type of each, in payload order.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    channels: Option<Vec<ChannelHeader>>,
    /// Sparse kinds (version 2): the number of occupied bricks.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    bricks: Option<u64>,
    /// Sparse kinds: the number of tiles; present (and the tile value in the payload) when the
    /// volume has tiles or a tile value other than its background.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    tiles: Option<u64>,
    /// Free-form provenance (method, source mesh, ...).
    #[serde(default)]
    meta: serde_json::Map<String, serde_json::Value>,
}

#[derive(Serialize, Deserialize, Debug)]
#[serde(deny_unknown_fields)]
struct ChannelHeader {
    name: String,
    value_type: ValueType,
}

const BITS_LAYOUT: &str = "x-y-zcolumns-u64le";

/// The value type of a typed kind's payload (dense or sparse); `None` for bits and channels.
fn value_type(kind: VolumeKind) -> Option<ValueType> {
    match kind {
        VolumeKind::Bits | VolumeKind::Channels => None,
        VolumeKind::Density => Some(ValueType::U8),
        VolumeKind::Distance | VolumeKind::SparseDistance => Some(ValueType::F32),
        VolumeKind::Material | VolumeKind::SparseMaterial => Some(ValueType::U16),
        VolumeKind::Colour | VolumeKind::SparseColour => Some(ValueType::Rgba8),
    }
}

/// The one layout each kind is written in.
fn layout_of(kind: VolumeKind) -> String {
    let t = value_type(kind).map(|t| t.name());
    match kind {
        VolumeKind::Bits => BITS_LAYOUT.into(),
        VolumeKind::Channels => format!("{BITS_LAYOUT}+channels"),
        VolumeKind::SparseDistance | VolumeKind::SparseMaterial | VolumeKind::SparseColour => {
            format!("bricks8-{}", t.expect("typed"))
        }
        _ => format!("xyz-{}", t.expect("typed")),
    }
}

/// The version a kind is written with.
fn version_of(kind: VolumeKind) -> u32 {
    match kind {
        VolumeKind::Bits | VolumeKind::Density => VERSION,
        _ => VERSION_2,
    }
}

pub fn encode(
    v: &Volume,
    meta: &serde_json::Map<String, serde_json::Value>,
) -> Result<Vec<u8>, CodecError> {
    let g = v.grid();
    let kind = v.kind();
    let mut header = Header {
        kind: kind.as_str().into(),
        dims: g.dims,
        origin: g.origin,
        voxel_size: g.voxel_size,
        layout: layout_of(kind),
        density_max: None,
        set_voxels: None,
        channels: None,
        bricks: None,
        tiles: None,
        meta: meta.clone(),
    };
    let owned: Vec<u8>;
    // A large sparse payload (a copy of every brick) is written straight into the encoder,
    // never held whole: at 2048³ it is as large as the volume.
    let mut streamed = None;
    let payload: &[u8] = match v {
        Volume::Bits(b) => words_as_bytes(b.words()),
        Volume::Density(d) => {
            header.density_max = Some(d.max());
            d.data()
        }
        Volume::Distance(d) => {
            owned = to_le_bytes(d.data());
            &owned
        }
        Volume::Material(d) => {
            owned = to_le_bytes(d.data());
            &owned
        }
        Volume::Colour(d) => {
            owned = to_le_bytes(d.data());
            &owned
        }
        Volume::Channels(c) => {
            header.set_voxels = Some(c.len());
            header.channels = Some(
                c.channels()
                    .iter()
                    .map(|ch| ChannelHeader {
                        name: ch.name.clone(),
                        value_type: ch.values.value_type(),
                    })
                    .collect(),
            );
            let len = channels_len(c);
            if len <= ONE_SHOT_MAX {
                let mut p = Vec::with_capacity(len);
                write_channels(c, &mut p).expect("writing to memory");
                owned = p;
                &owned
            } else {
                // Written to the encoder where they lie: no copy of the channels.
                streamed = Some(len);
                &[]
            }
        }
        Volume::SparseDistance(s) => {
            (header.bricks, header.tiles) = sparse_counts(s);
            if sparse_len(s) <= ONE_SHOT_MAX {
                owned = sparse_payload(s);
                &owned
            } else {
                streamed = Some(sparse_len(s));
                &[]
            }
        }
        Volume::SparseMaterial(s) => {
            (header.bricks, header.tiles) = sparse_counts(s);
            if sparse_len(s) <= ONE_SHOT_MAX {
                owned = sparse_payload(s);
                &owned
            } else {
                streamed = Some(sparse_len(s));
                &[]
            }
        }
        Volume::SparseColour(s) => {
            (header.bricks, header.tiles) = sparse_counts(s);
            if sparse_len(s) <= ONE_SHOT_MAX {
                owned = sparse_payload(s);
                &owned
            } else {
                streamed = Some(sparse_len(s));
                &[]
            }
        }
    };
    let json = serde_json::to_vec(&header).expect("header serialises");
    let mut out = Vec::with_capacity(16 + json.len());
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&version_of(kind).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(&json);
    if let Some(len) = streamed {
        let mut enc = streaming_encoder(out, len, zstd_level(kind));
        match v {
            Volume::SparseDistance(s) => write_sparse(s, &mut enc),
            Volume::SparseMaterial(s) => write_sparse(s, &mut enc),
            Volume::SparseColour(s) => write_sparse(s, &mut enc),
            Volume::Channels(c) => write_channels(c, &mut enc),
            _ => unreachable!("only sparse and channel payloads are streamed"),
        }
        .expect("writing to memory");
        return Ok(enc.finish().expect("writing to memory"));
    }
    if payload.len() <= ONE_SHOT_MAX {
        let start = out.len();
        out.resize(start + zstd::zstd_safe::compress_bound(payload.len()), 0);
        let n = ONE_SHOT
            .with(|c| {
                let mut c = c.borrow_mut();
                let c = match &mut *c {
                    Some(c) => c,
                    None => c.insert(one_shot_compressor()?),
                };
                c.set_compression_level(zstd_level(kind))?;
                c.compress_to_buffer(payload, &mut out[start..])
            })
            .expect("compressing to memory");
        out.truncate(start + n);
        return Ok(out);
    }
    let mut enc = streaming_encoder(out, payload.len(), zstd_level(kind));
    std::io::Write::write_all(&mut enc, payload).expect("writing to memory");
    Ok(enc.finish().expect("writing to memory"))
}

/// The bytes of a channel volume's payload: the bits' words, then each channel's values.
fn channels_len(c: &Attributed) -> usize {
    std::mem::size_of_val(c.bits().words())
        + c.channels()
            .iter()
            .map(|ch| ch.values.le_bytes().len())
            .sum::<usize>()
}

/// Writes a channel volume's payload ([`channels_len`] bytes) to `w`.
fn write_channels(c: &Attributed, w: &mut impl std::io::Write) -> std::io::Result<()> {
    w.write_all(words_as_bytes(c.bits().words()))?;
    for ch in c.channels() {
        w.write_all(ch.values.le_bytes())?;
    }
    Ok(())
}

/// Payloads up to this size are compressed in one call by a compressor each thread keeps (a
/// fresh zstd context per volume took half the time of encoding a 64³ bit volume, 37 µs against
/// 18 µs); larger ones are streamed, so no buffer of their compressed bound is allocated up
/// front. Both make the same frame: content size and checksum included.
const ONE_SHOT_MAX: usize = 4 << 20;

/// The encoder of a payload of `len` bytes larger than [`ONE_SHOT_MAX`], appending to `out`:
/// content size and checksum, like the one-shot frames, compressed by zstd's own threads
/// (beside the caller's: one a core, at most four). Its frames are the same bytes for any
/// number of workers (its jobs do not depend on it), one frame any zstd decoder reads.
fn streaming_encoder(out: Vec<u8>, len: usize, level: i32) -> zstd::Encoder<'static, Vec<u8>> {
    let workers = std::thread::available_parallelism().map_or(1, |n| n.get().min(4) as u32);
    let mut enc = zstd::Encoder::new(out, level).expect("zstd encoder");
    enc.include_checksum(true).expect("zstd option");
    enc.multithread(workers).expect("zstd option");
    enc.set_pledged_src_size(Some(len as u64))
        .expect("zstd option");
    enc
}

thread_local! {
    static ONE_SHOT: std::cell::RefCell<Option<zstd::bulk::Compressor<'static>>> =
        const { std::cell::RefCell::new(None) };
}

fn one_shot_compressor() -> std::io::Result<zstd::bulk::Compressor<'static>> {
    let mut c = zstd::bulk::Compressor::new(3)?;
    c.set_parameter(zstd::zstd_safe::CParameter::ChecksumFlag(true))?;
    Ok(c)
}

fn words_as_bytes(w: &[u64]) -> &[u8] {
    // SAFETY: u64 has no padding and any byte pattern is a valid u8; the crate is little-endian
    // only (lib.rs), so these are the little-endian words the format stores.
    unsafe { std::slice::from_raw_parts(w.as_ptr().cast::<u8>(), std::mem::size_of_val(w)) }
}

/// Decodes a `.vxl`, returning the volume and the header's `meta`.
pub fn decode(
    bytes: &[u8],
) -> Result<(Volume, serde_json::Map<String, serde_json::Value>), CodecError> {
    decode_limited(bytes, u64::MAX)
}

/// [`decode`], refusing grids of more than `max_voxels` voxels before their payload is
/// allocated or decompressed.
pub fn decode_limited(
    bytes: &[u8],
    max_voxels: u64,
) -> Result<(Volume, serde_json::Map<String, serde_json::Value>), CodecError> {
    if bytes.len() < 16 || &bytes[..8] != MAGIC {
        return Err(malformed("vxl", "not a .vxl file (bad magic)"));
    }
    let version = u32::from_le_bytes(bytes[8..12].try_into().unwrap());
    if !(VERSION..=VERSION_2).contains(&version) {
        return Err(malformed(
            "vxl",
            format!(
                "format version {version} is not supported (this build reads {VERSION} to {VERSION_2})"
            ),
        ));
    }
    let hlen = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    if hlen > MAX_HEADER || 16 + hlen > bytes.len() {
        return Err(malformed("vxl", "truncated header"));
    }
    let h: Header = serde_json::from_slice(&bytes[16..16 + hlen])
        .map_err(|e| malformed("vxl", format!("bad header: {e}")))?;
    let grid = Grid {
        origin: h.origin,
        voxel_size: h.voxel_size,
        dims: h.dims,
    };
    if h.dims.contains(&0)
        || !(h.voxel_size.is_finite() && h.voxel_size > 0.0)
        || h.origin.iter().any(|o| !o.is_finite())
    {
        return Err(malformed("vxl", "header has an invalid grid"));
    }
    let voxels = h.dims.iter().map(|&d| d as u128).product::<u128>();
    let kind = match h.kind.parse::<VolumeKind>() {
        Ok(k) if version_of(k) <= version => k,
        _ => return Err(malformed("vxl", format!("unknown kind {:?}", h.kind))),
    };
    if h.layout != layout_of(kind) {
        return Err(malformed(
            "vxl",
            format!("unknown {kind} layout {:?}", h.layout),
        ));
    }
    let column_bytes =
        h.dims[0] as u128 * h.dims[1] as u128 * words_per_column(h.dims[2]) as u128 * 8;
    let typed = value_type(kind).map_or(0, |t| t.bytes() as u128);
    let missing = |what: &str| malformed("vxl", format!("a {kind} volume without {what}"));
    let expected: u128 = match kind {
        VolumeKind::Bits => column_bytes,
        VolumeKind::Channels => {
            let set = h.set_voxels.ok_or_else(|| missing("set_voxels"))?;
            let channels = h.channels.as_ref().ok_or_else(|| missing("channels"))?;
            // Bounded before the payload's length is trusted with an allocation.
            if set as u128 > voxels || channels.len() > MAX_CHANNELS {
                return Err(malformed(
                    "vxl",
                    format!(
                        "{set} set voxels in {voxels}, {} channels (at most {MAX_CHANNELS})",
                        channels.len()
                    ),
                ));
            }
            column_bytes
                + channels
                    .iter()
                    .map(|c| set as u128 * c.value_type.bytes() as u128)
                    .sum::<u128>()
        }
        VolumeKind::SparseDistance | VolumeKind::SparseMaterial | VolumeKind::SparseColour => {
            let bricks = h.bricks.ok_or_else(|| missing("bricks"))? as u128;
            let tiles = h.tiles.map(u128::from);
            let grid_bricks: u128 = h.dims.iter().map(|&d| d.div_ceil(8) as u128).product();
            if bricks + tiles.unwrap_or(0) > grid_bricks {
                return Err(malformed(
                    "vxl",
                    format!(
                        "{bricks} bricks and {} tiles, but the grid has {grid_bricks} brick positions",
                        tiles.unwrap_or(0)
                    ),
                ));
            }
            typed
                + tiles.map_or(0, |t| typed + 12 * t)
                + bricks * (12 + typed * BRICK_VOXELS as u128)
        }
        _ => voxels * typed,
    };
    if expected > isize::MAX as u128 / 2 {
        return Err(malformed("vxl", "volume too large"));
    }
    if voxels > max_voxels as u128 {
        return Err(malformed(
            "vxl",
            format!("the grid has {voxels} voxels, over the limit of {max_voxels}"),
        ));
    }
    let expected = expected as usize;
    let frame = &bytes[16 + hlen..];
    // Our frames say how much they hold: one that says otherwise is refused before the payload
    // is allocated, and the payload is allocated whole only when the frame vouches for it.
    let declared = match zstd::zstd_safe::get_frame_content_size(frame) {
        Ok(d) => d,
        Err(_) => return Err(malformed("vxl", "corrupt payload: not a zstd frame")),
    };
    if declared.is_some_and(|d| d != expected as u64) {
        return Err(malformed(
            "vxl",
            format!(
                "payload has {} bytes, expected {expected}",
                declared.unwrap()
            ),
        ));
    }
    let mut dec = zstd::Decoder::new(frame).map_err(|e| malformed("vxl", e.to_string()))?;
    let corrupt = |e: std::io::Error| malformed("vxl", format!("corrupt payload: {e}"));
    let payload = if declared.is_some() {
        // The kind decides below how these bytes are read; bits are copied to words once.
        let mut p = vec![0u8; expected];
        dec.read_exact(&mut p).map_err(|e| {
            if e.kind() == std::io::ErrorKind::UnexpectedEof {
                malformed("vxl", format!("payload is shorter than {expected} bytes"))
            } else {
                corrupt(e)
            }
        })?;
        p
    } else {
        let mut p = Vec::new();
        (&mut dec)
            .take(expected as u64)
            .read_to_end(&mut p)
            .map_err(corrupt)?;
        p
    };
    // Reading on to the end verifies the frame's checksum, and that nothing follows.
    let mut extra = [0u8; 1];
    let more = loop {
        match dec.read(&mut extra) {
            Ok(n) => break n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(corrupt(e)),
        }
    };
    if payload.len() != expected || more != 0 {
        let got = if more != 0 {
            "more".to_string()
        } else {
            payload.len().to_string()
        };
        return Err(malformed(
            "vxl",
            format!("payload has {got} bytes, expected {expected}"),
        ));
    }
    let bad = |e: String| malformed("vxl", e);
    let (bricks, tiles) = (h.bricks.unwrap_or(0) as usize, h.tiles.map(|t| t as usize));
    let v = match kind {
        VolumeKind::Bits => Volume::Bits(read_bits(grid, &payload).map_err(bad)?),
        VolumeKind::Density => {
            let max = h
                .density_max
                .ok_or_else(|| malformed("vxl", "density volume without density_max"))?;
            Volume::Density(DensityVolume::from_data(grid, max, payload).map_err(bad)?)
        }
        VolumeKind::Distance => Volume::Distance(read_dense(grid, &payload).map_err(bad)?),
        VolumeKind::Material => Volume::Material(read_dense(grid, &payload).map_err(bad)?),
        VolumeKind::Colour => Volume::Colour(read_dense(grid, &payload).map_err(bad)?),
        VolumeKind::Channels => {
            let split = column_bytes as usize;
            let bits = read_bits(grid, &payload[..split]).map_err(bad)?;
            let set = h.set_voxels.unwrap_or(0);
            if bits.count_ones() != set {
                return Err(malformed(
                    "vxl",
                    format!("set_voxels is {set}, the bits hold {}", bits.count_ones()),
                ));
            }
            let mut a = Attributed::new(bits);
            let mut at = split;
            for c in h.channels.unwrap_or_default() {
                let n = set as usize * c.value_type.bytes();
                let values = ChannelValues::from_le_bytes(c.value_type, &payload[at..at + n])
                    .map_err(bad)?;
                a.add(&c.name, values).map_err(bad)?;
                at += n;
            }
            Volume::Channels(a)
        }
        VolumeKind::SparseDistance => {
            Volume::SparseDistance(read_sparse(grid, &payload, bricks, tiles).map_err(bad)?)
        }
        VolumeKind::SparseMaterial => {
            Volume::SparseMaterial(read_sparse(grid, &payload, bricks, tiles).map_err(bad)?)
        }
        VolumeKind::SparseColour => {
            Volume::SparseColour(read_sparse(grid, &payload, bricks, tiles).map_err(bad)?)
        }
    };
    Ok((v, h.meta))
}

fn read_bits(grid: Grid, payload: &[u8]) -> Result<BitVolume, String> {
    let words = payload
        .chunks_exact(8)
        .map(|c| u64::from_le_bytes(c.try_into().unwrap()))
        .collect();
    BitVolume::from_words(grid, words)
}

fn read_dense<T: Voxel>(grid: Grid, payload: &[u8]) -> Result<Dense<T>, String> {
    Dense::from_data(grid, valid_from_le_bytes(payload)?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::sparse::Sparse;

    /// A payload compressed in one call (by a compressor kept per thread, used again) and one
    /// streamed make the same kind of frame: the content size and a checksum in it, and the
    /// volume back out.
    #[test]
    fn frames_carry_their_size_and_checksum_either_way() {
        // 64³ bits: 32 KiB of payload, in one call; 512 × 256 × 320: 5 MiB, streamed.
        for (dims, one_shot) in [
            ([64, 64, 64], true),
            ([512, 256, 320], false),
            ([9, 9, 9], true),
        ] {
            let grid = Grid {
                origin: [0.5, -1.0, 2.0],
                voxel_size: 0.25,
                dims,
            };
            let mut b = BitVolume::new(grid);
            for i in 0..dims[0].min(dims[1]).min(dims[2]) {
                b.set(i, (i * 7) % dims[1], (i * 13) % dims[2], true);
            }
            let payload = std::mem::size_of_val(b.words());
            assert_eq!(payload <= ONE_SHOT_MAX, one_shot);
            let v = Volume::Bits(b);
            let bytes = encode(&v, &Default::default()).unwrap();
            let hlen = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
            let frame = &bytes[16 + hlen..];
            assert_eq!(
                zstd::zstd_safe::get_frame_content_size(frame).ok(),
                Some(Some(payload as u64)),
                "{dims:?}"
            );
            // The frame header descriptor's bit 2: a content checksum follows the frame.
            assert_ne!(frame[4] & 0b100, 0, "{dims:?}");
            assert_eq!(decode(&bytes).unwrap().0, v, "{dims:?}");
        }
    }

    fn payload_of(bytes: &[u8]) -> (serde_json::Value, Vec<u8>) {
        let hl = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
        let h = serde_json::from_slice(&bytes[16..16 + hl]).unwrap();
        (h, zstd::decode_all(&bytes[16 + hl..]).unwrap())
    }

    /// Tiles are kept: the header counts them, the payload holds the tile value after the
    /// background and the tiles' coordinates after the bricks' values (read here by the
    /// documented offsets, not by the decoder).
    /// A sparse payload over the one-shot size is streamed into the encoder: the same bytes
    /// as the whole payload, its size declared in the frame.
    #[test]
    fn large_sparse_payloads_stream_the_same_bytes() {
        let grid = Grid {
            origin: [0.0; 3],
            voxel_size: 0.5,
            dims: [130, 128, 90],
        };
        let mut s = Sparse::with_tile_value(grid, 1.5f32, -1.5);
        // A voxel in every brick: 3,264 bricks, 6.7 MB.
        for (i, x) in (0..130).step_by(8).enumerate() {
            for y in (0..128).step_by(8) {
                for z in (0..90).step_by(8) {
                    s.set(x + i as u32 % 8, y, z, (x + y + z) as f32 * 0.25);
                }
            }
        }
        s.set_tile([15, 15, 10], true).unwrap();
        assert!(sparse_len(&s) > ONE_SHOT_MAX && sparse_len(&s) == sparse_payload(&s).len());
        let v = Volume::SparseDistance(s.clone());
        let bytes = encode(&v, &Default::default()).unwrap();
        assert_eq!(payload_of(&bytes).1, sparse_payload(&s));
        let frame = &bytes[16 + u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize..];
        let declared = zstd::zstd_safe::get_frame_content_size(frame);
        assert!(matches!(declared, Ok(Some(n)) if n as usize == sparse_len(&s)));
        assert_eq!(decode(&bytes).unwrap().0, v);
    }

    #[test]
    fn sparse_tiles_round_trip_in_the_documented_layout() {
        let grid = Grid {
            origin: [-1.0, 0.5, 2.0],
            voxel_size: 0.125,
            dims: [20, 9, 17],
        };
        let mut s = Sparse::with_tile_value(grid, 0.375f32, -0.375);
        s.set(3, 8, 16, -0.25);
        s.set(19, 0, 0, 0.0);
        for t in [[2, 1, 2], [0, 0, 1], [1, 1, 0]] {
            s.set_tile(t, true).unwrap();
        }
        let v = Volume::SparseDistance(s.clone());
        let bytes = encode(&v, &Default::default()).unwrap();
        assert_eq!(decode(&bytes).unwrap().0, v);
        let (h, p) = payload_of(&bytes);
        assert_eq!(
            (h["bricks"].as_u64(), h["tiles"].as_u64()),
            (Some(2), Some(3))
        );
        let f = |at: usize| f32::from_le_bytes(p[at..at + 4].try_into().unwrap());
        let u = |at: usize| u32::from_le_bytes(p[at..at + 4].try_into().unwrap());
        assert_eq!((f(0), f(4)), (0.375, -0.375));
        // Bricks [0, 1, 2] (voxel (3, 8, 16)) and [2, 0, 0] (voxel (19, 0, 0)).
        assert_eq!(
            (8..32).step_by(4).map(u).collect::<Vec<_>>(),
            [0, 1, 2, 2, 0, 0]
        );
        assert_eq!(f(32 + 4 * ((3 * 8) * 8)), -0.25);
        assert_eq!(
            f(32 + 4 * 512 + 4 * ((3 * 8) * 8)).to_bits(),
            0.0f32.to_bits()
        );
        let tiles = 32 + 2 * 512 * 4;
        assert_eq!(p.len(), tiles + 3 * 12);
        let t: Vec<u32> = (tiles..p.len()).step_by(4).map(u).collect();
        assert_eq!(t, [0, 0, 1, 1, 1, 0, 2, 1, 2]);
        // A tile value other than the background is kept without tiles; one equal to it (and no
        // tiles) writes the layout of before tiles.
        let lone = Sparse::with_tile_value(grid, 1.0f32, -1.0);
        let v = Volume::SparseDistance(lone);
        let bytes = encode(&v, &Default::default()).unwrap();
        assert_eq!(payload_of(&bytes).0["tiles"], 0);
        assert_eq!(decode(&bytes).unwrap().0, v);
        let plain = Volume::SparseMaterial(Sparse::new(grid, 7u16));
        let bytes = encode(&plain, &Default::default()).unwrap();
        let (h, p) = payload_of(&bytes);
        assert!(h.get("tiles").is_none());
        assert_eq!(p, 7u16.to_le_bytes());
        assert_eq!(decode(&bytes).unwrap().0, plain);
    }

    /// Tiles out of order, on a brick, or past the brick grid are refused.
    #[test]
    fn bad_tiles_are_refused() {
        let grid = Grid {
            origin: [0.0; 3],
            voxel_size: 1.0,
            dims: [16, 8, 8],
        };
        let mut s = Sparse::with_tile_value(grid, 3.0f32, -3.0);
        s.set(0, 0, 0, 1.0);
        s.set_tile([1, 0, 0], true).unwrap();
        let v = Volume::SparseDistance(s);
        let good = encode(&v, &Default::default()).unwrap();
        let (h, mut p) = payload_of(&good);
        let n = p.len();
        let rebuild = |p: &[u8]| {
            let json = serde_json::to_vec(&h).unwrap();
            let mut out = MAGIC.to_vec();
            out.extend_from_slice(&VERSION_2.to_le_bytes());
            out.extend_from_slice(&(json.len() as u32).to_le_bytes());
            out.extend_from_slice(&json);
            out.extend(zstd::encode_all(p, 3).unwrap());
            out
        };
        assert_eq!(decode(&rebuild(&p)).unwrap().0, v);
        p[n - 12] = 0; // the tile onto brick [0, 0, 0]
        assert!(
            decode(&rebuild(&p))
                .unwrap_err()
                .to_string()
                .contains("also a brick")
        );
        p[n - 12] = 2; // past the brick grid (2 × 1 × 1)
        assert!(
            decode(&rebuild(&p))
                .unwrap_err()
                .to_string()
                .contains("outside")
        );
    }
}
