//! NumPy `.npy` (format 1.0): dtype `|u1`, shape (X, Y, Z), C order, so `np.load` gives
//! `a[x, y, z]`. Bit volumes hold 0/1, density volumes their occupancy. Distance volumes, dense
//! or sparse, are dtype `<f4` (every voxel: a sparse volume's tiles and background written out).
//! The file carries no grid: decoding gives origin 0 and voxel size 1. A decoded `u1` array
//! holding only 0 and 1 is a bit volume; any larger value makes it a density volume (maximum 8,
//! or 64 when a value exceeds 8); a `<f4` array is a (dense) distance volume.

use super::{CodecError, malformed};
use crate::grid::Grid;
use crate::volume::sparse::{BRICK, BRICK_VOXELS, Sparse};
use crate::volume::{
    Attributed, BitVolume, ChannelValues, Dense, DensityVolume, Volume, VolumeKind,
};

pub const MAGIC: &[u8; 6] = b"\x93NUMPY";

pub fn encode(v: &Volume) -> Vec<u8> {
    let mut out = Vec::with_capacity(128 + v.grid().voxel_count() as usize);
    write(v, &mut out).expect("writing to memory");
    out
}

/// Bytes per voxel of `kind` in `.npy` and `.raw`: 4 for distances, else 1.
pub fn value_bytes(kind: VolumeKind) -> u64 {
    match kind {
        VolumeKind::Distance | VolumeKind::SparseDistance => 4,
        _ => 1,
    }
}

/// The `.npy` header of an array of `dims` (magic to the padding newline), dtype `|u1`.
pub fn header(dims: [u32; 3]) -> Vec<u8> {
    typed_header(dims, "|u1")
}

/// Bytes per voxel of `v` in `.npy` and `.raw`: [`value_bytes`] of its kind, but for a bit
/// volume with one attribute channel (a download with `attributes=`), that channel's value.
pub fn value_bytes_of(v: &Volume) -> u64 {
    match v {
        Volume::Channels(a) => a
            .channels()
            .first()
            .map_or(1, |c| c.values.value_type().bytes() as u64),
        _ => value_bytes(v.kind()),
    }
}

/// A channel's values as `.npy` arrays hold them: the dtype, and the axes each value adds (an
/// RGBA colour is 4 bytes along a last axis).
pub fn channel_dtype(c: &ChannelValues) -> (&'static str, &'static [u64]) {
    match c {
        ChannelValues::Rgba8(_) => ("|u1", &[4]),
        ChannelValues::U16(_) => ("<u2", &[]),
        ChannelValues::U8(_) => ("|u1", &[]),
        ChannelValues::F32(_) => ("<f4", &[]),
    }
}

/// The `.npy` header `v` is written with.
pub fn header_of(v: &Volume) -> Vec<u8> {
    if let Volume::Channels(a) = v
        && let Some(c) = a.channels().first()
    {
        let (descr, per) = channel_dtype(&c.values);
        let shape: Vec<u64> = v
            .grid()
            .dims
            .map(u64::from)
            .into_iter()
            .chain(per.iter().copied())
            .collect();
        return array_header(&shape, descr);
    }
    let descr = if value_bytes(v.kind()) == 4 {
        "<f4"
    } else {
        "|u1"
    };
    typed_header(v.grid().dims, descr)
}

fn typed_header(dims: [u32; 3], descr: &str) -> Vec<u8> {
    array_header(&dims.map(u64::from), descr)
}

/// The `.npy` header of a C-ordered array of `shape` and dtype `descr` (`<f8`, `<u4`, `|b1`…).
pub fn array_header(shape: &[u64], descr: &str) -> Vec<u8> {
    let dims: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
    let shape = match dims.len() {
        1 => format!("({},)", dims[0]),
        _ => format!("({})", dims.join(", ")),
    };
    let mut header = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}");
    // Magic (6) + version (2) + length (2) + header + '\n' must be a multiple of 64.
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut out = Vec::with_capacity(10 + header.len());
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&[1, 0]);
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    out
}

/// Streams the `.npy` to `out` (a 2048³ volume is 8 GiB as bytes: no need to hold it).
pub fn write(v: &Volume, out: &mut impl std::io::Write) -> std::io::Result<()> {
    out.write_all(&header_of(v))?;
    write_data(v, out)
}

/// The first channel of `a` dense: each voxel's value (zero where it is not set), little
/// endian, in C order, a column at a time.
fn write_channel(a: &Attributed, out: &mut impl std::io::Write) -> std::io::Result<()> {
    let b = a.bits();
    let c = &a.channels()[0].values;
    let size = c.value_type().bytes();
    let z = b.dims()[2] as usize;
    let mut buf = vec![0u8; z * size];
    let mut next = 0usize;
    for col in b.words().chunks_exact(b.words_per_column()) {
        buf.fill(0);
        for (w, &word) in col.iter().enumerate() {
            let mut bits = word;
            while bits != 0 {
                let k = w * 64 + bits.trailing_zeros() as usize;
                bits &= bits - 1;
                let at = &mut buf[k * size..(k + 1) * size];
                match c {
                    ChannelValues::U8(v) => at[0] = v[next],
                    ChannelValues::U16(v) => at.copy_from_slice(&v[next].to_le_bytes()),
                    ChannelValues::F32(v) => at.copy_from_slice(&v[next].to_le_bytes()),
                    ChannelValues::Rgba8(v) => at.copy_from_slice(&v[next]),
                }
                next += 1;
            }
        }
        out.write_all(&buf)?;
    }
    Ok(())
}

/// The array's bytes alone, one byte (distances: a little-endian `f32`) per voxel in C order
/// (the `.raw` format), a column at a time.
pub fn write_data(v: &Volume, out: &mut impl std::io::Write) -> std::io::Result<()> {
    match v {
        Volume::Density(dv) => out.write_all(dv.data()),
        Volume::Distance(d) => {
            let z = v.grid().dims[2] as usize;
            let mut buf = Vec::with_capacity(4 * z);
            for col in d.data().chunks_exact(z) {
                buf.clear();
                for x in col {
                    buf.extend_from_slice(&x.to_le_bytes());
                }
                out.write_all(&buf)?;
            }
            Ok(())
        }
        Volume::SparseDistance(s) => write_sparse(s, out),
        Volume::Channels(a) if !a.channels().is_empty() => write_channel(a, out),
        Volume::Bits(_) | Volume::Channels(_) => {
            let b = v.bits().expect("a bit volume");
            let z = v.grid().dims[2] as usize;
            let mut buf = vec![0u8; z];
            for col in b.words().chunks_exact(b.words_per_column()) {
                for (k, o) in buf.iter_mut().enumerate() {
                    *o = (col[k / 64] >> (k % 64) & 1) as u8;
                }
                out.write_all(&buf)?;
            }
            Ok(())
        }
        other => Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            format!(
                "npy and raw hold bits, density or distances, not {}",
                other.kind()
            ),
        )),
    }
}

/// A sparse volume's every voxel as little-endian `f32`s, a Z-column at a time: each column
/// looks up its bricks once (one per 8 voxels), not every voxel.
fn write_sparse(s: &Sparse<f32>, out: &mut impl std::io::Write) -> std::io::Result<()> {
    let [nx, ny, nz] = s.grid().dims;
    let bd = s.brick_dims();
    let bricks: std::collections::HashMap<[u32; 3], &[f32; BRICK_VOXELS]> = s.bricks().collect();
    let mut buf = Vec::with_capacity(4 * nz as usize);
    for x in 0..nx {
        for y in 0..ny {
            buf.clear();
            for bz in 0..bd[2] {
                let at = [x / BRICK, y / BRICK, bz];
                let base = ((x % BRICK) * BRICK + y % BRICK) * BRICK;
                let brick = bricks.get(&at);
                let fill = if s.is_tile(at) {
                    s.tile_value()
                } else {
                    s.background()
                };
                for z in bz * BRICK..((bz + 1) * BRICK).min(nz) {
                    let v = brick.map_or(fill, |b| b[(base + z % BRICK) as usize]);
                    buf.extend_from_slice(&v.to_le_bytes());
                }
            }
            out.write_all(&buf)?;
        }
    }
    Ok(())
}

pub fn decode(bytes: &[u8]) -> Result<Volume, CodecError> {
    if bytes.len() < 10 || &bytes[..6] != MAGIC {
        return Err(malformed("npy", "not a .npy file (bad magic)"));
    }
    let (hlen, start) = match bytes[6] {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10),
        2 | 3 if bytes.len() >= 12 => (
            u32::from_le_bytes(bytes[8..12].try_into().unwrap()) as usize,
            12,
        ),
        v => return Err(malformed("npy", format!("unsupported format version {v}"))),
    };
    let header = bytes
        .get(start..start + hlen)
        .ok_or_else(|| malformed("npy", "truncated header"))?;
    let header = std::str::from_utf8(header).map_err(|_| malformed("npy", "header is not text"))?;
    let compact: String = header.chars().filter(|c| !c.is_whitespace()).collect();
    let float = compact.contains("'descr':'<f4'");
    if !float
        && ![
            "'descr':'|u1'",
            "'descr':'<u1'",
            "'descr':'u1'",
            "'descr':'|b1'",
        ]
        .iter()
        .any(|d| compact.contains(d))
    {
        return Err(malformed(
            "npy",
            format!("dtype must be uint8, bool or little-endian float32, header is {header:?}"),
        ));
    }
    if !compact.contains("'fortran_order':False") {
        return Err(malformed("npy", "only C-order arrays are supported"));
    }
    let shape = compact
        .split("'shape':(")
        .nth(1)
        .and_then(|s| s.split(')').next())
        .ok_or_else(|| malformed("npy", "header has no shape"))?;
    let dims: Vec<u32> = shape
        .split(',')
        .filter(|s| !s.is_empty())
        .map(|s| s.parse::<u32>())
        .collect::<Result<_, _>>()
        .map_err(|_| malformed("npy", format!("bad shape ({shape})")))?;
    let [x, y, z] = dims[..] else {
        return Err(malformed(
            "npy",
            format!("shape must have 3 axes, got ({shape})"),
        ));
    };
    let grid = Grid {
        origin: [0.0; 3],
        voxel_size: 1.0,
        dims: [x, y, z],
    };
    // Checked before anything is allocated (a count past u64 is u64::MAX: no file has as many
    // bytes).
    let voxels = grid.voxel_count();
    let data = &bytes[start + hlen..];
    if float {
        if data.len() as u64 != voxels.saturating_mul(4) || voxels == 0 {
            return Err(malformed(
                "npy",
                format!(
                    "expected {} data bytes for shape ({shape}) of float32, got {}",
                    voxels.saturating_mul(4),
                    data.len()
                ),
            ));
        }
        let values =
            crate::volume::kind::valid_from_le_bytes(data).map_err(|e| malformed("npy", e))?;
        return Dense::from_data(grid, values)
            .map(Volume::Distance)
            .map_err(|e| malformed("npy", e));
    }
    if data.len() as u64 != voxels || voxels == 0 {
        return Err(malformed(
            "npy",
            format!(
                "expected {voxels} data bytes for shape ({shape}), got {}",
                data.len()
            ),
        ));
    }
    let max = data.iter().copied().max().unwrap_or(0);
    if max > 1 {
        let m = if max <= 8 { 8 } else { 64 };
        return DensityVolume::from_data(grid, m, data.to_vec())
            .map(Volume::Density)
            .map_err(|e| malformed("npy", e));
    }
    let mut v = BitVolume::new(grid);
    let wpc = v.words_per_column();
    for (col, vals) in v
        .words_mut()
        .chunks_exact_mut(wpc)
        .zip(data.chunks_exact(z as usize))
    {
        for (k, &b) in vals.iter().enumerate() {
            col[k / 64] |= (b as u64) << (k % 64);
        }
    }
    Ok(Volume::Bits(v))
}

/// A normals volume as `.npy`: dtype `|i1`, shape (X, Y, Z, 3), C order, each normal component
/// scaled to −127..=127 (zero vectors where there is no normal).
pub fn encode_normals(dims: [u32; 3], normals: &[[i8; 3]]) -> Vec<u8> {
    assert_eq!(
        normals.len() as u64,
        dims.iter().map(|&d| d as u64).product::<u64>()
    );
    let mut header = format!(
        "{{'descr': '|i1', 'fortran_order': False, 'shape': ({}, {}, {}, 3), }}",
        dims[0], dims[1], dims[2]
    );
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut out = Vec::with_capacity(10 + header.len() + 3 * normals.len());
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&[1, 0]);
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    out.extend(normals.iter().flatten().map(|&c| c as u8));
    out
}
