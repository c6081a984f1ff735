//! The CPU engine: the reference implementation of every method and the fallback when there is no
//! GPU. Work is split into bands of x-rows; each band owns a contiguous slice of the volume's
//! words, so threads never share a word. Triangles are binned to the bands their columns touch.

pub mod distance;
mod solid;
mod surface;

use std::ops::Range;

use rayon::prelude::*;

use super::{Engine, EngineError, GridMesh, Method};
pub(crate) use super::{axis_bounds, box_range, centre_range};
use crate::cancel::{Canceled, Control};
use crate::volume::BitVolume;

pub use solid::crossing_voxel;
pub use solid::odd_parity_columns;
pub(crate) use solid::signed_crossings;
pub use surface::triangle_overlaps_voxel;

#[derive(Clone, Copy, Debug, Default)]
pub struct CpuEngine;

impl Engine for CpuEngine {
    fn name(&self) -> &'static str {
        "cpu"
    }

    fn voxelize_with(
        &self,
        mesh: &GridMesh,
        method: Method,
        ctl: &Control,
    ) -> Result<BitVolume, EngineError> {
        Ok(match method {
            Method::Solid => solid::voxelize(mesh, ctl)?,
            Method::Surface => surface::voxelize(mesh, ctl)?,
            Method::Conservative | Method::Interior => {
                // The solid first, then its surface written into it: one volume, no pass to
                // combine two.
                let mut solid = solid::voxelize(mesh, &ctl.stage(0.0, 0.5))?;
                let add = method == Method::Conservative;
                surface::apply(mesh, &mut solid, add, &ctl.stage(0.5, 1.0))?;
                solid
            }
        })
    }

    fn apply_surface(
        &self,
        mesh: &GridMesh,
        vol: &mut BitVolume,
        add: bool,
        ctl: &Control,
    ) -> Result<(), EngineError> {
        Ok(surface::apply(mesh, vol, add, ctl)?)
    }
}

/// The fewest voxels of a band of [`for_each_band`] (but for a grid smaller than this).
const BAND_VOXELS: u64 = 1 << 16;

/// Runs `work(band, triangle indices, band words)` for every band of x-rows in parallel.
/// `x_range(t)` gives the inclusive x-range of columns triangle `t` can touch, or `None`.
/// `ctl` is checked before each band (bands not started once it says stop are skipped) and
/// hears each band done.
fn for_each_band<F>(
    mesh: &GridMesh,
    vol: &mut BitVolume,
    x_range: impl Fn(&[[i64; 3]; 3]) -> Option<(u32, u32)> + Sync,
    ctl: &Control,
    work: F,
) -> Result<(), Canceled>
where
    F: Fn(Range<u32>, &[u32], &mut [u64]) + Sync,
{
    let [nx, ny, nz] = mesh.grid.dims;
    let threads = rayon::current_num_threads().max(1) as u32;
    // Eight bands per thread, of at least `BAND_VOXELS` each: a small grid (a service's typical
    // job, its threads busy with other jobs) in few bands, since a triangle is binned (and
    // walked) once per band it spans. The bands do not change the result.
    let voxels = nx as u64 * ny as u64 * nz as u64;
    let bands = (threads * 8).min(voxels.div_ceil(BAND_VOXELS).max(1) as u32);
    let band_len = nx.div_ceil(bands).max(1);
    let nbands = nx.div_ceil(band_len) as usize;
    let ranges: Vec<Option<(u32, u32)>> = mesh
        .triangles
        .par_iter()
        .with_min_len(crate::PAR_PIECE)
        .map(|t| x_range(&widen(t)))
        .collect();
    let mut bins: Vec<Vec<u32>> = vec![Vec::new(); nbands];
    for (t, r) in ranges.iter().enumerate() {
        if let Some((x0, x1)) = *r {
            for b in (x0 / band_len)..=(x1 / band_len) {
                bins[b as usize].push(t as u32);
            }
        }
    }
    ctl.check()?;
    let chunk = band_len as usize * ny as usize * vol.words_per_column();
    let done = ctl.counter(nbands as u64);
    vol.words_mut()
        .par_chunks_mut(chunk)
        .zip(bins.par_iter())
        .enumerate()
        .try_for_each(|(b, (words, tris))| {
            done.check()?;
            let start = b as u32 * band_len;
            work(start..(start + band_len).min(nx), tris, words);
            done.add(1);
            Ok(())
        })
}

pub(crate) use super::widen;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges() {
        // Centres at 128, 384, 640, ...
        assert_eq!(centre_range(128, 384, 10), Some((0, 1)));
        assert_eq!(centre_range(129, 383, 10), None);
        assert_eq!(centre_range(-1000, 129, 10), Some((0, 0)));
        // Closed boxes [0,256], [256,512], ...: a value on a face touches both.
        assert_eq!(box_range(256, 256, 10), Some((0, 1)));
        assert_eq!(box_range(257, 511, 10), Some((1, 1)));
        assert_eq!(box_range(-300, -1, 10), None);
        assert_eq!(box_range(2560, 3000, 10), Some((9, 9)));
    }
}
