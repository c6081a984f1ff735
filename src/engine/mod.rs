//! Engines turn a mesh on a grid into a volume. Every engine consumes the same [`GridMesh`]
//! (vertices snapped to a fixed-point lattice by [`GridMesh::new`]) and must produce the same bits:
//! the rules in `docs/methods.md` are implemented once here and in `cpu/`, which is the oracle the
//! GPU engine is tested against. Engines know nothing of files or HTTP. The GPU engine is built
//! only with the `gpu` Cargo feature (see [`gpu`]).

pub mod colour;
pub mod cpu;
pub mod density;
pub mod distance;
#[cfg(test)]
pub(crate) mod exact;
pub mod fill;
pub(crate) mod geom;
pub mod gpu;
pub mod hermite;
pub mod sdf;
mod snap;
pub mod winding;

pub use snap::{FIXED_HALF, FIXED_ONE, FIXED_SHIFT, GridMesh, MAX_FIXED};

use crate::cancel::{Canceled, Control};
use crate::volume::BitVolume;

crate::named_enum! {
    /// What a voxel being set means.
    pub enum Method: "method" {
        /// The voxel centre is inside (odd number of crossings on the ray towards −z).
        Solid = "solid",
        /// The closed voxel box touches the surface.
        Surface = "surface",
        /// `solid ∪ surface`.
        Conservative = "conservative",
        /// `solid − surface`.
        Interior = "interior",
    }
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum EngineError {
    #[error("no GPU: {0}")]
    NoDevice(String),
    #[error("GPU engine: {0}")]
    Gpu(String),
    #[error("mesh vertex {vertex} lies {voxels:.0} voxels from the grid; at most {max} are supported (crop the mesh or use a coarser or larger grid)", max = MAX_FIXED >> FIXED_SHIFT)]
    OutOfRange { vertex: usize, voxels: f64 },
    /// The work was canceled or ran past its deadline ([`Control::check`]).
    #[error(transparent)]
    Canceled(Canceled),
}

impl From<Canceled> for EngineError {
    fn from(c: Canceled) -> Self {
        EngineError::Canceled(c)
    }
}

/// A voxelization engine.
pub trait Engine: Send + Sync {
    /// Short name for logs and summaries (`cpu`, `gpu`).
    fn name(&self) -> &'static str;
    /// What it runs on, for summaries: the adapter for the GPU engine.
    fn describe(&self) -> String {
        self.name().to_string()
    }
    /// [`Engine::voxelize_with`] for a caller that neither cancels nor watches progress.
    fn voxelize(&self, mesh: &GridMesh, method: Method) -> Result<BitVolume, EngineError> {
        self.voxelize_with(mesh, method, &Control::none())
    }
    /// Voxelizes, checking `ctl` at the engine's natural points (CPU bands, GPU slabs) and
    /// reporting progress there; [`EngineError::Canceled`] once it says stop.
    fn voxelize_with(
        &self,
        mesh: &GridMesh,
        method: Method,
        ctl: &Control,
    ) -> Result<BitVolume, EngineError>;
    /// Adds `mesh`'s surface to `vol` (`conservative`) or takes it away (`interior`): `vol` is a
    /// solid on `mesh`'s grid. By default a surface volume of its own, combined; the CPU engine
    /// writes into `vol` directly (no second volume, no pass over both).
    fn apply_surface(
        &self,
        mesh: &GridMesh,
        vol: &mut BitVolume,
        add: bool,
        ctl: &Control,
    ) -> Result<(), EngineError> {
        let surface = self.voxelize_with(mesh, Method::Surface, ctl)?;
        if add {
            vol.union_with(&surface);
        } else {
            vol.subtract(&surface);
        }
        Ok(())
    }
    /// `distance`: the voxels whose centres lie within `thickness` lattice units (0..=
    /// [`distance::MAX_LATTICE`], from [`distance::thickness_lattice`]) of a triangle, exactly
    /// (ties set). By default the CPU engine's; checks `ctl` like [`Engine::voxelize_with`].
    fn distance_with(
        &self,
        mesh: &GridMesh,
        thickness: i64,
        ctl: &Control,
    ) -> Result<BitVolume, EngineError> {
        Ok(cpu::distance::voxelize(mesh, thickness, ctl)?)
    }
    /// The GPU engine's submissions and buffer reuse (for metrics); `None` for other engines.
    fn gpu_stats(&self) -> Option<gpu::GpuStats> {
        None
    }
}

crate::named_enum! {
    /// Which engine to use (`--engine`).
    pub enum EngineChoice: "engine" {
        /// The GPU engine on a hardware adapter when one exists, else the CPU engine. A software
        /// adapter (lavapipe) is used only when asked for (`gpu`, or an adapter named): on every
        /// measurement so far it is slower than the CPU engine on the same cores.
        Auto = "auto",
        Gpu = "gpu",
        Cpu = "cpu",
    }
}

impl EngineChoice {
    /// What `--engine` is when not given (`voxelize` and `serve`).
    pub const DEFAULT: EngineChoice = EngineChoice::Auto;
}

/// Opens the chosen engine. `Auto` never fails: without a hardware adapter (or the one
/// named) it uses the CPU engine and logs why: at `info` when only a software adapter exists
/// (the expected case on a machine without a GPU), as a warning otherwise. Built without the
/// `gpu` feature, `Gpu` is [`EngineError::NoDevice`] and `Auto` is the CPU engine.
pub fn open(choice: EngineChoice, gpu: gpu::GpuOptions) -> Result<Box<dyn Engine>, EngineError> {
    match choice {
        EngineChoice::Cpu => Ok(Box::new(cpu::CpuEngine)),
        EngineChoice::Gpu => open_gpu(gpu),
        // Nothing to try, so nothing to log.
        EngineChoice::Auto if !cfg!(feature = "gpu") => Ok(Box::new(cpu::CpuEngine)),
        EngineChoice::Auto => {
            let options = gpu::GpuOptions {
                // A named adapter is an explicit request, software or not.
                hardware_only: gpu.adapter.is_none(),
                ..gpu
            };
            match open_gpu(options) {
                Ok(e) => Ok(e),
                #[cfg(feature = "gpu")]
                Err(EngineError::NoDevice(why)) if why.starts_with(gpu::device::NO_HARDWARE) => {
                    tracing::info!("{why}; using the CPU engine (--engine gpu uses them)");
                    Ok(Box::new(cpu::CpuEngine))
                }
                Err(e) => {
                    tracing::warn!("{e}; using the CPU engine");
                    Ok(Box::new(cpu::CpuEngine))
                }
            }
        }
    }
}

/// Why `--engine gpu` fails in a build without the `gpu` feature.
#[cfg(not(feature = "gpu"))]
const NO_GPU_FEATURE: &str = "this voxd was built without the gpu feature (cargo build --features gpu); use --engine cpu or auto";

#[cfg(feature = "gpu")]
fn open_gpu(options: gpu::GpuOptions) -> Result<Box<dyn Engine>, EngineError> {
    Ok(Box::new(gpu::GpuEngine::new(options)?))
}

#[cfg(not(feature = "gpu"))]
fn open_gpu(_: gpu::GpuOptions) -> Result<Box<dyn Engine>, EngineError> {
    Err(EngineError::NoDevice(NO_GPU_FEATURE.to_string()))
}

/// Triangle vertices as i64 for arithmetic.
pub(crate) fn widen(t: &[[i32; 3]; 3]) -> [[i64; 3]; 3] {
    t.map(|p| p.map(i64::from))
}

/// Inclusive range of cells `i` (clamped to `0..n`) whose centre `256 i + 128` lies in `[lo, hi]`.
pub(crate) fn centre_range(lo: i64, hi: i64, n: u32) -> Option<(u32, u32)> {
    let a = (lo - FIXED_HALF).div_euclid(FIXED_ONE)
        + i64::from((lo - FIXED_HALF).rem_euclid(FIXED_ONE) != 0);
    let b = (hi - FIXED_HALF).div_euclid(FIXED_ONE);
    clamp_range(a, b, n)
}

/// Inclusive range of cells `i` (clamped to `0..n`) whose closed extent `[256 i, 256 i + 256]`
/// meets `[lo, hi]`.
pub(crate) fn box_range(lo: i64, hi: i64, n: u32) -> Option<(u32, u32)> {
    let a = (lo - FIXED_ONE).div_euclid(FIXED_ONE)
        + i64::from((lo - FIXED_ONE).rem_euclid(FIXED_ONE) != 0);
    let b = hi.div_euclid(FIXED_ONE);
    clamp_range(a, b, n)
}

pub(crate) fn clamp_range(a: i64, b: i64, n: u32) -> Option<(u32, u32)> {
    let (a, b) = (a.max(0), b.min(n as i64 - 1));
    (a <= b).then_some((a as u32, b as u32))
}

pub(crate) fn axis_bounds(v: &[[i64; 3]; 3], a: usize) -> (i64, i64) {
    (
        v[0][a].min(v[1][a]).min(v[2][a]),
        v[0][a].max(v[1][a]).max(v[2][a]),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Without the `gpu` feature, asking for the GPU says why there is none, and `auto` is the
    /// CPU engine.
    #[test]
    #[cfg(not(feature = "gpu"))]
    fn without_the_gpu_feature_gpu_is_refused_and_auto_is_the_cpu() {
        match open(EngineChoice::Gpu, gpu::GpuOptions::default()) {
            Err(EngineError::NoDevice(why)) => {
                assert!(why.contains("built without the gpu feature"), "{why}")
            }
            Err(e) => panic!("{e}"),
            Ok(e) => panic!("opened {}", e.name()),
        }
        let auto = open(EngineChoice::Auto, gpu::GpuOptions::default()).unwrap();
        assert_eq!(auto.name(), "cpu");
    }

    #[test]
    fn cpu_is_the_cpu_engine() {
        let e = open(EngineChoice::Cpu, gpu::GpuOptions::default()).unwrap();
        assert_eq!(e.name(), "cpu");
    }
}
