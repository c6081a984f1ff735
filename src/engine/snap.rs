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
    lattice_units(grid, p).map(round)
}

/// `x.round()` (half away from zero), bit for bit, without a call into the maths library
/// (the build targets x86-64 without SSE4.1, which has no rounding instruction): below 2^52
/// in magnitude, the integer part by truncation, plus one when the fraction (exact: the bits
/// of `x` below the point) is at least a half, with `x`'s sign (so −0.3 gives −0.0); every
/// larger, infinite or NaN `x` by `f64::round`.
#[inline]
pub(crate) fn round(x: f64) -> f64 {
    let a = x.abs();
    if a < (1u64 << 52) as f64 {
        let i = a as u64;
        let r = i + (a - i as f64 >= 0.5) as u64;
        (r as f64).copysign(x)
    } else {
        x.round()
    }
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
                (u, u.map(round))
            })
            .collect();
        let d = grid.dims.map(|d| d as f64 * FIXED_ONE as f64);
        let one = FIXED_ONE as f64;
        let snap = |tri: &[u32; 3]| -> Result<Option<[[i32; 3]; 3]>, EngineError> {
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
        };
        let triangles = snap_in_pieces(mesh, snap)?;
        Ok(GridMesh {
            grid: *grid,
            triangles,
        })
    }
}

/// `snap` of every triangle of `mesh`, in parallel pieces, the kept ones in triangle order; the
/// first error in triangle order (each piece stops at its first, and the first piece with one
/// is the mesh's first). Each piece writes into its own part of the one output array, and the
/// parts are moved together in place: no array between (for a million triangles each were
/// 36 MB of fresh pages, which this host's kernel clears slowly).
pub(crate) fn snap_in_pieces<F>(mesh: &Mesh, snap: F) -> Result<Vec<[[i32; 3]; 3]>, EngineError>
where
    F: Fn(&[u32; 3]) -> Result<Option<[[i32; 3]; 3]>, EngineError> + Sync,
{
    let tris = mesh.triangles();
    let mut out = vec![[[0i32; 3]; 3]; tris.len()];
    let kept: Vec<Result<usize, EngineError>> = out
        .par_chunks_mut(crate::PAR_PIECE)
        .zip(tris.par_chunks(crate::PAR_PIECE))
        .map(|(dst, piece)| {
            let mut n = 0;
            for tri in piece {
                if let Some(t) = snap(tri)? {
                    dst[n] = t;
                    n += 1;
                }
            }
            Ok(n)
        })
        .collect();
    let mut len = 0;
    for (i, k) in kept.into_iter().enumerate() {
        let k = k?;
        let start = i * crate::PAR_PIECE;
        if start != len {
            out.copy_within(start..start + k, len);
        }
        len += k;
    }
    out.truncate(len);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A grid of 8³ unit voxels at the origin.
    fn grid() -> Grid {
        Grid {
            origin: [0.0; 3],
            voxel_size: 1.0,
            dims: [8; 3],
        }
    }

    /// `n` small triangles inside the grid, each on its own three vertices, then the vertex
    /// `far` (an x and y inside the grid, z = −10^7 voxels: beyond the lattice's range) put in
    /// place of the first vertex of each triangle in `bad`, and a triangle left of the grid
    /// (culled, so its far vertex is no error) at index 0.
    fn mesh(n: usize, bad: &[usize]) -> (Mesh, Vec<usize>) {
        let mut positions = Vec::new();
        let mut triangles = Vec::new();
        for t in 0..n {
            let z = (t % 7) as f64 + 0.5;
            let b = positions.len() as u32;
            positions.extend([[1.0, 1.0, z], [3.0, 1.5, z], [2.0, 3.0, z + 0.5]]);
            triangles.push([b, b + 1, b + 2]);
        }
        // Culled: entirely left of the grid, however far its z.
        positions.extend([[-5.0, 1.0, -1e7], [-4.0, 1.0, 1.0], [-5.0, 2.0, 1.0]]);
        let c = positions.len() as u32 - 3;
        triangles[0] = [c, c + 1, c + 2];
        let mut far = Vec::new();
        for &t in bad {
            positions.push([2.0, 2.0, -1e7]);
            far.push(positions.len() - 1);
            triangles[t][0] = positions.len() as u32 - 1;
        }
        (Mesh::new(positions, triangles).unwrap(), far)
    }

    #[test]
    fn round_is_std_round() {
        let mut fixed = vec![
            0.0,
            0.5,
            1.5,
            2.5,
            0.49999999999999994,
            0.5000000000000001,
            1.0 - f64::EPSILON / 2.0,
            4503599627370495.5,
            4503599627370496.0,
            4503599627370497.0,
            9007199254740993.0,
            1e300,
            f64::MAX,
            f64::MIN_POSITIVE,
            5e-324,
            f64::INFINITY,
        ];
        fixed.extend(fixed.clone().iter().map(|x| -x));
        fixed.push(f64::NAN);
        let mut r: u64 = 0x2545_f491_4f6c_dd1d;
        let mut next = move || {
            r ^= r << 13;
            r ^= r >> 7;
            r ^= r << 17;
            r
        };
        for _ in 0..1_000_000 {
            // Any bits, and values near halves and integers of lattice size.
            let n = next();
            fixed.push(f64::from_bits(n));
            let k = (n >> 12) as i64 % (1 << 40) - (1 << 39);
            fixed.push(k as f64 / 2.0);
            fixed.push(k as f64 / 1024.0);
            fixed.push(f64::from_bits((k as f64 / 2.0).to_bits() ^ (n & 1)));
        }
        for x in fixed {
            assert_eq!(round(x).to_bits(), x.round().to_bits(), "{x:e}");
        }
    }

    #[test]
    fn the_first_out_of_range_vertex_in_triangle_order_is_reported() {
        let piece = crate::PAR_PIECE;
        let n = 3 * piece + 5;
        // Errors in one piece, in several, and the first in the last piece.
        let cases: [&[usize]; 4] = [
            &[piece + 3],
            &[2 * piece + 1, piece + 7, 3 * piece + 2],
            &[3 * piece + 4],
            &[5, 6],
        ];
        for bad in cases {
            let (m, far) = mesh(n, bad);
            let first = bad.iter().zip(&far).min().unwrap().1;
            match GridMesh::new(&m, &grid()) {
                Err(EngineError::OutOfRange { vertex, voxels }) => {
                    assert_eq!(vertex, *first, "{bad:?}");
                    assert_eq!(voxels, 1e7);
                }
                other => panic!("{bad:?}: {other:?}"),
            }
        }
        // Only the culled triangle has a far vertex: no error, and it is dropped.
        let (m, _) = mesh(n, &[]);
        let g = GridMesh::new(&m, &grid()).unwrap();
        assert_eq!(g.triangles.len(), n - 1);
        // Kept in order, on the lattice: triangle 1 is the second of the mesh.
        assert_eq!(g.triangles[0][0], [256, 256, (1.5 * 256.0) as i32]);
    }
}
