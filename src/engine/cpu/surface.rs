//! `surface`: voxel v is set iff some triangle intersects the closed box of v — the
//! separating-axis test of Akenine-Möller (2001) with its 13 axes, evaluated exactly in integers
//! on the fixed-point lattice. Degenerate triangles (segments, points) are handled by the same
//! test: a zero axis never separates, and the remaining axes are complete for them.
//!
//! Per triangle and column, the z-independent axes (box x and y, edge × z) are tested once; the
//! candidate voxels of the column come from the triangle's plane over the column square
//! (floored exactly and widened by a layer: it only prunes) and each is decided by the exact
//! z-dependent axes. A triangle that lies in one voxel's closed slab along an axis needs only
//! the two box axes across the slab and edge × that axis (its shadow along the axis decides),
//! so most small triangles skip most of the 13.

use super::{axis_bounds, box_range, for_each_band, widen};
use crate::cancel::{Canceled, Control};
use crate::engine::{FIXED_HALF, FIXED_ONE, GridMesh};
use crate::volume::BitVolume;

const H: i64 = FIXED_HALF;

pub(super) fn voxelize(mesh: &GridMesh, ctl: &Control) -> Result<BitVolume, Canceled> {
    let mut vol = BitVolume::new(mesh.grid);
    apply(mesh, &mut vol, true, ctl)?;
    Ok(vol)
}

/// Sets (`add`) or clears every voxel of `vol` that the surface method sets; `vol` is on
/// `mesh`'s grid. A voxel met by several triangles is set or cleared several times, to the
/// same end, so the order of the triangles does not matter.
pub(super) fn apply(
    mesh: &GridMesh,
    vol: &mut BitVolume,
    add: bool,
    ctl: &Control,
) -> Result<(), Canceled> {
    assert_eq!(
        vol.grid().dims,
        mesh.grid.dims,
        "volume not on the mesh's grid"
    );
    // One copy of the loops per operation, with no choice inside them.
    if add {
        apply_with::<true>(mesh, vol, ctl)
    } else {
        apply_with::<false>(mesh, vol, ctl)
    }
}

fn apply_with<const ADD: bool>(
    mesh: &GridMesh,
    vol: &mut BitVolume,
    ctl: &Control,
) -> Result<(), Canceled> {
    let [nx, ny, nz] = mesh.grid.dims;
    let wpc = vol.words_per_column();
    let x_range = |v: &[[i64; 3]; 3]| {
        let b = [0, 1, 2].map(|a| axis_bounds(v, a));
        box_range(b[1].0, b[1].1, ny)?;
        box_range(b[2].0, b[2].1, nz)?;
        box_range(b[0].0, b[0].1, nx)
    };
    let mark = |w: &mut u64, bit: u64| {
        if ADD { *w |= bit } else { *w &= !bit }
    };
    for_each_band(mesh, vol, x_range, ctl, |band, tris, words| {
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
            // A triangle inside one closed slab of x cells meets a voxel of that slab exactly
            // where its shadow on the yz plane meets the voxel's yz square: the axes y (the
            // column range), z and edge × x decide it. As the shadow is convex and spans the
            // triangle's whole y extent, every column of the y range is met, so the column's
            // axes (edge × z) cannot separate. Likewise with x and y swapped. And a triangle
            // inside one layer's closed slab meets a voxel of that layer exactly where its
            // shadow meets the voxel's square, which the column's axes (box x and y, edge × z)
            // decide: no z-dependent axis is needed.
            let (in_x, in_y) = (inside(b[0], x0, x1), inside(b[1], y0, y1));
            let one_column = in_x || in_y;
            let one_layer = inside(b[2], zk0, zk1);
            let axes = if in_x {
                Axes::EdgeX
            } else if in_y {
                Axes::EdgeY
            } else {
                Axes::All
            };
            let (x0, x1) = (x0.max(band.start), x1.min(band.end - 1));
            for x in x0..=x1 {
                for y in y0..=y1 {
                    let c = [x as i64 * FIXED_ONE + H, y as i64 * FIXED_ONE + H];
                    if !one_column && !tri.column_overlaps(c) {
                        continue;
                    }
                    let col = ((x - band.start) as usize * ny as usize + y as usize) * wpc;
                    if one_layer {
                        mark(&mut words[col + zk0 as usize / 64], 1 << (zk0 % 64));
                        continue;
                    }
                    // Pruning by the plane pays only over a few layers.
                    let (k0, k1) = if zk1 - zk0 >= 3 {
                        tri.candidate_layers(c, zk0, zk1)
                    } else {
                        (zk0, zk1)
                    };
                    for k in k0..=k1 {
                        if tri.layer_overlaps([c[0], c[1], k as i64 * FIXED_ONE + H], axes) {
                            mark(&mut words[col + k as usize / 64], 1 << (k % 64));
                        }
                    }
                }
            }
        }
    })
}

/// Is the extent `[lo, hi]` inside the closed box of cell `k0`, the only cell of `k0..=k1`?
/// (`k0..=k1` is `box_range`'s clamped answer, so one cell alone does not say it: a triangle
/// reaching out of the grid clamps to the border cell.)
fn inside((lo, hi): (i64, i64), k0: u32, k1: u32) -> bool {
    let base = k0 as i64 * FIXED_ONE;
    k0 == k1 && lo >= base && hi <= base + FIXED_ONE
}

/// The z-dependent axes that decide a voxel: all of them, or, for a triangle inside one x (y)
/// slab, edge × x (edge × y) alone beside box z.
#[derive(Clone, Copy)]
enum Axes {
    All,
    EdgeX,
    EdgeY,
}

/// A triangle prepared for box tests: vertices, edges and (unnormalised) normal.
struct Tri {
    v: [[i64; 3]; 3],
    e: [[i64; 3]; 3],
    n: [i64; 3],
    /// Every |n| component below 2^31: the normal's projection fits in i64 (see `layer_overlaps`).
    small: bool,
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
        let small = n.iter().all(|c| c.unsigned_abs() < 1 << 31);
        Tri { v, e, n, small }
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

    /// The z-dependent axes: box z, then triangle normal, edge × x and edge × y, or only those
    /// of `axes`.
    fn layer_overlaps(&self, c: [i64; 3], axes: Axes) -> bool {
        let r = self.rel(c);
        if separates(r.map(|p| p[2]), H) {
            return false;
        }
        let edge_x = |e: &[i64; 3]| {
            !separates(
                r.map(|p| e[2] * p[1] - e[1] * p[2]),
                H * (e[2].abs() + e[1].abs()),
            )
        };
        let edge_y = |e: &[i64; 3]| {
            !separates(
                r.map(|p| e[0] * p[2] - e[2] * p[0]),
                H * (e[2].abs() + e[0].abs()),
            )
        };
        match axes {
            Axes::EdgeX => return self.e.iter().all(edge_x),
            Axes::EdgeY => return self.e.iter().all(edge_y),
            Axes::All => {}
        }
        // |r| < 2^30 + H (coordinates and centres below 2^29): with |n| < 2^31 each product is
        // below 2^62 and their sum and the radius below 2^63.
        let beyond = if self.small {
            let d = self.n[0] * r[0][0] + self.n[1] * r[0][1] + self.n[2] * r[0][2];
            d.abs() > H * (self.n[0].abs() + self.n[1].abs() + self.n[2].abs())
        } else {
            let d = self.n[0] as i128 * r[0][0] as i128
                + self.n[1] as i128 * r[0][1] as i128
                + self.n[2] as i128 * r[0][2] as i128;
            d.abs()
                > H as i128
                    * (self.n[0].unsigned_abs() as i128
                        + self.n[1].unsigned_abs() as i128
                        + self.n[2].unsigned_abs() as i128)
        };
        if beyond {
            return false;
        }
        self.e.iter().all(|e| edge_x(e) && edge_y(e))
    }

    /// Voxel layers of a column worth testing: where the plane passes over the column square
    /// (floored exactly, widened by one layer), clamped to the triangle's own layers.
    ///
    /// Over the plane, z(x, y) = p.z − m(x, y) / n.z with m = n.x (x − p.x) + n.y (y − p.y), and
    /// over the square m ranges over m(centre) ± s, s = H (|n.x| + |n.y|): two floored divisions.
    fn candidate_layers(&self, c: [i64; 2], k0: u32, k1: u32) -> (u32, u32) {
        let mut n = self.n;
        if n[2] == 0 {
            return (k0, k1);
        }
        if n[2] < 0 {
            n = n.map(|v| -v);
        }
        let p = self.v[0];
        let (dx, dy) = (c[0] - p[0], c[1] - p[1]);
        let s = H as i128 * (n[0].unsigned_abs() as i128 + n[1].unsigned_abs() as i128);
        // |dx|, |dy| < 2^31 (coordinates and centres below 2^29): with |n.x|, |n.y| < 2^31
        // every term and sum below fits in i64, and i64 division is much cheaper than i128's.
        let (lo, hi) = if n[0].unsigned_abs() < 1 << 31 && n[1].unsigned_abs() < 1 << 31 {
            let (m, s) = (n[0] * dx + n[1] * dy, s as i64);
            (
                p[2] + (-(m + s)).div_euclid(n[2]),
                p[2] + (-(m - s)).div_euclid(n[2]),
            )
        } else {
            let m = n[0] as i128 * dx as i128 + n[1] as i128 * dy as i128;
            let (p2, n2) = (p[2] as i128, n[2] as i128);
            let z = |m: i128| (p2 + (-m).div_euclid(n2)).clamp(i64::MIN as i128, i64::MAX as i128);
            (z(m + s) as i64, z(m - s) as i64)
        };
        let a = (lo.div_euclid(FIXED_ONE) - 1).max(k0 as i64);
        let b = (hi.div_euclid(FIXED_ONE) + 1).min(k1 as i64);
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
        && t.layer_overlaps(c, Axes::All)
}
