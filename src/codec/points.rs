//! `format=points` (`-o x.points.ply`): the centres of a bit volume's set voxels as a PLY point
//! cloud, for point viewers — binary little-endian, `element vertex N` with `float x, y, z`:
//! voxel (i, j, k)'s centre in world units, origin + (index + ½) · voxel size, rounded once to
//! f32. Vertices in C order of the grid (x, then y, then z), like `indices`. Streamed a column
//! at a time; the length (the header + 12 bytes a voxel) is known before. Written only.

use crate::volume::Volume;

/// The header of `n` points.
pub fn header(n: u64) -> Vec<u8> {
    format!(
        "ply\nformat binary_little_endian 1.0\ncomment voxd: voxel centres\nelement vertex {n}\nproperty float x\nproperty float y\nproperty float z\nend_header\n"
    )
    .into_bytes()
}

/// The file's length for `v`, a bit volume (`None` otherwise).
pub fn len(v: &Volume) -> Option<u64> {
    let Volume::Bits(b) = v else { return None };
    let n = b.count_ones();
    Some(header(n).len() as u64 + 12 * n)
}

/// Streams the points of `v`'s set voxels (`InvalidInput` for a volume that is not bits).
pub fn write(v: &Volume, out: &mut impl std::io::Write) -> std::io::Result<()> {
    let Volume::Bits(b) = v else {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            format!("points lists the voxels of bit volumes, not {}", v.kind()),
        ));
    };
    const PIECE: usize = 64 * 1024;
    let g = b.grid();
    let centre = |a: usize, i: u32| (g.origin[a] + (f64::from(i) + 0.5) * g.voxel_size) as f32;
    let mut buf = header(b.count_ones());
    let d = b.dims();
    for x in 0..d[0] {
        for y in 0..d[1] {
            for (w, &word) in b.column(x, y).iter().enumerate() {
                let mut t = word;
                while t != 0 {
                    let z = (w * 64) as u32 + t.trailing_zeros();
                    t &= t - 1;
                    for (a, i) in [x, y, z].into_iter().enumerate() {
                        buf.extend_from_slice(&centre(a, i).to_le_bytes());
                    }
                }
            }
            if buf.len() >= PIECE {
                out.write_all(&buf)?;
                buf.clear();
            }
        }
    }
    out.write_all(&buf)
}
