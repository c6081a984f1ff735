//! The v1 routes: thin handlers that parse, validate and hand work to the queue or the store.

use std::collections::HashMap;
use std::sync::Arc;
use std::time::Duration;

use axum::Router;
use axum::body::{Body, Bytes};
use axum::extract::{DefaultBodyLimit, Path, Query, Request, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use serde_json::json;
use tower_http::compression::CompressionLayer;
use tower_http::compression::predicate::{NotForContentType, Predicate, SizeAbove};
use tracing::Instrument;

use super::jobs::{MethodSpec, Refused, State as JobState, Work};
use super::problem::{Kind, Problem};
use super::{App, hex_sha256};
use crate::codec::{VolumeFormat, vxl};
use crate::engine::Method;
use crate::grid::{Grid, GridError, GridLimits, GridSpec};
use crate::mesh::{self, ExternalResources, Format, LoadOptions, MeshError};

pub const VXL_MEDIA_TYPE: &str = "application/vnd.voxd.vxl";
const OPENAPI: &str = include_str!("../../openapi.yaml");

pub fn router(app: Arc<App>) -> Router {
    let compress = CompressionLayer::new().gzip(true).zstd(true).compress_when(
        SizeAbove::new(256)
            .and(NotForContentType::const_new(VXL_MEDIA_TYPE))
            .and(NotForContentType::const_new("application/problem+json")),
    );
    Router::new()
        .route(
            "/v1/voxelize",
            post(voxelize).layer(DefaultBodyLimit::disable()),
        )
        .route("/v1/jobs/{id}", get(get_job).delete(cancel_job))
        .route("/v1/volumes", get(list_volumes))
        .route("/v1/volumes/csg", post(super::volume_ops::csg))
        .route("/v1/volumes/intersect", post(super::volume_ops::intersect))
        .route(
            "/v1/volumes/{id}/morphology",
            post(super::volume_ops::morphology),
        )
        .route("/v1/volumes/{id}/stats", get(super::volume_ops::stats))
        .route("/v1/volumes/{id}/query", post(super::volume_ops::query))
        .route("/v1/volumes/{id}/normals", get(super::volume_ops::normals))
        .route(
            "/v1/volumes/{id}/preview.png",
            get(super::volume_ops::preview),
        )
        .route("/v1/volumes/{id}", get(get_volume).delete(delete_volume))
        .route("/v1/volumes/{id}/data", get(volume_data))
        .route("/healthz", get(healthz))
        .route("/readyz", get(readyz))
        .route("/metrics", get(metrics))
        .route("/openapi.yaml", get(openapi))
        .fallback(|| async { Problem::new(Kind::NotFound, "no such route; see /openapi.yaml") })
        .layer(compress)
        .layer(middleware::from_fn_with_state(app.clone(), request_context))
        .with_state(app)
}

/// Gives every request an id (the caller's `x-request-id` or a new one), a tracing span, the
/// id in the response header, and the id and path in every problem document.
async fn request_context(State(app): State<Arc<App>>, req: Request, next: Next) -> Response {
    let rid = req
        .headers()
        .get("x-request-id")
        .and_then(|v| v.to_str().ok())
        .filter(|v| !v.is_empty() && v.len() <= 128)
        .map(str::to_string)
        .unwrap_or_else(|| app.new_id());
    let path = req.uri().path().to_string();
    let span = tracing::info_span!("request", id = %rid, method = %req.method(), path = %path);
    let mut res = next.run(req).instrument(span).await;
    let is_problem = res
        .headers()
        .get(header::CONTENT_TYPE)
        .is_some_and(|v| v == "application/problem+json");
    if is_problem {
        let (mut parts, body) = res.into_parts();
        let bytes = axum::body::to_bytes(body, 1 << 20)
            .await
            .unwrap_or_default();
        let body = match serde_json::from_slice::<Problem>(&bytes) {
            Ok(mut p) => {
                p.request_id = Some(rid.clone());
                p.instance.get_or_insert(path);
                serde_json::to_vec(&p).unwrap_or_default()
            }
            Err(_) => bytes.to_vec(),
        };
        parts.headers.remove(header::CONTENT_LENGTH);
        res = Response::from_parts(parts, Body::from(body));
    }
    if let Ok(v) = HeaderValue::from_str(&rid) {
        res.headers_mut().insert("x-request-id", v);
    }
    res
}

fn bad(detail: impl Into<String>) -> Problem {
    Problem::new(Kind::InvalidParameter, detail)
}

fn parse<T: std::str::FromStr>(
    q: &HashMap<String, String>,
    key: &str,
) -> Result<Option<T>, Problem> {
    match q.get(key) {
        None => Ok(None),
        Some(v) => v
            .parse()
            .map(Some)
            .map_err(|_| bad(format!("query parameter {key}={v:?} is not valid"))),
    }
}

fn triple<T: std::str::FromStr>(
    q: &HashMap<String, String>,
    key: &str,
) -> Result<Option<[T; 3]>, Problem> {
    let Some(v) = q.get(key) else { return Ok(None) };
    let parts: Result<Vec<T>, _> = v.split(',').map(|p| p.trim().parse::<T>()).collect();
    match parts.ok().and_then(|p| <[T; 3]>::try_from(p).ok()) {
        Some(t) => Ok(Some(t)),
        None => Err(bad(format!(
            "{key} must be three comma-separated numbers X,Y,Z, got {v:?}"
        ))),
    }
}

const KNOWN_PARAMS: [&str; 13] = [
    "density_factor",
    "method",
    "resolution",
    "voxel_size",
    "cubic",
    "padding",
    "origin",
    "dims",
    "fill",
    "name",
    "wait",
    "format",
    "max_voxels",
];

fn format_of(q: &HashMap<String, String>, headers: &HeaderMap) -> Result<Option<Format>, Problem> {
    if let Some(f) = q.get("format") {
        return Format::from_name(f).map(Some).ok_or_else(|| {
            Problem::new(
                Kind::UnsupportedMediaType,
                format!("format={f:?} is not one of obj, glb, gltf, stl, ply"),
            )
        });
    }
    let ct = headers
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .unwrap_or("");
    let ct = ct
        .split(';')
        .next()
        .unwrap_or("")
        .trim()
        .to_ascii_lowercase();
    Ok(match ct.as_str() {
        "model/obj" | "text/plain" => Some(Format::Obj),
        "model/gltf-binary" => Some(Format::Glb),
        "model/gltf+json" => Some(Format::Gltf),
        "model/stl" | "model/x.stl-binary" | "model/x.stl-ascii" | "application/sla" => {
            Some(Format::Stl)
        }
        "model/ply" | "application/ply" | "model/x-ply" => Some(Format::Ply),
        // curl --data-binary sends x-www-form-urlencoded unless told otherwise: sniff those too.
        ""
        | "application/octet-stream"
        | "application/gzip"
        | "application/x-www-form-urlencoded" => None,
        other => {
            return Err(Problem::new(
                Kind::UnsupportedMediaType,
                format!(
                    "Content-Type {other:?} is not a mesh type; use model/obj, model/gltf-binary, model/gltf+json, model/stl, model/ply or ?format="
                ),
            ));
        }
    })
}

fn mesh_problem(e: MeshError) -> Problem {
    let kind = match &e {
        MeshError::ExternalRefused { .. } => Kind::ExternalResource,
        MeshError::TooManyTriangles { .. } => Kind::TooManyTriangles,
        MeshError::UnknownFormat => Kind::UnsupportedMediaType,
        MeshError::TooLarge(_) => Kind::BodyTooLarge,
        _ => Kind::InvalidMesh,
    };
    Problem::new(kind, e.to_string())
}

async fn voxelize(
    State(app): State<Arc<App>>,
    Query(q): Query<HashMap<String, String>>,
    headers: HeaderMap,
    body: Body,
) -> Result<Response, Problem> {
    if let Some(k) = q.keys().find(|k| !KNOWN_PARAMS.contains(&k.as_str())) {
        return Err(bad(format!(
            "unknown query parameter {k:?}; known: {}",
            KNOWN_PARAMS.join(", ")
        )));
    }
    let method = match q.get("method").map(String::as_str) {
        None => MethodSpec::Bits(Method::Solid),
        Some("density") => match parse::<u32>(&q, "density_factor")?.unwrap_or(2) {
            f @ (2 | 4) => MethodSpec::Density(f),
            f => return Err(bad(format!("density_factor must be 2 or 4, got {f}"))),
        },
        Some(m) => MethodSpec::Bits(
            m.parse()
                .map_err(|e: String| bad(e.replace("interior", "interior, density")))?,
        ),
    };
    let fill: crate::engine::fill::Fill = q
        .get("fill")
        .map(|f| f.parse().map_err(|e: String| bad(e)))
        .transpose()?
        .unwrap_or(crate::engine::fill::Fill::Parity);
    let padding = parse::<u32>(&q, "padding")?.unwrap_or(0);
    let cubic = parse::<bool>(&q, "cubic")?.unwrap_or(false);
    let wait = parse::<f64>(&q, "wait")?.unwrap_or(0.0);
    if !(0.0..=300.0).contains(&wait) {
        return Err(bad("wait must be between 0 and 300 seconds"));
    }
    let spec = match (
        triple::<f64>(&q, "origin")?,
        triple::<u32>(&q, "dims")?,
        parse::<f64>(&q, "voxel_size")?,
        parse::<u32>(&q, "resolution")?,
    ) {
        (Some(origin), Some(dims), Some(voxel_size), None) => GridSpec::Explicit {
            origin,
            voxel_size,
            dims,
        },
        (Some(_), _, _, _) | (_, Some(_), _, _) => {
            return Err(bad(
                "an explicit grid needs origin, dims and voxel_size together (and no resolution)",
            ));
        }
        (None, None, Some(size), None) => GridSpec::VoxelSize { size, cubic },
        (None, None, None, r) => GridSpec::Resolution {
            n: r.unwrap_or(256),
            cubic,
        },
        (None, None, Some(_), Some(_)) => {
            return Err(bad("give resolution or voxel_size, not both"));
        }
    };
    let max_voxels = parse::<u64>(&q, "max_voxels")?
        .unwrap_or(app.config.max_voxels)
        .min(app.config.max_voxels);
    let format = format_of(&q, &headers)?;
    let limit = app.config.max_body_bytes;
    let bytes: Bytes = axum::body::to_bytes(body, limit).await.map_err(|_| {
        Problem::new(
            Kind::BodyTooLarge,
            format!("the request body is larger than {limit} bytes"),
        )
    })?;
    if bytes.is_empty() {
        return Err(Problem::new(
            Kind::InvalidMesh,
            "the request body is empty; send the mesh file as the body",
        ));
    }
    let opts = LoadOptions {
        external: ExternalResources::Deny,
        max_triangles: app.config.max_triangles,
        max_decompressed_bytes: limit as u64 * 16,
    };
    let (mesh, diagnostics, sha, format_name) = tokio::task::spawn_blocking(move || {
        let m = mesh::load_bytes(&bytes, format, &opts)?;
        let d = m.diagnostics();
        let name = format
            .or_else(|| Format::sniff(&bytes))
            .map_or("gzip", Format::name);
        Ok::<_, MeshError>((m, d, hex_sha256(&bytes), name.to_string()))
    })
    .await
    .map_err(|e| Problem::new(Kind::Internal, e.to_string()))?
    .map_err(mesh_problem)?;
    let grid = Grid::fit(
        diagnostics.bbox_min,
        diagnostics.bbox_max,
        spec,
        padding,
        GridLimits { max_voxels },
    )
    .map_err(|e| match e {
        GridError::TooManyVoxels { .. } | GridError::AxisTooLong { .. } => {
            Problem::new(Kind::GridTooLarge, e.to_string())
        }
        other => bad(other.to_string()),
    })?;
    if let MethodSpec::Density(f) = method {
        crate::engine::density::fine_grid(&grid, f, GridLimits { max_voxels }).map_err(|e| {
            Problem::new(
                Kind::GridTooLarge,
                format!("density needs a {f}× finer grid: {e}"),
            )
        })?;
    }
    let work = Work {
        mesh,
        diagnostics,
        grid,
        method,
        fill,
        name: q.get("name").cloned(),
        format: format_name,
        sha256: sha,
    };
    let id = app.new_id();
    let (view, mut rx) = match app
        .jobs
        .submit(
            id.clone(),
            work,
            super::jobs::rfc3339(std::time::SystemTime::now()),
        )
        .await
    {
        Ok(v) => v,
        Err(Refused::Full { capacity }) => {
            return Err(Problem::new(
                Kind::QueueFull,
                format!("{capacity} jobs are already waiting; retry later"),
            )
            .retry_after(5));
        }
        Err(Refused::Closed) => {
            return Err(Problem::new(
                Kind::ShuttingDown,
                "the server is shutting down; retry on another replica",
            ));
        }
    };
    if wait > 0.0 {
        // The guard wait_for returns is not Send: test it and drop it in one statement.
        let finished =
            tokio::time::timeout(Duration::from_secs_f64(wait), rx.wait_for(|s| s.is_final()))
                .await
                .is_ok_and(|r| r.is_ok());
        if finished {
            let job = app.jobs.view(&id).await.expect("job exists");
            match (job.state, &job.volume_id) {
                (JobState::Succeeded, Some(v)) => {
                    if let Some(meta) = app.store.get(v) {
                        let mut r = (StatusCode::CREATED, axum::Json(meta)).into_response();
                        r.headers_mut().insert(
                            header::LOCATION,
                            HeaderValue::from_str(&format!("/v1/volumes/{v}")).expect("ascii"),
                        );
                        return Ok(r);
                    }
                }
                _ => {
                    if let Some(mut p) = job.problem.clone() {
                        p.instance = Some(format!("/v1/jobs/{id}"));
                        return Err(p);
                    }
                }
            }
        }
    }
    let view = app.jobs.view(&id).await.unwrap_or(view);
    let mut r = (StatusCode::ACCEPTED, axum::Json(view)).into_response();
    r.headers_mut().insert(
        header::LOCATION,
        HeaderValue::from_str(&format!("/v1/jobs/{id}")).expect("ascii"),
    );
    Ok(r)
}

fn not_found(what: &str, id: &str) -> Problem {
    Problem::new(Kind::NotFound, format!("no {what} with id {id:?}"))
}

async fn get_job(State(app): State<Arc<App>>, Path(id): Path<String>) -> Result<Response, Problem> {
    let v = app
        .jobs
        .view(&id)
        .await
        .ok_or_else(|| not_found("job", &id))?;
    Ok(axum::Json(v).into_response())
}

async fn cancel_job(
    State(app): State<Arc<App>>,
    Path(id): Path<String>,
) -> Result<Response, Problem> {
    match app.jobs.cancel(&id).await {
        None => Err(not_found("job", &id)),
        Some(Ok(v)) => Ok(axum::Json(v).into_response()),
        Some(Err(state)) => Err(Problem::new(
            Kind::NotCancelable,
            format!("job {id} has already {}", state.name()),
        )),
    }
}

async fn list_volumes(
    State(app): State<Arc<App>>,
    Query(q): Query<HashMap<String, String>>,
) -> Result<Response, Problem> {
    let limit = parse::<usize>(&q, "limit")?.unwrap_or(100);
    if !(1..=1000).contains(&limit) {
        return Err(bad("limit must be between 1 and 1000"));
    }
    let after = q.get("after").map(String::as_str);
    let (page, more) = app.store.list(after, limit);
    let next = if more {
        page.last()
            .map(|m| format!("/v1/volumes?after={}&limit={limit}", m.id))
    } else {
        None
    };
    Ok(axum::Json(json!({ "volumes": page, "next": next })).into_response())
}

async fn get_volume(
    State(app): State<Arc<App>>,
    Path(id): Path<String>,
) -> Result<Response, Problem> {
    Ok(axum::Json(app.store.get(&id).ok_or_else(|| not_found("volume", &id))?).into_response())
}

async fn delete_volume(
    State(app): State<Arc<App>>,
    Path(id): Path<String>,
) -> Result<Response, Problem> {
    match app.store.delete(&id) {
        Ok(true) => Ok(StatusCode::NO_CONTENT.into_response()),
        Ok(false) => Err(not_found("volume", &id)),
        Err(e) => Err(Problem::new(Kind::Internal, e.to_string())),
    }
}

async fn volume_data(
    State(app): State<Arc<App>>,
    Path(id): Path<String>,
    Query(q): Query<HashMap<String, String>>,
    headers: HeaderMap,
) -> Result<Response, Problem> {
    let format = match q.get("format") {
        None => VolumeFormat::Vxl,
        Some(f) => VolumeFormat::from_name(f)
            .ok_or_else(|| bad(format!("format={f:?} is not one of vxl, binvox, npy, raw")))?,
    };
    let meta = app.store.get(&id).ok_or_else(|| not_found("volume", &id))?;
    if meta.kind == "density" && format == VolumeFormat::Binvox {
        return Err(bad(
            "binvox holds one bit per voxel; download a density volume as vxl, npy or raw",
        ));
    }
    let etag = format!("\"{}-{}\"", &meta.sha256[..16], format.name());
    if headers
        .get(header::IF_NONE_MATCH)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| v.split(',').any(|t| t.trim() == etag || t.trim() == "*"))
    {
        let mut r = StatusCode::NOT_MODIFIED.into_response();
        r.headers_mut()
            .insert(header::ETAG, HeaderValue::from_str(&etag).expect("ascii"));
        return Ok(r);
    }
    let stored = app
        .store
        .read(&id)
        .map_err(|e| Problem::new(Kind::Internal, e.to_string()))?
        .ok_or_else(|| not_found("volume", &id))?;
    let (bytes, media) = match format {
        VolumeFormat::Vxl => (stored, VXL_MEDIA_TYPE),
        other => {
            let out = tokio::task::spawn_blocking(move || -> Result<Vec<u8>, String> {
                let (v, _) = vxl::decode(&stored).map_err(|e| e.to_string())?;
                other.encode(&v).map_err(|e| e.to_string())
            })
            .await
            .map_err(|e| Problem::new(Kind::Internal, e.to_string()))?
            .map_err(|e| Problem::new(Kind::Internal, format!("stored volume {id}: {e}")))?;
            (
                out,
                match other {
                    VolumeFormat::Npy => "application/x-npy",
                    VolumeFormat::Binvox => "application/x-binvox",
                    _ => "application/octet-stream",
                },
            )
        }
    };
    let name = meta.name.clone().unwrap_or_else(|| id.clone()).replace(
        |c: char| !c.is_ascii_alphanumeric() && c != '-' && c != '_',
        "_",
    );
    let mut r = bytes.into_response();
    let h = r.headers_mut();
    h.insert(header::CONTENT_TYPE, HeaderValue::from_static(media));
    h.insert(header::ETAG, HeaderValue::from_str(&etag).expect("ascii"));
    h.insert(
        header::CACHE_CONTROL,
        HeaderValue::from_static("private, max-age=0, must-revalidate"),
    );
    if let Ok(v) = HeaderValue::from_str(&format!(
        "attachment; filename=\"{name}.{}\"",
        format.name()
    )) {
        h.insert(header::CONTENT_DISPOSITION, v);
    }
    Ok(r)
}

async fn healthz() -> Response {
    axum::Json(json!({ "status": "ok" })).into_response()
}

async fn readyz(State(app): State<Arc<App>>) -> Result<Response, Problem> {
    if !app.store.writable() {
        return Err(Problem::new(Kind::Internal, "the store is not writable").retry_after(5));
    }
    Ok(axum::Json(json!({
        "status": "ready",
        "engine": app.engine.describe(),
        "queue_depth": app.jobs.depth().await,
        "running": app.jobs.running().await,
        "stored_bytes": app.store.used_bytes(),
    }))
    .into_response())
}

async fn metrics(State(app): State<Arc<App>>) -> Response {
    let mut r = app.metrics.render(&app.jobs).await.into_response();
    r.headers_mut().insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("text/plain; version=0.0.4"),
    );
    r
}

async fn openapi() -> Response {
    let mut r = OPENAPI.into_response();
    r.headers_mut().insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("application/yaml"),
    );
    r
}
