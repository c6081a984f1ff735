//! `format=points` (`-o x.points.ply`): the centres of a bit volume's set voxels as a PLY point
//! cloud, for point viewers — binary little-endian, `element vertex N` with `float x, y, z`:
//! voxel (i, j, k)'s centre in world units, origin + (index + ½) · voxel size, rounded once to
//! f32; and `uchar red, green, blue, alpha` (the voxel's sRGB colour) when the volume has a
//! colour channel. Vertices in C order of the grid (x, then y, then z), like `indices` (whose
//! row writer it shares). Streamed in pieces; the length (the header + 12 or 16 bytes a voxel)
//! is known before. Written only.

use crate::volume::Volume;

/// The header of `n` points, with colours or not.
pub fn header(n: u64, colour: bool) -> Vec<u8> {
    let rgba = if colour {
        "property uchar red\nproperty uchar green\nproperty uchar blue\nproperty uchar alpha\n"
    } else {
        ""
    };
    format!(
        "ply\nformat binary_little_endian 1.0\ncomment voxd: voxel centres\nelement vertex {n}\nproperty float x\nproperty float y\nproperty float z\n{rgba}end_header\n"
    )
    .into_bytes()
}

/// The file's length for `v`, a bit volume (`None` otherwise).
pub fn len(v: &Volume) -> Option<u64> {
    let c = v.colours().is_some();
    super::indices::rows_len(v, |n| header(n, c), if c { 16 } else { 12 })
}

/// Streams the points of `v`'s set voxels (`InvalidInput` for a volume that is not bits).
pub fn write(v: &Volume, out: &mut impl std::io::Write) -> std::io::Result<()> {
    let g = *v.grid();
    let centre = |a: usize, i: u32| (g.origin[a] + (f64::from(i) + 0.5) * g.voxel_size) as f32;
    let rgba = v.colours();
    let c = rgba.is_some();
    super::indices::write_rows(
        v,
        "points",
        |n| header(n, c),
        out,
        |p, i, buf| {
            for (k, c) in p.into_iter().enumerate() {
                buf.extend_from_slice(&centre(k, c).to_le_bytes());
            }
            if let Some(rgba) = rgba {
                buf.extend_from_slice(&rgba[i]);
            }
        },
    )
}
