//! Prometheus text exposition of the service's counters, written by hand (a few lines each).

use std::fmt::Write;
use std::sync::Mutex;

use crate::app::queue::QueueStats;
use crate::engine::gpu::GpuStats;

const BUCKETS: [f64; 9] = [0.01, 0.05, 0.1, 0.25, 0.5, 1.0, 5.0, 10.0, 60.0];

pub struct Metrics {
    engine: String,
    inner: Mutex<Inner>,
}

#[derive(Default)]
struct Inner {
    buckets: [u64; BUCKETS.len()],
    count: u64,
    sum: f64,
    voxels: u64,
    voxel_seconds: f64,
    last_rate: f64,
}

impl Metrics {
    pub fn new(engine: &str) -> Metrics {
        Metrics {
            engine: engine.replace('"', "'"),
            inner: Mutex::new(Inner::default()),
        }
    }

    pub fn job_done(&self, secs: f64, voxels: Option<u64>) {
        let mut m = self.inner.lock().unwrap();
        for (b, le) in m.buckets.iter_mut().zip(BUCKETS) {
            if secs <= le {
                *b += 1;
            }
        }
        m.count += 1;
        m.sum += secs;
        if let Some(v) = voxels {
            m.voxels += v;
            m.voxel_seconds += secs;
            m.last_rate = v as f64 / secs.max(1e-9);
        }
    }

    /// The text of `/metrics`: the queue's counts `q`, this process's jobs, and the GPU
    /// engine's submissions and buffers when it runs one (`gpu`).
    pub fn render(&self, q: &QueueStats, gpu: Option<GpuStats>) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "# HELP voxd_jobs Jobs known to this process (with a shared queue: to the queue, over all replicas), by state and method.\n# TYPE voxd_jobs gauge"
        );
        for (state, method, n) in &q.by_state {
            let _ = writeln!(
                s,
                "voxd_jobs{{state=\"{}\",method=\"{method}\"}} {n}",
                state.name()
            );
        }
        let _ = writeln!(
            s,
            "# HELP voxd_queue_depth Jobs waiting (in the shared queue: over all replicas).\n# TYPE voxd_queue_depth gauge\nvoxd_queue_depth {}",
            q.depth
        );
        let _ = writeln!(
            s,
            "# HELP voxd_queue_oldest_seconds How long the oldest waiting job has waited (0 when none waits).\n# TYPE voxd_queue_oldest_seconds gauge\nvoxd_queue_oldest_seconds {}",
            q.oldest_queued_s
        );
        let _ = writeln!(
            s,
            "# HELP voxd_queue_running Jobs running (in the shared queue: over all replicas).\n# TYPE voxd_queue_running gauge\nvoxd_queue_running {}",
            q.running
        );
        let _ = writeln!(
            s,
            "# HELP voxd_queue_available Whether the job queue answers (0: the shared queue's Redis is unreachable).\n# TYPE voxd_queue_available gauge\nvoxd_queue_available {}",
            u8::from(q.unavailable.is_none())
        );
        if !q.classes.is_empty() {
            let _ = writeln!(
                s,
                "# HELP voxd_queue_class_depth Jobs waiting in the shared queue, by size class.\n# TYPE voxd_queue_class_depth gauge"
            );
            for (class, n) in &q.classes {
                let _ = writeln!(s, "voxd_queue_class_depth{{class=\"{class}\"}} {n}");
            }
        }
        let m = self.inner.lock().unwrap();
        let _ = writeln!(
            s,
            "# HELP voxd_job_duration_seconds Time jobs spent running.\n# TYPE voxd_job_duration_seconds histogram"
        );
        for (b, le) in m.buckets.iter().zip(BUCKETS) {
            let _ = writeln!(s, "voxd_job_duration_seconds_bucket{{le=\"{le}\"}} {b}");
        }
        let _ = writeln!(
            s,
            "voxd_job_duration_seconds_bucket{{le=\"+Inf\"}} {}",
            m.count
        );
        let _ = writeln!(
            s,
            "voxd_job_duration_seconds_sum {}\nvoxd_job_duration_seconds_count {}",
            m.sum, m.count
        );
        let _ = writeln!(
            s,
            "# HELP voxd_voxels_total Voxels produced by succeeded jobs.\n# TYPE voxd_voxels_total counter\nvoxd_voxels_total {}",
            m.voxels
        );
        let _ = writeln!(
            s,
            "# HELP voxd_voxels_per_second Voxels per second of the last succeeded job.\n# TYPE voxd_voxels_per_second gauge\nvoxd_voxels_per_second {}",
            m.last_rate
        );
        let _ = writeln!(
            s,
            "# HELP voxd_engine_info The engine this process runs.\n# TYPE voxd_engine_info gauge\nvoxd_engine_info{{engine=\"{}\"}} 1",
            self.engine
        );
        if let Some(g) = gpu {
            // Counted since the device was opened (again, after a loss: a counter reset).
            let b = g.submissions;
            for (name, kind, help, v) in [
                (
                    "voxd_gpu_submissions_total",
                    "counter",
                    "Submissions to the GPU (each a batch of slabs recorded by jobs running at once).",
                    b.batches,
                ),
                (
                    "voxd_gpu_slabs_total",
                    "counter",
                    "Slabs submitted to the GPU (one command buffer each).",
                    b.items,
                ),
                (
                    "voxd_gpu_submission_slabs_max",
                    "gauge",
                    "The most slabs one submission carried.",
                    b.largest,
                ),
                (
                    "voxd_gpu_buffers_created_total",
                    "counter",
                    "GPU buffers created because the pool had none idle of their size class.",
                    g.buffers.created,
                ),
                (
                    "voxd_gpu_buffers_reused_total",
                    "counter",
                    "GPU buffer leases served by an idle buffer from the pool.",
                    g.buffers.reused,
                ),
                (
                    "voxd_gpu_pool_idle_bytes",
                    "gauge",
                    "Bytes of idle GPU buffers the pool keeps for the next jobs.",
                    g.buffers.idle_bytes,
                ),
            ] {
                let _ = writeln!(s, "# HELP {name} {help}\n# TYPE {name} {kind}\n{name} {v}");
            }
        }
        s
    }
}
