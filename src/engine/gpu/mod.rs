//! The GPU engine: one `wgpu` device (a real GPU, or Mesa lavapipe on the CPU) kept for the life
//! of the process, with the WGSL kernels of `shaders/` compiled once. It produces exactly the bits
//! of [`crate::engine::cpu`]: the same snapped triangles, the same integer tie rules (i64 and
//! emulated 128-bit arithmetic, so it needs `SHADER_INT64`).
//!
//! Large grids are split along x into slabs that fit the device's storage-binding limit; meshes
//! upload in chunks that fit it too. Work is cut on the host into items of at most 1024 columns
//! (solid) or voxels (surface) per invocation, so no invocation comes near lavapipe's silent
//! 65,535-iteration loop cap (`docs/lavapipe-notes.md`).

pub(crate) mod device;
mod work;

use std::sync::Mutex;
use std::time::{Duration, Instant};

pub use device::AdapterSummary;
use device::GpuDevice;
use wgpu::util::DeviceExt;

use super::{Engine, EngineError, GridMesh, Method};
use crate::cancel::Control;
use crate::volume::{BitVolume, words_per_column};

/// Settings of the GPU engine.
#[derive(Clone, Debug, Default)]
pub struct GpuOptions {
    /// Substring of the adapter name to use (case-insensitive), e.g. "llvmpipe"; `VOXD_ADAPTER`.
    pub adapter: Option<String>,
    /// Cap on one slab's bytes, below the device's limit; tests use it to force many slabs.
    pub max_slab_bytes: Option<u64>,
    /// Cap on one triangle chunk's bytes; tests use it to force several chunks.
    pub max_chunk_bytes: Option<u64>,
    /// How solid turns crossings into parity.
    pub solid_strategy: SolidStrategy,
    /// Only a hardware adapter (discrete, integrated or virtual GPU): a software one such as
    /// lavapipe counts as none. What `--engine auto` asks for when no adapter is named.
    pub hardware_only: bool,
}

/// Two ways to turn crossings into parity on the GPU; both give the same bits.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SolidStrategy {
    /// One atomic XOR of a single bit per crossing, then a prefix-XOR pass up each column. The
    /// default: faster in every measurement so far (docs/benchmarks.md).
    #[default]
    ToggleScan,
    /// Atomic XOR of all the words above each crossing; no scan pass.
    Masks,
}

impl crate::names::Named for SolidStrategy {
    const WHAT: &'static str = "solid strategy";
    const ALL: &'static [SolidStrategy] = &[SolidStrategy::ToggleScan, SolidStrategy::Masks];
    fn name(self) -> &'static str {
        match self {
            SolidStrategy::ToggleScan => "scan",
            SolidStrategy::Masks => "masks",
        }
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

pub struct GpuEngine {
    options: GpuOptions,
    device: Mutex<GpuDevice>,
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    dims: [u32; 3],
    slab_x0: u32,
    slab_rows: u32,
    words_per_column: u32,
    item_count: u32,
    item_offset: u32,
}

impl GpuEngine {
    /// Opens the best adapter that supports 64-bit integers in shaders (discrete, then
    /// integrated, then virtual, then CPU such as lavapipe), or the one `options.adapter` names.
    pub fn new(options: GpuOptions) -> Result<GpuEngine, EngineError> {
        let device = GpuDevice::open(options.adapter.as_deref(), options.hardware_only)?;
        Ok(GpuEngine {
            options,
            device: Mutex::new(device),
        })
    }

    pub fn adapter(&self) -> AdapterSummary {
        self.device
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .summary
            .clone()
    }

    /// Voxelizes and reports where the time went.
    pub fn voxelize_timed(
        &self,
        mesh: &GridMesh,
        method: Method,
    ) -> Result<(BitVolume, GpuTimings), EngineError> {
        self.voxelize_timed_with(mesh, method, &Control::none())
    }

    /// [`GpuEngine::voxelize_timed`], checking `ctl` before each slab (a submitted slab runs to
    /// its end: kernels are not interruptible) and reporting each slab done.
    pub fn voxelize_timed_with(
        &self,
        mesh: &GridMesh,
        method: Method,
        ctl: &Control,
    ) -> Result<(BitVolume, GpuTimings), EngineError> {
        ctl.check()?;
        let mut guard = self.device.lock().unwrap_or_else(|e| e.into_inner());
        if guard.is_lost() {
            tracing::warn!("GPU device was lost; opening it again");
            *guard = GpuDevice::open(self.options.adapter.as_deref(), self.options.hardware_only)?;
        }
        let dev = &*guard;
        let scope = dev.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let oom = dev.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let result = self.run(dev, mesh, method, ctl);
        let oom_err = pollster::block_on(oom.pop());
        let val_err = pollster::block_on(scope.pop());
        if let Some(e) = oom_err.or(val_err) {
            return Err(EngineError::Gpu(format!(
                "the GPU reported: {}",
                device::describe(&e)
            )));
        }
        if dev.is_lost() {
            return Err(EngineError::Gpu(
                "the GPU device was lost during the job; it will be reopened for the next one"
                    .into(),
            ));
        }
        result
    }

    fn run(
        &self,
        dev: &GpuDevice,
        mesh: &GridMesh,
        method: Method,
        ctl: &Control,
    ) -> Result<(BitVolume, GpuTimings), EngineError> {
        let grid = mesh.grid;
        let [nx, ny, nz] = grid.dims;
        let mut vol = BitVolume::new(grid);
        let wpc32 = 2 * words_per_column(nz) as u64;
        let row_bytes = ny as u64 * wpc32 * 4;
        let binding = dev.limits.max_storage_buffer_binding_size;
        let slab_limit = self
            .options
            .max_slab_bytes
            .map_or(binding, |m| m.min(binding))
            .min(dev.limits.max_buffer_size);
        if row_bytes > slab_limit {
            return Err(EngineError::Gpu(format!(
                "one x-row of this grid takes {row_bytes} bytes, more than this device binds at once ({slab_limit}); use fewer voxels along y or z"
            )));
        }
        let slab_rows = (slab_limit / row_bytes).min(nx as u64) as u32;
        let slab_bytes = slab_rows as u64 * row_bytes;
        let mut timings = GpuTimings::default();

        let t0 = Instant::now();
        let chunk_limit = self
            .options
            .max_chunk_bytes
            .map_or(binding, |m| m.min(binding));
        let tris_per_chunk = (chunk_limit / 36).max(1) as usize;
        let chunks: Vec<(usize, wgpu::Buffer)> = mesh
            .triangles
            .chunks(tris_per_chunk)
            .enumerate()
            .map(|(i, c)| {
                let contents: &[u8] = if c.is_empty() {
                    &[0u8; 36]
                } else {
                    bytemuck::cast_slice(c)
                };
                let buf = dev
                    .device
                    .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                        label: Some("triangles"),
                        contents,
                        usage: wgpu::BufferUsages::STORAGE,
                    });
                (i * tris_per_chunk, buf)
            })
            .collect();
        timings.upload += t0.elapsed();

        let storage = |label| {
            dev.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: slab_bytes,
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_SRC
                    | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        let need_solid = method != Method::Surface;
        let need_surface = method != Method::Solid;
        let slab_a = storage("slab a");
        let slab_b = (need_solid && need_surface).then(|| storage("slab b"));
        let staging = dev.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size: slab_bytes,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });

        let words64_per_row = ny as usize * words_per_column(nz);
        let done = ctl.counter(nx.div_ceil(slab_rows.max(1)) as u64);
        for x0 in (0..nx).step_by(slab_rows as usize) {
            done.check()?;
            let rows = slab_rows.min(nx - x0);
            let params = Params {
                dims: [nx, ny, nz],
                slab_x0: x0,
                slab_rows: rows,
                words_per_column: wpc32 as u32,
                item_count: 0,
                item_offset: 0,
            };
            let t_up = Instant::now();
            let mut enc = dev.device.create_command_encoder(&Default::default());
            enc.clear_buffer(&slab_a, 0, None);
            if let Some(b) = &slab_b {
                enc.clear_buffer(b, 0, None);
            }
            let xr = x0..x0 + rows;
            for (base, tris) in &chunks {
                let n = tris_per_chunk.min(mesh.triangles.len() - base);
                let part = &mesh.triangles[*base..*base + n];
                if need_solid {
                    let masks = self.options.solid_strategy == SolidStrategy::Masks;
                    // With masks a crossing touches up to every word of its column: fewer columns
                    // per item keep the invocation under the loop cap.
                    let side = if masks {
                        (work::MAX_TILE * 16 / wpc32 as u32).clamp(1, 1024).isqrt()
                    } else {
                        32
                    };
                    let items = work::solid_items(part, xr.clone(), grid.dims, side);
                    let pipeline = if masks { &dev.solid_masks } else { &dev.solid };
                    self.dispatch_items(dev, &mut enc, pipeline, &params, tris, &items, 4, &slab_a);
                }
                if need_surface {
                    let items = work::surface_items(part, xr.clone(), grid.dims);
                    let target = slab_b.as_ref().unwrap_or(&slab_a);
                    self.dispatch_items(
                        dev,
                        &mut enc,
                        &dev.surface,
                        &params,
                        tris,
                        &items,
                        5,
                        target,
                    );
                }
            }
            if need_solid && self.options.solid_strategy == SolidStrategy::ToggleScan {
                let cols = rows * ny;
                let u = self.uniform(dev, &params);
                let bind = [(0, u.as_entire_binding()), (1, slab_a.as_entire_binding())];
                dispatch(dev, &mut enc, &dev.prefix_xor, &bind, cols);
            }
            if let Some(b) = &slab_b {
                let pipeline = if method == Method::Interior {
                    &dev.subtract
                } else {
                    &dev.union
                };
                let u = self.uniform(dev, &params);
                let bind = [
                    (0, u.as_entire_binding()),
                    (1, slab_a.as_entire_binding()),
                    (2, b.as_entire_binding()),
                ];
                dispatch(
                    dev,
                    &mut enc,
                    pipeline,
                    &bind,
                    (rows as u64 * row_bytes / 4) as u32,
                );
            }
            let bytes = rows as u64 * row_bytes;
            enc.copy_buffer_to_buffer(&slab_a, 0, &staging, 0, bytes);
            timings.upload += t_up.elapsed();

            let t_run = Instant::now();
            dev.queue.submit([enc.finish()]);
            let slice = staging.slice(..bytes);
            let (tx, rx) = std::sync::mpsc::channel();
            slice.map_async(wgpu::MapMode::Read, move |r| {
                let _ = tx.send(r);
            });
            dev.device
                .poll(wgpu::PollType::wait_indefinitely())
                .map_err(|e| EngineError::Gpu(format!("waiting for the GPU: {e}")))?;
            rx.recv()
                .map_err(|_| EngineError::Gpu("the readback was dropped".into()))?
                .map_err(|e| EngineError::Gpu(format!("mapping the result: {e}")))?;
            timings.dispatch += t_run.elapsed();

            let t_read = Instant::now();
            {
                let view = slice
                    .get_mapped_range()
                    .map_err(|e| EngineError::Gpu(format!("reading the result: {e}")))?;
                let start = x0 as usize * words64_per_row;
                let dst = &mut vol.words_mut()[start..start + rows as usize * words64_per_row];
                bytemuck::cast_slice_mut::<u64, u8>(dst).copy_from_slice(&view);
            }
            staging.unmap();
            timings.readback += t_read.elapsed();
            timings.slabs += 1;
            done.add(1);
        }
        Ok((vol, timings))
    }

    fn uniform(&self, dev: &GpuDevice, p: &Params) -> wgpu::Buffer {
        dev.device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("params"),
                contents: bytemuck::bytes_of(p),
                usage: wgpu::BufferUsages::UNIFORM,
            })
    }

    #[allow(clippy::too_many_arguments)]
    fn dispatch_items(
        &self,
        dev: &GpuDevice,
        enc: &mut wgpu::CommandEncoder,
        pipeline: &wgpu::ComputePipeline,
        params: &Params,
        tris: &wgpu::Buffer,
        items: &[u32],
        stride: usize,
        target: &wgpu::Buffer,
    ) {
        let binding = dev.limits.max_storage_buffer_binding_size as usize;
        let per_batch = (binding / (4 * stride)).min(1 << 26);
        for batch in items.chunks(per_batch * stride) {
            let count = (batch.len() / stride) as u32;
            let buf = dev
                .device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("items"),
                    contents: bytemuck::cast_slice(batch),
                    usage: wgpu::BufferUsages::STORAGE,
                });
            let p = Params {
                item_count: count,
                ..*params
            };
            let u = self.uniform(dev, &p);
            let bind = [
                (0, u.as_entire_binding()),
                (1, tris.as_entire_binding()),
                (2, buf.as_entire_binding()),
                (3, target.as_entire_binding()),
            ];
            dispatch(dev, enc, pipeline, &bind, count);
        }
    }
}

/// Records one dispatch of `invocations` 64-wide invocations (2D when over 65,535 groups).
fn dispatch(
    dev: &GpuDevice,
    enc: &mut wgpu::CommandEncoder,
    pipeline: &wgpu::ComputePipeline,
    bind: &[(u32, wgpu::BindingResource<'_>)],
    invocations: u32,
) {
    if invocations == 0 {
        return;
    }
    let entries: Vec<wgpu::BindGroupEntry> = bind
        .iter()
        .map(|(b, r)| wgpu::BindGroupEntry {
            binding: *b,
            resource: r.clone(),
        })
        .collect();
    let group = dev.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: None,
        layout: &pipeline.get_bind_group_layout(0),
        entries: &entries,
    });
    let groups = invocations.div_ceil(64);
    let mut pass = enc.begin_compute_pass(&Default::default());
    pass.set_pipeline(pipeline);
    pass.set_bind_group(0, &group, &[]);
    pass.dispatch_workgroups(groups.min(65535), groups.div_ceil(65535), 1);
}

impl Engine for GpuEngine {
    fn name(&self) -> &'static str {
        "gpu"
    }
    fn describe(&self) -> String {
        format!("gpu ({})", self.adapter().name)
    }
    fn voxelize_with(
        &self,
        mesh: &GridMesh,
        method: Method,
        ctl: &Control,
    ) -> Result<BitVolume, EngineError> {
        self.voxelize_timed_with(mesh, method, ctl).map(|(v, _)| v)
    }
}
