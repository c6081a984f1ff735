//! `method=sdf`: the exact signed Euclidean distance from each voxel centre to the mesh, in a
//! sparse narrow band of 8³ bricks ([`Sparse<f32>`]). The rules are in `docs/methods.md`
//! ("sdf"); in short, with `R = 256·k` lattice units for `band=k`:
//!
//! * a voxel is in the band iff some triangle is strictly closer than `R` to its centre, decided
//!   exactly ([`lattice::compare`]; the f64 distance settles every voxel clearly inside or
//!   outside and only the rest take the exact test);
//! * its value is the least [`lattice::distance2`]'s square root over the triangles, times `s/256`, in f64,
//!   negated when the voxel is set in the `solid` volume of the same mesh, grid and fill,
//!   rounded once to f32;
//! * out of the band: `+k·s` (the background) or `−k·s` (the tile value); a brick is stored
//!   when it holds an in-band voxel or voxels of both signs, a brick position whose voxels are
//!   all inside and out of band is a tile.
//!
//! `band=all`: every voxel is in the band (background +∞, tile value −∞), every brick stored.
//!
//! The work: triangles are binned to the bricks they can reach ([`bins`]), then each brick's
//! 512 voxels take the least distance over its bin, in parallel over bricks; `band=all` searches
//! rings of bricks outward from each brick until no unseen triangle can be closer.

mod bins;
mod eval;
mod local;
mod signs;
#[cfg(test)]
mod tests;

use std::cmp::Ordering;

use rayon::prelude::*;

use super::fill::{self, Fill, FillReport};
use super::geom::lattice;
use super::snap::{FIXED_HALF, FIXED_ONE, MAX_FIXED, to_lattice};
use super::{Engine, EngineError, Method};
use crate::cancel::Control;
use crate::grid::Grid;
use crate::mesh::{Mesh, MeshDiagnostics};
use crate::volume::sparse::{BRICK, BRICK_VOXELS, Sparse};
use signs::Signs;

/// The band's half width: `band=k` voxels, or `band=all`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Band {
    Voxels(u32),
    All,
}

impl Band {
    /// OpenVDB's default half width for `meshToVolume`.
    pub const DEFAULT: Band = Band::Voxels(3);
    /// The widest `band=k`.
    pub const MAX: u32 = 64;

    /// `k` (1..=64) or `all`.
    pub fn parse(s: &str) -> Result<Band, String> {
        if s == "all" {
            return Ok(Band::All);
        }
        match s.parse::<u32>() {
            Ok(k) if (1..=Band::MAX).contains(&k) => Ok(Band::Voxels(k)),
            _ => Err(format!(
                "band must be an integer from 1 to {} (voxels) or \"all\", got {s:?}",
                Band::MAX
            )),
        }
    }

    /// The band's reach in lattice units (`None`: all).
    pub fn reach(self) -> Option<i64> {
        match self {
            Band::Voxels(k) => Some(i64::from(k) * FIXED_ONE),
            Band::All => None,
        }
    }

    /// The background (outside, out of band) and tile value (inside, out of band) on a grid
    /// of voxel size `s`.
    pub fn values(self, s: f64) -> (f32, f32) {
        match self {
            Band::Voxels(k) => {
                let b = (f64::from(k) * s) as f32;
                (b, -b)
            }
            Band::All => (f32::INFINITY, f32::NEG_INFINITY),
        }
    }
}

impl std::fmt::Display for Band {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Band::Voxels(k) => write!(f, "{k}"),
            Band::All => f.write_str("all"),
        }
    }
}

/// The mesh's triangles on `grid`'s lattice, every one (not culled like
/// [`super::GridMesh::new`], which drops triangles beside the grid: they matter to a distance),
/// except, with a band of `reach`, those whose box lies farther than `reach` from every voxel
/// centre. A vertex off the lattice's range is [`EngineError::OutOfRange`].
pub fn lattice_triangles(
    mesh: &Mesh,
    grid: &Grid,
    reach: Option<i64>,
) -> Result<Vec<[[i32; 3]; 3]>, EngineError> {
    let snapped: Vec<[f64; 3]> = mesh
        .positions()
        .par_iter()
        .with_min_len(crate::PAR_PIECE)
        .map(|&p| to_lattice(grid, p))
        .collect();
    let hi_centre = grid
        .dims
        .map(|d| (i64::from(d) - 1) * FIXED_ONE + FIXED_HALF);
    let snap = |tri: &[u32; 3]| -> Result<Option<[[i32; 3]; 3]>, EngineError> {
        let v = tri.map(|i| snapped[i as usize]);
        if let Some(r) = reach {
            let r = r as f64;
            for a in 0..3 {
                let lo = v[0][a].min(v[1][a]).min(v[2][a]);
                let hi = v[0][a].max(v[1][a]).max(v[2][a]);
                if hi < FIXED_HALF as f64 - r || lo > hi_centre[a] as f64 + r {
                    return Ok(None);
                }
            }
        }
        let mut out = [[0i32; 3]; 3];
        for (c, &vi) in tri.iter().enumerate() {
            for a in 0..3 {
                let x = v[c][a];
                if x.abs() > MAX_FIXED as f64 || x.is_nan() {
                    return Err(EngineError::OutOfRange {
                        vertex: vi as usize,
                        voxels: (x / FIXED_ONE as f64).abs(),
                    });
                }
                out[c][a] = x as i32;
            }
        }
        Ok(Some(out))
    };
    super::snap::snap_in_pieces(mesh, snap)
}

/// Bricks along each axis of `grid`.
pub fn brick_dims(grid: &Grid) -> [u32; 3] {
    grid.dims.map(|d| d.div_ceil(BRICK))
}

/// The bricks the work evaluates voxel by voxel ("candidate" bricks: those some triangle may
/// reach within the band; every brick for `band=all`), counted without keeping the bins: what
/// the voxel limit and the memory estimate of a `sdf` job count.
pub fn candidate_bricks(tris: &[[[i32; 3]; 3]], grid: &Grid, band: Band) -> u64 {
    match band.reach() {
        None => brick_dims(grid).iter().map(|&d| u64::from(d)).product(),
        Some(r) => bins::count(tris, brick_dims(grid), r),
    }
}

/// What one brick position becomes.
enum Brick {
    Stored([u32; 3], Box<[f32; BRICK_VOXELS]>),
    Tile([u32; 3]),
}

/// Signed distances of `mesh` on `grid` within `band`, signed by the `solid` volume of `fill`
/// (run on `engine`). Checks `ctl` per piece of bricks and reports progress: the solid takes
/// the first fifth, the distances the rest.
pub fn sdf_with(
    engine: &dyn Engine,
    mesh: &Mesh,
    grid: &Grid,
    band: Band,
    fill: Fill,
    diagnostics: &MeshDiagnostics,
    ctl: &Control,
) -> Result<(Sparse<f32>, FillReport), EngineError> {
    ctl.check()?;
    let t0 = std::time::Instant::now();
    let (solid, report) = fill::voxelize_with(
        engine,
        mesh,
        grid,
        Method::Solid,
        fill,
        diagnostics,
        &ctl.stage(0.0, 0.2),
    )?;
    let solid_s = t0.elapsed().as_secs_f64();
    // The solid's signs by brick (a few MB), and the solid (1 GB at 2048³) dropped before the
    // distances take their memory.
    let signs = Signs::new(&solid);
    drop(solid);
    let tris = lattice_triangles(mesh, grid, band.reach())?;
    let sparse = signed_distance(&tris, &signs, grid, band, &ctl.stage(0.2, 1.0))?;
    tracing::debug!(
        solid_s,
        total_s = t0.elapsed().as_secs_f64(),
        triangles = tris.len(),
        "sdf"
    );
    Ok((sparse, report))
}

/// Bricks evaluated between two insertions into the volume: what is held twice at most.
const PIECE_BRICKS: usize = 4096;

/// The sparse signed distance of lattice triangles `tris` on `grid`, signed by `signs`.
pub fn signed_distance(
    tris: &[[[i32; 3]; 3]],
    signs: &Signs,
    grid: &Grid,
    band: Band,
    ctl: &Control,
) -> Result<Sparse<f32>, EngineError> {
    let grid = *grid;
    let dims = grid.dims;
    let bd = brick_dims(&grid);
    let (background, tile) = band.values(grid.voxel_size);
    let mut out = Sparse::with_tile_value(grid, background, tile);
    let scale = grid.voxel_size / FIXED_ONE as f64;
    // Pieces of bricks, inserted piece by piece (not gathered into one list first: a large
    // grid has millions of tiles, and a brick's values would be held twice).
    let mut insert = |pieces: Vec<Vec<Brick>>| {
        for b in pieces.into_iter().flatten() {
            match b {
                Brick::Stored(at, values) => out
                    .insert_boxed(at, values)
                    .expect("a brick inside the brick grid, background past the grid"),
                Brick::Tile(at) => out.set_tile(at, true).expect("inside the brick grid"),
            }
        }
    };
    match band.reach() {
        Some(r) => {
            ctl.check()?;
            let t0 = std::time::Instant::now();
            let bins = bins::Bins::new(tris, bd, r);
            let bins_s = t0.elapsed().as_secs_f64();
            ctl.check()?;
            let planes: Vec<local::Plane> = tris
                .par_iter()
                .with_min_len(crate::PAR_PIECE)
                .map(local::Plane::new)
                .collect();
            let ctl_near = ctl.stage(0.05, 0.9);
            let counter = ctl_near.counter(bins.len() as u64);
            for piece in bins.groups().chunks(PIECE_BRICKS) {
                let near: Vec<Vec<Brick>> = piece
                    .par_chunks(16)
                    .map(|chunk| {
                        counter.check()?;
                        let mut out = Vec::new();
                        for &(key, lo, hi) in chunk {
                            let at = bins::unkey(key, bd);
                            let list = &bins.tris()[lo..hi];
                            out.extend(eval::band_brick(
                                tris, &planes, list, signs, dims, at, r, scale, background,
                            ));
                        }
                        counter.add(chunk.len() as u64);
                        Ok(out)
                    })
                    .collect::<Result<_, EngineError>>()?;
                insert(near);
            }
            tracing::debug!(
                bins_s,
                near_s = t0.elapsed().as_secs_f64() - bins_s,
                bricks = bins.len(),
                pairs = bins.tris().len(),
                "sdf band"
            );
            insert(far_bricks(
                signs,
                dims,
                &bins,
                background,
                &ctl.stage(0.9, 1.0),
            )?);
        }
        None => {
            let bins = bins::Bins::all(tris, bd);
            let total = u64::from(bd[0]) * u64::from(bd[1]) * u64::from(bd[2]);
            let counter = ctl.counter(total);
            let keys: Vec<u64> = (0..total).collect();
            let all: Vec<Vec<Brick>> = keys
                .par_chunks(16)
                .map(|chunk| {
                    counter.check()?;
                    let v = chunk
                        .iter()
                        .map(|&key| {
                            let at = bins::unkey(key, bd);
                            Brick::Stored(at, eval::all_brick(tris, &bins, signs, dims, at, scale))
                        })
                        .collect();
                    counter.add(chunk.len() as u64);
                    Ok(v)
                })
                .collect::<Result<_, EngineError>>()?;
            insert(all);
        }
    }
    ctl.complete();
    Ok(out)
}

/// The bricks no triangle reaches within the band (so none of their voxels is in it): a tile
/// where every voxel is inside, a stored brick of ±background where the solid has both.
fn far_bricks(
    signs: &Signs,
    dims: [u32; 3],
    bins: &bins::Bins,
    background: f32,
    ctl: &Control,
) -> Result<Vec<Vec<Brick>>, EngineError> {
    let bd = dims.map(|d| d.div_ceil(BRICK));
    let counter = ctl.counter(u64::from(bd[0]));
    let slabs: Vec<Vec<Brick>> = (0..bd[0])
        .into_par_iter()
        .map(|bx| {
            counter.check()?;
            let mut out = Vec::new();
            for by in 0..bd[1] {
                for bz in 0..bd[2] {
                    let at = [bx, by, bz];
                    let (a, l) = signs.brick(at);
                    if !a || bins.contains(bins::key(at, bd)) {
                        continue;
                    }
                    if l {
                        out.push(Brick::Tile(at));
                    } else {
                        out.push(Brick::Stored(
                            at,
                            eval::uniform_brick(signs, dims, at, background),
                        ));
                    }
                }
            }
            counter.add(1);
            Ok(out)
        })
        .collect::<Result<_, EngineError>>()?;
    Ok(slabs)
}

/// Is `p` strictly closer than `r` to some triangle of `list`, exactly?
fn in_band_exact(tris: &[[[i32; 3]; 3]], list: &[u32], p: [i64; 3], r: i64) -> bool {
    list.iter()
        .any(|&t| lattice::compare(p, &tris[t as usize], r) == Ordering::Less)
}
