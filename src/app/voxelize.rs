//! The voxelize pipeline, once for every front: load the mesh, diagnose it, fit the grid, check
//! the limits ([`prepare`], cheap next to the engine, so a front can refuse a request before it
//! queues it), then dispatch method and fill on an engine ([`run`]).

use std::time::Instant;

use super::error::{Error, Result};
use super::request::{MeshSource, MethodSpec, VoxelizeRequest};
use crate::cancel::Control;
use crate::engine::colour::{self, Want};
use crate::engine::density::{self, DensityError};
use crate::engine::distance;
use crate::engine::fill::{self, Fill, FillReport};
use crate::engine::sdf::{self, Band};
use crate::engine::{Engine, GridMesh};
use crate::grid::{Grid, GridLimits};
use crate::limits::Limits;
use crate::mesh::{self, Format, Mesh, MeshDiagnostics, MeshError};
use crate::volume::Volume;

/// A voxelization whose mesh is loaded and whose grid is fitted and within the limits: what a
/// job carries from the request to the engine.
#[derive(Clone, Debug)]
pub struct Prepared {
    pub mesh: Mesh,
    pub diagnostics: MeshDiagnostics,
    pub grid: Grid,
    pub method: MethodSpec,
    pub fill: Fill,
    /// The attribute channels asked for (checked against the mesh when prepared).
    pub attributes: Want,
    pub limits: Limits,
    pub source: Source,
    /// sdf: the bricks the engine evaluates (those some triangle may reach within the band;
    /// every brick for `band=all`), counted when the request is prepared; 0 for other methods.
    pub candidate_bricks: u64,
    /// Seconds spent loading and diagnosing the mesh.
    pub load_s: f64,
    pub diagnose_s: f64,
}

/// Where the mesh came from, as a volume records it.
#[derive(Clone, Debug, PartialEq)]
pub struct Source {
    /// The file's name, or `upload`.
    pub name: String,
    /// The format given or sniffed (of the mesh inside, for a gzip'd file or a zip).
    pub format: String,
    /// `gzip` for a gzip'd file or upload, `zip` for a zip upload (the mesh and its files).
    pub compression: Option<String>,
    /// sha256 of the uploaded bytes (uploads only: files are not hashed).
    pub sha256: Option<String>,
}

/// A computed volume and how it was computed.
#[derive(Clone, Debug)]
pub struct Voxelized {
    pub volume: Volume,
    pub fill: FillReport,
    pub voxelize_s: f64,
}

impl Prepared {
    /// The engine's work in classified voxels plus a share per triangle: what the scheduler
    /// orders jobs by.
    pub fn cost(&self) -> f64 {
        let near = match self.method {
            // Each candidate voxel takes the distances to a few triangles.
            MethodSpec::Sdf { .. } => 16.0 * 512.0 * self.candidate_bricks as f64,
            _ => 0.0,
        };
        self.method.voxels_per_voxel() as f64 * self.grid.voxel_count() as f64
            + 64.0 * self.mesh.triangles().len() as f64
            + near
    }
}

/// A loaded and diagnosed mesh, before its grid is fitted.
#[derive(Clone, Debug)]
pub struct Loaded {
    pub mesh: Mesh,
    pub diagnostics: MeshDiagnostics,
    pub source: Source,
    pub load_s: f64,
    pub diagnose_s: f64,
}

/// Loads and diagnoses the request's mesh within its limits. Blocking (parsing is CPU work and
/// a file source reads the disk): async callers run it on a blocking thread.
pub fn load(req: &VoxelizeRequest) -> Result<Loaded> {
    let t0 = Instant::now();
    let opts = req.load_options();
    let (mesh, format, gzip, sha256) = match &req.source {
        MeshSource::File { path, format } => {
            let bytes = std::fs::read(path)
                .map_err(|e| MeshError::Io(format!("{}: {e}", path.display())))?;
            let format = format.or_else(|| Format::from_path(path));
            let (m, format) = mesh::load_bytes_as(&bytes, format, &opts)?;
            (m, format, mesh::container(&bytes), None)
        }
        MeshSource::Bytes { bytes, format } => {
            if bytes.is_empty() {
                return Err(Error::new(
                    super::ErrorKind::InvalidMesh,
                    "the request body is empty; send the mesh file as the body",
                ));
            }
            let (m, format) = mesh::load_bytes_as(bytes, *format, &opts)?;
            (
                m,
                format,
                mesh::container(bytes),
                Some(super::sha256_hex(bytes)),
            )
        }
    };
    let load_s = t0.elapsed().as_secs_f64();
    let t1 = Instant::now();
    let diagnostics = mesh.diagnostics();
    Ok(Loaded {
        mesh,
        diagnostics,
        source: Source {
            name: req.source.display_name(),
            format: format.name().to_string(),
            compression: gzip,
            sha256,
        },
        load_s,
        diagnose_s: t1.elapsed().as_secs_f64(),
    })
}

impl Loaded {
    /// Fits the request's grid to the mesh and checks it (and a density's finer grid) against
    /// the voxel limit.
    pub fn fit(self, req: &VoxelizeRequest) -> Result<Prepared> {
        let grid_limits = GridLimits {
            max_voxels: req.limits.max_voxels,
        };
        // A narrow band's voxel limit counts its candidate voxels; its grid has a cap of its own.
        let fit_limits = match req.method {
            MethodSpec::Sdf {
                band: Band::Voxels(_),
            } => GridLimits {
                max_voxels: crate::limits::sdf_grid_voxels(req.limits.max_voxels),
            },
            _ => grid_limits,
        };
        let grid = Grid::fit(
            self.diagnostics.bbox_min,
            self.diagnostics.bbox_max,
            req.grid,
            req.padding,
            fit_limits,
        )?;
        colour::check(self.mesh.attributes(), req.attributes)?;
        let mut candidate_bricks = 0;
        match req.method {
            MethodSpec::Density { factor } => {
                density::fine_grid(&grid, factor, grid_limits)
                    .map_err(|source| DensityError::Grid { factor, source })?;
            }
            MethodSpec::Distance { thickness } => {
                distance_thickness(thickness, grid.voxel_size)?;
            }
            MethodSpec::Sdf { band } => {
                let tris = sdf::lattice_triangles(&self.mesh, &grid, band.reach())?;
                candidate_bricks = sdf::candidate_bricks(&tris, &grid, band);
                let voxels = candidate_bricks.saturating_mul(512);
                if voxels > req.limits.max_voxels {
                    return Err(Error::new(
                        super::ErrorKind::GridTooLarge,
                        format!(
                            "method=sdf with band={band} on the {}x{}x{} grid evaluates {candidate_bricks} bricks of 8³ ({voxels} voxels), over the limit of {}; use a narrower band or a coarser grid",
                            grid.dims[0],
                            grid.dims[1],
                            grid.dims[2],
                            crate::limits::describe_voxels(req.limits.max_voxels)
                        ),
                    ));
                }
            }
            MethodSpec::Bits(_) => {}
        }
        Ok(Prepared {
            mesh: self.mesh,
            diagnostics: self.diagnostics,
            grid,
            method: req.method,
            fill: req.fill,
            attributes: req.attributes,
            limits: req.limits,
            source: self.source,
            candidate_bricks,
            load_s: self.load_s,
            diagnose_s: self.diagnose_s,
        })
    }
}

/// Loads, diagnoses and fits: everything but the engine ([`load`] then [`Loaded::fit`]).
/// Blocking.
pub fn prepare(req: &VoxelizeRequest) -> Result<Prepared> {
    load(req)?.fit(req)
}

/// Runs a prepared voxelization on `engine`: the method, with its solid part under the fill.
/// `ctl` is checked at the engine's and the fill's check points (an error of kind
/// `engine-failure` once it says stop; see [`crate::cancel`]) and hears the progress. Blocking.
pub fn run(p: &Prepared, engine: &dyn Engine, ctl: &Control) -> Result<Voxelized> {
    let t = Instant::now();
    let (bits_ctl, colour_ctl) = if p.attributes.any() {
        (ctl.stage(0.0, 0.5), ctl.stage(0.5, 1.0))
    } else {
        (ctl.clone(), ctl.stage(1.0, 1.0))
    };
    let outer = ctl;
    let ctl = &bits_ctl;
    let (volume, fill) = match p.method {
        MethodSpec::Bits(m) => {
            let (v, r) =
                fill::voxelize_with(engine, &p.mesh, &p.grid, m, p.fill, &p.diagnostics, ctl)?;
            (Volume::Bits(v), r)
        }
        MethodSpec::Density { factor } => {
            let limits = GridLimits {
                max_voxels: p.limits.max_voxels,
            };
            let (d, r) = density::density_with(
                engine,
                &p.mesh,
                &p.grid,
                factor,
                limits,
                p.fill,
                &p.diagnostics,
                ctl,
            )?;
            (Volume::Density(d), r)
        }
        MethodSpec::Distance { thickness } => {
            let t = distance_thickness(thickness, p.grid.voxel_size)?;
            // Every triangle within reach, none flattened (GridMesh::new culls for the
            // crossing methods, which changes distances near the grid's faces).
            let mesh = GridMesh {
                grid: p.grid,
                triangles: sdf::lattice_triangles(&p.mesh, &p.grid, Some(t))?,
            };
            let v = engine.distance_with(&mesh, t, ctl)?;
            let mut r = FillReport::new(p.fill, &p.mesh, &p.grid, &p.diagnostics);
            r.warning = None;
            (Volume::Bits(v), r)
        }
        MethodSpec::Sdf { band } => {
            let (v, r) =
                sdf::sdf_with(engine, &p.mesh, &p.grid, band, p.fill, &p.diagnostics, ctl)?;
            (Volume::SparseDistance(v), r)
        }
    };
    let volume = match volume {
        Volume::Bits(b) if p.attributes.any() => {
            Volume::Channels(colour::attribute(&p.mesh, b, p.attributes, &colour_ctl)?)
        }
        v => v,
    };
    outer.complete();
    // The warning is the result's (the CLI prints it, the service puts it in the volume's
    // metadata): logged at info for the service's job lines, not at warn, which the CLI shows
    // by default and would print it twice.
    if let Some(w) = &fill.warning {
        tracing::info!(warning = w.as_str(), "fill");
    }
    Ok(Voxelized {
        volume,
        fill,
        voxelize_s: t.elapsed().as_secs_f64(),
    })
}

/// distance's thickness in lattice units ([`distance::thickness_lattice`]; `None`: half the
/// voxel diagonal, 222).
pub fn distance_thickness(thickness: Option<f64>, voxel_size: f64) -> Result<i64> {
    match thickness {
        None => Ok(distance::DEFAULT_LATTICE),
        Some(t) => distance::thickness_lattice(t, voxel_size).map_err(Error::invalid),
    }
}

/// [`prepare`] then [`run`].
pub fn voxelize(req: &VoxelizeRequest, engine: &dyn Engine) -> Result<(Prepared, Voxelized)> {
    let p = prepare(req)?;
    let v = run(&p, engine, &Control::none())?;
    Ok((p, v))
}
