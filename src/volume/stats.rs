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
pub const ACCEPTS: &[VolumeKind] = super::BITS_ONLY;
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
