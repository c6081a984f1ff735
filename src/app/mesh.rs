//! Meshes out of stored volumes (issue 33; definitions: docs/methods.md, "Meshes out"), for
//! `GET /v1/volumes/{id}/mesh`. Bounded in two steps before anything is built: the volume's
//! occupancy and the triangle count its boundary could give ([`plan`]: over
//! `Limits::max_triangles` is `too-many-triangles`, with the numbers), then the memory the
//! build needs for that many triangles ([`build_cost`]); the build runs under a [`Control`]
//! (cancelled when the client goes away), and the file is written while it is sent.

use super::error::{Error, ErrorKind, Result};
use super::ops::{blocking_with, load};
use super::store::VolumeStore;
use crate::cancel::Control;
use crate::extract::write::MeshFormat;
use std::borrow::Cow;

use crate::extract::surface_nets::{self, Field};
use crate::extract::{Algorithm, TriMesh, cubes, marching_cubes, occupancy};
use crate::grid::Grid;
use crate::limits::Limits;
use crate::volume::{BitVolume, Volume};

/// What to extract and how to write it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MeshRequest {
    pub algorithm: Algorithm,
    pub format: MeshFormat,
}

impl MeshRequest {
    /// From a front's strings; `None` takes the defaults (`cubes`, `obj`).
    pub fn parse(algorithm: Option<&str>, format: Option<&str>) -> Result<MeshRequest> {
        Ok(MeshRequest {
            algorithm: algorithm
                .map_or(Ok(Algorithm::Cubes), Algorithm::parse)
                .map_err(Error::invalid)?,
            format: format
                .map_or(Ok(MeshFormat::Obj), MeshFormat::parse)
                .map_err(Error::invalid)?,
        })
    }
}

/// A volume with the voxels its mesh bounds and the bound of its triangles.
pub struct Planned {
    /// The volume, where the algorithm reads its values (surface nets of distance and density
    /// volumes); else `None`.
    pub volume: Option<Volume>,
    /// The voxels inside the mesh.
    pub bits: BitVolume,
    pub triangles: u64,
    pub algorithm: Algorithm,
    /// A volume with channels, whose `rgba` colours the mesh's vertices
    /// ([`crate::extract::colour`]).
    pub colours: Option<crate::volume::Attributed>,
}

/// Bytes a build holds per triangle of the bound: the triangle (12), its share of vertices
/// (positions in lattice and world units, 48, and their table entries, 24) and of merged
/// rectangles (12).
pub const BYTES_PER_TRIANGLE: u64 = 96;

/// The voxels of `v` the mesh by `algorithm` bounds and its triangle bound (cubes: three per
/// boundary face and twelve per pinched edge; surface nets: exactly two per boundary face);
/// `too-many-triangles` over the limit.
pub fn plan(v: Volume, algorithm: Algorithm, limits: &Limits) -> Result<Planned> {
    if algorithm == Algorithm::DualContouring {
        return Err(Error::invalid(
            "algorithm=dual-contouring is contoured from the Hermite data of the mesh a volume \
             was made from, not from the volume (app::hermite)",
        ));
    }
    let mut colours = None;
    let (volume, bits) = match (algorithm, v) {
        (_, Volume::Bits(b)) => (None, b),
        // Bits with channels: extracted as bits, the colours kept for the vertices.
        (_, Volume::Channels(a)) => {
            let bits = a.bits().clone();
            colours = a.colours().is_some().then_some(a);
            (None, bits)
        }
        (Algorithm::Cubes | Algorithm::DualContouring, v) => (None, occupancy(&v)),
        (Algorithm::SurfaceNets | Algorithm::MarchingCubes, v) => {
            let bits = surface_nets::inside(&v).into_owned();
            (Some(v), bits)
        }
    };
    let triangles = match algorithm {
        Algorithm::Cubes => cubes::triangle_bound(&bits),
        Algorithm::SurfaceNets => 2 * cubes::boundary_counts(&bits).0,
        // A polygon of k crossings is at most k triangles; each crossing is in four polygons.
        Algorithm::MarchingCubes => 4 * cubes::boundary_counts(&bits).0,
        // Surface nets' quads, split.
        Algorithm::DualContouring => 2 * cubes::boundary_counts(&bits).0,
    };
    let max = limits.max_triangles as u64;
    if triangles > max {
        return Err(Error::new(
            ErrorKind::TooManyTriangles,
            format!(
                "the {} mesh of this volume's {} inside voxels could have up to {triangles} \
                 triangles, over the limit of {max}: extract a smaller or coarser volume",
                algorithm.as_str(),
                bits.count_ones()
            ),
        ));
    }
    Ok(Planned {
        volume,
        bits,
        triangles,
        algorithm,
        colours,
    })
}

/// Bytes the build of `p` needs beyond the occupancy: the triangles' share
/// ([`BYTES_PER_TRIANGLE`]), a bit per lattice point (the rectangles' corners), and with
/// colours a colour per vertex (4 bytes; at most three vertices a triangle).
pub fn build_cost(p: &Planned) -> u64 {
    let d = p.bits.dims().map(|n| u64::from(n) + 1);
    let colours = if p.colours.is_some() { 12 } else { 0 };
    p.triangles
        .saturating_mul(BYTES_PER_TRIANGLE + colours)
        .saturating_add((d[0] * d[1] * d[2]).div_ceil(8))
}

/// The occupancy and bound of stored volume `id` (loaded once, dropped after).
pub async fn plan_stored(
    store: &dyn VolumeStore,
    id: &str,
    algorithm: Algorithm,
    limits: &Limits,
    ctl: &Control,
) -> Result<Planned> {
    let v = load(store, id).await?;
    let limits = *limits;
    blocking_with(ctl, move |_| plan(v, algorithm, &limits)).await
}

/// The mesh of `p`, in world coordinates.
pub fn build(p: &Planned, ctl: &Control) -> Result<TriMesh> {
    let grid: Grid = *p.bits.grid();
    let field = match &p.volume {
        Some(v) => Field::new(v, Cow::Borrowed(&p.bits)),
        None => Field::bits(Cow::Borrowed(&p.bits)),
    };
    let m = match (p.algorithm, &p.volume) {
        (Algorithm::Cubes, _) => cubes::cubes(&p.bits, ctl)?,
        (Algorithm::MarchingCubes, _) => marching_cubes::marching_cubes(&field, ctl)?,
        (Algorithm::SurfaceNets | Algorithm::DualContouring, _) => {
            surface_nets::surface_nets(&field, ctl)?
        }
    };
    let mut m = m;
    if let Some(a) = &p.colours {
        m.colors = crate::extract::colour::vertex_colours(&m, a);
    }
    ctl.complete();
    Ok(m.to_world(&grid))
}

/// [`build`] on the blocking pool, cancelled when the returned future is dropped.
pub async fn build_async(p: Planned, ctl: &Control) -> Result<TriMesh> {
    blocking_with(ctl, move |ctl| build(&p, ctl)).await
}
