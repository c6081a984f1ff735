//! Meshes back out of volumes (issue 33): extraction algorithms, the checks every output
//! mesh must pass, and the mesh file writers.
//!
//! * [`cubes`]: the exact boundary of the set voxels, coplanar faces merged into rectangles,
//!   without T-junctions.
//! * [`surface_nets`]: one vertex per surface component of each dual cell, smooth, 2-manifold.
//! * [`marching_cubes`]: a vertex per crossed grid edge, the dual of surface nets' quads.
//! * [`dual_contouring`]: surface nets' topology, each vertex where its Hermite planes meet
//!   ([`qef`]), so sharp edges and corners stay sharp.
//! * [`check`]: watertight and consistently oriented (every edge used once in each direction),
//!   no degenerate or duplicate triangles, the enclosed volume.
//! * [`write`]: OBJ, binary STL, binary PLY.
//!
//! Meshes are built in lattice units (voxel corners at integer coordinates, so that the checks
//! are exact) and placed in the world by [`TriMesh::to_world`].

pub mod check;
pub mod colour;
pub mod cubes;
pub mod dual_contouring;
mod faces;
pub mod marching_cubes;
pub mod measure;
mod pinches;
pub mod qef;
mod relax;
mod slabs;
pub mod surface_nets;
mod untangle;
mod vec3;
pub mod write;

use crate::grid::Grid;

/// A triangle mesh: positions and counter-clockwise (outward) triangles, and, from a volume with
/// colours, one sRGB RGBA per vertex (`colour::vertex_colours`; empty otherwise).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriMesh {
    pub positions: Vec<[f64; 3]>,
    pub triangles: Vec<[u32; 3]>,
    pub colors: Vec<[u8; 4]>,
}

impl TriMesh {
    /// From lattice units (voxel (i, j, k) spans [i, i + 1] × …) to `grid`'s world coordinates.
    pub fn to_world(mut self, grid: &Grid) -> TriMesh {
        use rayon::prelude::*;
        self.positions
            .par_iter_mut()
            .with_min_len(1 << 14)
            .for_each(|p| *p = [0, 1, 2].map(|a| grid.origin[a] + p[a] * grid.voxel_size));
        self
    }
}

/// The extraction algorithms.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Algorithm {
    Cubes,
    SurfaceNets,
    MarchingCubes,
    /// From Hermite data: needs the mesh the volume was made from.
    DualContouring,
}

impl Algorithm {
    pub const ALL: [Algorithm; 4] = [
        Algorithm::Cubes,
        Algorithm::SurfaceNets,
        Algorithm::MarchingCubes,
        Algorithm::DualContouring,
    ];

    pub fn as_str(self) -> &'static str {
        match self {
            Algorithm::Cubes => "cubes",
            Algorithm::SurfaceNets => "surface-nets",
            Algorithm::MarchingCubes => "marching-cubes",
            Algorithm::DualContouring => "dual-contouring",
        }
    }

    pub fn parse(s: &str) -> Result<Algorithm, String> {
        Algorithm::ALL
            .into_iter()
            .find(|a| a.as_str() == s)
            .ok_or_else(|| {
                let names: Vec<_> = Algorithm::ALL.iter().map(|a| a.as_str()).collect();
                format!("algorithm must be one of {}, got {s:?}", names.join(", "))
            })
    }
}

/// The occupied voxels of any volume (its bits, or the voxels `Volume::occupied` calls set:
/// non-zero densities and ids, distances with the sign bit set, …).
pub fn occupancy(v: &crate::volume::Volume) -> crate::volume::BitVolume {
    if let crate::volume::Volume::Bits(b) = v {
        return b.clone();
    }
    let g = *v.grid();
    let mut b = crate::volume::BitVolume::new(g);
    for x in 0..g.dims[0] {
        for y in 0..g.dims[1] {
            for z in 0..g.dims[2] {
                if v.occupied(x, y, z) {
                    b.set(x, y, z, true);
                }
            }
        }
    }
    b
}

#[cfg(test)]
mod dc_tests;
#[cfg(test)]
mod sn_tests;
#[cfg(test)]
mod tests;
