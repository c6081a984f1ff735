//! Cutting triangles into work items on the host. An item is one triangle and a tile of at most
//! [`MAX_TILE`] columns (solid) or voxels (surface) inside the slab, so each GPU invocation does
//! bounded work whatever the triangle's size.

use std::ops::Range;

use rayon::prelude::*;

use crate::engine::{axis_bounds, box_range, centre_range, widen};

/// Columns (solid) or voxels (surface) per work item.
pub const MAX_TILE: u32 = 1024;

/// Items `[triangle, x0, y0, nx << 16 | ny]` of at most `side × side` columns covering, for each
/// triangle with a non-zero projected area, the columns of the slab whose centres lie in its
/// bounding box.
pub fn solid_items(
    tris: &[[[i32; 3]; 3]],
    slab: Range<u32>,
    dims: [u32; 3],
    side: u32,
) -> Vec<u32> {
    per_triangle(tris, |t, v, out| {
        let area2 =
            (v[1][0] - v[0][0]) * (v[2][1] - v[0][1]) - (v[1][1] - v[0][1]) * (v[2][0] - v[0][0]);
        if area2 == 0 {
            return;
        }
        let (xl, xh) = axis_bounds(v, 0);
        let (yl, yh) = axis_bounds(v, 1);
        let (Some((x0, x1)), Some((y0, y1))) =
            (centre_range(xl, xh, dims[0]), centre_range(yl, yh, dims[1]))
        else {
            return;
        };
        let (x0, x1) = (x0.max(slab.start), x1.min(slab.end - 1));
        if x0 > x1 {
            return;
        }
        for tx in (x0..=x1).step_by(side as usize) {
            for ty in (y0..=y1).step_by(side as usize) {
                let nx = (x1 - tx + 1).min(side);
                let ny = (y1 - ty + 1).min(side);
                out.extend_from_slice(&[t, tx, ty, nx << 16 | ny]);
            }
        }
    })
}

/// Items `[triangle, x0, y0, z0, nx << 20 | ny << 10 | nz]` covering the voxels of the slab whose
/// closed boxes meet each triangle's bounding box.
pub fn surface_items(tris: &[[[i32; 3]; 3]], slab: Range<u32>, dims: [u32; 3]) -> Vec<u32> {
    per_triangle(tris, |t, v, out| {
        let b = [0, 1, 2].map(|a| axis_bounds(v, a));
        let (Some((x0, x1)), Some((y0, y1)), Some((z0, z1))) = (
            box_range(b[0].0, b[0].1, dims[0]),
            box_range(b[1].0, b[1].1, dims[1]),
            box_range(b[2].0, b[2].1, dims[2]),
        ) else {
            return;
        };
        let (x0, x1) = (x0.max(slab.start), x1.min(slab.end - 1));
        if x0 > x1 {
            return;
        }
        let (ex, ey, ez) = (x1 - x0 + 1, y1 - y0 + 1, z1 - z0 + 1);
        let tz = ez.min(16);
        let txy = ((MAX_TILE / tz) as f64).sqrt() as u32;
        let tx = ex.min(txy).max(1);
        let ty = ey.min(MAX_TILE / (tx * tz)).clamp(1, 1023);
        for ix in (x0..=x1).step_by(tx as usize) {
            for iy in (y0..=y1).step_by(ty as usize) {
                for iz in (z0..=z1).step_by(tz as usize) {
                    let nx = (x1 - ix + 1).min(tx);
                    let ny = (y1 - iy + 1).min(ty);
                    let nz = (z1 - iz + 1).min(tz);
                    out.extend_from_slice(&[t, ix, iy, iz, nx << 20 | ny << 10 | nz]);
                }
            }
        }
    })
}

/// Items `[triangle, x0, y0, z0, nx << 20 | ny << 10 | nz]` covering the voxels of the slab whose
/// centres lie within `t` of each triangle's bounding box (`distance`), less the tiles whose
/// centres all lie farther than `t` from the triangle's plane (decided in `f64` with a voxel's
/// margin: it only prunes, the kernel decides exactly).
pub fn distance_items(
    tris: &[[[i32; 3]; 3]],
    slab: Range<u32>,
    dims: [u32; 3],
    t: i64,
) -> Vec<u32> {
    per_triangle(tris, |i, v, out| {
        let r = |a: usize| {
            let (lo, hi) = axis_bounds(v, a);
            centre_range(lo - t, hi + t, dims[a])
        };
        let (Some((x0, x1)), Some((y0, y1)), Some((z0, z1))) = (r(0), r(1), r(2)) else {
            return;
        };
        let (x0, x1) = (x0.max(slab.start), x1.min(slab.end - 1));
        if x0 > x1 {
            return;
        }
        let sub = |a: [i64; 3], b: [i64; 3]| [0, 1, 2].map(|k| (a[k] - b[k]) as f64);
        let (e1, e2) = (sub(v[1], v[0]), sub(v[2], v[0]));
        let n = [
            e1[1] * e2[2] - e1[2] * e2[1],
            e1[2] * e2[0] - e1[0] * e2[2],
            e1[0] * e2[1] - e1[1] * e2[0],
        ];
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        let one = crate::engine::FIXED_ONE as f64;
        // Is every centre of the tile farther than t from the plane? The plane's signed
        // distance over the tile's box of centres is its value at the box's middle ± the half
        // extents weighted by |n|.
        let far = |o: [u32; 3], s: [u32; 3]| {
            if len == 0.0 {
                return false;
            }
            let mid = [0, 1, 2].map(|a| (o[a] as f64 + (s[a] - 1) as f64 / 2.0) * one + one / 2.0);
            let m: f64 = (0..3)
                .map(|a| n[a] * (mid[a] - v[0][a] as f64))
                .sum::<f64>()
                / len;
            let spread: f64 = (0..3)
                .map(|a| n[a].abs() * (s[a] - 1) as f64 * one / 2.0)
                .sum::<f64>()
                / len;
            m.abs() - spread > t as f64 + one + m.abs() * 1e-9
        };
        let (ex, ey, ez) = (x1 - x0 + 1, y1 - y0 + 1, z1 - z0 + 1);
        let tz = ez.min(16);
        let txy = ((MAX_TILE / tz) as f64).sqrt() as u32;
        let tx = ex.min(txy).max(1);
        let ty = ey.min(MAX_TILE / (tx * tz)).clamp(1, 1023);
        for ix in (x0..=x1).step_by(tx as usize) {
            for iy in (y0..=y1).step_by(ty as usize) {
                for iz in (z0..=z1).step_by(tz as usize) {
                    let s = [
                        (x1 - ix + 1).min(tx),
                        (y1 - iy + 1).min(ty),
                        (z1 - iz + 1).min(tz),
                    ];
                    if !far([ix, iy, iz], s) {
                        out.extend_from_slice(&[i, ix, iy, iz, s[0] << 20 | s[1] << 10 | s[2]]);
                    }
                }
            }
        }
    })
}

fn per_triangle(
    tris: &[[[i32; 3]; 3]],
    f: impl Fn(u32, &[[i64; 3]; 3], &mut Vec<u32>) + Sync,
) -> Vec<u32> {
    let parts: Vec<Vec<u32>> = tris
        .par_chunks(16 * 1024)
        .enumerate()
        .map(|(c, chunk)| {
            let mut out = Vec::new();
            for (i, t) in chunk.iter().enumerate() {
                f((c * 16 * 1024 + i) as u32, &widen(t), &mut out);
            }
            out
        })
        .collect();
    parts.concat()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiles_cover_the_bbox_and_stay_small() {
        // A triangle spanning a 1000 × 700 × 300 box.
        let t = [
            [0, 0, 0],
            [1000 * 256, 0, 300 * 256],
            [0, 700 * 256, 150 * 256],
        ];
        let dims = [1000, 700, 300];
        let items = surface_items(&[t], 0..1000, dims);
        let mut voxels = 0u64;
        for it in items.chunks(5) {
            let (nx, ny, nz) = (it[4] >> 20, (it[4] >> 10) & 0x3ff, it[4] & 0x3ff);
            assert!(nx * ny * nz <= MAX_TILE && nx > 0 && ny > 0 && nz > 0);
            voxels += (nx * ny * nz) as u64;
        }
        assert_eq!(voxels, 1000 * 700 * 300);
        let items = solid_items(&[t], 100..200, dims, 32);
        let cols: u64 = items
            .chunks(4)
            .map(|it| ((it[3] >> 16) * (it[3] & 0xffff)) as u64)
            .sum();
        assert_eq!(cols, 100 * 700);
        assert!(items.chunks(4).all(|it| (100..200).contains(&it[1])));
    }
}
