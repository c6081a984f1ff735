//! Prometheus text exposition of the service's counters, written by hand (a few lines each):
//! requests by route, method and status and their latency; jobs by outcome and their duration;
//! the queue; the store's usage against its quota; the build; the process (from `/proc`).

use std::collections::BTreeMap;
use std::fmt::Write;
use std::sync::Mutex;

use crate::app::jobs::Outcome;
use crate::app::queue::QueueStats;
use crate::app::store::Usage;
use crate::engine::gpu::GpuStats;

/// Job durations: up to an hour, past the default `--job-timeout` (600 s) and well beyond.
const JOB_BUCKETS: [f64; 16] = [
    0.01, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0, 30.0, 60.0, 120.0, 300.0, 600.0, 1800.0,
    3600.0,
];

/// Request durations: a probe's milliseconds to a waited-for job's or a large download's
/// minutes.
const HTTP_BUCKETS: [f64; 15] = [
    0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0, 30.0, 60.0, 120.0, 300.0,
];

/// The methods a request's `method` label takes; any other is `other` (labels stay few).
const METHODS: [&str; 7] = ["GET", "HEAD", "POST", "PUT", "DELETE", "PATCH", "OPTIONS"];

/// A histogram over fixed buckets (cumulative counts are computed when rendered).
#[derive(Clone, Debug)]
struct Histogram {
    counts: Vec<u64>,
    count: u64,
    sum: f64,
}

impl Histogram {
    fn new(buckets: &[f64]) -> Histogram {
        Histogram {
            counts: vec![0; buckets.len()],
            count: 0,
            sum: 0.0,
        }
    }

    fn observe(&mut self, buckets: &[f64], v: f64) {
        if let Some(i) = buckets.iter().position(|le| v <= *le) {
            self.counts[i] += 1;
        }
        self.count += 1;
        self.sum += v;
    }

    /// The series of `name` with `labels` (`key="value",` each, or empty).
    fn render(&self, s: &mut String, name: &str, labels: &str, buckets: &[f64]) {
        let mut cum = 0;
        for (n, le) in self.counts.iter().zip(buckets) {
            cum += n;
            let _ = writeln!(s, "{name}_bucket{{{labels}le=\"{le}\"}} {cum}");
        }
        let _ = writeln!(s, "{name}_bucket{{{labels}le=\"+Inf\"}} {}", self.count);
        let labels = match labels.trim_end_matches(',') {
            "" => String::new(),
            l => format!("{{{l}}}"),
        };
        let _ = writeln!(s, "{name}_sum{labels} {}", self.sum);
        let _ = writeln!(s, "{name}_count{labels} {}", self.count);
    }
}

/// The optional features this build has.
const FEATURES: &[&str] = &[
    #[cfg(feature = "gpu")]
    "gpu",
    #[cfg(feature = "s3")]
    "s3",
    #[cfg(feature = "redis")]
    "redis",
];

pub struct Metrics {
    engine: String,
    inner: Mutex<Inner>,
}

struct Inner {
    jobs: Histogram,
    /// Jobs finished, by method and outcome.
    outcomes: BTreeMap<(String, &'static str), u64>,
    voxels: u64,
    last_rate: f64,
    /// Requests by route template, method and status.
    requests: BTreeMap<(String, &'static str, u16), u64>,
    /// Request durations by route template.
    latency: BTreeMap<String, Histogram>,
}

impl Metrics {
    pub fn new(engine: &str) -> Metrics {
        Metrics {
            engine: engine.replace(['"', '\\', '\n'], "'"),
            inner: Mutex::new(Inner {
                jobs: Histogram::new(&JOB_BUCKETS),
                outcomes: BTreeMap::new(),
                voxels: 0,
                last_rate: 0.0,
                requests: BTreeMap::new(),
                latency: BTreeMap::new(),
            }),
        }
    }

    /// A job finished: its method, how, in `secs`, with `voxels` when it succeeded.
    pub fn job_done(&self, method: &str, outcome: Outcome, secs: f64, voxels: Option<u64>) {
        let mut m = self.inner.lock().unwrap();
        m.jobs.observe(&JOB_BUCKETS, secs);
        *m.outcomes
            .entry((method.to_string(), outcome.name()))
            .or_default() += 1;
        if let Some(v) = voxels {
            m.voxels += v;
            m.last_rate = v as f64 / secs.max(1e-9);
        }
    }

    /// A request answered: its route template (`unmatched` for none), method, status and time.
    pub fn http_request(&self, route: &str, method: &axum::http::Method, status: u16, secs: f64) {
        let method = METHODS
            .into_iter()
            .find(|m| *m == method.as_str())
            .unwrap_or("other");
        let mut m = self.inner.lock().unwrap();
        *m.requests
            .entry((route.to_string(), method, status))
            .or_default() += 1;
        if let Some(h) = m.latency.get_mut(route) {
            h.observe(&HTTP_BUCKETS, secs);
        } else {
            let mut h = Histogram::new(&HTTP_BUCKETS);
            h.observe(&HTTP_BUCKETS, secs);
            m.latency.insert(route.to_string(), h);
        }
    }

    /// The text of `/metrics`: the queue's counts `q`, the store's `usage` (when it answered),
    /// this process's requests and jobs, and the GPU engine's submissions and buffers when it
    /// runs one (`gpu`).
    pub fn render(&self, q: &QueueStats, usage: Option<&Usage>, gpu: Option<GpuStats>) -> String {
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
            "# HELP voxd_job_duration_seconds Time jobs took, from a worker taking them to their volume stored (or their end), whatever their outcome.\n# TYPE voxd_job_duration_seconds histogram"
        );
        m.jobs
            .render(&mut s, "voxd_job_duration_seconds", "", &JOB_BUCKETS);
        let _ = writeln!(
            s,
            "# HELP voxd_jobs_finished_total Jobs this process's workers finished, by method and outcome (succeeded, failed, canceled, timed_out).\n# TYPE voxd_jobs_finished_total counter"
        );
        for ((method, outcome), n) in &m.outcomes {
            let _ = writeln!(
                s,
                "voxd_jobs_finished_total{{method=\"{method}\",outcome=\"{outcome}\"}} {n}"
            );
        }
        let _ = writeln!(
            s,
            "# HELP voxd_http_requests_total Requests answered, by route template (unmatched: no route), method and status.\n# TYPE voxd_http_requests_total counter"
        );
        for ((route, method, status), n) in &m.requests {
            let _ = writeln!(
                s,
                "voxd_http_requests_total{{route=\"{route}\",method=\"{method}\",status=\"{status}\"}} {n}"
            );
        }
        let _ = writeln!(
            s,
            "# HELP voxd_http_request_duration_seconds Time from a request's head read to its response's head ready, by route template.\n# TYPE voxd_http_request_duration_seconds histogram"
        );
        for (route, h) in &m.latency {
            h.render(
                &mut s,
                "voxd_http_request_duration_seconds",
                &format!("route=\"{route}\","),
                &HTTP_BUCKETS,
            );
        }
        if let Some(u) = usage {
            let _ = writeln!(
                s,
                "# HELP voxd_store_used_bytes Bytes of stored volumes, data and metadata (what the quota counts).\n# TYPE voxd_store_used_bytes gauge\nvoxd_store_used_bytes {}",
                u.bytes
            );
            let _ = writeln!(
                s,
                "# HELP voxd_store_quota_bytes The store's quota (--max-store-bytes); past it writes get 507.\n# TYPE voxd_store_quota_bytes gauge\nvoxd_store_quota_bytes {}",
                u.limit
            );
            let _ = writeln!(
                s,
                "# HELP voxd_store_volumes Volumes stored.\n# TYPE voxd_store_volumes gauge\nvoxd_store_volumes {}",
                u.volumes
            );
        }
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
        let _ = writeln!(
            s,
            "# HELP voxd_build_info The running build: its version and the optional features it was built with.\n# TYPE voxd_build_info gauge\nvoxd_build_info{{version=\"{}\",features=\"{}\"}} 1",
            env!("CARGO_PKG_VERSION"),
            FEATURES.join(",")
        );
        super::process_metrics::render(&mut s);
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Buckets are cumulative, a job past the last bucket counts in `+Inf` only, and methods a
    /// caller makes up share one label value.
    #[test]
    fn histograms_are_cumulative_and_labels_bounded() {
        let m = Metrics::new("cpu");
        m.job_done("solid", Outcome::Succeeded, 0.2, Some(8));
        m.job_done("solid", Outcome::TimedOut, 599.0, None);
        m.job_done("solid", Outcome::Failed, 7200.0, None);
        for method in ["BREW", "PROPFIND", "GET"] {
            m.http_request("unmatched", &method.parse().unwrap(), 404, 0.001);
        }
        let s = m.render(&QueueStats::default(), None, None);
        let has = |l: &str| s.lines().any(|x| x == l);
        assert!(
            has("voxd_job_duration_seconds_bucket{le=\"0.25\"} 1"),
            "{s}"
        );
        assert!(has("voxd_job_duration_seconds_bucket{le=\"600\"} 2"), "{s}");
        assert!(
            has("voxd_job_duration_seconds_bucket{le=\"3600\"} 2"),
            "{s}"
        );
        assert!(
            has("voxd_job_duration_seconds_bucket{le=\"+Inf\"} 3"),
            "{s}"
        );
        assert!(has("voxd_job_duration_seconds_count 3"), "{s}");
        assert!(has(
            "voxd_jobs_finished_total{method=\"solid\",outcome=\"timed_out\"} 1"
        ));
        assert!(has(
            "voxd_http_requests_total{route=\"unmatched\",method=\"other\",status=\"404\"} 2"
        ));
        assert!(has(
            "voxd_http_request_duration_seconds_count{route=\"unmatched\"} 3"
        ));
        assert!(!s.contains("BREW") && !s.contains("voxd_store_"), "{s}");
    }
}
