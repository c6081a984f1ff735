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

/// The trilinear interpolation of a distance volume's voxel-centre samples at world point `p`
/// and its gradient (the interpolant's own, analytic, in world units: per unit of length).
/// Samples outside the grid are the background. `None` when one of the eight samples is
/// infinite.
pub fn interpolate(v: &super::Sparse<f32>, p: [f64; 3]) -> Option<(f64, [f64; 3])> {
    let g = v.grid();
    let s = g.voxel_size;
    // Continuous index of p among the voxel centres (centre i sits at i + ½).
    let u: [f64; 3] = std::array::from_fn(|a| (p[a] - g.origin[a]) / s - 0.5);
    if u.iter().any(|c| !c.is_finite()) {
        return None;
    }
    let i0 = u.map(|c| c.floor());
    let f: [f64; 3] = std::array::from_fn(|a| u[a] - i0[a]);
    let sample = |dx: usize, dy: usize, dz: usize| {
        let idx = [i0[0] + dx as f64, i0[1] + dy as f64, i0[2] + dz as f64];
        let inside = (0..3).all(|a| idx[a] >= 0.0 && idx[a] < f64::from(g.dims[a]));
        if inside {
            v.get(idx[0] as u32, idx[1] as u32, idx[2] as u32)
        } else {
            v.background()
        }
    };
    let mut c = [[[0f64; 2]; 2]; 2];
    for (dx, cx) in c.iter_mut().enumerate() {
        for (dy, cy) in cx.iter_mut().enumerate() {
            for (dz, cz) in cy.iter_mut().enumerate() {
                let x = sample(dx, dy, dz);
                if !x.is_finite() {
                    return None;
                }
                *cz = f64::from(x);
            }
        }
    }
    // Weights along each axis: 1 − f at the low sample, f at the high; their derivatives −1, 1.
    let w = |a: usize, d: usize| if d == 0 { 1.0 - f[a] } else { f[a] };
    let dw = |d: usize| if d == 0 { -1.0 } else { 1.0 };
    let (mut value, mut grad) = (0.0, [0.0; 3]);
    for (dx, cx) in c.iter().enumerate() {
        for (dy, cy) in cx.iter().enumerate() {
            for (dz, &x) in cy.iter().enumerate() {
                value += w(0, dx) * w(1, dy) * w(2, dz) * x;
                grad[0] += dw(dx) * w(1, dy) * w(2, dz) * x;
                grad[1] += w(0, dx) * dw(dy) * w(2, dz) * x;
                grad[2] += w(0, dx) * w(1, dy) * dw(dz) * x;
            }
        }
    }
    Some((value, grad.map(|d| d / s)))
}

#[cfg(test)]
mod interpolation_tests {
    use super::*;
    use crate::grid::Grid;
    use crate::volume::Sparse;

    #[test]
    fn a_linear_field_interpolates_to_itself_with_its_gradient() {
        let g = Grid {
            origin: [-1.0, 0.5, 2.0],
            voxel_size: 0.25,
            dims: [10, 7, 9],
        };
        let (a, b, c, d0) = (0.75, -1.25, 0.5, 0.125);
        let field = |p: [f64; 3]| a * p[0] + b * p[1] + c * p[2] + d0;
        let mut s = Sparse::new(g, 100.0f32);
        for x in 0..10 {
            for y in 0..7 {
                for z in 0..9 {
                    s.set(x, y, z, field(g.voxel_center(x, y, z)) as f32);
                }
            }
        }
        // Points between the first and last centres, where every sample is in the grid.
        let mut t = 0.1234f64;
        for _ in 0..200 {
            let mut p = [0.0; 3];
            for (k, q) in p.iter_mut().enumerate() {
                t = (t * 7.31 + 0.377).fract();
                let n = f64::from(g.dims[k]);
                *q = g.origin[k] + g.voxel_size * (0.5 + t * (n - 1.0));
            }
            let (v, grad) = interpolate(&s, p).unwrap();
            assert!((v - field(p)).abs() < 1e-5, "{p:?}: {v} vs {}", field(p));
            for (got, want) in grad.iter().zip([a, b, c]) {
                assert!((got - want).abs() < 1e-4, "{p:?}: {grad:?}");
            }
        }
        // Far outside: the background, flat.
        assert_eq!(interpolate(&s, [50.0, 50.0, 50.0]), Some((100.0, [0.0; 3])));
        let inf = Sparse::new(g, f32::INFINITY);
        assert_eq!(interpolate(&inf, [0.0, 1.0, 3.0]), None);
    }
}
