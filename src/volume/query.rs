//! Point and ray queries against a volume, in world coordinates.
//!
//! A point is in voxel `floor((p − origin) / voxel_size)`; points outside the grid are empty. A
//! ray `origin + t · direction` (t ≥ 0, direction normalised here) is walked voxel by voxel
//! (Amanatides & Woo) through the grid; it reports how many solid voxels it crosses, the distance
//! at which it first enters solid and last leaves it, and the length it travels inside solid
//! voxels (the thickness, for translucency).

use serde::Serialize;

use super::kind::Named;
use super::{Volume, VolumeKind, VoxelValue};

/// The kinds queried: every kind has a value per voxel (points) and an occupancy (rays).
pub const ACCEPTS: &[VolumeKind] = <VolumeKind as Named>::ALL;

/// Whether the point is in an occupied voxel, and that voxel's value in its own type (0/1 for
/// bits, 0..=max for density); outside the grid, unoccupied and [`Volume::outside`].
pub fn point_value(v: &Volume, p: [f64; 3]) -> (bool, VoxelValue) {
    match v.grid().voxel_containing(p) {
        Some([x, y, z]) => (v.occupied(x, y, z), v.value(x, y, z)),
        None => (false, v.outside()),
    }
}

#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RayHit {
    pub solid_voxels: u64,
    /// Distance along the (normalised) ray where it first enters a solid voxel.
    pub entry: Option<f64>,
    /// Distance where it last leaves one.
    pub exit: Option<f64>,
    /// Length inside solid voxels.
    pub thickness: f64,
}

/// Walks the ray through the grid. `None` for a zero or non-finite direction.
pub fn ray(v: &Volume, origin: [f64; 3], direction: [f64; 3]) -> Option<RayHit> {
    // Scaled by its largest component first, so that any finite non-zero direction normalises
    // (its squared length could overflow, 1e200, or vanish, 1e-200).
    let m = direction.iter().fold(0.0f64, |m, d| m.max(d.abs()));
    if !(m.is_finite() && m > 0.0)
        || direction.iter().any(|d| !d.is_finite())
        || origin.iter().any(|o| !o.is_finite())
    {
        return None;
    }
    let scaled = direction.map(|x| x / m);
    let len = scaled.iter().map(|d| d * d).sum::<f64>().sqrt();
    let d = scaled.map(|x| x / len);
    let g = v.grid();
    let s = g.voxel_size;
    // Clip t to the grid box (slab test), t ≥ 0.
    let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
    let far = g.max_corner();
    for a in 0..3 {
        let (lo, hi) = (g.origin[a], far[a]);
        if d[a] == 0.0 {
            if origin[a] < lo || origin[a] >= hi {
                return Some(RayHit {
                    solid_voxels: 0,
                    entry: None,
                    exit: None,
                    thickness: 0.0,
                });
            }
        } else {
            let (ta, tb) = ((lo - origin[a]) / d[a], (hi - origin[a]) / d[a]);
            t0 = t0.max(ta.min(tb));
            t1 = t1.min(ta.max(tb));
        }
    }
    let mut hit = RayHit {
        solid_voxels: 0,
        entry: None,
        exit: None,
        thickness: 0.0,
    };
    if t0 >= t1 {
        return Some(hit);
    }
    // Start voxel: the one containing the point just inside the entry.
    let tm = t0 + 1e-9 * s;
    let mut idx = [0i64; 3];
    let mut step = [0i64; 3];
    let mut t_max = [f64::INFINITY; 3];
    let mut t_delta = [f64::INFINITY; 3];
    let start = g.index_of([0, 1, 2].map(|a| origin[a] + tm * d[a]));
    for a in 0..3 {
        idx[a] = (start[a].floor() as i64).clamp(0, g.dims[a] as i64 - 1);
    }
    // The walk's first boundary on each axis: the start voxel's far corner going up, its min
    // corner going down.
    let (lo_corner, hi_corner) = (g.corner(idx), g.corner(idx.map(|i| i + 1)));
    for a in 0..3 {
        if d[a] > 0.0 {
            step[a] = 1;
            t_max[a] = (hi_corner[a] - origin[a]) / d[a];
            t_delta[a] = s / d[a];
        } else if d[a] < 0.0 {
            step[a] = -1;
            t_max[a] = (lo_corner[a] - origin[a]) / d[a];
            t_delta[a] = -s / d[a];
        }
    }
    let mut t = t0;
    let max_steps = g.dims.iter().map(|&n| n as u64).sum::<u64>() + 3;
    for _ in 0..max_steps {
        let a = (0..3)
            .min_by(|&i, &j| t_max[i].total_cmp(&t_max[j]))
            .unwrap();
        let t_next = t_max[a].min(t1);
        let solid = v.occupied(idx[0] as u32, idx[1] as u32, idx[2] as u32);
        if solid && t_next > t {
            hit.solid_voxels += 1;
            hit.entry.get_or_insert(t);
            hit.exit = Some(t_next);
            hit.thickness += t_next - t;
        }
        if t_next >= t1 {
            break;
        }
        t = t_next;
        idx[a] += step[a];
        if idx[a] < 0 || idx[a] >= g.dims[a] as i64 {
            break;
        }
        t_max[a] += t_delta[a];
    }
    Some(hit)
}
