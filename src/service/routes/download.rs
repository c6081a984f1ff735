//! `GET /v1/volumes/{id}/data`: a stored volume in a download format, with its HTTP semantics
//! (`conditional`): one ETag per content coding, `304`, `If-Match`, and byte ranges of the
//! identity representation so that an interrupted download resumes.

use axum::body::Body;
use axum::extract::Path;
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use futures_util::StreamExt;
use serde::Deserialize;

use super::super::extract::Query;
use super::super::problem::Problem;
use super::AppState;
use super::conditional::{self, Coding, Ranged};
use super::volumes::{Caller, etag_sha, meta_of};
use crate::app::{Error, ErrorKind, cost, ops};
use crate::codec::VolumeFormat;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DataQuery {
    format: Option<String>,
    /// npy and raw of a channel volume: one channel (`rgba`, `material`) instead of occupancy.
    attributes: Option<String>,
}

/// The identity representation's ETag of a volume whose content is `sha256` in `format`
/// (with one attribute channel: `attributes`).
pub fn data_etag(sha256: &str, format: VolumeFormat, attributes: Option<&str>) -> String {
    match attributes {
        None => format!("\"{}-{}\"", etag_sha(sha256), format.name()),
        Some(a) => format!("\"{}-{}-{a}\"", etag_sha(sha256), format.name()),
    }
}

pub async fn data(
    axum::extract::State(app): AppState,
    caller: Caller,
    Path(id): Path<String>,
    Query(q): Query<DataQuery>,
    headers: HeaderMap,
) -> Result<Response, Problem> {
    let format = match &q.format {
        None => VolumeFormat::Vxl,
        Some(f) => VolumeFormat::from_name(f).ok_or_else(|| {
            Problem::invalid(format!(
                "format={f:?} is not one of {}",
                VolumeFormat::names()
            ))
        })?,
    };
    let meta = meta_of(&app, &caller, &id).await?;
    ops::check_format(meta.kind, format)?;
    ops::check_download(meta.kind, &meta.grid, format, &app.limits)?;
    crate::app::attributes::check(&meta, format, q.attributes.as_deref())?;
    // The coding is chosen before anything else, so that a 304 carries the ETag the 200 would.
    // A range asks for bytes of the identity representation (`.vxl` is compressed already):
    // clients resume a download without negotiating a coding, and the parts of one file must
    // come from one representation.
    let coding = if headers.contains_key(header::RANGE) {
        Coding::Identity
    } else {
        conditional::negotiate(&headers, format != VolumeFormat::Vxl)
    };
    let etag = conditional::coded_etag(
        &data_etag(&meta.sha256, format, q.attributes.as_deref()),
        coding,
    );
    if let Some(not_modified) = conditional::preconditions(&headers, &etag, || {
        format!("volume {id} as {}", format.name())
    })? {
        return Ok(not_modified);
    }
    // A conversion holds the decoded volume while it streams: that memory comes out of the
    // process-wide budget, for as long as the download lasts. A range streams the whole
    // conversion and drops the bytes before it (no more memory than a whole download).
    let hold = match format {
        VolumeFormat::Vxl => None,
        _ => Some(
            app.admit(
                cost::conversion(&meta),
                &format!("converting volume {id} to {}", format.name()),
            )
            .await?,
        ),
    };
    let download = ops::download(&*app.store, &meta, format, q.attributes.clone()).await?;
    // Ranges need the length up front: every format but `.binvox` (run-length encoded) has it.
    let part = match (coding, download.len) {
        (Coding::Identity, Some(n)) => Some((conditional::range(&headers, n, &etag), n)),
        _ => None,
    };
    if let Some((Ranged::Unsatisfiable, n)) = part {
        let mut r = Problem::from(Error::new(
            ErrorKind::RangeNotSatisfiable,
            format!(
                "{:?} holds no byte of the {n} bytes of volume {id} as {}",
                headers
                    .get(header::RANGE)
                    .map(|v| String::from_utf8_lossy(v.as_bytes())),
                format.name()
            ),
        ))
        .into_response();
        if let Ok(v) = HeaderValue::from_str(&format!("bytes */{n}")) {
            r.headers_mut().insert(header::CONTENT_RANGE, v);
        }
        r.headers_mut()
            .insert(header::ACCEPT_RANGES, HeaderValue::from_static("bytes"));
        return Ok(r);
    }
    let npz = crate::app::attributes::is_npz(format, q.attributes.as_deref());
    let extension = if npz {
        "indices.npz"
    } else {
        format.extension()
    };
    let disposition = super::disposition::attachment(meta.name.as_deref(), &id, extension);
    // The first chunk before the status line: a volume that fits in it (most `.vxl`s) and is
    // damaged, or a conversion that fails at once, is still a problem document; past it, a
    // failure can only end the transfer early (the client sees a short body).
    let mut rest = download.body.fuse();
    let first = rest.next().await.transpose().map_err(Error::from)?;
    let whole = futures_util::stream::iter(first.map(Ok))
        .chain(rest)
        .map(move |c| {
            let _hold = &hold;
            c
        });
    let (mut r, length) = match part {
        Some((Ranged::Part { start, end }, n)) => {
            let body = Body::from_stream(conditional::slice(whole, start, end));
            let mut r = (StatusCode::PARTIAL_CONTENT, body).into_response();
            if let Ok(v) = HeaderValue::from_str(&format!("bytes {start}-{end}/{n}")) {
                r.headers_mut().insert(header::CONTENT_RANGE, v);
            }
            (r, Some(end - start + 1))
        }
        _ => (
            conditional::encode(whole, coding),
            download.len.filter(|_| coding == Coding::Identity),
        ),
    };
    conditional::representation_headers(&mut r, &etag);
    let h = r.headers_mut();
    if let Some(n) = length {
        h.insert(header::CONTENT_LENGTH, HeaderValue::from(n));
    }
    if part.is_some() {
        h.insert(header::ACCEPT_RANGES, HeaderValue::from_static("bytes"));
    }
    h.insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static(if npz {
            "application/zip"
        } else {
            format.media_type()
        }),
    );
    if let Ok(v) = HeaderValue::from_str(&disposition) {
        h.insert(header::CONTENT_DISPOSITION, v);
    }
    Ok(r)
}
