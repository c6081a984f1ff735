//! Outward normals from the density gradient (Eisemann & Décoret §6): at the voxel holding a world
//! point, ∇d by central differences over its six face neighbours (outside the grid counts as 0; a
//! bit volume counts as 0/1), and n = −∇d / |∇d|. `None` where the gradient vanishes (deep inside,
//! far outside, or a symmetric configuration).

use super::{Volume, VolumeKind};

/// The kinds normals are taken of: occupancy levels (a density's, or a bit's 0/1).
pub const ACCEPTS: &[VolumeKind] = &[VolumeKind::Bits, VolumeKind::Density];

/// The voxel value with the grid's outside as 0.
fn value(v: &Volume, i: [i64; 3]) -> i32 {
    let d = v.grid().dims;
    if (0..3).any(|a| i[a] < 0 || i[a] >= d[a] as i64) {
        return 0;
    }
    let (x, y, z) = (i[0] as u32, i[1] as u32, i[2] as u32);
    match v {
        Volume::Density(dv) => dv.get(x, y, z) as i32,
        other => other.occupied(x, y, z) as i32,
    }
}

/// The gradient at voxel `i`, in value units per voxel, times two.
pub fn gradient2(v: &Volume, i: [i64; 3]) -> [i32; 3] {
    [0, 1, 2].map(|a| {
        let (mut lo, mut hi) = (i, i);
        lo[a] -= 1;
        hi[a] += 1;
        value(v, hi) - value(v, lo)
    })
}

/// The unit outward normal at world point `p`, or `None` (outside the grid, or no gradient).
pub fn normal_at(v: &Volume, p: [f64; 3]) -> Option<[f64; 3]> {
    let i = v.grid().voxel_containing(p)?;
    let gr = gradient2(v, i.map(i64::from));
    let len = (gr.iter().map(|&c| (c as f64) * (c as f64)).sum::<f64>()).sqrt();
    (len > 0.0).then(|| gr.map(|c| -(c as f64) / len))
}

/// A normal per voxel, components scaled to −127..=127, for boundary voxels (value strictly
/// between empty and full; for bit volumes, set voxels with an empty face neighbour); zero elsewhere.
/// Order: (x · Y + y) · Z + z.
pub fn boundary_normals(v: &Volume) -> Vec<[i8; 3]> {
    let d = v.grid().dims;
    let full = match v {
        Volume::Density(dv) => dv.max() as i32,
        _ => 1,
    };
    let mut out = Vec::with_capacity(v.grid().voxel_count() as usize);
    for x in 0..d[0] as i64 {
        for y in 0..d[1] as i64 {
            for z in 0..d[2] as i64 {
                let here = value(v, [x, y, z]);
                let boundary = match v {
                    Volume::Density(_) => here > 0 && here < full,
                    _ => {
                        let faces = [
                            [-1, 0, 0],
                            [1, 0, 0],
                            [0, -1, 0],
                            [0, 1, 0],
                            [0, 0, -1],
                            [0, 0, 1],
                        ];
                        here == 1
                            && faces
                                .iter()
                                .any(|o| value(v, [x + o[0], y + o[1], z + o[2]]) == 0)
                    }
                };
                let g = gradient2(v, [x, y, z]);
                let len = (g.iter().map(|&c| (c as f64) * (c as f64)).sum::<f64>()).sqrt();
                out.push(if boundary && len > 0.0 {
                    g.map(|c| (-(c as f64) / len * 127.0).round() as i8)
                } else {
                    [0; 3]
                });
            }
        }
    }
    out
}
