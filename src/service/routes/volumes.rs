//! `/v1/volumes…`: listing, metadata, deletion and download of stored volumes, and the
//! operations on them (CSG, overlap, morphology, statistics, queries, normals, previews). Each
//! handler translates into an application call (`app::ops`) and back.

use axum::body::Body;
use axum::extract::Path;
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use futures_util::StreamExt;
use serde::Deserialize;
use serde_json::{Value, json};

use super::super::extract::{Json, Query};
use super::super::problem::Problem;
use super::{AppState, created};
use crate::app::queue::Owner;
use crate::app::store::VolumeMeta;
use crate::app::{
    CsgExpr, Error, ErrorKind, MorphologyRequest, PreviewRequest, PreviewView, QueryRequest, cost,
    ops,
};
use crate::codec::VolumeFormat;
use crate::names::choices;
use crate::volume::preview::{Axis, Projection};

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ListQuery {
    limit: Option<usize>,
    after: Option<String>,
}

pub async fn list(
    axum::extract::State(app): AppState,
    caller: Caller,
    Query(q): Query<ListQuery>,
) -> Result<Response, Problem> {
    let limit = q.limit.unwrap_or(app.limits.default_list_page);
    if !(1..=app.limits.max_list_page).contains(&limit) {
        return Err(Problem::invalid(format!(
            "limit must be between 1 and {}",
            app.limits.max_list_page
        )));
    }
    let (page, mut more, scanned) = visible_page(&app, &caller, q.after, limit).await?;
    // A page is bounded in bytes too (at least one volume a page): the rest is on the next
    // page. Each volume is serialised once, into the body.
    let mut body = br#"{"volumes":["#.to_vec();
    let mut last = None;
    for (n, m) in page.iter().enumerate() {
        let b = serde_json::to_vec(m).map_err(|e| Error::internal(e.to_string()))?;
        if n > 0 && body.len() + b.len() > app.limits.max_list_page_bytes {
            more = true;
            break;
        }
        if n > 0 {
            body.push(b',');
        }
        body.extend_from_slice(&b);
        last = Some(&m.id);
    }
    // Cut short by bytes: after the last one shown; else after the last one looked at (those
    // past the last shown were other tenants').
    let cut = last.is_some_and(|l| page.last().is_some_and(|p| &p.id != l));
    let next = more
        .then(|| if cut { last.cloned() } else { scanned })
        .flatten()
        .map(|id| format!("/v1/volumes?after={id}&limit={limit}"));
    body.extend_from_slice(br#"],"next":"#);
    body.extend_from_slice(&serde_json::to_vec(&next).expect("a string serialises"));
    body.push(b'}');
    let mut r = Body::from(body).into_response();
    r.headers_mut().insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("application/json"),
    );
    Ok(r)
}

/// Store pages read at most for one page of a caller's volumes: where other tenants' volumes
/// fill them, a page may hold fewer than `limit` (its `next` goes on from there).
const SCAN_PAGES: usize = 16;

/// Up to `limit` volumes after `after` that `caller` may see, whether more may follow, and the
/// id of the last volume looked at (where the next page starts).
async fn visible_page(
    app: &crate::service::App,
    caller: &Caller,
    mut after: Option<String>,
    limit: usize,
) -> Result<(Vec<VolumeMeta>, bool, Option<String>), Error> {
    let mut out = Vec::with_capacity(limit);
    for _ in 0..SCAN_PAGES {
        let (page, more) = app
            .store
            .list(after.as_deref(), limit - out.len())
            .await
            .map_err(Error::from)?;
        after = page.last().map(|m| m.id.clone()).or(after);
        out.extend(
            page.into_iter()
                .filter(|m| sees(caller, m.owner.as_deref())),
        );
        if !more || out.len() == limit {
            return Ok((out, more, after));
        }
    }
    Ok((out, true, after))
}

pub async fn get(
    axum::extract::State(app): AppState,
    caller: Caller,
    Path(id): Path<String>,
) -> Result<Response, Problem> {
    let meta = meta_of(&app, &caller, &id).await?;
    Ok(axum::Json(meta).into_response())
}

/// The API key a request was made with (`None`: the service needs no keys).
pub type Caller = Option<axum::Extension<Owner>>;

/// Whether `caller` may see what `owner` owns: everything without keys.
pub fn sees(caller: &Caller, owner: Option<&str>) -> bool {
    caller
        .as_ref()
        .is_none_or(|axum::Extension(o)| o.sees(owner))
}

/// The tenant that owns what `caller` makes (`None` without keys).
pub fn tenant(caller: &Caller) -> Option<String> {
    caller.as_ref().map(|axum::Extension(o)| o.tenant.clone())
}

/// A stored volume's catalogue entry (read before any work, for its cost), if `caller` may see
/// it: another tenant's volume is `not-found`, as one that does not exist.
async fn meta_of(
    app: &crate::service::App,
    caller: &Caller,
    id: &str,
) -> Result<VolumeMeta, Error> {
    app.store
        .get(id)
        .await
        .map_err(Error::from)?
        .filter(|m| sees(caller, m.owner.as_deref()))
        .ok_or_else(|| Error::not_found("volume", id))
}

pub async fn delete(
    axum::extract::State(app): AppState,
    caller: Caller,
    Path(id): Path<String>,
    headers: HeaderMap,
) -> Result<Response, Problem> {
    // Only a volume the caller may see may be deleted (with keys, its owner is read first).
    let meta = match (&caller, headers.get(header::IF_MATCH)) {
        (None, None) => None,
        _ => Some(meta_of(&app, &caller, &id).await?),
    };
    if let (Some(want), Some(meta)) = (headers.get(header::IF_MATCH), &meta) {
        let want = want.to_str().unwrap_or("");
        // Strong comparison: the ETag of any download of this volume's current content.
        let prefix = format!("\"{}-", etag_sha(&meta.sha256));
        let matches = want
            .split(',')
            .map(str::trim)
            .any(|t| t == "*" || (t.starts_with(&prefix) && t.ends_with('"')));
        if !matches {
            return Err(Error::new(
                ErrorKind::PreconditionFailed,
                format!("volume {id} does not match If-Match {want:?}"),
            )
            .into());
        }
    }
    if app.store.delete(&id).await.map_err(Error::from)? {
        Ok(StatusCode::NO_CONTENT.into_response())
    } else {
        Err(Error::not_found("volume", &id).into())
    }
}

/// The part of a volume's sha256 its ETags carry.
fn etag_sha(sha256: &str) -> &str {
    &sha256[..16.min(sha256.len())]
}

/// Does `If-None-Match` hold one of `tags` (weak comparison: `W/` is ignored), or `*`?
fn none_match_hits(headers: &HeaderMap, tags: &[String]) -> bool {
    headers
        .get_all(header::IF_NONE_MATCH)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .flat_map(|v| v.split(','))
        .map(|t| t.trim())
        .any(|t| t == "*" || tags.iter().any(|e| t.strip_prefix("W/").unwrap_or(t) == e))
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DataQuery {
    format: Option<String>,
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
    let kind = meta.kind;
    ops::check_format(kind, format)?;
    ops::check_conversion(&meta.grid, format, &app.limits)?;
    // One ETag per representation: the identity body's, and (set on the way out, see
    // `etag_per_coding`) one per content coding; a cached copy of any of them is fresh.
    let etag = format!("\"{}-{}\"", etag_sha(&meta.sha256), format.name());
    let etag_value = HeaderValue::from_str(&etag).map_err(|e| Error::internal(e.to_string()))?;
    let tags: Vec<String> = std::iter::once(etag.clone())
        .chain(CODINGS.iter().map(|c| coded_etag(&etag, c)))
        .collect();
    if none_match_hits(&headers, &tags) {
        let mut r = StatusCode::NOT_MODIFIED.into_response();
        r.headers_mut().insert(header::ETAG, etag_value);
        return Ok(r);
    }
    // A conversion holds the decoded volume while it streams: that memory comes out of the
    // process-wide budget, for as long as the download lasts.
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
    let download = ops::download(&*app.store, &meta, format).await?;
    let media = format.media_type();
    let disposition = super::disposition::attachment(meta.name.as_deref(), &id, format.extension());
    // The first chunk before the status line: a volume that fits in it (most `.vxl`s) and is
    // damaged, or a conversion that fails at once, is still a problem document; past it, a
    // failure can only end the transfer early (the client sees a short body).
    let mut rest = download.body.fuse();
    let first = rest.next().await.transpose().map_err(Error::from)?;
    let body = futures_util::stream::iter(first.map(Ok))
        .chain(rest)
        .map(move |c| {
            let _hold = &hold;
            c
        });
    let mut r = Body::from_stream(body).into_response();
    let h = r.headers_mut();
    if let Some(n) = download.len {
        h.insert(header::CONTENT_LENGTH, HeaderValue::from(n));
    }
    h.insert(header::CONTENT_TYPE, HeaderValue::from_static(media));
    h.insert(header::ETAG, etag_value);
    h.insert(
        header::CACHE_CONTROL,
        HeaderValue::from_static("private, max-age=0, must-revalidate"),
    );
    if let Ok(v) = HeaderValue::from_str(&disposition) {
        h.insert(header::CONTENT_DISPOSITION, v);
    }
    Ok(r)
}

/// Content codings the compression layer may apply.
const CODINGS: [&str; 2] = ["gzip", "zstd"];

/// The ETag of `etag`'s representation under a content coding.
fn coded_etag(etag: &str, coding: &str) -> String {
    format!("{}+{coding}\"", etag.trim_end_matches('"'))
}

/// Gives a compressed response its own ETag (RFC 9110: one per content coding).
pub async fn etag_per_coding(mut r: Response) -> Response {
    let coding = r
        .headers()
        .get(header::CONTENT_ENCODING)
        .and_then(|v| v.to_str().ok())
        .map(str::to_string);
    if let (Some(c), Some(tag)) = (coding, r.headers().get(header::ETAG))
        && let Ok(v) = HeaderValue::from_str(&coded_etag(tag.to_str().unwrap_or(""), &c))
    {
        r.headers_mut().insert(header::ETAG, v);
    }
    r
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NameQuery {
    name: Option<String>,
}

pub async fn csg(
    axum::extract::State(app): AppState,
    caller: Caller,
    Query(q): Query<NameQuery>,
    Json(expr): Json<Value>,
) -> Result<Response, Problem> {
    if let Some(n) = &q.name {
        super::check_name(n, &app.limits)?;
    }
    let expr = CsgExpr::from_json(&expr, &app.limits)?;
    // Every operand must be the caller's to see before anything about it is checked.
    let mut metas = std::collections::HashMap::new();
    for id in expr.volume_ids() {
        let m = meta_of(&app, &caller, &id).await?;
        metas.insert(id, m);
    }
    ops::check_csg(&*app.store, &expr, &app.limits).await?;
    let _memory = app
        .admit(cost::csg(&metas, &expr), "this CSG expression")
        .await?;
    drop(metas);
    let label = ops::Label {
        name: q.name,
        owner: tenant(&caller),
    };
    let meta = ops::csg_stored(&*app.store, expr, label).await?;
    Ok(created(&meta))
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IntersectBody {
    a: String,
    b: String,
}

pub async fn intersect(
    axum::extract::State(app): AppState,
    caller: Caller,
    Json(body): Json<IntersectBody>,
) -> Result<Response, Problem> {
    let (a, b) = (
        meta_of(&app, &caller, &body.a).await?,
        meta_of(&app, &caller, &body.b).await?,
    );
    let _memory = app
        .admit(
            cost::intersect(&a, &b),
            &format!("the overlap of volumes {} and {}", body.a, body.b),
        )
        .await?;
    let overlap = ops::intersect_stored(&*app.store, &body.a, &body.b).await?;
    Ok(axum::Json(overlap).into_response())
}

pub async fn morphology(
    axum::extract::State(app): AppState,
    caller: Caller,
    Path(id): Path<String>,
    Query(q): Query<NameQuery>,
    Json(req): Json<MorphologyRequest>,
) -> Result<Response, Problem> {
    if let Some(n) = &q.name {
        super::check_name(n, &app.limits)?;
    }
    // The request is checked before the volume is looked up: a bad request is 400 whatever
    // the id.
    req.check(&app.limits)?;
    let src = meta_of(&app, &caller, &id).await?;
    let out = ops::morphology_grid(&src.grid, &req, &app.limits)?;
    let _memory = app
        .admit(
            cost::morphology(&src, &out),
            &format!("morphology of volume {id}"),
        )
        .await?;
    let label = ops::Label {
        name: q.name,
        owner: tenant(&caller),
    };
    let meta = ops::morphology_stored(&*app.store, &id, req, label, app.limits).await?;
    Ok(created(&meta))
}

pub async fn stats(
    axum::extract::State(app): AppState,
    caller: Caller,
    Path(id): Path<String>,
) -> Result<Response, Problem> {
    let meta = meta_of(&app, &caller, &id).await?;
    let _memory = app
        .admit(cost::stats(&meta), &format!("statistics of volume {id}"))
        .await?;
    Ok(axum::Json(ops::stats_stored(&*app.store, &id).await?).into_response())
}

pub async fn query(
    axum::extract::State(app): AppState,
    caller: Caller,
    Path(id): Path<String>,
    Json(req): Json<QueryRequest>,
) -> Result<Response, Problem> {
    let limits = app.limits;
    req.check(&limits)?;
    let meta = meta_of(&app, &caller, &id).await?;
    let answer_bytes = limits.max_queries as u64 * 64;
    let _memory = app
        .admit(
            cost::read_only(&meta, answer_bytes),
            &format!("a query of volume {id}"),
        )
        .await?;
    let answer = ops::with_stored(&*app.store, &id, move |v| ops::query(v, &req, &limits)).await?;
    Ok(axum::Json(answer).into_response())
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NormalsQuery {
    /// `x,y,z;x,y,z;...`, world coordinates.
    points: Option<String>,
}

pub async fn normals(
    axum::extract::State(app): AppState,
    caller: Caller,
    Path(id): Path<String>,
    Query(q): Query<NormalsQuery>,
) -> Result<Response, Problem> {
    let raw = q
        .points
        .ok_or_else(|| Problem::invalid("give points=x,y,z;x,y,z;... (world coordinates)"))?;
    let points: Vec<[f64; 3]> = raw
        .split(';')
        .filter(|p| !p.trim().is_empty())
        .map(|p| {
            crate::names::parse_triple::<f64>(p)
                .ok()
                .filter(|t| t.iter().all(|c| c.is_finite()))
                .ok_or_else(|| {
                    Error::invalid(format!("points: {p:?} is not x,y,z (three numbers)"))
                })
        })
        .collect::<Result<_, _>>()?;
    let limits = app.limits;
    ops::check_normal_points(&points, &limits)?;
    let meta = meta_of(&app, &caller, &id).await?;
    let _memory = app
        .admit(
            cost::read_only(&meta, points.len() as u64 * 64),
            &format!("normals of volume {id}"),
        )
        .await?;
    let normals = ops::with_stored(&*app.store, &id, move |v| {
        ops::normals_at(v, &points, &limits)
    })
    .await?;
    Ok(axum::Json(json!({ "normals": normals })).into_response())
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PreviewQuery {
    axis: Option<String>,
    slice: Option<u32>,
    projection: Option<String>,
}

pub async fn preview(
    axum::extract::State(app): AppState,
    caller: Caller,
    Path(id): Path<String>,
    Query(q): Query<PreviewQuery>,
) -> Result<Response, Problem> {
    // The two closed sets read their tables (`volume::preview`); the messages name the choices.
    let axis = match q.axis.as_deref() {
        None => Axis::DEFAULT,
        Some(a) => a
            .parse::<Axis>()
            .map_err(|_| Problem::invalid(format!("axis={a:?} is not {}", choices::<Axis>())))?,
    };
    let view = match (q.slice, q.projection.as_deref()) {
        // A slice wins over a projection given with it.
        (Some(k), _) => PreviewView::Slice(k),
        (None, None) => PreviewView::Projection(Projection::DEFAULT),
        (None, Some(p)) => PreviewView::Projection(p.parse::<Projection>().map_err(|_| {
            Problem::invalid(format!(
                "projection={p:?} is not {}",
                choices::<Projection>()
            ))
        })?),
    };
    let req = PreviewRequest {
        axis: axis.index(),
        view,
    };
    let limits = app.limits;
    let meta = meta_of(&app, &caller, &id).await?;
    let _memory = app
        .admit(
            cost::read_only(&meta, limits.max_preview_pixels.saturating_mul(9)),
            &format!("a preview of volume {id}"),
        )
        .await?;
    let png = ops::with_stored(&*app.store, &id, move |v| {
        ops::preview_png(v, &req, &limits)
    })
    .await?;
    let mut r = png.into_response();
    r.headers_mut()
        .insert(header::CONTENT_TYPE, HeaderValue::from_static("image/png"));
    Ok(r)
}
