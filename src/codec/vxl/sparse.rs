//! The payload of a sparse volume in a `.vxl` (layout `"bricks8-<t>"`, described in the parent
//! module): written whole or in pieces, and read back with its order and validity checked.

use crate::grid::Grid;
use crate::volume::Voxel;
use crate::volume::kind::valid_from_le_bytes;
use crate::volume::sparse::{BRICK_VOXELS, Sparse};

/// Does a sparse volume need the tile fields: tiles, or a tile value other than the background
/// (compared by bits: −0.0 is not +0.0)?
fn has_tiles<T: Voxel>(s: &Sparse<T>) -> bool {
    if s.tile_count() > 0 {
        return true;
    }
    let (mut a, mut b) = (vec![], vec![]);
    s.tile_value().write_le(&mut a);
    s.background().write_le(&mut b);
    a != b
}

/// The header's `bricks` and `tiles`.
pub(super) fn sparse_counts<T: Voxel>(s: &Sparse<T>) -> (Option<u64>, Option<u64>) {
    let tiles = has_tiles(s).then(|| s.tile_count() as u64);
    (Some(s.brick_count() as u64), tiles)
}

/// A sparse volume's payload: background, tile value (with tiles), brick coordinates, brick
/// values, tile coordinates.
pub(super) fn sparse_payload<T: Voxel>(s: &Sparse<T>) -> Vec<u8> {
    let mut out = Vec::with_capacity(sparse_len(s));
    write_sparse(s, &mut out).expect("writing to memory");
    out
}

/// The length of [`sparse_payload`].
pub(super) fn sparse_len<T: Voxel>(s: &Sparse<T>) -> usize {
    let values = 1 + usize::from(has_tiles(s)) + s.brick_count() * BRICK_VOXELS;
    T::TYPE.bytes() * values + 12 * (s.brick_count() + s.tile_count())
}

/// [`sparse_payload`] written to `w` in pieces of about 1 MiB.
pub(super) fn write_sparse<T: Voxel>(
    s: &Sparse<T>,
    w: &mut impl std::io::Write,
) -> std::io::Result<()> {
    const PIECE: usize = 1 << 20;
    let mut buf = Vec::with_capacity(PIECE + T::TYPE.bytes() * BRICK_VOXELS);
    let flush = |buf: &mut Vec<u8>, w: &mut dyn std::io::Write, force: bool| {
        if force || buf.len() >= PIECE {
            w.write_all(buf)?;
            buf.clear();
        }
        Ok::<(), std::io::Error>(())
    };
    s.background().write_le(&mut buf);
    if has_tiles(s) {
        s.tile_value().write_le(&mut buf);
    }
    for (at, _) in s.bricks() {
        for c in at {
            buf.extend_from_slice(&c.to_le_bytes());
        }
        flush(&mut buf, w, false)?;
    }
    for (_, values) in s.bricks() {
        for &v in values.iter() {
            v.write_le(&mut buf);
        }
        flush(&mut buf, w, false)?;
    }
    for at in s.tiles() {
        for c in at {
            buf.extend_from_slice(&c.to_le_bytes());
        }
        flush(&mut buf, w, false)?;
    }
    flush(&mut buf, w, true)
}

/// A sparse volume from its payload (of the length the header implies): `tiles` is the
/// header's (`None`: no tile value in the payload).
pub(super) fn read_sparse<T: Voxel>(
    grid: Grid,
    payload: &[u8],
    bricks: usize,
    tiles: Option<usize>,
) -> Result<Sparse<T>, String> {
    let size = T::TYPE.bytes();
    let background = T::read_le(&payload[..size]);
    if !background.is_valid() {
        return Err(format!("background {background:?} is not a valid value"));
    }
    let mut at_byte = size;
    let mut s = match tiles {
        None => Sparse::new(grid, background),
        Some(_) => {
            let tile_value = T::read_le(&payload[size..2 * size]);
            if !tile_value.is_valid() {
                return Err(format!("tile value {tile_value:?} is not a valid value"));
            }
            at_byte += size;
            Sparse::with_tile_value(grid, background, tile_value)
        }
    };
    let coords = &payload[at_byte..at_byte + 12 * bricks];
    let values_end = at_byte + 12 * bricks + size * BRICK_VOXELS * bricks;
    let values = &payload[at_byte + 12 * bricks..values_end];
    let coord = |c: &[u8]| {
        let u = |i: usize| u32::from_le_bytes(c[i..i + 4].try_into().unwrap());
        [u(0), u(4), u(8)]
    };
    let mut last: Option<[u32; 3]> = None;
    for (c, v) in coords
        .chunks_exact(12)
        .zip(values.chunks_exact(size * BRICK_VOXELS))
    {
        let at = coord(c);
        if last.is_some_and(|l| l >= at) {
            return Err(format!(
                "brick {at:?} is out of order (bricks are listed in increasing (x, y, z))"
            ));
        }
        last = Some(at);
        let vals: Vec<T> = valid_from_le_bytes(v)?;
        s.insert_brick(at, vals.try_into().expect("512 values"))?;
    }
    let mut last: Option<[u32; 3]> = None;
    for c in payload[values_end..].chunks_exact(12) {
        let at = coord(c);
        if last.is_some_and(|l| l >= at) {
            return Err(format!(
                "tile {at:?} is out of order (tiles are listed in increasing (x, y, z))"
            ));
        }
        last = Some(at);
        let before = s.brick_count();
        s.set_tile(at, true)?;
        if s.brick_count() != before {
            return Err(format!("tile {at:?} is also a brick"));
        }
    }
    Ok(s)
}
