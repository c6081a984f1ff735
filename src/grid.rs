//! The voxel grid: a world origin, a cubic voxel size and integer dims, and the one set of rules
//! (`docs/methods.md`, "Grid") that fits a grid to a mesh. Every engine and codec takes its grid
//! from here; nothing else decides where a voxel is.

use serde::{Deserialize, Serialize};

/// Largest dimension along one axis. Keeps snapped fixed-point coordinates inside `i32`
/// (see [`crate::engine::snap`]).
pub const MAX_DIM: u32 = 1 << 20;

/// The origin may be at most this many voxels from zero, so that `origin + i · voxel_size` keeps
/// voxel precision (f64 has 52 bits; this leaves 12 for positions within a voxel).
const MAX_ORIGIN_VOXELS: f64 = (1u64 << 40) as f64;

/// A grid: voxel (i, j, k) is the closed box `origin + [i, i+1] × [j, j+1] × [k, k+1] · voxel_size`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Grid {
    pub origin: [f64; 3],
    pub voxel_size: f64,
    pub dims: [u32; 3],
}

/// How the caller chose the grid (as data too: a shared queue keeps it with a job).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "by", rename_all = "snake_case")]
pub enum GridSpec {
    /// `voxel_size = longest bbox edge / n`, origin at the bbox minimum, dims fitted per axis
    /// (or `(n, n, n)` when `cubic`).
    Resolution { n: u32, cubic: bool },
    /// The same fit with a given voxel size; `cubic` makes every axis as long as the longest.
    VoxelSize { size: f64, cubic: bool },
    /// A fixed grid, so volumes of different meshes line up.
    Explicit {
        origin: [f64; 3],
        voxel_size: f64,
        dims: [u32; 3],
    },
}

/// Limits a grid must respect.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridLimits {
    pub max_voxels: u64,
}

impl Default for GridLimits {
    fn default() -> Self {
        GridLimits {
            max_voxels: crate::limits::Limits::LOCAL.max_voxels,
        }
    }
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum GridError {
    #[error("resolution must be at least 1")]
    ZeroResolution,
    #[error("voxel size must be a positive, finite, normal number, got {0:e}")]
    BadVoxelSize(f64),
    #[error("grid origin must be finite, got {0:?}")]
    BadOrigin([f64; 3]),
    #[error(
        "a grid with origin {origin:?} and voxel size {voxel_size:e} cannot be represented: its voxel boundaries must be distinct finite numbers, and its volume finite; scale the mesh or change the voxel size"
    )]
    Unrepresentable { origin: [f64; 3], voxel_size: f64 },
    #[error("grid dims must be at least 1 on every axis, got {0:?}")]
    ZeroDims([u32; 3]),
    #[error(
        "the mesh has no extent (all vertices coincide), so a resolution cannot set the voxel size; give a voxel size or an explicit grid"
    )]
    NoExtent,
    #[error(
        "grid {dims:?} has {voxels} voxels, over the limit of {limit} ({limit_desc}); lower the resolution or raise the voxel size"
    )]
    TooManyVoxels {
        dims: [u64; 3],
        voxels: u128,
        limit: u64,
        limit_desc: String,
    },
    #[error("grid {dims:?} is longer than {max} voxels along one axis; lower the resolution or raise the voxel size", max = MAX_DIM)]
    AxisTooLong { dims: [u64; 3] },
}

impl Grid {
    /// Fits a grid to a bounding box as `docs/methods.md` says, then adds `padding` empty voxels
    /// on every side, then checks the limits.
    pub fn fit(
        bbox_min: [f64; 3],
        bbox_max: [f64; 3],
        spec: GridSpec,
        padding: u32,
        limits: GridLimits,
    ) -> Result<Grid, GridError> {
        let extent = [0, 1, 2].map(|a| bbox_max[a] - bbox_min[a]);
        let longest = extent.iter().cloned().fold(0.0, f64::max);
        let (origin, voxel_size, dims): ([f64; 3], f64, [u64; 3]) = match spec {
            GridSpec::Resolution { n, cubic } => {
                if n == 0 {
                    return Err(GridError::ZeroResolution);
                }
                if longest <= 0.0 || !longest.is_finite() {
                    return Err(GridError::NoExtent);
                }
                let s = longest / n as f64;
                let dims = if cubic {
                    [n as u64; 3]
                } else {
                    // The longest axis is exactly n by definition; the others are fitted.
                    extent.map(|e| {
                        if e == longest {
                            n as u64
                        } else {
                            fitted_dim(e, s).min(n as u64)
                        }
                    })
                };
                (bbox_min, s, dims)
            }
            GridSpec::VoxelSize { size, cubic } => {
                check_voxel_size(size)?;
                let mut dims = extent.map(|e| fitted_dim(e, size));
                if cubic {
                    let m = *dims.iter().max().unwrap();
                    dims = [m; 3];
                }
                (bbox_min, size, dims)
            }
            GridSpec::Explicit {
                origin,
                voxel_size,
                dims,
            } => {
                check_voxel_size(voxel_size)?;
                if origin.iter().any(|o| !o.is_finite()) {
                    return Err(GridError::BadOrigin(origin));
                }
                if dims.contains(&0) {
                    return Err(GridError::ZeroDims(dims));
                }
                (origin, voxel_size, dims.map(u64::from))
            }
        };
        let p = padding as u64;
        let dims = dims.map(|d| d + 2 * p);
        let origin = origin.map(|o| o - p as f64 * voxel_size);
        check_voxel_size(voxel_size)?;
        // Every voxel boundary must be a distinct, finite number: a voxel size that vanishes
        // next to the origin (or a far corner that overflows) gives a grid no one can read.
        for a in 0..3 {
            let far = origin[a] + dims[a] as f64 * voxel_size;
            if !origin[a].is_finite()
                || !far.is_finite()
                || origin[a] + voxel_size == origin[a]
                || origin[a].abs() / voxel_size > MAX_ORIGIN_VOXELS
            {
                return Err(GridError::Unrepresentable { origin, voxel_size });
            }
        }
        if dims.iter().any(|&d| d > MAX_DIM as u64) {
            return Err(GridError::AxisTooLong { dims });
        }
        let voxels = dims.iter().map(|&d| d as u128).product::<u128>();
        if voxels > limits.max_voxels as u128 {
            return Err(GridError::TooManyVoxels {
                dims,
                voxels,
                limit: limits.max_voxels,
                limit_desc: crate::limits::describe_voxels(limits.max_voxels),
            });
        }
        // And its volume (voxels × voxel_size³, what a volume's metadata reports) a finite
        // number: a single voxel of 1e103 has none.
        if !(voxels as f64 * voxel_size.powi(3)).is_finite() {
            return Err(GridError::Unrepresentable { origin, voxel_size });
        }
        Ok(Grid {
            origin,
            voxel_size,
            dims: dims.map(|d| d as u32),
        })
    }

    /// X·Y·Z, or `u64::MAX` when that does not fit (three u32 axes can multiply past u64), so
    /// a count compared with a limit is never a wrapped small one.
    pub fn voxel_count(&self) -> u64 {
        Grid::count(self.dims)
    }

    /// [`Grid::voxel_count`] of a grid with `dims`, before any grid is made (a file's header).
    pub fn count(dims: [u32; 3]) -> u64 {
        let n: u128 = dims.iter().map(|&d| d as u128).product();
        u64::try_from(n).unwrap_or(u64::MAX)
    }

    // Index ↔ world. Grid coordinates are continuous, in voxels from the origin: voxel i spans
    // [i, i + 1] on each axis and its centre is i + ½. These are the only places that turn one
    // into the other (`origin + index · s` and `(p − origin) / s`), so every caller rounds alike.

    /// World position of the continuous grid coordinates `index`: `origin + index · voxel_size`.
    pub fn world_of(&self, index: [f64; 3]) -> [f64; 3] {
        [0, 1, 2].map(|a| self.origin[a] + index[a] * self.voxel_size)
    }

    /// World position of the min corner of voxel `i`; any `i`, so `dims` gives the far corner and
    /// negative indices lie before the origin.
    pub fn corner(&self, i: [i64; 3]) -> [f64; 3] {
        self.world_of(i.map(|x| x as f64))
    }

    /// World position of the centre of voxel (i, j, k).
    pub fn voxel_center(&self, i: u32, j: u32, k: u32) -> [f64; 3] {
        self.world_of([i, j, k].map(|x| x as f64 + 0.5))
    }

    /// World position of the grid's far corner.
    pub fn max_corner(&self) -> [f64; 3] {
        self.corner(self.dims.map(i64::from))
    }

    /// Continuous grid coordinates of world point `p`: `(p − origin) / voxel_size`.
    pub fn index_of(&self, p: [f64; 3]) -> [f64; 3] {
        [0, 1, 2].map(|a| (p[a] - self.origin[a]) / self.voxel_size)
    }

    /// The voxel whose box `[i, i + 1)` (half open) holds `p`: `floor(index_of(p))`, `None`
    /// outside the grid (or for a non-finite point).
    pub fn voxel_containing(&self, p: [f64; 3]) -> Option<[u32; 3]> {
        let f = self.index_of(p).map(f64::floor);
        (0..3)
            .all(|a| f[a] >= 0.0 && f[a] < self.dims[a] as f64)
            .then(|| f.map(|x| x as u32))
    }

    /// Volume of one voxel, `voxel_size³`.
    pub fn voxel_volume(&self) -> f64 {
        self.voxel_size.powi(3)
    }

    /// Volume of `voxels` voxels, `voxels · voxel_size³`.
    pub fn volume_of(&self, voxels: u64) -> f64 {
        voxels as f64 * self.voxel_volume()
    }

    /// True when `other` has the same voxel size and its origin is a whole number of voxels away,
    /// so the two can be combined voxel by voxel.
    pub fn is_aligned_with(&self, other: &Grid) -> bool {
        self.voxel_size == other.voxel_size
            && self
                .index_of(other.origin)
                .iter()
                .all(|d| (d - d.round()).abs() <= 1e-6)
    }

    /// Where `other`'s voxel 0 lies in this grid's indices, when the two are aligned
    /// ([`Grid::is_aligned_with`]); `None` otherwise.
    pub fn offset_to(&self, other: &Grid) -> Option<[i64; 3]> {
        self.is_aligned_with(other)
            .then(|| self.index_of(other.origin).map(|d| d.round() as i64))
    }

    /// The aligned grid of `dims` voxels whose voxel 0 is this grid's voxel `lo` (which may lie
    /// outside this grid).
    pub fn sub_grid(&self, lo: [i64; 3], dims: [u32; 3]) -> Grid {
        Grid {
            origin: self.corner(lo),
            voxel_size: self.voxel_size,
            dims,
        }
    }

    /// This grid with `r` more voxels on every side.
    pub fn padded(&self, r: u32) -> Grid {
        self.sub_grid([-(r as i64); 3], self.dims.map(|d| d + 2 * r))
    }
}

/// `ceil(extent / s)`, at least 1. A quotient within 1e-9 of a whole number counts as that number,
/// so that an extent of exactly k voxels does not grow to k + 1 through rounding in the division.
fn fitted_dim(extent: f64, s: f64) -> u64 {
    let q = extent / s;
    let r = q.round();
    let d = if (q - r).abs() <= 1e-9 * r.max(1.0) {
        r
    } else {
        q.ceil()
    };
    if !d.is_finite() || d > u64::MAX as f64 / 4.0 {
        return u64::MAX / 4;
    }
    (d as u64).max(1)
}

fn check_voxel_size(s: f64) -> Result<(), GridError> {
    // Normal, not merely positive: a subnormal voxel size (a mesh whose extent is ~1e-320)
    // has almost no precision left.
    if s.is_normal() && s > 0.0 {
        Ok(())
    } else {
        Err(GridError::BadVoxelSize(s))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resolution_fit_is_tight_and_longest_axis_exact() {
        let g = Grid::fit(
            [0.0; 3],
            [0.3, 0.1, 0.29],
            GridSpec::Resolution { n: 3, cubic: false },
            0,
            GridLimits::default(),
        )
        .unwrap();
        assert_eq!(g.dims, [3, 1, 3]);
        assert_eq!(g.origin, [0.0; 3]);
        let c = Grid::fit(
            [0.0; 3],
            [0.3, 0.1, 0.29],
            GridSpec::Resolution { n: 3, cubic: true },
            0,
            GridLimits::default(),
        )
        .unwrap();
        assert_eq!(c.dims, [3, 3, 3]);
    }

    #[test]
    fn padding_moves_origin_and_grows_dims() {
        let g = Grid::fit(
            [1.0; 3],
            [2.0; 3],
            GridSpec::Resolution { n: 4, cubic: false },
            2,
            GridLimits::default(),
        )
        .unwrap();
        assert_eq!(g.dims, [8, 8, 8]);
        assert_eq!(g.origin, [0.5; 3]);
    }

    #[test]
    fn voxel_size_fit_rounds_exact_multiples_down() {
        let g = Grid::fit(
            [0.0; 3],
            [0.3, 0.7, 0.05],
            GridSpec::VoxelSize {
                size: 0.1,
                cubic: false,
            },
            0,
            GridLimits::default(),
        )
        .unwrap();
        assert_eq!(g.dims, [3, 7, 1]);
        let c = Grid::fit(
            [0.0; 3],
            [0.3, 0.7, 0.05],
            GridSpec::VoxelSize {
                size: 0.1,
                cubic: true,
            },
            0,
            GridLimits::default(),
        )
        .unwrap();
        assert_eq!(c.dims, [7, 7, 7]);
    }

    /// A mesh whose extent is subnormal once gave a grid with voxel size 0, stored and then
    /// unreadable; grids whose voxels vanish next to the origin are refused too.
    #[test]
    fn refuses_grids_that_cannot_be_represented() {
        let l = GridLimits::default();
        let tiny = Grid::fit(
            [0.0; 3],
            [5e-324, 5e-324, 5e-324],
            GridSpec::Resolution { n: 8, cubic: false },
            0,
            l,
        );
        assert!(matches!(tiny, Err(GridError::BadVoxelSize(_))), "{tiny:?}");
        let explicit = |origin: [f64; 3], voxel_size: f64| {
            Grid::fit(
                [0.0; 3],
                [1.0; 3],
                GridSpec::Explicit {
                    origin,
                    voxel_size,
                    dims: [2; 3],
                },
                0,
                l,
            )
        };
        assert!(matches!(
            explicit([0.0; 3], 1e-310),
            Err(GridError::BadVoxelSize(_))
        ));
        assert!(matches!(
            explicit([1e9, 0.0, 0.0], 1e-9),
            Err(GridError::Unrepresentable { .. })
        ));
        assert!(matches!(
            explicit([1.79e308, 0.0, 0.0], 1e307),
            Err(GridError::Unrepresentable { .. })
        ));
        // One voxel whose volume (size³) overflows.
        assert!(matches!(
            explicit([0.0; 3], 1e103),
            Err(GridError::Unrepresentable { .. })
        ));
        assert!(explicit([-3.0, 2.0, 1e3], 0.01).is_ok());
    }

    #[test]
    fn refuses_bad_grids() {
        let l = GridLimits::default();
        let fit = |s| Grid::fit([0.0; 3], [1.0; 3], s, 0, l);
        assert_eq!(
            fit(GridSpec::Resolution { n: 0, cubic: false }),
            Err(GridError::ZeroResolution)
        );
        assert!(matches!(
            fit(GridSpec::VoxelSize {
                size: f64::NAN,
                cubic: false
            }),
            Err(GridError::BadVoxelSize(_))
        ));
        assert!(matches!(
            fit(GridSpec::VoxelSize {
                size: -1.0,
                cubic: false
            }),
            Err(GridError::BadVoxelSize(_))
        ));
        assert!(matches!(
            fit(GridSpec::Resolution {
                n: 2049,
                cubic: true
            }),
            Err(GridError::TooManyVoxels { .. })
        ));
        assert!(
            fit(GridSpec::Resolution {
                n: 2048,
                cubic: true
            })
            .is_ok()
        );
        let small = GridLimits { max_voxels: 1000 };
        let e = Grid::fit(
            [0.0; 3],
            [1.0; 3],
            GridSpec::Resolution { n: 11, cubic: true },
            0,
            small,
        )
        .unwrap_err();
        assert!(e.to_string().contains("10³"), "{e}");
        assert_eq!(
            Grid::fit(
                [1.0; 3],
                [1.0; 3],
                GridSpec::Resolution { n: 8, cubic: false },
                0,
                l
            ),
            Err(GridError::NoExtent)
        );
        assert!(matches!(
            Grid::fit(
                [0.0; 3],
                [1.0; 3],
                GridSpec::Explicit {
                    origin: [0.0; 3],
                    voxel_size: 1.0,
                    dims: [0, 1, 1]
                },
                0,
                l
            ),
            Err(GridError::ZeroDims(_))
        ));
    }

    #[test]
    fn alignment() {
        let a = Grid {
            origin: [0.0; 3],
            voxel_size: 0.5,
            dims: [4; 3],
        };
        let b = Grid {
            origin: [1.5, -0.5, 2.0],
            voxel_size: 0.5,
            dims: [2; 3],
        };
        let c = Grid {
            origin: [0.25, 0.0, 0.0],
            voxel_size: 0.5,
            dims: [2; 3],
        };
        assert!(a.is_aligned_with(&b));
        assert!(!a.is_aligned_with(&c));
        assert_eq!(a.offset_to(&b), Some([3, -1, 4]));
        assert_eq!(b.offset_to(&a), Some([-3, 1, -4]));
        assert_eq!(a.offset_to(&c), None);
        let sub = a.sub_grid([3, -1, 4], [2; 3]);
        assert_eq!(sub, b);
        assert_eq!(a.padded(2).offset_to(&a), Some([2; 3]));
        assert_eq!(a.padded(2).dims, [8; 3]);
    }

    #[test]
    fn index_world_conversions() {
        let g = Grid {
            origin: [1.0, -2.0, 0.5],
            voxel_size: 0.25,
            dims: [4, 2, 8],
        };
        assert_eq!(g.corner([0; 3]), g.origin);
        assert_eq!(g.corner([4, 2, 8]), g.max_corner());
        assert_eq!(g.max_corner(), [2.0, -1.5, 2.5]);
        assert_eq!(g.corner([-1, 0, 0]), [0.75, -2.0, 0.5]);
        assert_eq!(g.voxel_center(1, 0, 3), [1.375, -1.875, 1.375]);
        assert_eq!(g.world_of([1.5, 0.5, 3.5]), g.voxel_center(1, 0, 3));
        assert_eq!(g.index_of(g.voxel_center(1, 0, 3)), [1.5, 0.5, 3.5]);
        assert_eq!(g.voxel_containing(g.voxel_center(3, 1, 7)), Some([3, 1, 7]));
        // Boxes are half open: the far corner is outside, the origin inside.
        assert_eq!(g.voxel_containing(g.origin), Some([0; 3]));
        assert_eq!(g.voxel_containing(g.max_corner()), None);
        assert_eq!(g.voxel_containing([0.99, -1.9, 0.6]), None);
        assert_eq!(g.voxel_containing([f64::NAN, -1.9, 0.6]), None);
        assert_eq!(g.voxel_volume(), 0.015625);
        assert_eq!(g.volume_of(64), 1.0);
    }
}
