//! `distance` (Hsieh et al.'s distance-threshold voxels): voxel v is set iff some triangle
//! lies within `t` lattice units of v's centre, `geom::lattice::within(centre, tri, t)`, decided
//! exactly in integers (ties set). See `docs/methods.md` (`distance`).
//!
//! Each triangle visits only the voxels whose centres are within `t` of its bounding box: per
//! column of the two outer axes, the exact sphere-swept box gives the range along the third
//! (an integer square root); over a triangle longer than a few voxels that range is cut, too,
//! to the slab of its plane dilated by `t` (computed in `f64` and widened by a voxel: it only
//! prunes, the exact test decides). The axis ranged over is the one of y and z the normal
//! leans on most, so the slab is thin.

use super::{centre_range, for_each_band};
use crate::cancel::{Canceled, Control};
use crate::engine::distance::MAX_LATTICE;
use crate::engine::geom::lattice;
use crate::engine::{FIXED_HALF, FIXED_ONE, GridMesh};
use crate::volume::BitVolume;

/// The voxels within `t` (lattice units, 0..=[`MAX_LATTICE`]) of the mesh.
///
/// # Panics
/// When `t` is out of range (the fronts refuse such a thickness first:
/// [`thickness_lattice`](crate::engine::distance::thickness_lattice)).
pub fn voxelize(mesh: &GridMesh, t: i64, ctl: &Control) -> Result<BitVolume, Canceled> {
    assert!(
        (0..=MAX_LATTICE).contains(&t),
        "thickness {t} out of 0..={MAX_LATTICE}"
    );
    let mut vol = BitVolume::new(mesh.grid);
    let [nx, ny, _] = mesh.grid.dims;
    let dims = mesh.grid.dims;
    let wpc = vol.words_per_column();
    let x_range = |v: &[[i64; 3]; 3]| {
        let r = |a: usize| {
            let (lo, hi) = super::axis_bounds(v, a);
            centre_range(lo - t, hi + t, dims[a])
        };
        r(1)?;
        r(2)?;
        r(0)
    };
    for_each_band(mesh, &mut vol, x_range, ctl, |band, tris, words| {
        for &i in tris {
            let tri = &mesh.triangles[i as usize];
            let p = Prepared::new(tri, t);
            let Some((x0, x1)) = centre_range(p.lo[0] - t, p.hi[0] + t, nx) else {
                continue;
            };
            let (x0, x1) = (x0.max(band.start), x1.min(band.end - 1));
            let (a, b) = (p.outer, 3 - p.outer);
            let na = dims[a];
            for x in x0..=x1 {
                let cx = centre(x);
                let dx = gap(cx, p.lo[0], p.hi[0]);
                let ra = isqrt(p.t2 - dx * dx);
                let Some((a0, a1)) = centre_range(p.lo[a] - ra, p.hi[a] + ra, na) else {
                    continue;
                };
                for ia in a0..=a1 {
                    let ca = centre(ia);
                    let da = gap(ca, p.lo[a], p.hi[a]);
                    let rest = p.t2 - dx * dx - da * da;
                    if rest < 0 {
                        continue;
                    }
                    let rb = isqrt(rest);
                    let Some((b0, b1)) = centre_range(p.lo[b] - rb, p.hi[b] + rb, dims[b]) else {
                        continue;
                    };
                    let (b0, b1) = if b1 - b0 >= 3 {
                        match p.slab(cx, ca, dims[b]) {
                            Some((s0, s1)) => (b0.max(s0), b1.min(s1)),
                            None => continue,
                        }
                    } else {
                        (b0, b1)
                    };
                    for ib in b0..=b1 {
                        let cb = centre(ib);
                        let mut c = [cx, 0, 0];
                        c[a] = ca;
                        c[b] = cb;
                        if lattice::within(c, tri, t) {
                            let (y, z) = if a == 1 { (ia, ib) } else { (ib, ia) };
                            let col = ((x - band.start) as usize * ny as usize + y as usize) * wpc;
                            words[col + z as usize / 64] |= 1 << (z % 64);
                        }
                    }
                }
            }
        }
    })?;
    Ok(vol)
}

#[inline]
fn centre(i: u32) -> i64 {
    i as i64 * FIXED_ONE + FIXED_HALF
}

/// The distance from `c` to the interval `[lo, hi]`.
#[inline]
fn gap(c: i64, lo: i64, hi: i64) -> i64 {
    (lo - c).max(c - hi).max(0)
}

/// ⌊√n⌋ for 0 ≤ n < 2⁵².
#[inline]
fn isqrt(n: i64) -> i64 {
    if n <= 0 {
        return 0;
    }
    let mut r = (n as f64).sqrt() as i64;
    while r * r > n {
        r -= 1;
    }
    while (r + 1) * (r + 1) <= n {
        r += 1;
    }
    r
}

/// A triangle prepared for the walk.
struct Prepared {
    v0: [i64; 3],
    lo: [i64; 3],
    hi: [i64; 3],
    n: [f64; 3],
    t2: i64,
    /// t·|n| / |n_b| in lattice units, and `f64::INFINITY` when n_b = 0 (or the triangle has
    /// no area): the half-width of the plane's slab along b.
    half: f64,
    /// The outer one of y (1) and z (2): the other, b, is ranged over.
    outer: usize,
}

impl Prepared {
    fn new(tri: &[[i32; 3]; 3], t: i64) -> Prepared {
        let v = lattice::vertices(tri);
        let lo = [0, 1, 2].map(|a| super::axis_bounds(&v, a).0);
        let hi = [0, 1, 2].map(|a| super::axis_bounds(&v, a).1);
        let (e1, e2) = (sub(v[1], v[0]), sub(v[2], v[0]));
        // Each component below 2⁶² (edges below 2³¹): exact in i64, rounded once in f64.
        let n = [
            e1[1] * e2[2] - e1[2] * e2[1],
            e1[2] * e2[0] - e1[0] * e2[2],
            e1[0] * e2[1] - e1[1] * e2[0],
        ]
        .map(|c| c as f64);
        let b = if n[1].abs() > n[2].abs() { 1 } else { 2 };
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        let half = if n[b] == 0.0 {
            f64::INFINITY
        } else {
            t as f64 * len / n[b].abs()
        };
        Prepared {
            v0: v[0],
            lo,
            hi,
            n,
            t2: t * t,
            half,
            outer: 3 - b,
        }
    }

    /// The cells along b whose centres may lie within `t` of the plane, on the line through
    /// (cx, ca): the slab |n·(p − v0)| ≤ t|n| along b, widened by a voxel and by 10⁻¹² of the
    /// magnitudes for the roundings (an over-wide range only costs exact tests).
    fn slab(&self, cx: i64, ca: i64, nb: u32) -> Option<(u32, u32)> {
        if !self.half.is_finite() {
            return Some((0, nb.saturating_sub(1)));
        }
        let (a, b) = (self.outer, 3 - self.outer);
        let (mx, ma) = (
            self.n[0] * (cx - self.v0[0]) as f64,
            self.n[a] * (ca - self.v0[a]) as f64,
        );
        let mid = self.v0[b] as f64 - (mx + ma) / self.n[b];
        // The roundings of m and of the quotients are below 2⁻⁵⁰ of these terms.
        let err = (mx.abs() + ma.abs()) / self.n[b].abs() + self.half + mid.abs();
        let w = self.half + FIXED_ONE as f64 + err * 1e-12;
        // Clamped far outside the grid (coordinates are below 2²⁹) before the casts.
        let lim = 2f64.powi(40);
        let lo = (mid - w).clamp(-lim, lim).floor() as i64;
        let hi = (mid + w).clamp(-lim, lim).ceil() as i64;
        centre_range(lo, hi, nb)
    }
}

#[inline]
fn sub(a: [i64; 3], b: [i64; 3]) -> [i64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

#[cfg(test)]
mod tests;
