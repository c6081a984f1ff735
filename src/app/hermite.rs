//! Hermite data and dual contouring from a mesh (issue 33; docs/methods.md, "Hermite data" and
//! "dual-contouring"): the `solid` of a voxelization request, then the crossings of its
//! differing edges with the mesh. Bounded: the solid by the request's voxel limit, the Hermite
//! data by the solid's boundary (one edge per boundary face, [`hermite::BYTES_PER_EDGE`] each,
//! checked against the memory limit before it is built).

use super::error::{Error, ErrorKind, Result};
use super::request::{MethodSpec, VoxelizeRequest};
use super::voxelize::{Prepared, load, run};
use crate::cancel::Control;
use crate::engine::hermite::{self, Hermite};
use crate::engine::{Engine, FIXED_ONE, Method};
use crate::extract::{TriMesh, cubes, dual_contouring};
use crate::volume::{BitVolume, Volume};

/// A mesh's solid and its Hermite data.
pub struct Solid {
    pub prepared: Prepared,
    pub bits: BitVolume,
    pub hermite: Hermite,
}

/// The solid of `req` (its method must be `solid`) on `engine` and its Hermite data; refused
/// with `too-many-triangles` when the boundary's edges, at [`hermite::BYTES_PER_EDGE`] each,
/// would need more than `max_bytes`.
pub fn solid_and_hermite(
    req: &VoxelizeRequest,
    engine: &dyn Engine,
    max_bytes: u64,
    ctl: &Control,
) -> Result<Solid> {
    if req.method != MethodSpec::Bits(Method::Solid) {
        return Err(Error::invalid(format!(
            "Hermite data is taken from method=solid, not {}",
            req.method.name()
        )));
    }
    let prepared = load(req)?.fit(req)?;
    let v = run(&prepared, engine, &ctl.stage(0.0, 0.5))?;
    let Volume::Bits(bits) = v.volume else {
        return Err(Error::invalid("method=solid gave no bit volume"));
    };
    let (faces, _) = cubes::boundary_counts(&bits);
    let need = faces.saturating_mul(hermite::BYTES_PER_EDGE);
    if need > max_bytes {
        return Err(Error::new(
            ErrorKind::TooManyTriangles,
            format!(
                "the solid's {faces} boundary edges need {need} bytes of Hermite data, over the \
                 limit of {max_bytes}: use a coarser grid"
            ),
        ));
    }
    let tris =
        crate::engine::sdf::lattice_triangles(&prepared.mesh, &prepared.grid, Some(FIXED_ONE))
            .map_err(Error::from)?;
    let hermite = hermite::hermite(&tris, &bits, &ctl.stage(0.5, 1.0))?;
    Ok(Solid {
        prepared,
        bits,
        hermite,
    })
}

/// The dual contouring mesh of `s`, in world coordinates.
pub fn dual_contour(s: &Solid, ctl: &Control) -> Result<TriMesh> {
    let m = dual_contouring::dual_contouring(&s.bits, &s.hermite, ctl)?;
    Ok(m.to_world(&s.prepared.grid))
}
