//! `POST /v1/voxelize`: the query and headers become a [`Submission`] and the body its upload,
//! handed to the application's one submission path ([`jobs::submit`]: admission, preparation,
//! the record, queued or waited for), whose outcome becomes the response. Translation only.

use std::time::Duration;

use axum::body::Body;
use axum::http::{HeaderMap, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde::Deserialize;

use super::super::extract::{Query, check_content_encoding, flag, read_body, triple};
use super::super::problem::Problem;
use super::{AppState, check_name, created, set_location};
use crate::app::jobs::{self, Jobs, Submission, Submitted};
use crate::app::queue::Owner;
use crate::app::request::{Band, MethodName, MethodParams};
use crate::app::{self, Error, ErrorKind, GridOptions, MethodSpec};
use crate::engine::fill::Fill;
use crate::mesh::Format;
use crate::names::Named;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VoxelizeQuery {
    method: Option<MethodName>,
    density_factor: Option<u32>,
    /// distance: world units.
    thickness: Option<f64>,
    /// sdf: voxels (1..=64) or `all`.
    band: Option<String>,
    fill: Option<Fill>,
    resolution: Option<u32>,
    voxel_size: Option<f64>,
    #[serde(default, deserialize_with = "triple::deserialize")]
    origin: Option<[f64; 3]>,
    #[serde(default, deserialize_with = "triple::deserialize")]
    dims: Option<[u32; 3]>,
    #[serde(default, deserialize_with = "flag::deserialize")]
    cubic: bool,
    /// Colour channel (solid, surface, conservative, interior, distance).
    #[serde(default, deserialize_with = "flag::deserialize")]
    color: bool,
    /// Material-id channel (the same methods).
    #[serde(default, deserialize_with = "flag::deserialize")]
    material: bool,
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

/// The mesh media types, one row per mesh format: the type a client should send first, then
/// the others taken for it. Messages list the formats and their first types in this order.
const MEDIA_TYPES: &[(Format, &[&str])] = &[
    (Format::Obj, &["model/obj", "text/plain"]),
    (Format::Glb, &["model/gltf-binary"]),
    (Format::Gltf, &["model/gltf+json"]),
    (
        Format::Stl,
        &[
            "model/stl",
            "model/x.stl-binary",
            "model/x.stl-ascii",
            "application/sla",
        ],
    ),
    (
        Format::Ply,
        &["model/ply", "application/ply", "model/x-ply"],
    ),
];

/// Content-Types that say nothing of the mesh: its format is sniffed. (curl --data-binary
/// sends x-www-form-urlencoded unless told otherwise.)
const SNIFFED: &[&str] = &[
    "",
    "application/octet-stream",
    "application/gzip",
    "application/zip",
    "application/x-www-form-urlencoded",
];

/// The mesh format from `?format=`, else the Content-Type; `None` to sniff.
fn format_of(q: &VoxelizeQuery, headers: &HeaderMap) -> app::Result<Option<Format>> {
    if let Some(f) = &q.format {
        return Format::from_name(f).map(Some).ok_or_else(|| {
            let names: Vec<&str> = MEDIA_TYPES.iter().map(|(f, _)| f.name()).collect();
            Error::new(
                ErrorKind::UnsupportedMediaType,
                format!("format={f:?} is not one of {}", names.join(", ")),
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
    if SNIFFED.contains(&ct.as_str()) {
        return Ok(None);
    }
    match MEDIA_TYPES
        .iter()
        .find(|(_, types)| types.contains(&ct.as_str()))
    {
        Some((f, _)) => Ok(Some(*f)),
        None => {
            let firsts: Vec<&str> = MEDIA_TYPES.iter().map(|(_, types)| types[0]).collect();
            Err(Error::new(
                ErrorKind::UnsupportedMediaType,
                format!(
                    "Content-Type {ct:?} is not a mesh type; use {} or ?format=",
                    firsts.join(", ")
                ),
            ))
        }
    }
}

pub async fn submit(
    axum::extract::State(app): AppState,
    Query(q): Query<VoxelizeQuery>,
    owner: Option<axum::Extension<Owner>>,
    request_id: Option<axum::Extension<super::RequestId>>,
    headers: HeaderMap,
    body: Body,
) -> Result<Response, Problem> {
    let owner = owner.map(|axum::Extension(o)| o);
    let method = q.method.unwrap_or(MethodName::DEFAULT);
    let band = match &q.band {
        Some(b) => Some(Band::parse(b).map_err(Problem::invalid)?),
        None => None,
    };
    let method = MethodSpec::with(
        method.name(),
        MethodParams {
            density_factor: q.density_factor,
            thickness: q.thickness,
            band,
        },
    )?;
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
        fill: method.fill(q.fill)?,
        attributes: method.attributes(crate::app::request::Want {
            colour: q.color,
            material: q.material,
        })?,
        limits,
        name: q.name,
        owner,
        wait: Duration::from_secs_f64(q.wait),
        request_id: request_id.map(|axum::Extension(r)| r.0),
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
        memory: Some(&app.memory),
    };
    // The response names the job it made (`JobId`) for the access log.
    let (id, mut r) = match jobs::submit(jobs, sub, upload).await? {
        Submitted::Done { id, meta } => (id, created(&meta)),
        Submitted::Failed { id, error } => {
            let mut p = Problem::from(error);
            p.instance = Some(format!("/v1/jobs/{id}"));
            (id, p.into_response())
        }
        Submitted::Pending(record) => {
            let (id, location) = (record.id.clone(), format!("/v1/jobs/{}", record.id));
            let mut r =
                (StatusCode::ACCEPTED, axum::Json(super::jobs::view(*record))).into_response();
            set_location(&mut r, &location);
            (id, r)
        }
    };
    r.extensions_mut().insert(super::JobId(id));
    Ok(r)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn format_for(format: Option<&str>, content_type: &str) -> app::Result<Option<Format>> {
        let q: VoxelizeQuery =
            serde_urlencoded::from_str(&format.map(|f| format!("format={f}")).unwrap_or_default())
                .unwrap();
        let mut headers = HeaderMap::new();
        headers.insert(header::CONTENT_TYPE, content_type.parse().unwrap());
        format_of(&q, &headers)
    }

    /// Every mesh format has one row of media types, and no type names two formats.
    #[test]
    fn every_mesh_format_has_its_media_types() {
        for f in Format::ALL {
            let rows = MEDIA_TYPES.iter().filter(|(g, _)| *g == f).count();
            assert_eq!(rows, 1, "{f}");
        }
        let mut seen = std::collections::HashSet::new();
        for (_, types) in MEDIA_TYPES {
            for t in *types {
                assert!(seen.insert(*t) && !SNIFFED.contains(t), "{t}");
            }
        }
    }

    /// The texts users see, as they were when written by hand.
    #[test]
    fn refusals_list_the_formats_and_types_as_before() {
        let e = format_for(Some("doc"), "model/obj").unwrap_err();
        assert_eq!(e.kind, ErrorKind::UnsupportedMediaType);
        assert_eq!(
            e.detail,
            "format=\"doc\" is not one of obj, glb, gltf, stl, ply"
        );
        let e = format_for(None, "Text/HTML; charset=utf-8").unwrap_err();
        assert_eq!(e.kind, ErrorKind::UnsupportedMediaType);
        assert_eq!(
            e.detail,
            "Content-Type \"text/html\" is not a mesh type; use model/obj, model/gltf-binary, model/gltf+json, model/stl, model/ply or ?format="
        );
    }

    #[test]
    fn types_and_names_choose_the_format() {
        assert_eq!(format_for(None, "model/x-ply").unwrap(), Some(Format::Ply));
        assert_eq!(format_for(None, "text/plain").unwrap(), Some(Format::Obj));
        assert_eq!(
            format_for(None, "application/x-www-form-urlencoded").unwrap(),
            None
        );
        assert_eq!(
            format_for(Some("GLB"), "model/obj").unwrap(),
            Some(Format::Glb)
        );
    }
}
