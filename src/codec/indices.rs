//! `format=indices`: the set voxels of a bit volume as a NumPy `.npy` of dtype `<u4` and shape
//! (N, 3), one row (x, y, z) per set voxel, rows in C order of the grid (x, then y, then z
//! ascending: what `np.argwhere` gives on the dense `.npy`). Written in pieces; its
//! length (header + 12 bytes a voxel) is known before. The grid is not stored (keep the `.vxl`).

use crate::volume::{Attributed, Volume};

/// The header of `n` rows.
pub fn header(n: u64) -> Vec<u8> {
    super::npy::array_header(&[n, 3], "<u4")
}

/// The file's length for `v`, a bit volume (`None` otherwise, and for a volume with a channel:
/// its `.npz` is compressed).
pub fn len(v: &Volume) -> Option<u64> {
    if let Volume::Channels(a) = v
        && !a.channels().is_empty()
    {
        return None;
    }
    rows_len(v, header, 12)
}

/// A bit volume with one channel (a download with `attributes=`) as an `.npz`: `indices`
/// (N, 3) `uint32` as above and the channel by its name, one row a voxel in the same order:
/// `rgba` (N, 4) `uint8`, `material` (N,) `uint16` (any other type as its `.npy` dtype).
fn write_npz(a: &Attributed, out: &mut impl std::io::Write) -> std::io::Result<()> {
    let n = a.len();
    let idx: Vec<u8> = a
        .bits()
        .iter_ones()
        .flat_map(|p| p.into_iter().flat_map(u32::to_le_bytes))
        .collect();
    let c = &a.channels()[0];
    let (descr, per) = super::npy::channel_dtype(&c.values);
    let shape = std::iter::once(n).chain(per.iter().copied()).collect();
    let name: &'static str = match c.name.as_str() {
        crate::engine::colour::RGBA => crate::engine::colour::RGBA,
        crate::engine::colour::MATERIAL => crate::engine::colour::MATERIAL,
        _ => "values",
    };
    let arrays = [
        super::npz::Array {
            name: "indices",
            descr: "<u4",
            shape: vec![n, 3],
            data: idx,
        },
        super::npz::Array {
            name,
            descr,
            shape,
            data: c.values.to_le_bytes(),
        },
    ];
    let mut buf = std::io::Cursor::new(Vec::new());
    super::npz::write(&arrays, &mut buf)?;
    out.write_all(&buf.into_inner())
}

/// Streams the rows of `v`'s set voxels (`InvalidInput` for a volume that is not bits); a bit
/// volume with one channel as an `.npz` ([`write_npz`]).
pub fn write(v: &Volume, out: &mut impl std::io::Write) -> std::io::Result<()> {
    if let Volume::Channels(a) = v
        && !a.channels().is_empty()
    {
        return write_npz(a, out);
    }
    write_rows(v, "indices", header, out, |p, _, buf| {
        for c in p {
            buf.extend_from_slice(&c.to_le_bytes());
        }
    })
}

/// The length of a file of `header(n)` and a `width`-byte row per set voxel of `v` (`None`:
/// not a bit volume). Shared with `points`.
pub(super) fn rows_len(v: &Volume, header: impl Fn(u64) -> Vec<u8>, width: u64) -> Option<u64> {
    let n = v.bits()?.count_ones();
    Some(header(n).len() as u64 + width * n)
}

/// Streams `header(n)` then `row(voxel, rank, buffer)` (appending the row) for each of the `n` set voxels of `v` in C order
/// (`BitVolume::iter_ones`), in pieces of about 64 KiB; `InvalidInput` naming `format` for a
/// volume that is not bits. Shared with `points`.
pub(super) fn write_rows(
    v: &Volume,
    format: &str,
    header: impl Fn(u64) -> Vec<u8>,
    out: &mut impl std::io::Write,
    mut row: impl FnMut([u32; 3], usize, &mut Vec<u8>),
) -> std::io::Result<()> {
    let Some(b) = v.bits() else {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            format!("{format} lists the voxels of bit volumes, not {}", v.kind()),
        ));
    };
    const PIECE: usize = 64 * 1024;
    let mut buf = header(b.count_ones());
    for (i, p) in b.iter_ones().enumerate() {
        row(p, i, &mut buf);
        if buf.len() >= PIECE {
            out.write_all(&buf)?;
            buf.clear();
        }
    }
    out.write_all(&buf)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::Grid;
    use crate::volume::BitVolume;

    #[test]
    fn rows_are_the_set_voxels_in_c_order() {
        let mut b = BitVolume::new(Grid {
            origin: [0.0; 3],
            voxel_size: 1.0,
            dims: [3, 2, 130],
        });
        let set = [[0, 0, 129], [0, 1, 0], [2, 0, 64], [2, 0, 65], [2, 1, 3]];
        for p in set {
            b.set(p[0], p[1], p[2], true);
        }
        let v = Volume::Bits(b);
        let mut out = Vec::new();
        write(&v, &mut out).unwrap();
        assert_eq!(Some(out.len() as u64), len(&v));
        let h = header(5);
        assert_eq!(&out[..h.len()], &h[..]);
        let header_text = String::from_utf8_lossy(&h);
        assert!(header_text.contains("'descr': '<u4'") && header_text.contains("(5, 3)"));
        let rows: Vec<[u32; 3]> = out[h.len()..]
            .chunks(12)
            .map(|r| {
                std::array::from_fn(|k| u32::from_le_bytes(r[4 * k..4 * k + 4].try_into().unwrap()))
            })
            .collect();
        assert_eq!(rows, set.to_vec());
    }
}
