//! Opening the one device: adapter choice, limits, pipelines (compiled once), loss detection,
//! and the device's buffer pool and submission batcher.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use serde::Serialize;

use super::POOL_BYTES;
use super::batch::Batcher;
use super::pool::BufferPool;
use crate::engine::EngineError;

const COMMON: &str = include_str!("../../../shaders/common.wgsl");
const SOLID: &str = include_str!("../../../shaders/solid.wgsl");
const PREFIX_XOR: &str = include_str!("../../../shaders/prefix_xor.wgsl");
const SURFACE: &str = include_str!("../../../shaders/surface.wgsl");
const DISTANCE: &str = include_str!("../../../shaders/distance.wgsl");
const COMBINE: &str = include_str!("../../../shaders/combine.wgsl");

/// What the engine runs on, for logs, summaries and health checks.
#[derive(Clone, Debug, Serialize)]
pub struct AdapterSummary {
    pub name: String,
    pub backend: String,
    pub device_type: String,
    pub driver: String,
    pub max_storage_buffer_binding_size: u64,
    pub max_buffer_size: u64,
}

pub(super) struct GpuDevice {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub limits: wgpu::Limits,
    pub summary: AdapterSummary,
    pub solid: wgpu::ComputePipeline,
    pub solid_masks: wgpu::ComputePipeline,
    pub prefix_xor: wgpu::ComputePipeline,
    pub surface: wgpu::ComputePipeline,
    pub distance: wgpu::ComputePipeline,
    pub union: wgpu::ComputePipeline,
    pub subtract: wgpu::ComputePipeline,
    /// Buffers kept from one job for the next.
    pub pool: BufferPool,
    /// The jobs' slabs on their way to the queue, submitted together.
    pub batcher: Batcher<super::engine::Submission, Result<(), String>>,
    lost: Arc<AtomicBool>,
}

/// How the refusal of a software-only machine begins, when only hardware adapters were asked for.
pub(crate) const NO_HARDWARE: &str = "no hardware GPU adapter";

fn rank(t: wgpu::DeviceType) -> u8 {
    match t {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Cpu => 3,
        wgpu::DeviceType::Other => 4,
    }
}

impl GpuDevice {
    /// The best adapter with 64-bit shader integers, or the one named like `options.adapter`;
    /// `options.hardware_only`: never a software (CPU) adapter such as lavapipe.
    pub fn open(options: &super::GpuOptions) -> Result<GpuDevice, EngineError> {
        let (wanted, hardware_only) = (options.adapter.as_deref(), options.hardware_only);
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let adapters = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::all()));
        let names: Vec<String> = adapters.iter().map(|a| a.get_info().name).collect();
        let mut usable: Vec<wgpu::Adapter> = adapters
            .into_iter()
            .filter(|a| a.features().contains(wgpu::Features::SHADER_INT64))
            .filter(|a| {
                wanted.is_none_or(|w| a.get_info().name.to_lowercase().contains(&w.to_lowercase()))
            })
            .collect();
        let software: Vec<String> = usable
            .iter()
            .filter(|a| a.get_info().device_type == wgpu::DeviceType::Cpu)
            .map(|a| a.get_info().name)
            .collect();
        if hardware_only {
            usable.retain(|a| a.get_info().device_type != wgpu::DeviceType::Cpu);
        }
        usable.sort_by_key(|a| rank(a.get_info().device_type));
        let Some(adapter) = usable.into_iter().next() else {
            let why = match wanted {
                _ if hardware_only && !software.is_empty() => format!(
                    "{NO_HARDWARE}, only software ones ({software:?}), which are slower than the CPU engine"
                ),
                Some(w) => format!("no adapter named like {w:?} with 64-bit shader integers (adapters: {names:?})"),
                None if names.is_empty() => "no GPU adapter found (install a Vulkan driver, e.g. Debian's mesa-vulkan-drivers for lavapipe)".into(),
                None => format!("no adapter supports 64-bit shader integers (adapters: {names:?})"),
            };
            return Err(EngineError::NoDevice(why));
        };
        let info = adapter.get_info();
        let limits = adapter.limits();
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("voxd"),
            required_features: wgpu::Features::SHADER_INT64,
            required_limits: limits.clone(),
            ..Default::default()
        }))
        .map_err(|e| EngineError::NoDevice(format!("{}: {e}", info.name)))?;
        let lost = Arc::new(AtomicBool::new(false));
        let flag = lost.clone();
        device.set_device_lost_callback(move |reason, msg| {
            tracing::error!(?reason, msg, "GPU device lost");
            flag.store(true, Ordering::SeqCst);
        });
        device.on_uncaptured_error(Arc::new(|e: wgpu::Error| {
            tracing::error!("uncaptured GPU error: {e}")
        }));
        let summary = AdapterSummary {
            name: info.name.clone(),
            backend: format!("{:?}", info.backend),
            device_type: format!("{:?}", info.device_type),
            driver: format!("{} {}", info.driver, info.driver_info)
                .trim()
                .to_string(),
            max_storage_buffer_binding_size: limits.max_storage_buffer_binding_size,
            max_buffer_size: limits.max_buffer_size,
        };
        tracing::info!(?summary, "GPU engine ready");
        let pipeline = |label: &str, src: &str, constants: &[(&str, f64)]| {
            let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(label),
                source: wgpu::ShaderSource::Wgsl(format!("{COMMON}\n{src}").into()),
            });
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(label),
                layout: None,
                module: &module,
                entry_point: Some("main"),
                compilation_options: wgpu::PipelineCompilationOptions {
                    constants,
                    ..Default::default()
                },
                cache: None,
            })
        };
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let dev = GpuDevice {
            solid: pipeline("solid", SOLID, &[("MASKS", 0.0)]),
            solid_masks: pipeline("solid_masks", SOLID, &[("MASKS", 1.0)]),
            prefix_xor: pipeline("prefix_xor", PREFIX_XOR, &[]),
            surface: pipeline("surface", SURFACE, &[]),
            distance: pipeline("distance", DISTANCE, &[]),
            union: pipeline("union", COMBINE, &[("SUBTRACT", 0.0)]),
            subtract: pipeline("subtract", COMBINE, &[("SUBTRACT", 1.0)]),
            pool: BufferPool::new(
                options.pool_bytes.unwrap_or(POOL_BYTES),
                limits.max_buffer_size,
            ),
            batcher: Batcher::new(),
            device,
            queue,
            limits,
            summary,
            lost,
        };
        if let Some(e) = pollster::block_on(scope.pop()) {
            return Err(EngineError::Gpu(format!(
                "compiling the kernels: {}",
                describe(&e)
            )));
        }
        Ok(dev)
    }

    pub fn is_lost(&self) -> bool {
        self.lost.load(Ordering::SeqCst)
    }
}

/// The readable part of a wgpu error (its Debug form embeds whole shader sources).
pub(super) fn describe(e: &wgpu::Error) -> String {
    match e {
        wgpu::Error::Validation { description, .. } => description.clone(),
        other => other.to_string(),
    }
}
