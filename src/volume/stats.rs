//! Statistics of a bit volume. Voxels are solid unit-density cubes of the grid's voxel size.
//!
//! - `surface_voxels`: solid voxels with at least one of their 6 face neighbours empty (outside
//!   the grid counts as empty).
//! - components: connected groups of solid voxels, 6-connected (shared faces) and 26-connected
//!   (shared faces, edges or corners), by union-find over runs of set bits along z.
//! - `centre_of_mass` and `inertia` (about the centre of mass, world units, each voxel a solid
//!   cube: its own s⁵/6 on the diagonal plus the parallel-axis term).

use serde::Serialize;

use super::{BitVolume, VolumeKind};

/// The kinds statistics describe.
pub const ACCEPTS: &[VolumeKind] = super::BITS_AND_CHANNELS;
use crate::cancel::{Canceled, Control};

#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Stats {
    pub solid_voxels: u64,
    pub volume: f64,
    /// Inclusive index bounds and their world box; absent when empty.
    pub bounds_index: Option<([u32; 3], [u32; 3])>,
    pub bounds_world: Option<([f64; 3], [f64; 3])>,
    pub surface_voxels: u64,
    pub components_6: u64,
    pub components_26: u64,
    pub centre_of_mass: Option<[f64; 3]>,
    pub inertia: Option<[[f64; 3]; 3]>,
}

pub fn stats(v: &BitVolume) -> Stats {
    stats_with(v, &Control::none()).expect("Control::none never stops")
}

/// [`stats`], checking `ctl` every 2²⁰ solid voxels of the moments and per x-plane of the
/// surface count and the two component passes, and reporting progress there.
pub fn stats_with(v: &BitVolume, ctl: &Control) -> Result<Stats, Canceled> {
    ctl.check()?;
    let g = *v.grid();
    let s = g.voxel_size;
    let n = v.count_ones();
    let bounds_index = v.solid_bounds();
    let bounds_world = bounds_index.map(|(lo, hi)| {
        (
            g.corner(lo.map(i64::from)),
            g.corner(hi.map(|h| h as i64 + 1)),
        )
    });
    // Moments about the grid origin in voxel units (exact integer sums).
    let (mut m1, mut m2) = ([0u128; 3], [[0u128; 3]; 3]);
    let moments = ctl.stage(0.0, 0.25).counter(n);
    for (i, p) in v.iter_ones().enumerate() {
        if i > 0 && i.is_multiple_of(1 << 20) {
            moments.add(1 << 20);
            ctl.check()?;
        }
        let c = p.map(|x| x as u128);
        for a in 0..3 {
            m1[a] += c[a];
            for b in 0..3 {
                m2[a][b] += c[a] * c[b];
            }
        }
    }
    let (centre_of_mass, inertia) = if n == 0 {
        (None, None)
    } else {
        let nf = n as f64;
        // Mean voxel index + ½ is the centre in voxel units.
        let mean = m1.map(|x| x as f64 / nf);
        let com = g.world_of(mean.map(|m| m + 0.5));
        // Covariance of the voxel centres (voxel units), then the inertia of cubes about the com.
        let cov = |a: usize, b: usize| m2[a][b] as f64 / nf - mean[a] * mean[b];
        let mass = nf * g.voxel_volume();
        let trace = (0..3).map(|k| cov(k, k)).sum::<f64>();
        let i: [[f64; 3]; 3] = std::array::from_fn(|a| {
            std::array::from_fn(|b| {
                let point = if a == b {
                    trace - cov(a, a)
                } else {
                    -cov(a, b)
                };
                mass * s * s * (point + if a == b { 1.0 / 6.0 } else { 0.0 })
            })
        });
        (Some(com), Some(i))
    };
    let surface_voxels = surface_count(v, &ctl.stage(0.25, 0.4))?;
    let components_6 = components(v, false, &ctl.stage(0.4, 0.7))?;
    let components_26 = components(v, true, &ctl.stage(0.7, 1.0))?;
    ctl.complete();
    Ok(Stats {
        solid_voxels: n,
        volume: g.volume_of(n),
        bounds_index,
        bounds_world,
        surface_voxels,
        components_6,
        components_26,
        centre_of_mass,
        inertia,
    })
}

fn surface_count(v: &BitVolume, ctl: &Control) -> Result<u64, Canceled> {
    let [nx, ny, _] = v.dims();
    let wpc = v.words_per_column();
    let empty = vec![0u64; wpc];
    let mut count = 0u64;
    let planes = ctl.counter(nx as u64);
    for x in 0..nx {
        ctl.check()?;
        planes.add(1);
        for y in 0..ny {
            let col = v.column(x, y);
            let nb = |dx: i64, dy: i64| {
                let (a, b) = (x as i64 + dx, y as i64 + dy);
                if a < 0 || b < 0 || a >= nx as i64 || b >= ny as i64 {
                    &empty[..]
                } else {
                    v.column(a as u32, b as u32)
                }
            };
            let (w, e, s, n) = (nb(-1, 0), nb(1, 0), nb(0, -1), nb(0, 1));
            for i in 0..wpc {
                // Neighbours along z: bit k−1 and k+1 of the column (outside counts as empty).
                let below = (col[i] << 1) | if i > 0 { col[i - 1] >> 63 } else { 0 };
                let above = (col[i] >> 1) | if i + 1 < wpc { col[i + 1] << 63 } else { 0 };
                // Bits at k ≥ Z are zero, so the top voxel's upper neighbour reads as empty.
                let inner = col[i] & w[i] & e[i] & s[i] & n[i] & below & above;
                count += (col[i] & !inner).count_ones() as u64;
            }
        }
    }
    Ok(count)
}

/// Runs of consecutive set bits along z in each column, then union-find across neighbouring
/// columns: 6-connected runs in face-adjacent columns overlap in z; 26-connected runs in any of the
/// 8 surrounding columns overlap or touch (z ranges within one voxel).
fn components(v: &BitVolume, diag: bool, ctl: &Control) -> Result<u64, Canceled> {
    let [nx, ny, nz] = v.dims();
    // Half the share for finding runs, half for joining them.
    let planes = ctl.counter(2 * nx as u64);
    let mut runs: Vec<(u32, u32)> = Vec::new(); // (z0, z1) inclusive
    let mut first = vec![0usize; nx as usize * ny as usize + 1];
    for x in 0..nx {
        ctl.check()?;
        planes.add(1);
        for y in 0..ny {
            let col = v.column(x, y);
            let mut z = 0;
            while z < nz {
                if col[(z / 64) as usize] >> (z % 64) & 1 == 1 {
                    let z0 = z;
                    while z < nz && col[(z / 64) as usize] >> (z % 64) & 1 == 1 {
                        z += 1;
                    }
                    runs.push((z0, z - 1));
                } else {
                    z += 1;
                }
            }
            first[(x * ny + y) as usize + 1] = runs.len();
        }
    }
    let mut parent: Vec<usize> = (0..runs.len()).collect();
    fn find(p: &mut [usize], mut i: usize) -> usize {
        while p[i] != i {
            p[i] = p[p[i]];
            i = p[i];
        }
        i
    }
    let slack = if diag { 1 } else { 0 };
    let offsets: &[(i64, i64)] = if diag {
        &[(1, -1), (1, 0), (1, 1), (0, 1)]
    } else {
        &[(1, 0), (0, 1)]
    };
    for x in 0..nx as i64 {
        ctl.check()?;
        planes.add(1);
        for y in 0..ny as i64 {
            let here = (x * ny as i64 + y) as usize;
            for &(dx, dy) in offsets {
                let (a, b) = (x + dx, y + dy);
                if a < 0 || b < 0 || a >= nx as i64 || b >= ny as i64 {
                    continue;
                }
                let there = (a * ny as i64 + b) as usize;
                for i in first[here]..first[here + 1] {
                    for j in first[there]..first[there + 1] {
                        let (p, q) = (runs[i], runs[j]);
                        if p.0 <= q.1 + slack && q.0 <= p.1 + slack {
                            let (ri, rj) = (find(&mut parent, i), find(&mut parent, j));
                            parent[ri] = rj;
                        }
                    }
                }
            }
        }
    }
    Ok((0..runs.len())
        .filter(|&i| find(&mut parent, i) == i)
        .count() as u64)
}

/// Statistics of a distance volume (`levelset::DISTANCE_KINDS`; a dense one is read as every
/// brick stored, background +∞).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DistanceStats {
    /// The band's half width in voxels: the background over the voxel size (null: +∞, every
    /// voxel stored).
    pub band_voxels: Option<f64>,
    /// The value of the voxels in no brick and of points outside the grid (null: +∞).
    pub background: Option<f32>,
    /// Voxels in the band: |v| < background.
    pub active_voxels: u64,
    /// Voxels inside: sign bit set.
    pub inside_voxels: u64,
    /// inside_voxels · s³: the inside voxels' cubes, not the volume under the interpolated
    /// zero level.
    pub enclosed_volume: f64,
    pub bricks: u64,
    pub tiles: u64,
    /// The least and greatest value of the grid's voxels (null when infinite).
    pub min: Option<f32>,
    pub max: Option<f32>,
}

pub fn distance_stats(s: &super::Sparse<f32>) -> DistanceStats {
    let g = *s.grid();
    let [nx, ny, nz] = g.dims.map(u64::from);
    let e = |b: u32, n: u64| (n - u64::from(b) * 8).min(8);
    let in_grid = |[bx, by, bz]: [u32; 3]| e(bx, nx) * e(by, ny) * e(bz, nz);
    let bg = s.background();
    let active = |v: f32| v.abs() < bg;
    let (mut n_active, mut n_inside) = (0u64, 0u64);
    let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
    let mut note = |v: f32, n: u64| {
        if n > 0 {
            n_active += if active(v) { n } else { 0 };
            n_inside += if v.is_sign_negative() { n } else { 0 };
            lo = lo.min(v);
            hi = hi.max(v);
        }
    };
    let mut covered = 0u64;
    for (at, b) in s.bricks() {
        covered += in_grid(at);
        let d = g.dims;
        for (i, &v) in b.iter().enumerate() {
            let o = i as u32;
            let p = [at[0] * 8 + o / 64, at[1] * 8 + o / 8 % 8, at[2] * 8 + o % 8];
            if (0..3).all(|a| p[a] < d[a]) {
                note(v, 1);
            }
        }
    }
    let tiles: u64 = s.tiles().map(in_grid).sum();
    note(s.tile_value(), tiles);
    note(bg, nx * ny * nz - covered - tiles);
    let finite = |v: f32| v.is_finite().then_some(v);
    DistanceStats {
        // The background is band·s rounded to f32: a whole band within f32's precision is that
        // whole number, not 3.0000000071.
        band_voxels: bg.is_finite().then(|| {
            let b = f64::from(bg) / g.voxel_size;
            if (b - b.round()).abs() <= b * f64::from(f32::EPSILON) {
                b.round()
            } else {
                b
            }
        }),
        background: finite(bg),
        active_voxels: n_active,
        inside_voxels: n_inside,
        enclosed_volume: g.volume_of(n_inside),
        bricks: s.brick_count() as u64,
        tiles: s.tile_count() as u64,
        min: finite(lo),
        max: finite(hi),
    }
}

#[cfg(test)]
mod distance_tests {
    use super::*;
    use crate::grid::Grid;
    use crate::volume::Sparse;

    #[test]
    fn distance_stats_count_every_voxel_once() {
        let g = Grid {
            origin: [0.0; 3],
            voxel_size: 0.5,
            dims: [12, 9, 8],
        };
        let mut s = Sparse::with_tile_value(g, 1.5f32, -1.5);
        s.set_tile([1, 0, 0], true).unwrap();
        s.set(0, 0, 0, -0.0);
        s.set(0, 0, 1, 0.25);
        s.set(3, 8, 7, -1.5);
        let st = distance_stats(&s);
        // Brute force over the dense copy.
        let d = s.to_dense();
        let vals: Vec<f32> = d.data().to_vec();
        assert_eq!(
            st.inside_voxels,
            vals.iter().filter(|v| v.is_sign_negative()).count() as u64
        );
        assert_eq!(st.inside_voxels, 4 * 8 * 8 + 2);
        assert_eq!(st.active_voxels, 2);
        assert_eq!(st.enclosed_volume, (4 * 8 * 8 + 2) as f64 * 0.125);
        assert_eq!((st.band_voxels, st.background), (Some(3.0), Some(1.5)));
        assert_eq!((st.bricks, st.tiles), (2, 1));
        assert_eq!((st.min, st.max), (Some(-1.5), Some(1.5)));
        // A voxel size whose band·s is not a float32: still a whole band.
        let g = Grid {
            voxel_size: 0.050265625,
            ..g
        };
        let bg = (3.0 * g.voxel_size) as f32;
        assert_ne!(f64::from(bg) / g.voxel_size, 3.0);
        let st = distance_stats(&Sparse::with_tile_value(g, bg, -bg));
        assert_eq!(st.band_voxels, Some(3.0));
    }
}
