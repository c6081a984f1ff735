//! The router in-process (`tower::ServiceExt::oneshot`): the route table, parameter and error
//! paths. What needs a process (signals, restarts, concurrency) is tested end to end in
//! `tests/service/` against the real binary.
//!
//! Here: the harness and request helpers the themes share; the tests are in `requests`,
//! `contract` and `keys`.

use std::sync::Arc;

use axum::body::Body;
use axum::http::{Request, StatusCode};
use serde_json::Value;
use tower::ServiceExt;

use super::{ROUTES, router};
use crate::app::Limits;
use crate::engine::Engine;
use crate::queue::JobQueue;
use crate::queue::local::LocalQueue;
use crate::service::App;
use crate::store::VolumeStore;
use crate::store::fs::FsStore;
use crate::testkit::Scratch;

/// A router over a directory store in a scratch directory (removed when the harness drops).
struct Harness {
    app: Arc<App>,
    dir: Scratch,
}

async fn harness(name: &str) -> Harness {
    harness_with(name, |l| l).await
}

async fn harness_with(name: &str, tune: impl FnOnce(Limits) -> Limits) -> Harness {
    let limits = Limits {
        max_voxels: 1 << 20,
        ..Limits::SERVICE
    }
    .with_body_bytes(1 << 16);
    let h = built(name, 4, tune(limits), None).await;
    let app = &h.app;
    tokio::spawn(crate::app::jobs::work(
        app.queue.clone(),
        app.store.clone(),
        app.engine.clone(),
        app.clone(),
        Some(app.memory.clone()),
    ));
    h
}

struct Reply {
    status: StatusCode,
    content_type: String,
    body: Vec<u8>,
}

impl Reply {
    fn json(&self) -> Value {
        serde_json::from_slice(&self.body)
            .unwrap_or_else(|e| panic!("{e}: {}", String::from_utf8_lossy(&self.body)))
    }
    /// Asserts the status (showing the body when it is another).
    fn ok(&self, status: StatusCode) {
        assert_eq!(
            self.status,
            status,
            "{}",
            String::from_utf8_lossy(&self.body)
        );
    }
    /// Asserts a problem document of `slug` with `status`; its detail.
    fn problem(&self, status: u16, slug: &str) -> String {
        self.ok(StatusCode::from_u16(status).unwrap());
        assert_eq!(self.content_type, "application/problem+json");
        let p = self.json();
        assert_eq!(
            p["type"],
            format!("https://voxd.dev/problems/{slug}"),
            "{p}"
        );
        assert_eq!(p["status"], status);
        assert!(
            p["request_id"].is_string() && p["instance"].is_string(),
            "{p}"
        );
        p["detail"].as_str().unwrap().to_string()
    }
}

async fn call(app: &Arc<App>, method: &str, uri: &str, ct: Option<&str>, body: &[u8]) -> Reply {
    let headers: Vec<(&str, &str)> = ct.map(|ct| ("content-type", ct)).into_iter().collect();
    call_with(app, method, uri, &headers, body).await.0
}

use crate::app::testing::TETRA_OBJ as TETRA;

mod contract;
mod keys;
mod requests;

async fn call_with(
    app: &Arc<App>,
    method: &str,
    uri: &str,
    headers: &[(&str, &str)],
    body: &[u8],
) -> (Reply, axum::http::HeaderMap) {
    let mut req = Request::builder().method(method).uri(uri);
    for (k, v) in headers {
        req = req.header(*k, *v);
    }
    let res = router(app.clone())
        .oneshot(req.body(Body::from(body.to_vec())).unwrap())
        .await
        .unwrap();
    let (status, h) = (res.status(), res.headers().clone());
    let content_type = h
        .get("content-type")
        .map(|v| v.to_str().unwrap().to_string())
        .unwrap_or_default();
    let body = axum::body::to_bytes(res.into_body(), usize::MAX)
        .await
        .unwrap()
        .to_vec();
    (
        Reply {
            status,
            content_type,
            body,
        },
        h,
    )
}

/// Flips a bit of byte `at` of a stored volume's bytes `data` where the directory store keeps
/// them: in a pack record or in the volume's own file (found by content).
fn damage(dir: &std::path::Path, data: &[u8], at: usize) {
    for e in std::fs::read_dir(dir.join("volumes")).unwrap() {
        let path = e.unwrap().path();
        let mut bytes = std::fs::read(&path).unwrap();
        if let Some(start) = bytes.windows(data.len()).position(|w| w == data) {
            bytes[start + at] ^= 0x40;
            std::fs::write(&path, &bytes).unwrap();
            return;
        }
    }
    panic!("the stored bytes are in no file");
}

/// A router with API keys (`keys`: the keys file's text) and no workers, so that submitted jobs
/// stay queued.
async fn keyed(name: &str, keys: &str, protect_metrics: bool) -> Harness {
    let mut k =
        crate::service::auth::ApiKeys::parse(keys, crate::service::auth::KeyLimits::DEFAULT)
            .unwrap();
    k.protect_metrics = protect_metrics;
    built(name, 16, Limits::SERVICE, Some(Arc::new(k))).await
}

/// A router over a directory store in a fresh scratch directory, a local queue of `capacity`
/// and the CPU engine, with no workers: what both kinds of harness start from.
async fn built(
    name: &str,
    capacity: usize,
    limits: Limits,
    keys: Option<Arc<crate::service::auth::ApiKeys>>,
) -> Harness {
    let dir = Scratch::new(&format!("router-{name}"));
    let store: Arc<dyn VolumeStore> = Arc::new(FsStore::open(&dir, 1 << 30).unwrap());
    let queue: Arc<dyn JobQueue> =
        Arc::new(LocalQueue::open(capacity, store.clone()).await.unwrap());
    let engine: Arc<dyn Engine> = Arc::new(crate::engine::cpu::CpuEngine);
    let app = App::with_keys(
        engine,
        store,
        queue,
        limits,
        Default::default(),
        keys,
        crate::app::memory::MemoryBudget::new(4 << 30),
    );
    Harness { app, dir }
}
