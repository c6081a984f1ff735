//! `distance`'s thickness: how the request's world-unit `thickness` becomes the lattice-unit
//! threshold the engines compare with (one definition for the HTTP and CLI fronts and the
//! engines). See `docs/methods.md` (`distance`).

use crate::engine::FIXED_ONE;

/// The largest thickness, in voxels: the engines enumerate a triangle's bounding box dilated by
/// it, so it bounds their work per triangle.
pub const MAX_VOXELS: i64 = 32;

/// The largest thickness in lattice units (32 voxels).
pub const MAX_LATTICE: i64 = MAX_VOXELS * FIXED_ONE;

/// The default thickness as a multiple of the voxel size: half the voxel's diagonal, √3/2
/// (a triangle that touches a voxel's box is within it of the centre, so `distance` with it
/// holds every voxel of `surface`).
pub const DEFAULT_FACTOR: f64 = 0.866_025_403_784_438_6;

/// The default thickness in world units for voxels of size `voxel_size`: s·√3/2.
pub fn default_thickness(voxel_size: f64) -> f64 {
    voxel_size * DEFAULT_FACTOR
}

/// The default thickness in lattice units: round(256·√3/2) = 222.
pub const DEFAULT_LATTICE: i64 = 222;

/// The thickness `t_world` (world units) on voxels of size `voxel_size`, in lattice units:
/// t·256/s rounded half away from zero. Refused (the message says why) when t is negative or
/// not finite, or comes to more than [`MAX_VOXELS`] voxels.
pub fn thickness_lattice(t_world: f64, voxel_size: f64) -> Result<i64, String> {
    if !t_world.is_finite() || t_world < 0.0 {
        return Err(format!(
            "thickness must be a finite number ≥ 0 (world units), not {t_world}"
        ));
    }
    if !(voxel_size.is_finite() && voxel_size > 0.0) {
        return Err(format!("voxel size {voxel_size} is not a positive number"));
    }
    // f64::round rounds half away from zero.
    let l = (t_world * FIXED_ONE as f64 / voxel_size).round();
    if l > MAX_LATTICE as f64 {
        return Err(format!(
            "thickness {t_world} is {:.3} voxels of size {voxel_size}; at most {MAX_VOXELS} are supported",
            t_world / voxel_size
        ));
    }
    Ok(l as i64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn snapping() {
        for s in [1.0, 0.1, 3.7, 1e-6, 1e6] {
            assert_eq!(
                thickness_lattice(default_thickness(s), s),
                Ok(DEFAULT_LATTICE)
            );
            assert_eq!(thickness_lattice(0.0, s), Ok(0));
            assert_eq!(thickness_lattice(32.0 * s, s), Ok(MAX_LATTICE));
            assert!(thickness_lattice(32.01 * s, s).is_err());
        }
        assert_eq!(DEFAULT_FACTOR, 3f64.sqrt() / 2.0);
        // Half a lattice unit rounds away from zero; just below it rounds down.
        assert_eq!(thickness_lattice(2.5, 256.0), Ok(3));
        assert_eq!(thickness_lattice(0.5, 256.0), Ok(1));
        assert_eq!(thickness_lattice(0.499, 256.0), Ok(0));
        for bad in [-1.0, -1e-300, f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            assert!(thickness_lattice(bad, 1.0).is_err(), "{bad}");
        }
        assert!(thickness_lattice(1.0, 0.0).is_err());
    }
}
