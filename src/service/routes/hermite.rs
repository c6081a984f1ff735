//! `GET /v1/volumes/{id}/hermite`: the Hermite data of the solid of a stored volume's kept
//! mesh on its grid (`app::hermite`, layout in docs/format.md, "Hermite data (.npz)"). Checked
//! in order before the work: the volume, that it keeps its mesh, the memory for the mesh and
//! its solid; then the solid's differing edges against `--max-triangles` (one edge a triangle's
//! worth) and the memory for their Hermite data and its `.npz`. The data depends only on the
//! volume, so its ETag is known first (a `304` computes nothing).

use axum::extract::Path;
use axum::http::{HeaderMap, HeaderValue, header};
use axum::response::{IntoResponse, Response};

use super::super::problem::Problem;
use super::AppState;
use super::conditional;
use super::volumes::{Caller, etag_sha, meta_of};
use crate::app::hermite::{self, MeshSolid};
use crate::app::{Error, ErrorKind};
use crate::cancel::Control;

/// Bytes the `.npz` of Hermite data takes while it is written, per edge: its arrays (74
/// bytes) and the zip they are written to, no larger.
pub const NPZ_BYTES_PER_EDGE: u64 = 160;

/// The solid of volume `meta`'s kept mesh, admitted by the memory budget (held by the permit
/// returned), with its edges checked against `--max-triangles`.
pub(super) async fn solid_of_stored(
    app: &crate::service::App,
    meta: &crate::app::store::VolumeMeta,
    what: &str,
    ctl: &Control,
) -> Result<(MeshSolid, crate::app::memory::MemoryPermit), Problem> {
    // Said before any memory is asked for.
    crate::app::sources::require_kept(meta).map_err(|e| {
        e.context(format!(
            "{what} is computed from the mesh the volume was made from"
        ))
    })?;
    let permit = app
        .admit(
            hermite::stored_solid_cost(meta),
            &format!("the solid of {what}"),
        )
        .await?;
    let s = hermite::stored_solid(&*app.store, meta, &app.limits, ctl).await?;
    let max = app.limits.max_triangles as u64;
    if s.faces > max {
        return Err(Error::new(
            ErrorKind::TooManyTriangles,
            format!(
                "the solid of volume {} has {} differing edges, over the limit of {max} \
                 (--max-triangles): {what} needs one crossing each; use a coarser grid",
                meta.id, s.faces
            ),
        )
        .into());
    }
    Ok((s, permit))
}

pub async fn hermite(
    axum::extract::State(app): AppState,
    caller: Caller,
    Path(id): Path<String>,
    headers: HeaderMap,
) -> Result<Response, Problem> {
    let meta = meta_of(&app, &caller, &id).await?;
    let etag = format!("\"{}-hermite\"", etag_sha(&meta.sha256));
    let what = || format!("the Hermite data of volume {id}");
    if let Some(not_modified) = conditional::preconditions(&headers, &etag, what)? {
        return Ok(not_modified);
    }
    let ctl = Control::new();
    let (s, solid) = solid_of_stored(&app, &meta, &what(), &ctl).await?;
    let more = s
        .hermite_bytes()
        .saturating_add(s.faces.saturating_mul(NPZ_BYTES_PER_EDGE));
    let data = app.admit(more, &what()).await?;
    let h = hermite::stored_hermite(s, &ctl).await?;
    let bytes =
        crate::app::ops::blocking(move || Ok(crate::codec::npz::encode_hermite(&h.hermite)))
            .await?;
    drop((solid, data));
    let mut r = bytes.into_response();
    conditional::representation_headers(&mut r, &etag);
    let h = r.headers_mut();
    h.insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("application/octet-stream"),
    );
    let disposition = super::disposition::attachment(meta.name.as_deref(), &id, "npz");
    if let Ok(v) = HeaderValue::from_str(&disposition) {
        h.insert(header::CONTENT_DISPOSITION, v);
    }
    Ok(r)
}
