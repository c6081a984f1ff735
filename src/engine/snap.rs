//! The one place where floating-point geometry becomes integers.
//!
//! Vertex positions are mapped to grid units, `g = (p − origin) / voxel_size` (f64), and rounded
//! (half away from zero) to a lattice of 1/256 voxel: voxel (i, j, k) is the integer box
//! `[256 i, 256 i + 256] × …` and its centre is `256 i + 128`. Every later test (column in triangle,
//! crossing depth, triangle–box overlap) is exact integer arithmetic on these values, so every
//! engine that starts from a `GridMesh` can reach the same bits.
//!
//! Triangles that cannot touch the grid are dropped before snapping: entirely left/right of it in
//! x or y, or entirely above it in z (more than one voxel beyond, so rounding cannot matter). A
//! triangle entirely below the grid (all z < −1 voxel) still flips every column it covers, but its
//! depth is irrelevant: it is flattened to z = −1 voxel, which changes no bit of any method.

use rayon::prelude::*;

use crate::grid::Grid;
use crate::mesh::Mesh;

use super::EngineError;

/// Fractional bits of the fixed-point lattice.
pub const FIXED_SHIFT: u32 = 8;
/// One voxel in fixed-point units.
pub const FIXED_ONE: i64 = 1 << FIXED_SHIFT;
/// Half a voxel: voxel centres are at `FIXED_ONE * i + FIXED_HALF`.
pub const FIXED_HALF: i64 = FIXED_ONE / 2;
/// Largest magnitude of a snapped coordinate: 2^21 voxels. Keeps every edge function and SAT
/// projection inside i64 and every depth numerator inside i128.
pub const MAX_FIXED: i64 = 1 << 29;

/// World point `p` in lattice units before rounding: `(p − origin) · (FIXED_ONE / voxel_size)`.
/// (Not `index_of(p) · FIXED_ONE`, which rounds differently.)
pub(crate) fn lattice_units(grid: &Grid, p: [f64; 3]) -> [f64; 3] {
    let scale = FIXED_ONE as f64 / grid.voxel_size;
    [0, 1, 2].map(|a| (p[a] - grid.origin[a]) * scale)
}

/// The snap: world point `p` on the fixed-point lattice, [`lattice_units`] rounded half away
/// from zero. Every engine sees a vertex at exactly these coordinates.
pub(crate) fn to_lattice(grid: &Grid, p: [f64; 3]) -> [f64; 3] {
    lattice_units(grid, p).map(f64::round)
}

/// `p` moved onto the lattice, in world coordinates: the point the engines see for `p`,
/// `origin + to_lattice(p) / (FIXED_ONE / voxel_size)`.
pub(crate) fn snapped_world(grid: &Grid, p: [f64; 3]) -> [f64; 3] {
    let scale = FIXED_ONE as f64 / grid.voxel_size;
    let l = to_lattice(grid, p);
    [0, 1, 2].map(|a| grid.origin[a] + l[a] / scale)
}

/// A mesh on a grid: triangles with vertices on the fixed-point lattice, in grid units.
#[derive(Clone, Debug, PartialEq)]
pub struct GridMesh {
    pub grid: Grid,
    pub triangles: Vec<[[i32; 3]; 3]>,
}

impl GridMesh {
    pub fn new(mesh: &Mesh, grid: &Grid) -> Result<GridMesh, EngineError> {
        // Unrounded, because the culling below looks at the exact positions, and rounded
        // (`to_lattice`), the coordinates kept: both once per vertex (rounding is a call, and
        // a vertex is in six triangles on average).
        let g: Vec<([f64; 3], [f64; 3])> = mesh
            .positions()
            .par_iter()
            .with_min_len(crate::PAR_PIECE)
            .map(|&p| {
                let u = lattice_units(grid, p);
                (u, u.map(f64::round))
            })
            .collect();
        let d = grid.dims.map(|d| d as f64 * FIXED_ONE as f64);
        let one = FIXED_ONE as f64;
        // Indexed collect (direct writes), then one pass for errors and dropped triangles.
        let snapped: Vec<Result<Option<[[i32; 3]; 3]>, EngineError>> = mesh
            .triangles()
            .par_iter()
            .with_min_len(crate::PAR_PIECE)
            .map(|tri| {
                let v = tri.map(|i| g[i as usize].0);
                let lo = [0, 1, 2].map(|a| v[0][a].min(v[1][a]).min(v[2][a]));
                let hi = [0, 1, 2].map(|a| v[0][a].max(v[1][a]).max(v[2][a]));
                if hi[0] < -one
                    || lo[0] > d[0] + one
                    || hi[1] < -one
                    || lo[1] > d[1] + one
                    || lo[2] > d[2] + one
                {
                    return Ok(None);
                }
                let below = hi[2] < -one;
                let mut out = [[0i32; 3]; 3];
                for (c, &vi) in tri.iter().enumerate() {
                    let rounded = &g[vi as usize].1;
                    for a in 0..3 {
                        if a == 2 && below {
                            out[c][a] = -(FIXED_ONE as i32);
                            continue;
                        }
                        let r = rounded[a];
                        if r.abs() > MAX_FIXED as f64 {
                            return Err(EngineError::OutOfRange {
                                vertex: vi as usize,
                                voxels: (r / one).abs(),
                            });
                        }
                        out[c][a] = r as i32;
                    }
                }
                Ok(Some(out))
            })
            .collect();
        let mut triangles = Vec::with_capacity(snapped.len());
        for t in snapped {
            triangles.extend(t?);
        }
        Ok(GridMesh {
            grid: *grid,
            triangles,
        })
    }
}
