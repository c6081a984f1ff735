//! The router in-process (`tower::ServiceExt::oneshot`): the route table, parameter and error
//! paths. What needs a process (signals, restarts, concurrency) is tested end to end in
//! `tests/service.rs` against the real binary.

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

struct Harness {
    app: Arc<App>,
    dir: std::path::PathBuf,
}

impl Drop for Harness {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

async fn harness(name: &str) -> Harness {
    harness_with(name, |l| l).await
}

async fn harness_with(name: &str, tune: impl FnOnce(Limits) -> Limits) -> Harness {
    let dir = std::env::temp_dir().join(format!("voxd-router-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let store: Arc<dyn VolumeStore> = Arc::new(FsStore::open(&dir, 1 << 30).unwrap());
    let queue: Arc<dyn JobQueue> = Arc::new(LocalQueue::open(4, store.clone()).await.unwrap());
    let engine: Arc<dyn Engine> = Arc::new(crate::engine::cpu::CpuEngine);
    let limits = Limits {
        max_voxels: 1 << 20,
        ..Limits::SERVICE
    }
    .with_body_bytes(1 << 16);
    let limits = tune(limits);
    let app = App::with_keys(engine, store, queue, limits, Default::default(), None);
    tokio::spawn(crate::app::jobs::work(
        app.queue.clone(),
        app.store.clone(),
        app.engine.clone(),
        app.clone(),
    ));
    Harness { app, dir }
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

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_router_answers_exactly_the_route_table() {
    let h = harness("table").await;
    for (path, methods) in ROUTES {
        let p = path.replace("{id}", "x");
        for m in ["GET", "POST", "DELETE", "PUT", "PATCH"] {
            let r = call(&h.app, m, &p, None, b"").await;
            let fallback = r.status == StatusCode::NOT_FOUND
                && String::from_utf8_lossy(&r.body).contains("no such route");
            assert!(!fallback, "{m} {p} reached the fallback");
            if methods.contains(&m) {
                assert_ne!(
                    r.status,
                    StatusCode::METHOD_NOT_ALLOWED,
                    "{m} {p} is in the table"
                );
            } else {
                assert_eq!(
                    r.status,
                    StatusCode::METHOD_NOT_ALLOWED,
                    "{m} {p} is not in the table"
                );
            }
        }
    }
    let r = call(&h.app, "GET", "/v1/nothing", None, b"").await;
    r.problem(404, "not-found");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn query_strings_are_typed() {
    let h = harness("query").await;
    let post = |q: &'static str| call(&h.app, "POST", q, Some("model/obj"), TETRA);
    let d = post("/v1/voxelize?colour=red")
        .await
        .problem(400, "invalid-parameter");
    assert!(d.contains("colour") && d.contains("resolution"), "{d}");
    let d = post("/v1/voxelize?method=sculpt")
        .await
        .problem(400, "invalid-parameter");
    assert!(d.contains("sculpt") && d.contains("density"), "{d}");
    let d = post("/v1/voxelize?fill=blob")
        .await
        .problem(400, "invalid-parameter");
    assert!(d.contains("winding"), "{d}");
    post("/v1/voxelize?resolution=-3")
        .await
        .problem(400, "invalid-parameter");
    post("/v1/voxelize?resolution=8&voxel_size=0.1")
        .await
        .problem(400, "invalid-parameter");
    let d = post("/v1/voxelize?origin=0,0&dims=2,2,2&voxel_size=1")
        .await
        .problem(400, "invalid-parameter");
    assert!(d.contains("X,Y,Z"), "{d}");
    post("/v1/voxelize?dims=2,2,2&voxel_size=1")
        .await
        .problem(400, "invalid-parameter");
    post("/v1/voxelize?method=density&density_factor=3")
        .await
        .problem(400, "invalid-parameter");
    post("/v1/voxelize?wait=301")
        .await
        .problem(400, "invalid-parameter");
    post("/v1/voxelize?cubic=maybe")
        .await
        .problem(400, "invalid-parameter");
    post("/v1/voxelize?format=dwg")
        .await
        .problem(415, "unsupported-media-type");
    call(&h.app, "GET", "/v1/volumes?limit=0", None, b"")
        .await
        .problem(400, "invalid-parameter");
    call(&h.app, "GET", "/v1/volumes?page=2", None, b"")
        .await
        .problem(400, "invalid-parameter");
    call(&h.app, "GET", "/v1/volumes/x/preview.png?axis=w", None, b"")
        .await
        .problem(400, "invalid-parameter");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bodies_and_their_errors() {
    let h = harness("bodies").await;
    call(&h.app, "POST", "/v1/voxelize", Some("model/obj"), b"")
        .await
        .problem(422, "invalid-mesh");
    call(&h.app, "POST", "/v1/voxelize", Some("text/html"), b"<html>")
        .await
        .problem(415, "unsupported-media-type");
    let big = vec![b' '; 70_000];
    call(&h.app, "POST", "/v1/voxelize", Some("model/obj"), &big)
        .await
        .problem(413, "body-too-large");
    call(
        &h.app,
        "POST",
        "/v1/voxelize?resolution=200",
        Some("model/obj"),
        TETRA,
    )
    .await
    .problem(422, "grid-too-large");
    // JSON bodies: not JSON, the wrong shape, unknown fields, limits.
    call(&h.app, "POST", "/v1/volumes/csg", None, b"{not json")
        .await
        .problem(400, "invalid-parameter");
    call(
        &h.app,
        "POST",
        "/v1/volumes/csg",
        None,
        br#"{"op":"melt","operands":["a"]}"#,
    )
    .await
    .problem(400, "invalid-parameter");
    call(
        &h.app,
        "POST",
        "/v1/volumes/csg",
        None,
        br#"{"op":"union","operands":[]}"#,
    )
    .await
    .problem(400, "invalid-parameter");
    call(
        &h.app,
        "POST",
        "/v1/volumes/csg",
        None,
        br#"{"op":"union","operands":["a"],"x":1}"#,
    )
    .await
    .problem(400, "invalid-parameter");
    call(
        &h.app,
        "POST",
        "/v1/volumes/csg",
        None,
        br#"{"op":"union","operands":["nope"]}"#,
    )
    .await
    .problem(404, "not-found");
    let deep = (0..40).fold(r#""a""#.to_string(), |e, _| {
        format!(r#"{{"op":"union","operands":[{e}]}}"#)
    });
    let d = call(&h.app, "POST", "/v1/volumes/csg", None, deep.as_bytes())
        .await
        .problem(400, "invalid-parameter");
    assert!(d.contains("deeper than 32"), "{d}");
    call(
        &h.app,
        "POST",
        "/v1/volumes/intersect",
        None,
        br#"{"a":"x"}"#,
    )
    .await
    .problem(400, "invalid-parameter");
    call(
        &h.app,
        "POST",
        "/v1/volumes/x/morphology",
        None,
        br#"{"op":"dilate","radius":65}"#,
    )
    .await
    .problem(400, "invalid-parameter");
    call(
        &h.app,
        "POST",
        "/v1/volumes/x/morphology",
        None,
        br#"{"op":"dilate"}"#,
    )
    .await
    .problem(400, "invalid-parameter");
    call(
        &h.app,
        "POST",
        "/v1/volumes/x/morphology",
        None,
        br#"{"op":"dilate","radius":1}"#,
    )
    .await
    .problem(404, "not-found");
    call(
        &h.app,
        "POST",
        "/v1/volumes/x/query",
        None,
        br#"{"points":[[0,0]]}"#,
    )
    .await
    .problem(400, "invalid-parameter");
    call(&h.app, "GET", "/v1/volumes/x/normals?points=1,2", None, b"")
        .await
        .problem(400, "invalid-parameter");
    call(&h.app, "GET", "/v1/jobs/nope", None, b"")
        .await
        .problem(404, "not-found");
    call(&h.app, "DELETE", "/v1/volumes/nope", None, b"")
        .await
        .problem(404, "not-found");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_voxelization_through_the_router() {
    let h = harness("voxelize").await;
    let r = call(
        &h.app,
        "POST",
        "/v1/voxelize?resolution=8&wait=30&name=t",
        Some("model/obj"),
        TETRA,
    )
    .await;
    r.ok(StatusCode::CREATED);
    let meta = r.json();
    let id = meta["id"].as_str().unwrap().to_string();
    assert_eq!(meta["name"], "t");
    assert_eq!(meta["source"]["triangles"], 4);
    // The stored .vxl carries the same metadata keys the command line writes.
    let data = call(&h.app, "GET", &format!("/v1/volumes/{id}/data"), None, b"").await;
    assert_eq!(data.status, StatusCode::OK);
    let (v, header) = crate::codec::vxl::decode(&data.body).unwrap();
    assert_eq!(v.grid().dims, [8, 8, 8]);
    for k in [
        "method",
        "fill",
        "source",
        "source_format",
        "source_sha256",
        "triangles",
        "job",
    ] {
        assert!(header.contains_key(k), "{k} missing from {header:?}");
    }
    // Derived volumes, then density where only bits are accepted.
    let body = format!(r#"{{"op":"intersection","operands":["{id}","{id}"]}}"#);
    let r = call(&h.app, "POST", "/v1/volumes/csg", None, body.as_bytes()).await;
    assert_eq!(r.status, StatusCode::CREATED);
    assert_eq!(r.json()["solid_voxels"], meta["solid_voxels"]);
    let r = call(
        &h.app,
        "POST",
        "/v1/voxelize?resolution=8&wait=30&method=density",
        Some("model/obj"),
        TETRA,
    )
    .await;
    assert_eq!(r.status, StatusCode::CREATED);
    let did = r.json()["id"].as_str().unwrap().to_string();
    call(
        &h.app,
        "GET",
        &format!("/v1/volumes/{did}/stats"),
        None,
        b"",
    )
    .await
    .problem(422, "wrong-volume-kind");
    call(
        &h.app,
        "GET",
        &format!("/v1/volumes/{did}/data?format=binvox"),
        None,
        b"",
    )
    .await
    .problem(400, "invalid-parameter");
    let r = call(&h.app, "GET", "/readyz", None, b"").await;
    assert_eq!(r.status, StatusCode::OK);
    assert_eq!(r.json()["queue_depth"], 0);
    let listed = call(&h.app, "GET", "/v1/volumes?limit=2", None, b"")
        .await
        .json();
    assert_eq!(listed["volumes"].as_array().unwrap().len(), 2);
    assert!(listed["next"].is_string());
}

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

/// The contract in both directions: bounded conversions, one ETag per content coding with weak
/// `If-None-Match`, `If-Match` on delete, content codings refused, names bounded, grids that
/// cannot be represented refused before anything is stored, 405 as a problem.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn contract_edges() {
    let h = harness("contract").await;
    let obj = [("content-type", "model/obj")];
    // A 4096×1×1 volume is tiny stored, but 4096³ as binvox: refused before any work.
    let (r, _) = call_with(
        &h.app,
        "POST",
        "/v1/voxelize?origin=0,0,0&voxel_size=0.001&dims=4096,1,1&wait=30",
        &obj,
        TETRA,
    )
    .await;
    r.ok(StatusCode::CREATED);
    let id = r.json()["id"].as_str().unwrap().to_string();
    let d = call(
        &h.app,
        "GET",
        &format!("/v1/volumes/{id}/data?format=binvox"),
        None,
        b"",
    )
    .await
    .problem(422, "grid-too-large");
    assert!(d.contains("binvox"), "{d}");
    // ETags: identity and gzip differ; a weak If-None-Match of either is fresh.
    let uri = format!("/v1/volumes/{id}/data?format=npy");
    let (plain, ph) = call_with(&h.app, "GET", &uri, &[], b"").await;
    let (gz, gh) = call_with(&h.app, "GET", &uri, &[("accept-encoding", "gzip")], b"").await;
    assert_eq!((plain.status, gz.status), (StatusCode::OK, StatusCode::OK));
    assert_eq!(gh.get("content-encoding").unwrap(), "gzip");
    let (pt, gt) = (ph["etag"].to_str().unwrap(), gh["etag"].to_str().unwrap());
    assert_ne!(pt, gt);
    for t in [pt.to_string(), gt.to_string(), format!("W/{gt}")] {
        let (r, _) = call_with(&h.app, "GET", &uri, &[("if-none-match", &t)], b"").await;
        assert_eq!(r.status, StatusCode::NOT_MODIFIED, "{t}");
    }
    // If-Match on delete.
    let (r, _) = call_with(
        &h.app,
        "DELETE",
        &format!("/v1/volumes/{id}"),
        &[("if-match", "\"0000000000000000-vxl\"")],
        b"",
    )
    .await;
    r.problem(412, "precondition-failed");
    let (r, _) = call_with(
        &h.app,
        "DELETE",
        &format!("/v1/volumes/{id}"),
        &[("if-match", pt)],
        b"",
    )
    .await;
    assert_eq!(r.status, StatusCode::NO_CONTENT);
    // Content codings.
    let (r, _) = call_with(
        &h.app,
        "POST",
        "/v1/voxelize",
        &[("content-type", "model/obj"), ("content-encoding", "br")],
        TETRA,
    )
    .await;
    r.problem(415, "unsupported-media-type");
    let (r, _) = call_with(
        &h.app,
        "POST",
        "/v1/voxelize",
        &[("content-type", "model/obj"), ("content-encoding", "gzip")],
        TETRA,
    )
    .await;
    // Said to be gzip, but not: the body's content is at fault (as for a broken gzip stream).
    r.problem(422, "invalid-mesh");
    let (r, _) = call_with(
        &h.app,
        "POST",
        "/v1/volumes/intersect",
        &[("content-encoding", "gzip")],
        b"{}",
    )
    .await;
    r.problem(415, "unsupported-media-type");
    // Names, empty queries, grids that cannot be represented, methods.
    let long = format!("/v1/voxelize?name={}", "n".repeat(300));
    call(&h.app, "POST", &long, Some("model/obj"), TETRA)
        .await
        .problem(400, "invalid-parameter");
    // A name's limit is in characters (what openapi.yaml's maxLength counts), not bytes: 256
    // three-byte characters are a name, 257 are not.
    let euro = "%E2%82%AC";
    let name = |n: usize| format!("/v1/voxelize?resolution=8&wait=30&name={}", euro.repeat(n));
    let (r, _) = call_with(&h.app, "POST", &name(256), &obj, TETRA).await;
    r.ok(StatusCode::CREATED);
    assert_eq!(r.json()["name"], "€".repeat(256));
    h.app
        .store
        .delete(r.json()["id"].as_str().unwrap())
        .await
        .unwrap();
    call(&h.app, "POST", &name(257), Some("model/obj"), TETRA)
        .await
        .problem(400, "invalid-parameter");
    call(&h.app, "POST", "/v1/volumes/x/query", None, b"{}")
        .await
        .problem(400, "invalid-parameter");
    call(&h.app, "POST", "/v1/volumes/x/query", None, b"null")
        .await
        .problem(400, "invalid-parameter");
    let subnormal =
        b"v 0 0 0\nv 5e-324 0 0\nv 0 5e-324 0\nv 0 0 5e-324\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";
    call(
        &h.app,
        "POST",
        "/v1/voxelize?wait=30",
        Some("model/obj"),
        subnormal,
    )
    .await
    .problem(400, "invalid-parameter");
    assert_eq!(
        h.app.store.usage().await.unwrap().volumes,
        0,
        "nothing was stored"
    );
    call(&h.app, "PUT", "/v1/volumes", None, b"")
        .await
        .problem(405, "method-not-allowed");
    // A union of two small volumes far apart lives on a huge grid: refused before any is read.
    let mut ids = vec![];
    for o in ["0,0,0", "100,100,100"] {
        let uri = format!("/v1/voxelize?origin={o}&voxel_size=0.25&dims=4,4,4&wait=30");
        let (r, _) = call_with(&h.app, "POST", &uri, &obj, TETRA).await;
        r.ok(StatusCode::CREATED);
        ids.push(r.json()["id"].as_str().unwrap().to_string());
    }
    let body = format!(r#"{{"op":"union","operands":["{}","{}"]}}"#, ids[0], ids[1]);
    let d = call(&h.app, "POST", "/v1/volumes/csg", None, body.as_bytes())
        .await
        .problem(422, "grid-too-large");
    assert!(d.contains("union"), "{d}");
}

/// Downloads stream: a conversion arrives in bounded chunks with its exact length announced
/// (the whole response is never built in memory), and a damaged stored volume ends its stream
/// with an error instead of arriving whole.
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

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn downloads_stream_in_bounded_chunks() {
    use futures_util::StreamExt;
    let h = harness("stream").await;
    // 1024×32×32 = 2^20 voxels (the harness's limit): 1 MiB as .npy.
    let (r, _) = call_with(
        &h.app,
        "POST",
        "/v1/voxelize?origin=0,0,0&voxel_size=0.001&dims=1024,32,32&wait=30",
        &[("content-type", "model/obj")],
        TETRA,
    )
    .await;
    r.ok(StatusCode::CREATED);
    let id = r.json()["id"].as_str().unwrap().to_string();
    let get = |uri: String| {
        let app = h.app.clone();
        async move {
            router(app)
                .oneshot(Request::get(uri).body(Body::empty()).unwrap())
                .await
                .unwrap()
        }
    };
    let res = get(format!("/v1/volumes/{id}/data?format=npy")).await;
    assert_eq!(res.status(), StatusCode::OK);
    let len: usize = res.headers()["content-length"]
        .to_str()
        .unwrap()
        .parse()
        .unwrap();
    let mut body = res.into_body().into_data_stream();
    let (mut frames, mut got) = (0, vec![]);
    while let Some(c) = body.next().await {
        let c = c.unwrap();
        assert!(c.len() <= 256 << 10, "a chunk of {} bytes", c.len());
        frames += 1;
        got.extend_from_slice(&c);
    }
    assert_eq!(got.len(), len);
    assert!(frames >= 4, "{frames} chunks");
    let stored = h.app.store.read(&id).await.unwrap().unwrap();
    let (v, _) = crate::codec::vxl::decode(&stored).unwrap();
    assert_eq!(got, crate::codec::npy::encode(&v));
    // Stored bytes damaged on disk: a volume within the first chunk is a problem document; a
    // longer one fails before its last chunk (never arrives whole).
    assert!(stored.len() < 256 << 10);
    let last = stored.len() - 1;
    damage(&h.dir, &stored, last);
    call(&h.app, "GET", &format!("/v1/volumes/{id}/data"), None, b"")
        .await
        .problem(500, "internal");
    // Random bits do not compress: a .vxl of several chunks.
    let mut noisy = crate::volume::BitVolume::new(crate::Grid {
        origin: [0.0; 3],
        voxel_size: 1.0,
        dims: [4096, 32, 32],
    });
    let mut seed = 0x9e37_79b9_7f4a_7c15u64;
    for x in 0..4096 {
        for y in 0..32 {
            for z in 0..32 {
                seed ^= seed << 13;
                seed ^= seed >> 7;
                seed ^= seed << 17;
                noisy.set(x, y, z, seed & 1 == 1);
            }
        }
    }
    let vxl = crate::codec::vxl::encode(&crate::volume::Volume::Bits(noisy), &Default::default())
        .unwrap();
    assert!(vxl.len() > 256 << 10, "{} bytes", vxl.len());
    let mut meta = h.app.store.get(&id).await.unwrap().unwrap();
    meta.id = "big".into();
    meta.bytes = vxl.len() as u64;
    meta.sha256 = crate::app::sha256_hex(&vxl);
    h.app.store.put(meta, vxl.clone().into()).await.unwrap();
    damage(&h.dir, &vxl, last);
    let res = get("/v1/volumes/big/data".into()).await;
    assert_eq!(res.status(), StatusCode::OK);
    let mut body = res.into_body().into_data_stream();
    let mut got = 0;
    let err = loop {
        match body.next().await {
            Some(Ok(c)) => got += c.len(),
            Some(Err(e)) => break e,
            None => panic!("a damaged volume streamed whole ({got} bytes)"),
        }
    };
    assert!(
        got < vxl.len() && err.to_string().contains("sha256"),
        "{got}: {err}"
    );
}

/// A list page is bounded in bytes as well as in count, and the pages together hold every
/// volume once.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn list_pages_are_bounded_in_bytes() {
    let h = harness_with("listbytes", |l| Limits {
        max_list_page_bytes: 1500,
        ..l
    })
    .await;
    let mut ids = std::collections::BTreeSet::new();
    for _ in 0..5 {
        let r = call(
            &h.app,
            "POST",
            "/v1/voxelize?resolution=4&wait=30",
            Some("model/obj"),
            TETRA,
        )
        .await;
        assert_eq!(r.status, StatusCode::CREATED);
        ids.insert(r.json()["id"].as_str().unwrap().to_string());
    }
    let (mut seen, mut uri, mut pages) = (
        std::collections::BTreeSet::new(),
        "/v1/volumes?limit=100".to_string(),
        0,
    );
    loop {
        let r = call(&h.app, "GET", &uri, None, b"").await;
        assert_eq!(r.status, StatusCode::OK);
        assert_eq!(r.content_type, "application/json");
        let page = r.json();
        let vols = page["volumes"].as_array().unwrap();
        assert!(!vols.is_empty());
        // One volume alone may pass the bound; more than one never do.
        assert!(
            vols.len() == 1 || r.body.len() <= 1500 + 100,
            "{} bytes",
            r.body.len()
        );
        for v in vols {
            assert!(seen.insert(v["id"].as_str().unwrap().to_string()));
        }
        pages += 1;
        match page["next"].as_str() {
            Some(n) => uri = n.to_string(),
            None => break,
        }
        assert!(pages < 10);
    }
    assert_eq!(seen, ids);
    assert!(pages >= 3, "{pages} pages");
}

/// A router with API keys (`keys`: the keys file's text) and no workers, so that submitted jobs
/// stay queued.
async fn keyed(name: &str, keys: &str, protect_metrics: bool) -> Harness {
    let dir = std::env::temp_dir().join(format!("voxd-router-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let store: Arc<dyn VolumeStore> = Arc::new(FsStore::open(&dir, 1 << 30).unwrap());
    let queue: Arc<dyn JobQueue> = Arc::new(LocalQueue::open(16, store.clone()).await.unwrap());
    let engine: Arc<dyn Engine> = Arc::new(crate::engine::cpu::CpuEngine);
    let mut k =
        crate::service::auth::ApiKeys::parse(keys, crate::service::auth::KeyLimits::DEFAULT)
            .unwrap();
    k.protect_metrics = protect_metrics;
    let app = App::with_keys(
        engine,
        store,
        queue,
        Limits::SERVICE,
        Default::default(),
        Some(Arc::new(k)),
    );
    Harness { app, dir }
}

/// With keys, every /v1 route needs one: none or a wrong one is 401 with the Bearer challenge
/// (before the route is even looked at: an unknown /v1 path too), a valid one passes;
/// /healthz, /readyz, /metrics and /openapi.yaml stay open unless --protect-metrics, which
/// closes /metrics only.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn api_keys_guard_v1_and_leave_the_probes_open() {
    let (key, line) = crate::service::auth::generate("team-a").unwrap();
    let h = keyed("keys-guard", &line, false).await;
    let auth = format!("Bearer {key}");
    for (method, path) in ROUTES
        .iter()
        .filter(|(p, _)| p.starts_with("/v1"))
        .flat_map(|(p, ms)| ms.iter().map(move |m| (*m, p.replace("{id}", "x"))))
        .chain([("GET", "/v1/nope".to_string())])
    {
        let (r, hd) = call_with(&h.app, method, &path, &[], b"").await;
        r.problem(401, "unauthorized");
        assert_eq!(hd["www-authenticate"], "Bearer realm=\"voxd\"", "{path}");
        let (r, hd) = call_with(
            &h.app,
            method,
            &path,
            &[("authorization", "Bearer voxd_wrong")],
            b"",
        )
        .await;
        r.problem(401, "unauthorized");
        assert_eq!(
            hd["www-authenticate"],
            "Bearer realm=\"voxd\", error=\"invalid_token\""
        );
        let (r, _) = call_with(&h.app, method, &path, &[("authorization", &auth)], b"").await;
        assert_ne!(r.status, StatusCode::UNAUTHORIZED, "{method} {path}");
    }
    let (r, _) = call_with(
        &h.app,
        "GET",
        "/v1/volumes",
        &[("authorization", &auth)],
        b"",
    )
    .await;
    assert_eq!(r.status, StatusCode::OK);
    for open in ["/healthz", "/readyz", "/metrics", "/openapi.yaml"] {
        assert_eq!(
            call(&h.app, "GET", open, None, b"").await.status,
            StatusCode::OK,
            "{open}"
        );
    }
    let metrics = String::from_utf8(call(&h.app, "GET", "/metrics", None, b"").await.body).unwrap();
    assert!(
        metrics.contains("voxd_key_requests_total{key=\"team-a\"}"),
        "{metrics}"
    );
    assert!(!metrics.contains(&key));

    let h = keyed("keys-metrics", &line, true).await;
    call(&h.app, "GET", "/metrics", None, b"")
        .await
        .problem(401, "unauthorized");
    let (r, _) = call_with(&h.app, "GET", "/metrics", &[("authorization", &auth)], b"").await;
    assert_eq!(r.status, StatusCode::OK);
    for open in ["/healthz", "/readyz"] {
        assert_eq!(
            call(&h.app, "GET", open, None, b"").await.status,
            StatusCode::OK,
            "{open}"
        );
    }
}

/// Per key: a request rate (429 rate-limited with Retry-After) and a number of jobs queued or
/// running (429 too-many-jobs), each key on its own; a job's record names its key; a job
/// canceled frees its place.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn api_keys_have_their_own_rates_and_job_limits() {
    let (ka, la) = crate::service::auth::generate("limited").unwrap();
    let (kb, lb) = crate::service::auth::generate("other").unwrap();
    let h = keyed(
        "keys-limits",
        &format!("{la}:rate=1,burst=4,jobs=2\n{lb}:rate=0,jobs=0\n"),
        false,
    )
    .await;
    let (a, b) = (format!("Bearer {ka}"), format!("Bearer {kb}"));
    let submit = async |auth: &str| {
        call_with(
            &h.app,
            "POST",
            "/v1/voxelize?resolution=8",
            &[("authorization", auth), ("content-type", "model/obj")],
            TETRA,
        )
        .await
    };
    let mut ids = Vec::new();
    for _ in 0..2 {
        let (r, _) = submit(&a).await;
        r.ok(StatusCode::ACCEPTED);
        assert_eq!(r.json()["key_name"], "limited");
        ids.push(r.json()["id"].as_str().unwrap().to_string());
    }
    let (r, hd) = submit(&a).await;
    let detail = r.problem(429, "too-many-jobs");
    assert!(
        detail.contains("limited") && detail.contains('2'),
        "{detail}"
    );
    assert!(hd.contains_key("retry-after"));
    // The other key is held back by neither limit of the first.
    for _ in 0..5 {
        let (r, _) = submit(&b).await;
        assert_eq!(r.status, StatusCode::ACCEPTED);
        assert_eq!(r.json()["key_name"], "other");
    }
    // The burst of 4 is spent (3 submits, this cancel); the 5th request within the second
    // waits: 1 s.
    let (r, _) = call_with(
        &h.app,
        "DELETE",
        &format!("/v1/jobs/{}", ids[0]),
        &[("authorization", &a)],
        b"",
    )
    .await;
    r.ok(StatusCode::OK);
    let (r, hd) = call_with(&h.app, "GET", "/v1/volumes", &[("authorization", &a)], b"").await;
    r.problem(429, "rate-limited");
    assert_eq!(hd["retry-after"], "1");
    // After a second, one more request is allowed: a submit, in the place the cancel freed.
    tokio::time::sleep(std::time::Duration::from_millis(1100)).await;
    let (r, _) = submit(&a).await;
    r.ok(StatusCode::ACCEPTED);
    // A full queue (16: 2 of one key and 5 of the other queued so far, 9 more) refuses before
    // the upload is read or parsed: a body that is no mesh at all is 429 queue-full, not 422.
    for _ in 0..9 {
        assert_eq!(submit(&b).await.0.status, StatusCode::ACCEPTED);
    }
    let (r, hd) = call_with(
        &h.app,
        "POST",
        "/v1/voxelize?resolution=8",
        &[("authorization", &b), ("content-type", "model/obj")],
        b"this is not a mesh",
    )
    .await;
    r.problem(429, "queue-full");
    assert_eq!(hd["retry-after"], "5");
}
