//! `surface`: voxel v is set iff some triangle intersects the closed box of v — the
//! separating-axis test of Akenine-Möller (2001) with its 13 axes, evaluated exactly in integers
//! on the fixed-point lattice. Degenerate triangles (segments, points) are handled by the same
//! test: a zero axis never separates, and the remaining axes are complete for them.
//!
//! Per triangle and column, the z-independent axes (box x and y, edge × z) are tested once; the
//! candidate voxels of the column come from the triangle's plane over the column square
//! (f64, widened by a voxel: it only prunes) and each is decided by the exact z-dependent axes.

use super::{axis_bounds, box_range, for_each_band, widen};
use crate::cancel::{Canceled, Control};
use crate::engine::{FIXED_HALF, FIXED_ONE, GridMesh};
use crate::volume::BitVolume;

const H: i64 = FIXED_HALF;

pub(super) fn voxelize(mesh: &GridMesh, ctl: &Control) -> Result<BitVolume, Canceled> {
    let mut vol = BitVolume::new(mesh.grid);
    let [nx, ny, nz] = mesh.grid.dims;
    let wpc = vol.words_per_column();
    let x_range = |v: &[[i64; 3]; 3]| {
        let b = [0, 1, 2].map(|a| axis_bounds(v, a));
        box_range(b[1].0, b[1].1, ny)?;
        box_range(b[2].0, b[2].1, nz)?;
        box_range(b[0].0, b[0].1, nx)
    };
    for_each_band(mesh, &mut vol, x_range, ctl, |band, tris, words| {
        for &t in tris {
            let tri = Tri::new(widen(&mesh.triangles[t as usize]));
            let b = [0, 1, 2].map(|a| axis_bounds(&tri.v, a));
            let (Some((x0, x1)), Some((y0, y1)), Some((zk0, zk1))) = (
                box_range(b[0].0, b[0].1, nx),
                box_range(b[1].0, b[1].1, ny),
                box_range(b[2].0, b[2].1, nz),
            ) else {
                continue;
            };
            let (x0, x1) = (x0.max(band.start), x1.min(band.end - 1));
            for x in x0..=x1 {
                for y in y0..=y1 {
                    let c = [x as i64 * FIXED_ONE + H, y as i64 * FIXED_ONE + H];
                    if !tri.column_overlaps(c) {
                        continue;
                    }
                    let (k0, k1) = tri.candidate_layers(c, zk0, zk1);
                    let col = ((x - band.start) as usize * ny as usize + y as usize) * wpc;
                    for k in k0..=k1 {
                        if tri.layer_overlaps([c[0], c[1], k as i64 * FIXED_ONE + H]) {
                            words[col + k as usize / 64] |= 1 << (k % 64);
                        }
                    }
                }
            }
        }
    })?;
    Ok(vol)
}

/// A triangle prepared for box tests: vertices, edges and (unnormalised) normal.
struct Tri {
    v: [[i64; 3]; 3],
    e: [[i64; 3]; 3],
    n: [i64; 3],
}

impl Tri {
    fn new(v: [[i64; 3]; 3]) -> Tri {
        let sub = |a: [i64; 3], b: [i64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
        let e = [sub(v[1], v[0]), sub(v[2], v[1]), sub(v[0], v[2])];
        let (a, b) = (e[0], sub(v[2], v[0]));
        let n = [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ];
        Tri { v, e, n }
    }

    /// Vertices relative to a point.
    fn rel(&self, c: [i64; 3]) -> [[i64; 3]; 3] {
        self.v.map(|p| [p[0] - c[0], p[1] - c[1], p[2] - c[2]])
    }

    /// The z-independent axes: edge × z. (Box x and y hold by the column range.)
    fn column_overlaps(&self, c: [i64; 2]) -> bool {
        let r = self.rel([c[0], c[1], 0]);
        self.e.iter().all(|e| {
            !separates(
                r.map(|p| e[1] * p[0] - e[0] * p[1]),
                H * (e[0].abs() + e[1].abs()),
            )
        })
    }

    /// The z-dependent axes: box z, triangle normal, edge × x, edge × y.
    fn layer_overlaps(&self, c: [i64; 3]) -> bool {
        let r = self.rel(c);
        if separates(r.map(|p| p[2]), H) {
            return false;
        }
        let d = self.n[0] as i128 * r[0][0] as i128
            + self.n[1] as i128 * r[0][1] as i128
            + self.n[2] as i128 * r[0][2] as i128;
        if d.abs()
            > H as i128
                * (self.n[0].unsigned_abs() as i128
                    + self.n[1].unsigned_abs() as i128
                    + self.n[2].unsigned_abs() as i128)
        {
            return false;
        }
        self.e.iter().all(|e| {
            !separates(
                r.map(|p| e[2] * p[1] - e[1] * p[2]),
                H * (e[2].abs() + e[1].abs()),
            ) && !separates(
                r.map(|p| e[0] * p[2] - e[2] * p[0]),
                H * (e[2].abs() + e[0].abs()),
            )
        })
    }

    /// Voxel layers of a column worth testing: where the plane passes over the column square
    /// (floored exactly, widened by one layer), clamped to the triangle's own layers.
    fn candidate_layers(&self, c: [i64; 2], k0: u32, k1: u32) -> (u32, u32) {
        let mut n = self.n.map(i128::from);
        if n[2] == 0 {
            return (k0, k1);
        }
        if n[2] < 0 {
            n = n.map(|v| -v);
        }
        let p = self.v[0].map(i128::from);
        let (mut lo, mut hi) = (i128::MAX, i128::MIN);
        for dx in [-H, H] {
            for dy in [-H, H] {
                let (x, y) = ((c[0] + dx) as i128, (c[1] + dy) as i128);
                let z = (p[2] * n[2] - n[0] * (x - p[0]) - n[1] * (y - p[1])).div_euclid(n[2]);
                lo = lo.min(z);
                hi = hi.max(z);
            }
        }
        let one = FIXED_ONE as i128;
        let a = (lo.div_euclid(one) - 1).max(k0 as i128);
        let b = (hi.div_euclid(one) + 1).min(k1 as i128);
        if a > b { (1, 0) } else { (a as u32, b as u32) }
    }
}

/// An axis separates when the projections of the triangle all lie beyond the box's radius `r`.
fn separates(p: [i64; 3], r: i64) -> bool {
    p[0].min(p[1]).min(p[2]) > r || p[0].max(p[1]).max(p[2]) < -r
}

/// Does the triangle touch the closed box of voxel (x, y, z)? The plain 13-axis test, for tests
/// and for engines to compare against.
pub fn triangle_overlaps_voxel(tri: &[[i32; 3]; 3], x: u32, y: u32, z: u32) -> bool {
    let t = Tri::new(widen(tri));
    let c = [x, y, z].map(|i| i as i64 * FIXED_ONE + H);
    let r = t.rel(c);
    (0..2).all(|a| !separates(r.map(|p| p[a]), H))
        && t.column_overlaps([c[0], c[1]])
        && t.layer_overlaps(c)
}
