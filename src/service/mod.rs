//! The HTTP service (`voxd serve`): axum on tokio, one engine behind a bounded job queue, volumes
//! in a store on disk. Handlers parse and validate; the queue (jobs.rs) decides what runs; the
//! store (store.rs) keeps results; errors are problem documents (problem.rs). The API contract
//! is `openapi.yaml`, and a test keeps the router and that file in step.

// Handlers return `Result<_, Problem>`; a problem (a few strings) is built only on error paths,
// where its 144 bytes cost nothing measurable, and boxing it would clutter every handler.
#![allow(clippy::result_large_err)]

pub mod jobs;
mod metrics;
pub mod problem;
mod routes;
pub mod store;
mod volume_ops;

use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use jobs::{Jobs, Work};
use problem::{Kind, Problem};
use store::{SourceInfo, Store, VolumeMeta};

use crate::codec::vxl;
use crate::engine::gpu::GpuOptions;
use crate::engine::{Engine, EngineChoice};
use crate::volume::Volume;

/// Everything `voxd serve` can be told (each also as a `VOXD_*` variable).
#[derive(Clone, Debug)]
pub struct Config {
    pub addr: SocketAddr,
    pub data_dir: PathBuf,
    pub engine: EngineChoice,
    pub adapter: Option<String>,
    /// Jobs waiting at most; more get 429.
    pub queue_capacity: usize,
    /// Jobs running at once (the GPU engine always runs one).
    pub workers: usize,
    pub max_body_bytes: usize,
    pub max_triangles: usize,
    pub max_voxels: u64,
    pub max_store_bytes: u64,
}

pub struct App {
    pub config: Config,
    pub engine: Arc<dyn Engine>,
    pub jobs: Jobs,
    pub store: Store,
    pub metrics: metrics::Metrics,
    ids: AtomicU64,
    id_salt: u64,
}

impl App {
    /// A fresh id: 16 hex digits, unique in this process and unlikely across processes.
    pub fn new_id(&self) -> String {
        use std::hash::{BuildHasher, Hasher};
        let n = self.ids.fetch_add(1, Ordering::SeqCst);
        let mut h = std::collections::hash_map::RandomState::new().build_hasher();
        h.write_u64(self.id_salt ^ n);
        h.write_u128(
            std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .unwrap_or_default()
                .as_nanos(),
        );
        format!("{:016x}", h.finish())
    }
}

/// Opens the engine and the store; the router and the state behind it.
pub fn build(config: Config) -> Result<(axum::Router, Arc<App>), String> {
    let engine: Arc<dyn Engine> = crate::engine::open(
        config.engine,
        GpuOptions {
            adapter: config.adapter.clone(),
            ..Default::default()
        },
    )
    .map_err(|e| e.to_string())?
    .into();
    tracing::info!(engine = %engine.describe(), "engine ready");
    let store = Store::open(&config.data_dir, config.max_store_bytes)
        .map_err(|e| format!("{}: {e}", config.data_dir.display()))?;
    let jobs = Jobs::open(config.queue_capacity, config.data_dir.join("jobs"))
        .map_err(|e| format!("{}: {e}", config.data_dir.display()))?;
    let app = Arc::new(App {
        jobs,
        store,
        metrics: metrics::Metrics::new(&engine.describe()),
        engine,
        ids: AtomicU64::new(0),
        id_salt: std::process::id() as u64,
        config,
    });
    Ok((routes::router(app.clone()), app))
}

/// Serves until `shutdown` resolves; then refuses new jobs, fails queued ones explicitly,
/// finishes the running ones and returns. `on_bound` hears the bound address (port 0 → real port).
pub async fn serve(
    config: Config,
    shutdown: impl std::future::Future<Output = ()> + Send + 'static,
    on_bound: impl FnOnce(SocketAddr),
) -> Result<(), String> {
    let workers = if config.engine == EngineChoice::Cpu {
        config.workers.max(1)
    } else {
        1
    };
    let addr = config.addr;
    let (router, app) = build(config)?;
    let workers: Vec<_> = (0..workers)
        .map(|_| tokio::spawn(worker(app.clone())))
        .collect();
    let listener = tokio::net::TcpListener::bind(addr)
        .await
        .map_err(|e| format!("cannot listen on {addr}: {e}"))?;
    on_bound(listener.local_addr().map_err(|e| e.to_string())?);
    let app2 = app.clone();
    let stop = async move {
        shutdown.await;
        let failed = app2
            .jobs
            .close(Problem::new(
                Kind::ShuttingDown,
                "the server shut down before this job started; submit it again",
            ))
            .await;
        tracing::info!(
            failed_queued = failed,
            "shutting down: finishing running jobs"
        );
    };
    axum::serve(listener, router)
        .with_graceful_shutdown(stop)
        .await
        .map_err(|e| e.to_string())?;
    for w in workers {
        let _ = w.await;
    }
    tracing::info!("stopped");
    Ok(())
}

/// Takes jobs from the queue and runs them on the engine until the queue closes.
async fn worker(app: Arc<App>) {
    while let Some((id, work, canceled)) = app.jobs.next().await {
        let span = tracing::info_span!("job", id = %id, method = work.method.name(), dims = ?work.grid.dims);
        let _e = span.enter();
        let t = Instant::now();
        let app2 = app.clone();
        let id2 = id.clone();
        let result = tokio::task::spawn_blocking(move || run_job(&app2, &id2, &work, &canceled))
            .await
            .unwrap_or_else(|e| {
                Err(Problem::new(
                    Kind::Internal,
                    format!("the job panicked: {e}"),
                ))
            });
        let secs = t.elapsed().as_secs_f64();
        match &result {
            Ok(v) => tracing::info!(volume = %v, secs, "job succeeded"),
            Err(p) => tracing::warn!(problem = %p.detail, secs, "job failed"),
        }
        app.metrics.job_done(
            secs,
            result
                .as_ref()
                .ok()
                .and_then(|v| app.store.get(v))
                .map(|m| m.grid.voxel_count()),
        );
        app.jobs.finish(&id, result).await;
    }
}

fn run_job(
    app: &App,
    id: &str,
    work: &Work,
    canceled: &std::sync::atomic::AtomicBool,
) -> Result<String, Problem> {
    let engine_problem = |e: crate::engine::EngineError| match e {
        crate::engine::EngineError::OutOfRange { .. } => {
            Problem::new(Kind::InvalidMesh, e.to_string())
        }
        _ => Problem::new(Kind::EngineFailure, e.to_string()),
    };
    let (vol, fill) = match work.method {
        jobs::MethodSpec::Bits(m) => {
            let (v, r) = crate::engine::fill::voxelize(
                &*app.engine,
                &work.mesh,
                &work.grid,
                m,
                work.fill,
                &work.diagnostics,
            )
            .map_err(engine_problem)?;
            (Volume::Bits(v), r)
        }
        jobs::MethodSpec::Density(f) => {
            let limits = crate::grid::GridLimits {
                max_voxels: u64::MAX,
            };
            let (d, r) = crate::engine::density::density(
                &*app.engine,
                &work.mesh,
                &work.grid,
                f,
                limits,
                work.fill,
                &work.diagnostics,
            )
            .map_err(|e| match e {
                crate::engine::density::DensityError::Engine(e) => engine_problem(e),
                _ => Problem::new(Kind::EngineFailure, e.to_string()),
            })?;
            (Volume::Density(d), r)
        }
    };
    if let Some(w) = &fill.warning {
        tracing::warn!(warning = %w, "fill");
    }
    if canceled.load(Ordering::SeqCst) {
        return Err(Problem::new(Kind::NotCancelable, "canceled"));
    }
    let (solid, occupied) = match &vol {
        Volume::Bits(b) => (b.count_ones(), b.count_ones() as f64),
        Volume::Density(d) => (d.count_nonzero(), d.occupied_voxels()),
    };
    let kind = vol.kind();
    let mut meta = serde_json::Map::new();
    meta.insert("method".into(), work.method.name().into());
    meta.insert("fill".into(), fill.used.name().into());
    meta.insert("job".into(), id.into());
    meta.insert("source_sha256".into(), work.sha256.clone().into());
    let bytes =
        vxl::encode(&vol, &meta).map_err(|e| Problem::new(Kind::Internal, e.to_string()))?;
    let vid = app.new_id();
    let g = work.grid;
    let m = VolumeMeta {
        id: vid.clone(),
        name: work.name.clone(),
        kind: kind.into(),
        method: work.method.name().into(),
        grid: g,
        solid_voxels: solid,
        volume: occupied * g.voxel_size.powi(3),
        source: SourceInfo {
            format: work.format.clone(),
            sha256: work.sha256.clone(),
            triangles: work.mesh.triangles().len(),
        },
        diagnostics: Some(work.diagnostics.clone()),
        fill: Some(fill),
        engine: app.engine.describe(),
        created: jobs::rfc3339(std::time::SystemTime::now()),
        bytes: bytes.len() as u64,
        sha256: hex_sha256(&bytes),
        provenance: None,
    };
    app.store.put(m, &bytes).map_err(|e| match e {
        store::StoreError::Full { .. } => Problem::new(Kind::StorageFull, e.to_string()),
        store::StoreError::Io(_) => Problem::new(Kind::Internal, e.to_string()),
    })?;
    Ok(vid)
}

pub fn hex_sha256(b: &[u8]) -> String {
    use sha2::Digest;
    sha2::Sha256::digest(b)
        .iter()
        .map(|x| format!("{x:02x}"))
        .collect()
}
