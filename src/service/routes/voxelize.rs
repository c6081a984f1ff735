//! `POST /v1/voxelize`: the query and headers become a [`Submission`] and the body its upload,
//! handed to the application's one submission path ([`jobs::submit`]: admission, preparation,
//! the record, queued or waited for), whose outcome becomes the response. Translation only.

use std::time::Duration;

use axum::body::Body;
use axum::http::{HeaderMap, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde::Deserialize;

use super::super::extract::{Query, check_content_encoding, read_body, triple};
use super::super::problem::Problem;
use super::{AppState, check_name, created, set_location};
use crate::app::jobs::{self, Jobs, Submission, Submitted};
use crate::app::queue::Owner;
use crate::app::request::MethodName;
use crate::app::{self, Error, ErrorKind, GridOptions, MethodSpec};
use crate::engine::fill::Fill;
use crate::mesh::Format;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VoxelizeQuery {
    method: Option<MethodName>,
    density_factor: Option<u32>,
    fill: Option<Fill>,
    resolution: Option<u32>,
    voxel_size: Option<f64>,
    #[serde(default, deserialize_with = "triple::deserialize")]
    origin: Option<[f64; 3]>,
    #[serde(default, deserialize_with = "triple::deserialize")]
    dims: Option<[u32; 3]>,
    #[serde(default)]
    cubic: bool,
    #[serde(default)]
    padding: u32,
    name: Option<String>,
    /// Seconds to wait for the job.
    #[serde(default)]
    wait: f64,
    /// The mesh format, when the Content-Type does not say.
    format: Option<String>,
    /// A lower voxel budget than the server's.
    max_voxels: Option<u64>,
}

/// The mesh format from `?format=`, else the Content-Type; `None` to sniff.
fn format_of(q: &VoxelizeQuery, headers: &HeaderMap) -> app::Result<Option<Format>> {
    if let Some(f) = &q.format {
        return Format::from_name(f).map(Some).ok_or_else(|| {
            Error::new(
                ErrorKind::UnsupportedMediaType,
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
            return Err(Error::new(
                ErrorKind::UnsupportedMediaType,
                format!(
                    "Content-Type {other:?} is not a mesh type; use model/obj, model/gltf-binary, model/gltf+json, model/stl, model/ply or ?format="
                ),
            ));
        }
    })
}

pub async fn submit(
    axum::extract::State(app): AppState,
    Query(q): Query<VoxelizeQuery>,
    owner: Option<axum::Extension<Owner>>,
    headers: HeaderMap,
    body: Body,
) -> Result<Response, Problem> {
    let owner = owner.map(|axum::Extension(o)| o);
    let method = match q.method {
        None => MethodSpec::Bits(crate::engine::Method::Solid),
        Some(m) => MethodSpec::new(crate::names::Named::name(m), q.density_factor)?,
    };
    if !(0.0..=app.limits.max_wait_s).contains(&q.wait) {
        return Err(Problem::invalid(format!(
            "wait must be between 0 and {} seconds",
            app.limits.max_wait_s
        )));
    }
    let grid = GridOptions {
        resolution: q.resolution,
        voxel_size: q.voxel_size,
        origin: q.origin,
        dims: q.dims,
        cubic: q.cubic,
    }
    .spec(app.limits.default_resolution)?;
    let mut limits = app.limits;
    limits.max_voxels = q
        .max_voxels
        .unwrap_or(limits.max_voxels)
        .min(limits.max_voxels);
    if let Some(name) = &q.name {
        check_name(name, &app.limits)?;
    }
    let format = format_of(&q, &headers)?;
    let gzip = check_content_encoding(&headers, true)?;
    let sub = Submission {
        format,
        grid,
        padding: q.padding,
        method,
        fill: q.fill.unwrap_or(Fill::Parity),
        limits,
        name: q.name,
        owner,
        wait: Duration::from_secs_f64(q.wait),
    };
    // Read once the queue has said it would take the job; held in the in-flight budget until
    // queued.
    let upload = async {
        let body = read_body(&app, &headers, body, limits.max_body_bytes).await?;
        // The body's content is at fault, not the request's form: like a gzip stream that
        // breaks off, an invalid mesh (422).
        if gzip && !body.bytes.starts_with(&[0x1f, 0x8b]) {
            return Err(Error::new(
                ErrorKind::InvalidMesh,
                "Content-Encoding says gzip, but the body is not gzip data",
            ));
        }
        Ok((body.bytes.clone(), body))
    };
    let jobs = Jobs {
        queue: &*app.queue,
        store: &*app.store,
        pool: Some(&app.ingest),
    };
    let record = match jobs::submit(jobs, sub, upload).await? {
        Submitted::Done(meta) => return Ok(created(&meta)),
        Submitted::Failed { id, error } => {
            let mut p = Problem::from(error);
            p.instance = Some(format!("/v1/jobs/{id}"));
            return Err(p);
        }
        Submitted::Pending(record) => *record,
    };
    let location = format!("/v1/jobs/{}", record.id);
    let mut r = (StatusCode::ACCEPTED, axum::Json(super::jobs::view(record))).into_response();
    set_location(&mut r, &location);
    Ok(r)
}
