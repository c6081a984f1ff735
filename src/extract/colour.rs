//! Vertex colours of an extracted mesh from a volume with an `rgba` channel (issue 34: the viewer
//! and the mesh downloads show colours). A vertex at lattice position p (voxel (i, j, k) spans
//! [i, i + 1] × …) takes the average, in linear light, of the colours of the set voxels among the
//! eight whose centres are the corners of the cell around p (per axis the voxels
//! ⌊p − ½⌋ and ⌊p − ½⌋ + 1): for `cubes` the voxels that meet at a corner, for surface nets
//! the cell the vertex lies in. A vertex with none of them set (a vertex pulled outside its
//! cell) takes the nearest set voxel's colour within two voxels, else stays white. Averaged in
//! linear light, rounded once to sRGB bytes; alpha averaged as is.
//!
//! `cubes` merges coplanar faces into rectangles whatever their voxels' colours, so a large flat
//! face shows its corners' colours interpolated, not each voxel's.

use super::TriMesh;
use crate::engine::colour::to_rgba8;
use crate::mesh::texture::srgb_to_linear_table;
use crate::volume::Attributed;

/// One colour per vertex of `m` (lattice coordinates) from `a`'s `rgba` channel; empty when `a`
/// has none.
pub fn vertex_colours(m: &TriMesh, a: &Attributed) -> Vec<[u8; 4]> {
    let Some(colours) = a.colours() else {
        return vec![];
    };
    let dims = a.bits().dims();
    let lin = srgb_to_linear_table();
    let at = |v: [i64; 3]| -> Option<[u8; 4]> {
        if (0..3).any(|k| v[k] < 0 || v[k] >= i64::from(dims[k])) {
            return None;
        }
        a.rank(v[0] as u32, v[1] as u32, v[2] as u32)
            .map(|r| colours[r])
    };
    m.positions
        .iter()
        .map(|p| {
            let base = p.map(|c| (c - 0.5).floor() as i64);
            let mut sum = [0.0f64; 4];
            let mut n = 0u32;
            for c in 0..8 {
                let v = [0, 1, 2].map(|k| base[k] + (c >> k & 1) as i64);
                if let Some(col) = at(v) {
                    for k in 0..3 {
                        sum[k] += f64::from(lin[usize::from(col[k])]);
                    }
                    sum[3] += f64::from(col[3]) / 255.0;
                    n += 1;
                }
            }
            if n == 0 {
                // The nearest set voxel within two voxels of the cell (by centre distance).
                let mut best: Option<(f64, [u8; 4])> = None;
                for dx in -2..=3 {
                    for dy in -2..=3 {
                        for dz in -2..=3 {
                            let v = [base[0] + dx, base[1] + dy, base[2] + dz];
                            if let Some(col) = at(v) {
                                let d: f64 =
                                    (0..3).map(|k| (v[k] as f64 + 0.5 - p[k]).powi(2)).sum();
                                if best.is_none_or(|(b, _)| d < b) {
                                    best = Some((d, col));
                                }
                            }
                        }
                    }
                }
                return best.map_or([255; 4], |(_, c)| c);
            }
            // Stored as the colour voxels are: sRGB bytes, alpha linear.
            to_rgba8(sum.map(|v| (v / f64::from(n)) as f32))
        })
        .collect()
}
