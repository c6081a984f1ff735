//! Solid fills for meshes that are not watertight (`docs/methods.md`, "Meshes that are not
//! watertight"). `parity` is the solid method itself. `vote` runs parity along z, along x and
//! along y — the same exact rule on axis-rotated coordinates, on whichever engine — and keeps a
//! voxel where at least two agree. `flood` marks the conservative surface, floods the exterior
//! from the grid's border through unmarked voxels (6-connected), and calls everything unreached
//! solid (so the surface voxels are solid too). `winding` keeps a voxel where the generalised
//! winding number of the mesh at its centre is at least ½ in magnitude ([`super::winding`]).
//! `auto` is parity for a watertight mesh and winding otherwise.
//!
//! Every fill comes with a [`FillReport`]: the fill asked for and the one used, the number of
//! odd-parity columns (columns the mesh covers an odd number of times: holes along z), and a
//! warning when parity was used on a mesh that is not watertight.

use serde::{Deserialize, Serialize};
use std::collections::VecDeque;

use super::winding::{self, WindingStats};
use super::{Engine, EngineError, GridMesh, Method};
use crate::cancel::{Canceled, Control};
use crate::grid::Grid;
use crate::mesh::{Mesh, MeshDiagnostics};
use crate::volume::BitVolume;

crate::named_enum! {
    /// How solid-based methods decide inside (`fill=`, `--fill`); the module doc says each.
    pub enum Fill: "fill" {
        Parity = "parity",
        Vote = "vote",
        Winding = "winding",
        Flood = "flood",
        Auto = "auto",
    }
}

impl Fill {
    /// The fill when none is asked for: parity (exact) for a watertight mesh, winding for one
    /// that is not (parity was the default before: an open mesh streaked).
    pub const DEFAULT: Fill = Fill::Auto;

    /// The fill `auto` resolves to for a mesh (others are themselves).
    pub fn resolve(self, diagnostics: &MeshDiagnostics) -> Fill {
        match self {
            Fill::Auto if diagnostics.watertight => Fill::Parity,
            Fill::Auto => Fill::Winding,
            f => f,
        }
    }
}

/// How a solid was filled, for summaries and volume metadata.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FillReport {
    pub requested: Fill,
    pub used: Fill,
    /// Columns of the grid the mesh covers an odd number of times (holes along z); see
    /// [`crate::engine::cpu::odd_parity_columns`].
    pub odd_parity_columns: u64,
    /// Set when parity was used on a mesh that is not watertight.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub warning: Option<String>,
    /// For `auto`: why it resolved to the fill used.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
    /// For `winding`: how many voxels the exact count and the hierarchy decided.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub winding: Option<WindingStats>,
}

impl FillReport {
    /// The report for `fill` on `mesh` (`grid` gives the columns counted), before any voxel is
    /// computed; [`solid`] adds the winding statistics.
    pub fn new(fill: Fill, mesh: &Mesh, grid: &Grid, diagnostics: &MeshDiagnostics) -> FillReport {
        let used = fill.resolve(diagnostics);
        // A watertight mesh has none: each of its edges is shared by exactly two triangles, so
        // (mod 2) the projected triangles' boundaries cancel and every generic point of the
        // plane (a column centre under the tie rule is one) is covered an even number of
        // times; triangles flat in projection cover nothing and cancel alike. Snapping keeps
        // equal positions equal, so the edges still pair up. (tests/fill.rs checks this
        // against a brute-force count.)
        let odd = if diagnostics.watertight {
            0
        } else {
            super::cpu::odd_parity_columns(mesh, grid)
        };
        let warning = (used == Fill::Parity && !diagnostics.watertight).then(|| {
            format!(
                "parity fill on a mesh that is not watertight ({} boundary and {} non-manifold edges, {odd} odd-parity columns): the solid may be streaked or empty; fill=winding or fill=auto is robust",
                diagnostics.boundary_edges, diagnostics.non_manifold_edges
            )
        });
        let reason = (fill == Fill::Auto).then(|| {
            if diagnostics.watertight {
                "auto: the mesh is watertight, so parity (exact for a closed mesh)".to_string()
            } else {
                format!(
                    "auto: the mesh is not watertight ({} boundary and {} non-manifold edges), so winding",
                    diagnostics.boundary_edges, diagnostics.non_manifold_edges
                )
            }
        });
        FillReport {
            requested: fill,
            used,
            odd_parity_columns: odd,
            warning,
            reason,
            winding: None,
        }
    }
}

/// `method` with its solid part computed under `fill` (conservative = filled solid ∪ surface,
/// interior = filled solid − surface; `surface` has no solid part and ignores the fill), and the
/// report of the fill.
pub fn voxelize(
    engine: &dyn Engine,
    mesh: &Mesh,
    grid: &Grid,
    method: Method,
    fill: Fill,
    diagnostics: &MeshDiagnostics,
) -> Result<(BitVolume, FillReport), EngineError> {
    voxelize_with(
        engine,
        mesh,
        grid,
        method,
        fill,
        diagnostics,
        &Control::none(),
    )
}

/// [`voxelize`], checking `ctl` wherever the engine and the fill do and reporting progress.
pub fn voxelize_with(
    engine: &dyn Engine,
    mesh: &Mesh,
    grid: &Grid,
    method: Method,
    fill: Fill,
    diagnostics: &MeshDiagnostics,
    ctl: &Control,
) -> Result<(BitVolume, FillReport), EngineError> {
    ctl.check()?;
    let mut report = FillReport::new(fill, mesh, grid, diagnostics);
    if method == Method::Surface {
        report.warning = None;
        report.reason = Some("method=surface has no inside: no fill is used".into());
    }
    if report.used == Fill::Parity || method == Method::Surface {
        return Ok((
            engine.voxelize_with(&GridMesh::new(mesh, grid)?, method, ctl)?,
            report,
        ));
    }
    // The surface of conservative and interior is the cheap part.
    let with_surface = matches!(method, Method::Conservative | Method::Interior);
    let split = if with_surface { 0.9 } else { 1.0 };
    // The diagnosis says whether the winding fill's caps are needed (it counts the edges they
    // would close).
    let known_closed =
        diagnostics.unoriented_edges == Some(0) && diagnostics.triangles == mesh.triangles().len();
    let (mut s, stats) = solid_inner(
        engine,
        mesh,
        grid,
        report.used,
        known_closed,
        &ctl.stage(0.0, split),
    )?;
    report.winding = stats;
    if with_surface {
        engine.apply_surface(
            &GridMesh::new(mesh, grid)?,
            &mut s,
            method == Method::Conservative,
            &ctl.stage(split, 1.0),
        )?;
    }
    Ok((s, report))
}

/// The solid of `mesh` on `grid` under `fill` (`auto` must be resolved first: it is treated as
/// winding), with the winding statistics when the fill is winding.
pub fn solid(
    engine: &dyn Engine,
    mesh: &Mesh,
    grid: &Grid,
    fill: Fill,
) -> Result<(BitVolume, Option<WindingStats>), EngineError> {
    solid_with(engine, mesh, grid, fill, &Control::none())
}

/// [`solid`], checking `ctl` (engine bands or slabs, vote's three passes, the flood, winding's
/// blocks and rows) and reporting progress there.
pub fn solid_with(
    engine: &dyn Engine,
    mesh: &Mesh,
    grid: &Grid,
    fill: Fill,
    ctl: &Control,
) -> Result<(BitVolume, Option<WindingStats>), EngineError> {
    solid_inner(engine, mesh, grid, fill, false, ctl)
}

/// [`solid_with`]; `known_closed`: the mesh needs no caps to close it (for the winding fill).
fn solid_inner(
    engine: &dyn Engine,
    mesh: &Mesh,
    grid: &Grid,
    fill: Fill,
    known_closed: bool,
    ctl: &Control,
) -> Result<(BitVolume, Option<WindingStats>), EngineError> {
    ctl.check()?;
    let out = match fill {
        Fill::Parity => (
            engine.voxelize_with(&GridMesh::new(mesh, grid)?, Method::Solid, ctl)?,
            None,
        ),
        Fill::Vote => (vote(engine, mesh, grid, ctl)?, None),
        Fill::Flood => {
            let surface = engine.voxelize_with(
                &GridMesh::new(mesh, grid)?,
                Method::Surface,
                &ctl.stage(0.0, 0.5),
            )?;
            (flood_with(&surface, &ctl.stage(0.5, 1.0))?, None)
        }
        Fill::Winding | Fill::Auto => {
            let (v, stats) = if known_closed {
                winding::solid_of_closed_with(mesh, grid, ctl)?
            } else {
                winding::solid_with(mesh, grid, ctl)?
            };
            (v, Some(stats))
        }
    };
    ctl.complete();
    Ok(out)
}

/// Parity along the axis that `rot` moves to z: `rot` maps output axis a to input axis rot[a].
fn parity_along(
    engine: &dyn Engine,
    mesh: &Mesh,
    grid: &Grid,
    rot: [usize; 3],
    ctl: &Control,
) -> Result<BitVolume, EngineError> {
    let positions = mesh.positions().iter().map(|p| rot.map(|a| p[a])).collect();
    let rotated = Mesh::new(positions, mesh.triangles().to_vec())
        .expect("a permutation of a valid mesh is valid");
    let g = Grid {
        origin: rot.map(|a| grid.origin[a]),
        voxel_size: grid.voxel_size,
        dims: rot.map(|a| grid.dims[a]),
    };
    let r = engine.voxelize_with(
        &GridMesh::new(&rotated, &g)?,
        Method::Solid,
        &ctl.stage(0.0, 0.8),
    )?;
    // Back to the grid's own axes: voxel (x, y, z) is r at its rotated index.
    let mut out = BitVolume::new(*grid);
    for (i, p) in r.iter_ones().enumerate() {
        if i.is_multiple_of(1 << 20) {
            ctl.check()?;
        }
        let mut q = [0u32; 3];
        for a in 0..3 {
            q[rot[a]] = p[a];
        }
        out.set(q[0], q[1], q[2], true);
    }
    ctl.complete();
    Ok(out)
}

fn vote(
    engine: &dyn Engine,
    mesh: &Mesh,
    grid: &Grid,
    ctl: &Control,
) -> Result<BitVolume, EngineError> {
    let z = parity_along(engine, mesh, grid, [0, 1, 2], &ctl.part(0, 3))?;
    let x = parity_along(engine, mesh, grid, [1, 2, 0], &ctl.part(1, 3))?;
    let y = parity_along(engine, mesh, grid, [2, 0, 1], &ctl.part(2, 3))?;
    let mut out = z.clone();
    for ((o, (a, b)), c) in out
        .words_mut()
        .iter_mut()
        .zip(x.words().iter().zip(y.words()))
        .zip(z.words())
    {
        *o = (a & b) | (b & c) | (a & c);
    }
    Ok(out)
}

/// Everything not reachable from the border through voxels that are not in `walls` (6-connected).
pub fn flood(walls: &BitVolume) -> BitVolume {
    flood_with(walls, &Control::none()).expect("Control::none never stops")
}

/// [`flood`], checking `ctl` every 2¹⁶ voxels reached and reporting them (of the voxels that
/// are not walls).
pub fn flood_with(walls: &BitVolume, ctl: &Control) -> Result<BitVolume, Canceled> {
    ctl.check()?;
    let [nx, ny, nz] = walls.dims();
    let open = walls.grid().voxel_count() - walls.count_ones();
    let reached_count = ctl.counter(open);
    let mut popped = 0u64;
    let mut reached = BitVolume::new(*walls.grid());
    let mut queue = VecDeque::new();
    let visit = |p: [u32; 3], reached: &mut BitVolume, queue: &mut VecDeque<[u32; 3]>| {
        if !walls.get(p[0], p[1], p[2]) && !reached.get(p[0], p[1], p[2]) {
            reached.set(p[0], p[1], p[2], true);
            queue.push_back(p);
        }
    };
    for x in 0..nx {
        for y in 0..ny {
            for z in 0..nz {
                if x == 0 || y == 0 || z == 0 || x == nx - 1 || y == ny - 1 || z == nz - 1 {
                    visit([x, y, z], &mut reached, &mut queue);
                }
            }
        }
    }
    while let Some(p) = queue.pop_front() {
        popped += 1;
        if popped.is_multiple_of(1 << 16) {
            reached_count.add(1 << 16);
            ctl.check()?;
        }
        for a in 0..3 {
            for step in [-1i64, 1] {
                let v = p[a] as i64 + step;
                if v >= 0 && v < walls.dims()[a] as i64 {
                    let mut q = p;
                    q[a] = v as u32;
                    visit(q, &mut reached, &mut queue);
                }
            }
        }
    }
    // Solid = not reached.
    let tail = reached.tail_mask();
    let wpc = reached.words_per_column();
    for col in reached.words_mut().chunks_exact_mut(wpc) {
        for w in col.iter_mut() {
            *w = !*w;
        }
        if let Some(l) = col.last_mut() {
            *l &= tail;
        }
    }
    ctl.complete();
    Ok(reached)
}
