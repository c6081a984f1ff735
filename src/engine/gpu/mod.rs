//! The GPU engine: one `wgpu` device (a real GPU, or Mesa lavapipe on the CPU) kept for the life
//! of the process, with the WGSL kernels of `shaders/` compiled once. It produces exactly the bits
//! of [`crate::engine::cpu`]: the same snapped triangles, the same integer tie rules (i64 and
//! emulated 128-bit arithmetic, so it needs `SHADER_INT64`).
//!
//! Large grids are split along x into slabs that fit the device's storage-binding limit; meshes
//! upload in chunks that fit it too. Work is cut on the host into items of at most 1024 columns
//! (solid) or voxels (surface) per invocation, so no invocation comes near lavapipe's silent
//! 65,535-iteration loop cap (`README.md#architecture`).
//!
//! This module holds what the rest of voxd names whether or not the engine is built: the options
//! ([`GpuOptions`], [`SolidStrategy`]) and the statistics ([`GpuStats`], [`GpuTimings`]). The
//! engine itself (`GpuEngine`, wgpu and the shaders) is built only with the `gpu` Cargo feature
//! (on by default); without it `engine::open` answers `--engine gpu` with
//! [`EngineError::NoDevice`](crate::engine::EngineError::NoDevice) and `auto` uses the CPU.
//! Not here: the rules the bits follow (`engine/cpu/`, the oracle).

#[cfg(feature = "gpu")]
mod batch;
#[cfg(feature = "gpu")]
pub(crate) mod device;
#[cfg(feature = "gpu")]
mod engine;
#[cfg(feature = "gpu")]
mod pool;
#[cfg(feature = "gpu")]
mod work;

use std::time::Duration;

#[cfg(feature = "gpu")]
pub use device::AdapterSummary;
#[cfg(feature = "gpu")]
pub use engine::GpuEngine;

/// Settings of the GPU engine.
#[derive(Clone, Debug, Default)]
pub struct GpuOptions {
    /// Substring of the adapter name to use (case-insensitive), e.g. "llvmpipe"; `VOXD_ADAPTER`.
    pub adapter: Option<String>,
    /// Cap on one slab's bytes, below the device's limit; tests use it to force many slabs.
    pub max_slab_bytes: Option<u64>,
    /// Cap on one triangle chunk's bytes; tests use it to force several chunks.
    pub max_chunk_bytes: Option<u64>,
    /// Idle buffers kept for the next jobs, in bytes; [`POOL_BYTES`] when `None`.
    pub pool_bytes: Option<u64>,
    /// How solid turns crossings into parity.
    pub solid_strategy: SolidStrategy,
    /// Only a hardware adapter (discrete, integrated or virtual GPU): a software one such as
    /// lavapipe counts as none. What `--engine auto` asks for when no adapter is named.
    pub hardware_only: bool,
}

crate::named_enum! {
    /// Two ways to turn crossings into parity on the GPU; both give the same bits.
    #[derive(Default)]
    pub enum SolidStrategy: "solid strategy" {
        /// One atomic XOR of a single bit per crossing, then a prefix-XOR pass up each column.
        /// The default: faster in every measurement so far (`docs/benchmarks-history.md`,
        /// `#solid-toggle--prefix-xor-vs-atomic-xor-of-masks-lavapipe-igea-subdiv4`).
        #[default]
        ToggleScan = "scan",
        /// Atomic XOR of all the words above each crossing; no scan pass.
        Masks = "masks",
    }
}

/// Where the time of one voxelization went.
#[derive(Clone, Copy, Debug, Default)]
pub struct GpuTimings {
    /// Building work items and writing triangles and items to the device.
    pub upload: Duration,
    /// Kernels, from submission to completion.
    pub dispatch: Duration,
    /// Mapping the results and copying them into the volume.
    pub readback: Duration,
    pub slabs: u32,
}

/// What the engine's device has done since it was opened: batches of submissions and buffer
/// reuse (for benchmarks, metrics and tests).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GpuStats {
    pub submissions: BatchStats,
    pub buffers: PoolStats,
}

/// What the batches have been: for metrics, benchmarks and tests.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BatchStats {
    /// Batches run (device submissions).
    pub batches: u64,
    /// Items in them (command buffers).
    pub items: u64,
    /// Items in the largest batch.
    pub largest: u64,
}

/// Idle buffers the pool keeps, in bytes (of their size classes).
pub const POOL_BYTES: u64 = 256 << 20;

/// Counts of what the pool did, for benchmarks and tests.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PoolStats {
    /// Buffers created because no idle one of their class was there.
    pub created: u64,
    /// Leases served by an idle buffer.
    pub reused: u64,
    /// Idle buffers held now, and their bytes.
    pub idle: u64,
    pub idle_bytes: u64,
}
