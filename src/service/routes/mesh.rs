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
use crate::app::ops::blocking_with;
use crate::app::{Error, ErrorKind, cost, hermite, stream};
use crate::cancel::Control;
use crate::extract::Algorithm;
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
    if algorithm == Algorithm::DualContouring {
        return dual_contouring(&app, &meta, format, coding, &etag).await;
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
            mesh::build_cost(&planned).saturating_add(format.size_bound(
                planned.triangles,
                planned.triangles,
                planned.colours.is_some(),
            )),
            &format!(
                "a mesh of volume {id} (up to {} triangles)",
                planned.triangles
            ),
        )
        .await?;
    let m = mesh::build_async(planned, &ctl).await?;
    Ok(respond(
        m,
        (loading, building),
        &meta,
        format,
        coding,
        &etag,
    ))
}

/// Dual contouring of the kept mesh's Hermite data (`app::hermite`): the solid (admitted and
/// bounded as `GET …/hermite` does), the triangle bound of its quads, the memory for the
/// Hermite data and the mesh, then the contouring.
async fn dual_contouring(
    app: &crate::service::App,
    meta: &crate::app::store::VolumeMeta,
    format: write::MeshFormat,
    coding: Coding,
    etag: &str,
) -> Result<Response, Problem> {
    let id = &meta.id;
    let what = format!("the dual-contouring mesh of volume {id}");
    let ctl = Control::new();
    let (s, solid) = super::hermite::solid_of_stored(app, meta, &what, &ctl).await?;
    // Surface nets' quads, split: two triangles per differing edge.
    let triangles = 2 * s.faces;
    let max = app.limits.max_triangles as u64;
    if triangles > max {
        return Err(Error::new(
            ErrorKind::TooManyTriangles,
            format!(
                "{what} could have up to {triangles} triangles, over the limit of {max}: \
                 extract a coarser volume"
            ),
        )
        .into());
    }
    let building = app
        .admit(
            s.hermite_bytes()
                .saturating_add(triangles.saturating_mul(mesh::BYTES_PER_TRIANGLE))
                .saturating_add(format.size_bound(triangles, triangles, false)),
            &format!("{what} (up to {triangles} triangles)"),
        )
        .await?;
    let h = hermite::stored_hermite(s, &ctl).await?;
    let m = blocking_with(&ctl, move |ctl| hermite::dual_contour(&h, ctl)).await?;
    Ok(respond(m, (solid, building), meta, format, coding, etag))
}

/// The mesh `m` written while it is sent, `held` (its memory) kept until the last byte.
fn respond<H: Send + 'static>(
    m: crate::extract::TriMesh,
    held: H,
    meta: &crate::app::store::VolumeMeta,
    format: write::MeshFormat,
    coding: Coding,
    etag: &str,
) -> Response {
    let id = &meta.id;
    let len = write::encoded_len(&m, format);
    let body = stream::from_writer(move |w| {
        // The memory stays counted until the mesh is written.
        let _held = held;
        write::write(&m, format, w)
    });
    let mut r = conditional::encode(body.fuse(), coding);
    conditional::representation_headers(&mut r, etag);
    let h = r.headers_mut();
    if let (Some(n), Coding::Identity) = (len, coding) {
        h.insert(header::CONTENT_LENGTH, HeaderValue::from(n));
    }
    h.insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static(format.media_type()),
    );
    let disposition = super::disposition::attachment(meta.name.as_deref(), id, format.as_str());
    if let Ok(v) = HeaderValue::from_str(&disposition) {
        h.insert(header::CONTENT_DISPOSITION, v);
    }
    r
}
