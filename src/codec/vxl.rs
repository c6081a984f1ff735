//! The native `.vxl` format (version 1), documented with a Python reader in `docs/format.md`.
//!
//! ```text
//! bytes 0..8     magic  "\x89VXL\r\n\x1a\n"
//! bytes 8..12    format version, u32 little-endian (1)
//! bytes 12..16   header length H, u32 little-endian
//! bytes 16..16+H header, UTF-8 JSON (see `Header`)
//! rest           one zstd frame (with content checksum) holding the payload:
//!                kind "bits":    X·Y·W little-endian u64 words, W = ceil(Z/64); column (x, y) at
//!                                word (x·Y + y)·W; bit k%64 of word k/64 is voxel (x, y, k)
//!                kind "density": X·Y·Z bytes, C order of an (X, Y, Z) array, values 0..=max
//! ```

use std::io::Read;

use serde::{Deserialize, Serialize};

use super::{CodecError, malformed};
use crate::grid::Grid;
use crate::volume::{BitVolume, DensityVolume, Volume, words_per_column};

pub const MAGIC: &[u8; 8] = b"\x89VXL\r\n\x1a\n";
pub const VERSION: u32 = 1;
const MAX_HEADER: usize = 1 << 20;
const ZSTD_LEVEL: i32 = 3;

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
    /// Free-form provenance (method, source mesh, ...).
    #[serde(default)]
    meta: serde_json::Map<String, serde_json::Value>,
}

const BITS_LAYOUT: &str = "x-y-zcolumns-u64le";
const DENSITY_LAYOUT: &str = "xyz-u8";

pub fn encode(
    v: &Volume,
    meta: &serde_json::Map<String, serde_json::Value>,
) -> Result<Vec<u8>, CodecError> {
    let g = v.grid();
    let header = Header {
        kind: v.kind().into(),
        dims: g.dims,
        origin: g.origin,
        voxel_size: g.voxel_size,
        layout: match v {
            Volume::Bits(_) => BITS_LAYOUT,
            Volume::Density(_) => DENSITY_LAYOUT,
        }
        .into(),
        density_max: match v {
            Volume::Density(d) => Some(d.max()),
            Volume::Bits(_) => None,
        },
        meta: meta.clone(),
    };
    let json = serde_json::to_vec(&header).expect("header serialises");
    let mut out = Vec::with_capacity(16 + json.len());
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&VERSION.to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(&json);
    let payload: &[u8] = match v {
        Volume::Bits(b) => words_as_bytes(b.words()),
        Volume::Density(d) => d.data(),
    };
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
                c.compress_to_buffer(payload, &mut out[start..])
            })
            .expect("compressing to memory");
        out.truncate(start + n);
        return Ok(out);
    }
    let mut enc = zstd::Encoder::new(out, ZSTD_LEVEL).expect("zstd encoder");
    enc.include_checksum(true).expect("zstd option");
    enc.set_pledged_src_size(Some(payload.len() as u64))
        .expect("zstd option");
    std::io::Write::write_all(&mut enc, payload).expect("writing to memory");
    Ok(enc.finish().expect("writing to memory"))
}

/// Payloads up to this size are compressed in one call by a compressor each thread keeps (a
/// fresh zstd context per volume took half the time of encoding a 64³ bit volume, 37 µs against
/// 18 µs); larger ones are streamed, so no buffer of their compressed bound is allocated up
/// front. Both make the same frame: content size and checksum included.
const ONE_SHOT_MAX: usize = 4 << 20;

thread_local! {
    static ONE_SHOT: std::cell::RefCell<Option<zstd::bulk::Compressor<'static>>> =
        const { std::cell::RefCell::new(None) };
}

fn one_shot_compressor() -> std::io::Result<zstd::bulk::Compressor<'static>> {
    let mut c = zstd::bulk::Compressor::new(ZSTD_LEVEL)?;
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
    if version != VERSION {
        return Err(malformed(
            "vxl",
            format!("format version {version} is not supported (this build reads {VERSION})"),
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
    let expected: u128 = match h.kind.as_str() {
        "bits" => h.dims[0] as u128 * h.dims[1] as u128 * words_per_column(h.dims[2]) as u128 * 8,
        "density" => voxels,
        k => return Err(malformed("vxl", format!("unknown kind {k:?}"))),
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
    let v = match h.kind.as_str() {
        "bits" => {
            if h.layout != BITS_LAYOUT {
                return Err(malformed(
                    "vxl",
                    format!("unknown bits layout {:?}", h.layout),
                ));
            }
            let words = payload
                .chunks_exact(8)
                .map(|c| u64::from_le_bytes(c.try_into().unwrap()))
                .collect();
            Volume::Bits(BitVolume::from_words(grid, words).map_err(|e| malformed("vxl", e))?)
        }
        _ => {
            if h.layout != DENSITY_LAYOUT {
                return Err(malformed(
                    "vxl",
                    format!("unknown density layout {:?}", h.layout),
                ));
            }
            let max = h
                .density_max
                .ok_or_else(|| malformed("vxl", "density volume without density_max"))?;
            Volume::Density(
                DensityVolume::from_data(grid, max, payload).map_err(|e| malformed("vxl", e))?,
            )
        }
    };
    Ok((v, h.meta))
}

#[cfg(test)]
mod tests {
    use super::*;

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
}
