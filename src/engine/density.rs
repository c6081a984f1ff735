//! `density`: each voxel split into f×f×f sub-voxels (f = 2: centres at ¼ and ¾ of the voxel; f = 4
//! for 0..64), the sub-voxel centres classified by `solid` on the f-times finer grid (whichever
//! engine runs it, the bits are the same), and the solid sub-voxels counted per voxel.

use rayon::prelude::*;

use super::fill::{self, Fill, FillReport};
use super::{Engine, EngineError};
use crate::cancel::{Canceled, Control};
use crate::grid::{Grid, GridError, GridLimits};
use crate::mesh::{Mesh, MeshDiagnostics};
use crate::volume::DensityVolume;

#[derive(Debug, thiserror::Error)]
pub enum DensityError {
    #[error("density needs a {factor}× finer grid: {source}")]
    Grid { factor: u32, source: GridError },
    #[error(transparent)]
    Engine(#[from] EngineError),
}

/// The grid `factor` times finer than `grid` over the same box, within `limits`.
pub fn fine_grid(grid: &Grid, factor: u32, limits: GridLimits) -> Result<Grid, GridError> {
    let dims = grid.dims.map(|d| d as u64 * factor as u64);
    if dims.iter().any(|&d| d > crate::grid::MAX_DIM as u64) {
        return Err(GridError::AxisTooLong { dims });
    }
    let voxels = dims.iter().map(|&d| d as u128).product::<u128>();
    if voxels > limits.max_voxels as u128 {
        let limit_desc = format!("{} voxels", limits.max_voxels);
        return Err(GridError::TooManyVoxels {
            dims,
            voxels,
            limit: limits.max_voxels,
            limit_desc,
        });
    }
    Ok(Grid {
        origin: grid.origin,
        voxel_size: grid.voxel_size / factor as f64,
        dims: dims.map(|d| d as u32),
    })
}

/// Density of `mesh` on `grid` with `factor` ∈ {2, 4}, computed by `engine` with the sub-voxels
/// classified by `fill` (the report's odd-parity columns are those of the finer grid); the finer
/// grid must fit `limits`.
pub fn density(
    engine: &dyn Engine,
    mesh: &Mesh,
    grid: &Grid,
    factor: u32,
    limits: GridLimits,
    fill: Fill,
    diagnostics: &MeshDiagnostics,
) -> Result<(DensityVolume, FillReport), DensityError> {
    density_with(
        engine,
        mesh,
        grid,
        factor,
        limits,
        fill,
        diagnostics,
        &Control::none(),
    )
}

/// [`density`], checking `ctl` in the fine solid (as its fill does) and per x-plane while
/// counting, and reporting progress there.
#[allow(clippy::too_many_arguments)]
pub fn density_with(
    engine: &dyn Engine,
    mesh: &Mesh,
    grid: &Grid,
    factor: u32,
    limits: GridLimits,
    fill: Fill,
    diagnostics: &MeshDiagnostics,
    ctl: &Control,
) -> Result<(DensityVolume, FillReport), DensityError> {
    assert!(factor == 2 || factor == 4, "density factor must be 2 or 4");
    let fine =
        fine_grid(grid, factor, limits).map_err(|source| DensityError::Grid { factor, source })?;
    let mut report = FillReport::new(fill, mesh, &fine, diagnostics);
    let (solid, stats) = fill::solid_with(engine, mesh, &fine, report.used, &ctl.stage(0.0, 0.9))?;
    report.winding = stats;
    let [_, ny, nz] = grid.dims;
    let (fy, wpc) = (fine.dims[1] as usize, solid.words_per_column());
    let words = solid.words();
    let f = factor as usize;
    let mask = (1u64 << f) - 1;
    let mut data = vec![0u8; grid.voxel_count() as usize];
    let planes = ctl.stage(0.9, 1.0).counter(grid.dims[0] as u64);
    data.par_chunks_mut(ny as usize * nz as usize)
        .enumerate()
        .try_for_each(|(x, plane)| {
            planes.check()?;
            for y in 0..ny as usize {
                let out = &mut plane[y * nz as usize..(y + 1) * nz as usize];
                for dx in 0..f {
                    for dy in 0..f {
                        let col = ((x * f + dx) * fy + (y * f + dy)) * wpc;
                        let col = &words[col..col + wpc];
                        for (z, o) in out.iter_mut().enumerate() {
                            let bit = z * f; // f divides 64: a group never straddles two words
                            *o += ((col[bit / 64] >> (bit % 64)) & mask).count_ones() as u8;
                        }
                    }
                }
            }
            planes.add(1);
            Ok::<_, Canceled>(())
        })
        .map_err(EngineError::from)?;
    ctl.complete();
    Ok((
        DensityVolume::from_data(*grid, (f * f * f) as u8, data).expect("counts fit the grid"),
        report,
    ))
}
