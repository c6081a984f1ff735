//! The GPU engine's implementation (built with the `gpu` feature): [`GpuEngine`] on the one
//! device of [`device`], recording each slab's work into pooled buffers ([`pool`]), cutting
//! triangles into bounded items ([`work`]) and handing the recordings to the batcher
//! ([`batch`]). The options and statistics it reads and reports are the parent module's, which
//! is built without the feature too.

use std::sync::{Arc, Mutex};
use std::time::Instant;

use super::device::{AdapterSummary, GpuDevice};
use super::pool::Leases;
use super::{GpuOptions, GpuStats, GpuTimings, SolidStrategy};
use super::{device, work};
use crate::cancel::Control;
use crate::engine::distance::MAX_LATTICE;
use crate::engine::{Engine, EngineError, GridMesh, Method};
use crate::volume::{BitVolume, words_per_column};

pub struct GpuEngine {
    options: GpuOptions,
    /// The device the next job runs on: replaced when it is lost. Jobs run on it at once, each
    /// on its own thread; their submissions are batched ([`batch`]).
    device: Mutex<Arc<GpuDevice>>,
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
    /// `distance`'s threshold in lattice units (0 for the others).
    thickness: u32,
    /// To the uniform block's size (a multiple of 16 bytes).
    _pad: [u32; 3],
}

/// What a job computes: a method's bits, or `distance`'s with its threshold (lattice units).
#[derive(Clone, Copy, Debug, PartialEq)]
enum Job {
    Method(Method),
    Distance(i64),
}

/// One slab's recorded work, handed to the batcher: the device runs `commands`, after which
/// the first `bytes` of `readback` hold the slab.
pub(super) struct Submission {
    commands: wgpu::CommandBuffer,
    readback: wgpu::Buffer,
    bytes: u64,
}

const SLAB_USAGE: wgpu::BufferUsages = wgpu::BufferUsages::STORAGE
    .union(wgpu::BufferUsages::COPY_SRC)
    .union(wgpu::BufferUsages::COPY_DST);
const INPUT_USAGE: wgpu::BufferUsages =
    wgpu::BufferUsages::STORAGE.union(wgpu::BufferUsages::COPY_DST);
const PARAMS_USAGE: wgpu::BufferUsages =
    wgpu::BufferUsages::UNIFORM.union(wgpu::BufferUsages::COPY_DST);
const READBACK_USAGE: wgpu::BufferUsages =
    wgpu::BufferUsages::MAP_READ.union(wgpu::BufferUsages::COPY_DST);

/// The first `size` bytes of `buffer`, to bind (a pooled buffer may be larger than its use).
fn bound(buffer: &wgpu::Buffer, size: u64) -> wgpu::BindingResource<'_> {
    wgpu::BindingResource::Buffer(wgpu::BufferBinding {
        buffer,
        offset: 0,
        size: Some(std::num::NonZeroU64::new(size).expect("bindings are never empty")),
    })
}

impl GpuEngine {
    /// Opens the best adapter that supports 64-bit integers in shaders (discrete, then
    /// integrated, then virtual, then CPU such as lavapipe), or the one `options.adapter` names.
    pub fn new(options: GpuOptions) -> Result<GpuEngine, EngineError> {
        let device = GpuDevice::open(&options)?;
        Ok(GpuEngine {
            options,
            device: Mutex::new(Arc::new(device)),
        })
    }

    /// The device for the next job: the one open, or a new one if it was lost.
    fn device(&self) -> Result<Arc<GpuDevice>, EngineError> {
        let mut guard = self.device.lock().unwrap_or_else(|e| e.into_inner());
        if guard.is_lost() {
            tracing::warn!("GPU device was lost; opening it again");
            *guard = Arc::new(GpuDevice::open(&self.options)?);
        }
        Ok(guard.clone())
    }

    /// The device open now (lost or not).
    fn current(&self) -> Arc<GpuDevice> {
        self.device
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }

    pub fn adapter(&self) -> AdapterSummary {
        self.current().summary.clone()
    }

    /// Submissions and buffer reuse on the open device.
    pub fn stats(&self) -> GpuStats {
        let dev = self.current();
        GpuStats {
            submissions: dev.batcher.stats(),
            buffers: dev.pool.stats(),
        }
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
    /// its end: kernels are not interruptible) and reporting each slab done. Calls from several
    /// threads run at once: each records its own work, and their submissions are batched.
    pub fn voxelize_timed_with(
        &self,
        mesh: &GridMesh,
        method: Method,
        ctl: &Control,
    ) -> Result<(BitVolume, GpuTimings), EngineError> {
        self.job(mesh, Job::Method(method), ctl)
    }

    /// `distance` with threshold `thickness` (lattice units, 0..=[`MAX_LATTICE`]), slab by slab
    /// as [`GpuEngine::voxelize_timed_with`]; the same bits as the CPU engine's.
    pub fn distance_timed_with(
        &self,
        mesh: &GridMesh,
        thickness: i64,
        ctl: &Control,
    ) -> Result<(BitVolume, GpuTimings), EngineError> {
        assert!(
            (0..=MAX_LATTICE).contains(&thickness),
            "thickness {thickness} out of 0..={MAX_LATTICE}"
        );
        self.job(mesh, Job::Distance(thickness), ctl)
    }

    fn job(
        &self,
        mesh: &GridMesh,
        job: Job,
        ctl: &Control,
    ) -> Result<(BitVolume, GpuTimings), EngineError> {
        ctl.check()?;
        let dev = self.device()?;
        let mut leases = Leases::new(&dev.pool);
        // This job's buffers (and, when this thread leads a batch, that batch's submission);
        // each slab's recording has a scope of its own (`run`).
        let result = scoped(&dev, || self.run(&dev, &mut leases, mesh, job, ctl))?;
        if dev.is_lost() {
            return Err(EngineError::Gpu(
                "the GPU device was lost during the job; it will be reopened for the next one"
                    .into(),
            ));
        }
        leases.recycle();
        Ok(result)
    }

    fn run(
        &self,
        dev: &GpuDevice,
        leases: &mut Leases<'_>,
        mesh: &GridMesh,
        job: Job,
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
        let chunks: Vec<(usize, wgpu::Buffer, u64)> = mesh
            .triangles
            .chunks(tris_per_chunk)
            .enumerate()
            .map(|(i, c)| {
                let contents: &[u8] = if c.is_empty() {
                    &[0u8; 36]
                } else {
                    bytemuck::cast_slice(c)
                };
                let buf =
                    leases.filled(&dev.device, &dev.queue, "triangles", INPUT_USAGE, contents);
                (i * tris_per_chunk, buf, contents.len() as u64)
            })
            .collect();
        timings.upload += t0.elapsed();

        let (method, thickness) = match job {
            Job::Method(m) => (Some(m), None),
            Job::Distance(t) => (None, Some(t)),
        };
        let need_solid = method.is_some_and(|m| m != Method::Surface);
        let need_surface = method.is_some_and(|m| m != Method::Solid);
        let slab_a = leases.take(&dev.device, "slab a", SLAB_USAGE, slab_bytes);
        let slab_b = (need_solid && need_surface)
            .then(|| leases.take(&dev.device, "slab b", SLAB_USAGE, slab_bytes));
        let staging = leases.take(&dev.device, "readback", READBACK_USAGE, slab_bytes);

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
                thickness: thickness.unwrap_or(0) as u32,
                _pad: [0; 3],
            };
            let t_up = Instant::now();
            // This slab's work items and parameters: back to the pool once it has run.
            let mut inputs = Leases::new(&dev.pool);
            let bytes = rows as u64 * row_bytes;
            // Its own error scope: a slab whose recording the GPU refused (a buffer it could
            // not create, say) fails here, and its inputs are freed, not given back to the pool.
            let commands = scoped(dev, || {
                let mut rec = Recorder {
                    dev,
                    leases: &mut inputs,
                    enc: dev.device.create_command_encoder(&Default::default()),
                    slab_bytes,
                };
                rec.enc.clear_buffer(&slab_a, 0, Some(slab_bytes));
                if let Some(b) = &slab_b {
                    rec.enc.clear_buffer(b, 0, Some(slab_bytes));
                }
                let xr = x0..x0 + rows;
                for (base, tris, tri_bytes) in &chunks {
                    let n = tris_per_chunk.min(mesh.triangles.len() - base);
                    let part = &mesh.triangles[*base..*base + n];
                    let tris = (tris, *tri_bytes);
                    if need_solid {
                        let masks = self.options.solid_strategy == SolidStrategy::Masks;
                        // With masks a crossing touches up to every word of its column: fewer
                        // columns per item keep the invocation under the loop cap.
                        let side = if masks {
                            (work::MAX_TILE * 16 / wpc32 as u32).clamp(1, 1024).isqrt()
                        } else {
                            32
                        };
                        let items = work::solid_items(part, xr.clone(), grid.dims, side);
                        let pipeline = if masks { &dev.solid_masks } else { &dev.solid };
                        rec.items(pipeline, &params, tris, &items, 4, &slab_a);
                    }
                    if need_surface {
                        let items = work::surface_items(part, xr.clone(), grid.dims);
                        let target = slab_b.as_ref().unwrap_or(&slab_a);
                        rec.items(&dev.surface, &params, tris, &items, 5, target);
                    }
                    if let Some(t) = thickness {
                        let items = work::distance_items(part, xr.clone(), grid.dims, t);
                        rec.items(&dev.distance, &params, tris, &items, 5, &slab_a);
                    }
                }
                if need_solid && self.options.solid_strategy == SolidStrategy::ToggleScan {
                    let cols = rows * ny;
                    let u = rec.params(&params);
                    let bind = [(0, bound(&u, PARAMS_SIZE)), (1, bound(&slab_a, slab_bytes))];
                    rec.dispatch(&dev.prefix_xor, &bind, cols);
                }
                if let Some(b) = &slab_b {
                    let pipeline = if method == Some(Method::Interior) {
                        &dev.subtract
                    } else {
                        &dev.union
                    };
                    let u = rec.params(&params);
                    let bind = [
                        (0, bound(&u, PARAMS_SIZE)),
                        (1, bound(&slab_a, slab_bytes)),
                        (2, bound(b, slab_bytes)),
                    ];
                    rec.dispatch(pipeline, &bind, (rows as u64 * row_bytes / 4) as u32);
                }
                rec.enc
                    .copy_buffer_to_buffer(&slab_a, 0, &staging, 0, Some(bytes));
                Ok(rec.enc.finish())
            })?;
            timings.upload += t_up.elapsed();

            let t_run = Instant::now();
            let submission = Submission {
                commands,
                readback: staging.clone(),
                bytes,
            };
            dev.batcher
                .run(submission, |batch| run_batch(dev, batch))
                .unwrap_or_else(|| Err("the submission this slab was in failed".into()))
                .map_err(EngineError::Gpu)?;
            timings.dispatch += t_run.elapsed();
            inputs.recycle();

            let t_read = Instant::now();
            let slice = staging.slice(..bytes);
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
}

/// Bytes of [`Params`].
const PARAMS_SIZE: u64 = std::mem::size_of::<Params>() as u64;

/// Records one slab's commands, with its inputs in leased buffers.
struct Recorder<'a, 'p> {
    dev: &'a GpuDevice,
    leases: &'a mut Leases<'p>,
    enc: wgpu::CommandEncoder,
    slab_bytes: u64,
}

impl Recorder<'_, '_> {
    /// A parameter block of its own (each dispatch reads the parameters written for it: writes
    /// land before the submission, so two dispatches cannot share one buffer).
    fn params(&mut self, p: &Params) -> wgpu::Buffer {
        let dev = self.dev;
        self.leases.filled(
            &dev.device,
            &dev.queue,
            "params",
            PARAMS_USAGE,
            bytemuck::bytes_of(p),
        )
    }

    /// Dispatches `pipeline` over `items` (`stride` words each), in batches the device binds.
    fn items(
        &mut self,
        pipeline: &wgpu::ComputePipeline,
        params: &Params,
        (tris, tri_bytes): (&wgpu::Buffer, u64),
        items: &[u32],
        stride: usize,
        target: &wgpu::Buffer,
    ) {
        let binding = self.dev.limits.max_storage_buffer_binding_size as usize;
        let per_batch = (binding / (4 * stride)).min(1 << 26);
        for batch in items.chunks(per_batch * stride) {
            let count = (batch.len() / stride) as u32;
            let bytes: &[u8] = bytemuck::cast_slice(batch);
            let dev = self.dev;
            let buf = self
                .leases
                .filled(&dev.device, &dev.queue, "items", INPUT_USAGE, bytes);
            let u = self.params(&Params {
                item_count: count,
                ..*params
            });
            let bind = [
                (0, bound(&u, PARAMS_SIZE)),
                (1, bound(tris, tri_bytes)),
                (2, bound(&buf, bytes.len() as u64)),
                (3, bound(target, self.slab_bytes)),
            ];
            self.dispatch(pipeline, &bind, count);
        }
    }

    /// Records one dispatch of `invocations` 64-wide invocations (2D when over 65,535 groups).
    fn dispatch(
        &mut self,
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
        let group = self
            .dev
            .device
            .create_bind_group(&wgpu::BindGroupDescriptor {
                label: None,
                layout: &pipeline.get_bind_group_layout(0),
                entries: &entries,
            });
        let groups = invocations.div_ceil(64);
        let mut pass = self.enc.begin_compute_pass(&Default::default());
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &group, &[]);
        pass.dispatch_workgroups(groups.min(65535), groups.div_ceil(65535), 1);
    }
}

/// `f` under validation and out-of-memory error scopes of this thread (scopes are per thread):
/// an error the GPU reported meanwhile is the result.
fn scoped<T>(
    dev: &GpuDevice,
    f: impl FnOnce() -> Result<T, EngineError>,
) -> Result<T, EngineError> {
    let validation = dev.device.push_error_scope(wgpu::ErrorFilter::Validation);
    let oom = dev.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
    let result = f();
    let oom_err = pollster::block_on(oom.pop());
    let val_err = pollster::block_on(validation.pop());
    match oom_err.or(val_err) {
        Some(e) => Err(EngineError::Gpu(format!(
            "the GPU reported: {}",
            device::describe(&e)
        ))),
        None => result,
    }
}

/// Runs one batch as the leader: one submission of every slab's commands, then the wait for
/// the device, then each readback mapped. One result per slab, in order.
fn run_batch(dev: &GpuDevice, batch: Vec<Submission>) -> Vec<Result<(), String>> {
    let n = batch.len();
    let mut readbacks = Vec::with_capacity(n);
    let commands: Vec<wgpu::CommandBuffer> = batch
        .into_iter()
        .map(|s| {
            readbacks.push((s.readback, s.bytes));
            s.commands
        })
        .collect();
    dev.queue.submit(commands);
    let (tx, rx) = std::sync::mpsc::channel();
    for (i, (buffer, bytes)) in readbacks.iter().enumerate() {
        let tx = tx.clone();
        buffer
            .slice(..*bytes)
            .map_async(wgpu::MapMode::Read, move |r| {
                let _ = tx.send((i, r));
            });
    }
    drop(tx);
    if let Err(e) = dev.device.poll(wgpu::PollType::wait_indefinitely()) {
        return vec![Err(format!("waiting for the GPU: {e}")); n];
    }
    let mut results = vec![Err("the readback was dropped".to_string()); n];
    for (i, r) in rx.try_iter() {
        results[i] = r.map_err(|e| format!("mapping the result: {e}"));
    }
    results
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
    fn distance_with(
        &self,
        mesh: &GridMesh,
        thickness: i64,
        ctl: &Control,
    ) -> Result<BitVolume, EngineError> {
        self.distance_timed_with(mesh, thickness, ctl)
            .map(|(v, _)| v)
    }
    fn gpu_stats(&self) -> Option<GpuStats> {
        Some(self.stats())
    }
}
