//! `format=points` (`-o x.points.ply`): the centres of a bit volume's set voxels as a PLY point
//! cloud, for point viewers — binary little-endian, `element vertex N` with `float x, y, z`:
//! voxel (i, j, k)'s centre in world units, origin + (index + ½) · voxel size, rounded once to
//! f32. Vertices in C order of the grid (x, then y, then z), like `indices` (whose row writer
//! it shares). Streamed in pieces; the length (the header + 12 bytes a voxel) is known before. Written only.

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
    super::indices::rows_len(v, header)
}

/// Streams the points of `v`'s set voxels (`InvalidInput` for a volume that is not bits).
pub fn write(v: &Volume, out: &mut impl std::io::Write) -> std::io::Result<()> {
    let g = *v.grid();
    let centre = |a: usize, i: u32| (g.origin[a] + (f64::from(i) + 0.5) * g.voxel_size) as f32;
    super::indices::write_rows(v, "points", header, out, |p| {
        let mut row = [0u8; 12];
        for (k, c) in p.into_iter().enumerate() {
            row[4 * k..4 * k + 4].copy_from_slice(&centre(k, c).to_le_bytes());
        }
        row
    })
}
