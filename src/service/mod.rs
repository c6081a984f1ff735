//! The HTTP service (`voxd serve`): axum on tokio over the application layer. Handlers
//! (`routes/`, one file per resource) translate requests into the application's typed requests
//! and its results or errors into responses (problem documents, `problem.rs`); the engine, the
//! store (`Arc<dyn VolumeStore>`) and the queue (`Arc<dyn JobQueue>`) are the state. The API
//! contract is `openapi.yaml`, and a test keeps the route table and that file in step.

pub mod auth;
mod extract;
mod metrics;
pub mod problem;
mod process_metrics;
pub mod routes;
pub mod server;

use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;

use crate::app::queue::JobQueue;
use crate::app::store::VolumeStore;
use crate::app::{self, Error, ErrorKind, Limits};
use crate::engine::{Engine, EngineChoice};
use crate::queue::local::LocalQueue;
#[cfg(feature = "redis")]
use crate::queue::redis::{RedisOptions, RedisQueue};
use crate::store::StoreSpec;
use crate::store::fs::FsStore;
#[cfg(feature = "s3")]
use crate::store::s3::S3Store;

pub use routes::{ROUTES, admin_router, router};

/// Everything `voxd serve` can be told (each also as a `VOXD_*` variable).
#[derive(Clone, Debug)]
pub struct Config {
    pub addr: SocketAddr,
    /// The probes' own listener (`--admin-addr`): `/healthz`, `/readyz` and `/metrics` only,
    /// with [`server::ADMIN_CONNECTIONS`] places of its own.
    pub admin_addr: Option<SocketAddr>,
    pub data_dir: PathBuf,
    /// Where volumes and job records live (`--store`); `None`: the directory `data_dir`.
    pub store: Option<StoreSpec>,
    pub engine: EngineChoice,
    pub adapter: Option<String>,
    /// Jobs waiting at most; more get 429.
    pub queue_capacity: usize,
    /// Jobs running at once, on either engine (on a GPU their submissions are batched).
    pub workers: usize,
    pub limits: Limits,
    pub max_store_bytes: u64,
    /// Bytes of memory admitted work may use at once (`--max-memory`; the process-wide
    /// [`app::memory::MemoryBudget`]).
    pub max_memory: u64,
    pub connections: server::ConnectionLimits,
    /// How long shutdown waits for requests and running jobs before it gives up on them.
    pub shutdown_timeout: std::time::Duration,
    /// How long one job may run (`--job-timeout`); past it the job is stopped and fails.
    pub job_timeout: Option<std::time::Duration>,
    /// The job queue: `None` for the in-process one, or a `redis://` URL for one shared by
    /// replicas (`--queue`).
    pub queue: Option<String>,
    /// A shared queue's lease (`--lease-seconds`) and starts per job (`--max-attempts`).
    pub lease: std::time::Duration,
    /// Starts per job on either queue (`--max-attempts`): a job whose process died during it
    /// that many times fails.
    pub max_attempts: u32,
    /// Uploads that no job refers to are deleted once this old (`--upload-grace`).
    pub upload_grace: std::time::Duration,
    /// API keys (`--api-keys-file`): `None` leaves the routes open.
    pub api_keys_file: Option<PathBuf>,
    /// Each key's limits unless its line says otherwise (`--key-rate`, `--key-burst`,
    /// `--key-max-jobs`).
    pub key_limits: auth::KeyLimits,
    /// `/metrics` needs a key too (`--protect-metrics`; only with keys).
    pub protect_metrics: bool,
}

/// The state every handler sees.
pub struct App {
    pub engine: Arc<dyn Engine>,
    pub store: Arc<dyn VolumeStore>,
    pub queue: Arc<dyn JobQueue>,
    pub limits: Limits,
    pub http: server::ConnectionLimits,
    /// Who may call the `/v1` routes (`None`: anyone).
    pub keys: Option<Arc<auth::ApiKeys>>,
    /// The process-wide memory budget every request, operation and job is admitted by.
    pub memory: app::memory::MemoryBudget,
    /// Parsing and validating uploads runs here, not on the engine's threads, so a running job
    /// never delays accepting (or refusing) the next one.
    ingest: Arc<rayon::ThreadPool>,
    metrics: metrics::Metrics,
    /// Set when shutdown begins: `/readyz` says `shutting-down` from then on.
    shutting_down: std::sync::atomic::AtomicBool,
}

impl App {
    /// The state over parts already opened (tests build it over their own), with API keys
    /// (`None`: open routes).
    pub fn with_keys(
        engine: Arc<dyn Engine>,
        store: Arc<dyn VolumeStore>,
        queue: Arc<dyn JobQueue>,
        limits: Limits,
        http: server::ConnectionLimits,
        keys: Option<Arc<auth::ApiKeys>>,
        memory: app::memory::MemoryBudget,
    ) -> Arc<App> {
        let threads = std::thread::available_parallelism()
            .map_or(2, |n| n.get())
            .clamp(1, 4);
        let ingest = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .thread_name(|i| format!("voxd-ingest-{i}"))
            .build()
            .expect("a thread pool for uploads");
        Arc::new(App {
            metrics: metrics::Metrics::new(&engine.describe()),
            engine,
            store,
            queue,
            limits,
            http,
            keys,
            memory,
            ingest: Arc::new(ingest),
            shutting_down: Default::default(),
        })
    }

    /// Whether shutdown has begun (the listener closed, queued jobs failed).
    pub fn shutting_down(&self) -> bool {
        self.shutting_down
            .load(std::sync::atomic::Ordering::Relaxed)
    }

    /// Holds `bytes` of the process-wide memory budget for `what` while the permit lives:
    /// waits at most [`MEMORY_WAIT`], then `busy` (503, `Retry-After`); work over the whole
    /// budget is `too-much-memory` (422) at once.
    pub async fn admit(&self, bytes: u64, what: &str) -> app::Result<app::memory::MemoryPermit> {
        self.memory.admit(bytes, what, MEMORY_WAIT).await
    }
}

/// How long a request waits for its memory before it is refused as `busy`.
pub const MEMORY_WAIT: std::time::Duration = std::time::Duration::from_secs(5);

impl app::jobs::JobObserver for App {
    fn job_done(
        &self,
        method: &str,
        outcome: app::jobs::Outcome,
        secs: f64,
        result: &app::Result<crate::app::store::VolumeMeta>,
    ) {
        self.metrics.job_done(
            method,
            outcome,
            secs,
            result.as_ref().ok().map(|m| m.grid.voxel_count()),
        );
    }
}

/// Opens the engine, the store and the queue of `config`.
pub async fn open(config: &Config) -> Result<Arc<App>, String> {
    // The keys first: a bad keys file stops the start before anything is opened.
    let keys = match &config.api_keys_file {
        None => {
            if config.protect_metrics {
                return Err("--protect-metrics needs --api-keys-file".into());
            }
            None
        }
        Some(path) => {
            let mut keys = auth::ApiKeys::load(path, config.key_limits)
                .map_err(|e| format!("API keys: {e}"))?;
            keys.protect_metrics = config.protect_metrics;
            tracing::info!(
                keys = keys.len(),
                protect_metrics = config.protect_metrics,
                "API keys required on /v1"
            );
            Some(Arc::new(keys))
        }
    };
    let (choice, adapter) = (config.engine, config.adapter.clone());
    let engine: Arc<dyn Engine> =
        tokio::task::spawn_blocking(move || app::files::open_engine(choice, adapter))
            .await
            .map_err(|e| e.to_string())?
            .map_err(|e| e.to_string())?
            .into();
    tracing::info!(engine = %engine.describe(), "engine ready");
    let store = open_store(config).await?;
    #[cfg(feature = "s3")]
    if config.queue.is_none() && matches!(config.store, Some(StoreSpec::S3(_))) {
        // The in-process queue keeps its jobs' meshes in memory and takes any record it finds
        // unfinished at start for one of its own interrupted jobs.
        tracing::warn!(
            "the in-process queue over a shared S3 store: jobs are seen by this process only, \
             and several replicas on one bucket must not use it (a replica starting marks the \
             others' unfinished jobs failed); replicas need a shared queue (--queue redis://…)"
        );
    }
    let queue: Arc<dyn JobQueue> = match &config.queue {
        None => Arc::new(
            LocalQueue::open_with(
                config.queue_capacity.max(1),
                store.clone(),
                config.limits,
                config.max_attempts.max(1),
            )
            .await
            .map_err(|e| format!("{}: {e}", store.describe()))?
            .with_job_timeout(config.job_timeout),
        ),
        #[cfg(not(feature = "redis"))]
        Some(url) => {
            return Err(format!(
                "--queue {url}: this voxd was built without the redis feature (cargo build --features redis)"
            ));
        }
        #[cfg(feature = "redis")]
        Some(url) => Arc::new(
            RedisQueue::open(
                url,
                RedisOptions {
                    lease: config.lease,
                    max_attempts: config.max_attempts.max(1),
                    job_timeout: config.job_timeout,
                    limits: config.limits,
                    ..RedisOptions::new(config.queue_capacity.max(1))
                },
                store.clone(),
            )
            .await?,
        ),
    };
    // Uploads no job refers to go after `--upload-grace`, now and periodically.
    tokio::spawn(app::jobs::sweep::sweep_periodically(
        store.clone(),
        Arc::downgrade(&queue),
        config.upload_grace,
    ));
    Ok(App::with_keys(
        engine,
        store,
        queue,
        config.limits,
        config.connections,
        keys,
        app::memory::MemoryBudget::new(config.max_memory),
    ))
}

/// Opens the store `config` names: an S3 bucket, or a directory (`--store`, else `--data-dir`).
pub async fn open_store(config: &Config) -> Result<Arc<dyn VolumeStore>, String> {
    let quota = config.max_store_bytes;
    let dir = match &config.store {
        #[cfg(feature = "s3")]
        Some(StoreSpec::S3(loc)) => {
            let store = S3Store::open(loc, quota).await.map_err(|e| match e {
                // The error names the bucket, the endpoint and what failed.
                crate::app::store::StoreError::Io(e) => e.to_string(),
                e => format!("{loc}: {e}"),
            })?;
            return Ok(Arc::new(store));
        }
        Some(StoreSpec::Dir(dir)) => dir.clone(),
        None => config.data_dir.clone(),
    };
    let shown = dir.display().to_string();
    Ok(Arc::new(
        tokio::task::spawn_blocking(move || FsStore::open(&dir, quota))
            .await
            .map_err(|e| e.to_string())?
            .map_err(|e| format!("{shown}: {e}"))?,
    ))
}

/// Serves until `shutdown` resolves; then refuses new jobs, fails queued ones explicitly,
/// finishes the running ones and returns. `on_bound` hears the bound addresses (port 0 → real
/// port): the service's and the admin listener's, if there is one.
pub async fn serve(
    config: Config,
    shutdown: impl std::future::Future<Output = ()> + Send + 'static,
    on_bound: impl FnOnce(SocketAddr, Option<SocketAddr>),
) -> Result<(), String> {
    let app = open(&config).await?;
    let n = config.workers.max(1);
    tracing::info!(workers = n, "workers");
    let workers: Vec<_> = (0..n)
        .map(|_| {
            tokio::spawn(app::jobs::work(
                app.queue.clone(),
                app.store.clone(),
                app.engine.clone(),
                app.clone(),
                Some(app.memory.clone()),
            ))
        })
        .collect();
    let listener =
        server::bind(config.addr).map_err(|e| format!("cannot listen on {}: {e}", config.addr))?;
    let admin = match config.admin_addr {
        Some(a) => {
            Some(server::bind(a).map_err(|e| format!("cannot listen on {a} (--admin-addr): {e}"))?)
        }
        None => None,
    };
    on_bound(
        listener.local_addr().map_err(|e| e.to_string())?,
        admin
            .as_ref()
            .map(|l| l.local_addr().map_err(|e| e.to_string()))
            .transpose()?,
    );
    // Shutdown closes the service's listener at once; the admin one answers probes and scrapes
    // until the process is done (requests drained, running jobs finished), `/readyz` with
    // `shutting-down`.
    let (stopping, stopped) = tokio::sync::watch::channel(false);
    let admin = admin.map(|l| {
        let mut stopped = stopped.clone();
        tokio::spawn(server::run(
            l,
            admin_router(app.clone()),
            server::ConnectionLimits {
                max_connections: server::ADMIN_CONNECTIONS,
                // Probes come from few addresses (the orchestrator's).
                max_connections_per_client: 0,
                ..config.connections
            },
            async move {
                let _ = stopped.wait_for(|s| *s).await;
            },
            // Probes only: nothing worth waiting for once the work is done.
            config
                .shutdown_timeout
                .min(std::time::Duration::from_secs(2)),
        ))
    });
    let (queue, state) = (app.queue.clone(), app.clone());
    let stop = async move {
        shutdown.await;
        state
            .shutting_down
            .store(true, std::sync::atomic::Ordering::Relaxed);
        let failed = queue
            .close(Error::new(
                ErrorKind::ShuttingDown,
                "the server shut down before this job started; submit it again",
            ))
            .await;
        tracing::info!(
            failed_queued = failed,
            "shutting down: finishing running jobs"
        );
    };
    server::run(
        listener,
        router(app),
        config.connections,
        stop,
        config.shutdown_timeout,
    )
    .await;
    // Running jobs finish (their volumes are stored) unless they outlast the shutdown timeout;
    // then the process leaves them, and a restart shows them as interrupted.
    let finish = async {
        for w in workers {
            let _ = w.await;
        }
    };
    if tokio::time::timeout(config.shutdown_timeout, finish)
        .await
        .is_err()
    {
        tracing::warn!(
            "jobs still running after the shutdown timeout ({} s); leaving them",
            config.shutdown_timeout.as_secs()
        );
    }
    let _ = stopping.send(true);
    if let Some(a) = admin {
        let _ = a.await;
    }
    tracing::info!("stopped");
    Ok(())
}
