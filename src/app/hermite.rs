//! Hermite data and dual contouring from a mesh (issue 33; docs/methods.md, "Hermite data" and
//! "dual-contouring"): the `solid` of the mesh on a grid, then the crossings of its differing
//! edges with the mesh. From a request (`voxd hermite`, `voxd mesh --algorithm
//! dual-contouring`) or from a stored volume's kept mesh ([`super::sources`]) on the volume's
//! grid with the fill it used (`GET /v1/volumes/{id}/hermite`, `…/mesh?algorithm=
//! dual-contouring`). Bounded: the solid by the grid's voxels, the Hermite data by the solid's
//! boundary (one edge per boundary face, [`hermite::BYTES_PER_EDGE`] each, checked before it is
//! built).

use super::error::{Error, ErrorKind, Result};
use super::request::{MethodSpec, VoxelizeRequest};
use super::store::{VolumeMeta, VolumeStore};
use super::voxelize::load;
use crate::cancel::Control;
use crate::engine::fill::{self, Fill};
use crate::engine::hermite::{self, Hermite};
use crate::engine::{Engine, FIXED_ONE, Method};
use crate::extract::{TriMesh, cubes, dual_contouring};
use crate::grid::Grid;
use crate::limits::Limits;
use crate::mesh::{ExternalResources, LoadOptions, Mesh, MeshDiagnostics};
use crate::volume::BitVolume;

/// A mesh's solid on a grid and its Hermite data.
pub struct Solid {
    pub grid: Grid,
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
    let p = load(req)?.fit(req)?;
    let s = MeshSolid::new(
        p.mesh,
        &p.diagnostics,
        p.grid,
        p.fill,
        engine,
        &ctl.stage(0.0, 0.5),
    )?;
    let need = s.hermite_bytes();
    if need > max_bytes {
        return Err(Error::new(
            ErrorKind::TooManyTriangles,
            format!(
                "the solid's {} boundary edges need {need} bytes of Hermite data, over the \
                 limit of {max_bytes}: use a coarser grid",
                s.faces
            ),
        ));
    }
    s.hermite(&ctl.stage(0.5, 1.0))
}

/// The dual contouring mesh of `s`, in world coordinates.
pub fn dual_contour(s: &Solid, ctl: &Control) -> Result<TriMesh> {
    let m = dual_contouring::dual_contouring(&s.bits, &s.hermite, ctl)?;
    Ok(m.to_world(&s.grid))
}

/// Bytes the solid of a stored volume's kept mesh needs before its Hermite data: the source
/// object read and the mesh decoded from it (about twice its bytes), the mesh's lattice
/// triangles (96 bytes each), and the solid's bit grids (as a `solid` job's).
pub fn stored_solid_cost(meta: &VolumeMeta) -> u64 {
    let tris = meta.source.triangles as u64;
    let source =
        crate::mesh::binary::encoded_len(3 * meta.source.triangles, meta.source.triangles) as u64;
    source
        .saturating_mul(2)
        .saturating_add(tris.saturating_mul(96))
        .saturating_add(super::cost::voxelize_job(
            &meta.grid,
            &MethodSpec::Bits(Method::Solid),
            0,
        ))
}

/// The fill a stored volume's solid is taken with: the one it used (`auto` resolved), else
/// `auto`.
fn fill_of(meta: &VolumeMeta) -> Fill {
    meta.fill.as_ref().map_or(Fill::Auto, |f| f.used)
}

/// A mesh and its solid on a grid, before the Hermite data: the two steps apart, so that a
/// caller can bound the Hermite data (by [`MeshSolid::faces`]) before it is built.
pub struct MeshSolid {
    mesh: Mesh,
    pub grid: Grid,
    pub bits: BitVolume,
    /// Boundary faces of the solid: its differing edges, the Hermite data's length.
    pub faces: u64,
}

impl MeshSolid {
    /// The solid of `mesh` on `grid` with `fill` (`method=solid`'s) on `engine`.
    pub fn new(
        mesh: Mesh,
        diagnostics: &MeshDiagnostics,
        grid: Grid,
        fill: Fill,
        engine: &dyn Engine,
        ctl: &Control,
    ) -> Result<MeshSolid> {
        let (bits, _) =
            fill::voxelize_with(engine, &mesh, &grid, Method::Solid, fill, diagnostics, ctl)?;
        let faces = cubes::boundary_counts(&bits).0;
        Ok(MeshSolid {
            mesh,
            grid,
            bits,
            faces,
        })
    }

    /// Bytes its Hermite data takes at most: [`hermite::BYTES_PER_EDGE`] per boundary face.
    pub fn hermite_bytes(&self) -> u64 {
        self.faces.saturating_mul(hermite::BYTES_PER_EDGE)
    }

    /// The solid with its Hermite data ([`MeshSolid::hermite_bytes`] more).
    pub fn hermite(self, ctl: &Control) -> Result<Solid> {
        let tris = crate::engine::sdf::lattice_triangles(&self.mesh, &self.grid, Some(FIXED_ONE))
            .map_err(Error::from)?;
        let hermite = hermite::hermite(&tris, &self.bits, ctl)?;
        Ok(Solid {
            grid: self.grid,
            bits: self.bits,
            hermite,
        })
    }
}

/// The kept mesh of stored volume `meta` and its solid on the volume's grid with the fill it
/// used, on the CPU engine ([`stored_solid_cost`] bytes); `source-not-kept` when the volume
/// keeps no mesh. Cancelled when the future is dropped.
pub async fn stored_solid(
    store: &dyn VolumeStore,
    meta: &VolumeMeta,
    limits: &Limits,
    ctl: &Control,
) -> Result<MeshSolid> {
    let opts = LoadOptions {
        external: ExternalResources::Deny,
        max_triangles: limits.max_triangles,
        max_decompressed_bytes: limits.max_decompressed_bytes,
        max_texture_bytes: limits.max_texture_bytes,
        // The shape only.
        textures: false,
    };
    let mesh = super::sources::load(store, meta, opts).await?;
    let diagnostics = match meta.diagnostics.clone() {
        Some(d) => d,
        None => MeshDiagnostics::of(&mesh),
    };
    let (grid, fill) = (meta.grid, fill_of(meta));
    super::ops::blocking_with(ctl, move |ctl| {
        MeshSolid::new(
            mesh,
            &diagnostics,
            grid,
            fill,
            &crate::engine::cpu::CpuEngine,
            ctl,
        )
    })
    .await
}

/// The Hermite data of `s` ([`MeshSolid::hermite_bytes`] more). Cancelled when the future is
/// dropped.
pub async fn stored_hermite(s: MeshSolid, ctl: &Control) -> Result<Solid> {
    super::ops::blocking_with(ctl, move |ctl| s.hermite(ctl)).await
}
