//! `GET /v1/volumes/{id}/mesh?algorithm=…&format=…`: a stored volume's extracted mesh
//! (`app::mesh`), written while it is sent. Checked in order before the work: the parameters,
//! the volume, the memory to load it; then the triangle bound (`too-many-triangles`) and the
//! memory to build that many triangles. The mesh depends only on the volume's content, the
//! algorithm and the format, so its ETag is known before anything is built (a `304` builds
//! nothing).

use axum::extract::Path;
use axum::http::{HeaderMap, HeaderValue, header};
use axum::response::Response;
use futures_util::StreamExt;
use serde::Deserialize;

use super::super::extract::Query;
use super::super::problem::Problem;
use super::AppState;
use super::conditional::{self, Coding};
use super::volumes::{Caller, etag_sha, meta_of};
use crate::app::mesh::{self, MeshRequest};
use crate::app::{cost, stream};
use crate::cancel::Control;
use crate::extract::write;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeshQuery {
    algorithm: Option<String>,
    format: Option<String>,
}

pub async fn mesh(
    axum::extract::State(app): AppState,
    caller: Caller,
    Path(id): Path<String>,
    Query(q): Query<MeshQuery>,
    headers: HeaderMap,
) -> Result<Response, Problem> {
    let req = MeshRequest::parse(q.algorithm.as_deref(), q.format.as_deref())?;
    let (algorithm, format) = (req.algorithm, req.format);
    let meta = meta_of(&app, &caller, &id).await?;
    let coding = conditional::negotiate(&headers, format == write::MeshFormat::Obj);
    let etag = conditional::coded_etag(
        &format!(
            "\"{}-mesh-{}-{}\"",
            etag_sha(&meta.sha256),
            algorithm.as_str(),
            format.as_str()
        ),
        coding,
    );
    let what = || {
        format!(
            "the {} mesh of volume {id} as {}",
            algorithm.as_str(),
            format.as_str()
        )
    };
    if let Some(not_modified) = conditional::preconditions(&headers, &etag, what)? {
        return Ok(not_modified);
    }
    let loading = app
        .admit(
            cost::read_only(&meta, cost::bits_bytes(&meta.grid)),
            &format!("a mesh of volume {id}"),
        )
        .await?;
    let ctl = Control::new();
    let planned = mesh::plan_stored(&*app.store, &id, algorithm, &app.limits, &ctl).await?;
    let building = app
        .admit(
            mesh::build_cost(&planned)
                .saturating_add(format.size_bound(planned.triangles, planned.triangles)),
            &format!(
                "a mesh of volume {id} (up to {} triangles)",
                planned.triangles
            ),
        )
        .await?;
    let m = mesh::build_async(planned, &ctl).await?;
    let len = write::encoded_len(&m, format);
    let body = stream::from_writer(move |w| {
        // The memory stays counted until the mesh is written.
        let _held = (loading, building);
        write::write(&m, format, w)
    });
    let mut r = conditional::encode(body.fuse(), coding);
    conditional::representation_headers(&mut r, &etag);
    let h = r.headers_mut();
    if let (Some(n), Coding::Identity) = (len, coding) {
        h.insert(header::CONTENT_LENGTH, HeaderValue::from(n));
    }
    h.insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static(format.media_type()),
    );
    let disposition = super::disposition::attachment(meta.name.as_deref(), &id, format.as_str());
    if let Ok(v) = HeaderValue::from_str(&disposition) {
        h.insert(header::CONTENT_DISPOSITION, v);
    }
    Ok(r)
}
