//! `/v1/volumes…`: listing, metadata, deletion and download of stored volumes, and the
//! operations on them (CSG, overlap, morphology, statistics, queries, normals, previews). Each
//! handler translates into an application call (`app::ops`) and back.

use axum::body::Body;
use axum::extract::Path;
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde::Deserialize;
use serde_json::{Value, json};

use super::super::extract::{Json, Query};
use super::super::problem::Problem;
use super::conditional::{self, Coding};
use super::{AppState, created};
use crate::app::queue::Owner;
use crate::app::store::VolumeMeta;
use crate::app::{
    CsgExpr, Error, ErrorKind, MorphologyRequest, PreviewRequest, PreviewView, QueryRequest, cost,
    ops,
};
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
    headers: HeaderMap,
) -> Result<Response, Problem> {
    let meta = meta_of(&app, &caller, &id).await?;
    let json = serde_json::to_vec(&meta).map_err(|e| Error::internal(e.to_string()))?;
    // The same rule as on downloads (`conditional`): the handler picks the coding, so a 304
    // carries the ETag the 200 would. Small documents are sent as they are.
    let coding = conditional::negotiate(&headers, json.len() > 256);
    let etag = conditional::coded_etag(&meta_etag(&json), coding);
    if let Some(not_modified) =
        conditional::preconditions(&headers, &etag, || format!("volume {id}'s metadata"))?
    {
        return Ok(not_modified);
    }
    let once =
        futures_util::stream::once(
            async move { Ok::<_, std::io::Error>(bytes::Bytes::from(json)) },
        );
    let mut r = conditional::encode(once, coding);
    r.headers_mut().insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("application/json"),
    );
    conditional::representation_headers(&mut r, &etag);
    Ok(r)
}

/// The identity ETag of a volume's metadata document `json` (a digest of it: whatever the
/// document holds, a change is a new tag).
fn meta_etag(json: &[u8]) -> String {
    use sha2::Digest;
    let sha = crate::app::store::hex(&sha2::Sha256::digest(json));
    format!("\"{}-meta\"", etag_sha(&sha))
}

/// Every ETag a representation of volume `meta` may have been sent with: its metadata and its
/// downloads in every format, in every content coding. `If-Match` on DELETE compares with
/// these (strongly), `If-None-Match` (weakly).
fn volume_etags(meta: &VolumeMeta) -> Result<Vec<String>, Error> {
    let json = serde_json::to_vec(meta).map_err(|e| Error::internal(e.to_string()))?;
    let channels: Vec<Option<&str>> = std::iter::once(None)
        .chain(
            meta.attributes
                .iter()
                .flat_map(|a| a.channels.iter().map(|c| Some(c.as_str()))),
        )
        .collect();
    let identity =
        std::iter::once(meta_etag(&json)).chain(crate::codec::FORMATS.iter().flat_map(|f| {
            channels
                .iter()
                .map(|c| super::download::data_etag(&meta.sha256, f.format, *c))
        }));
    Ok(identity
        .flat_map(|t| Coding::BY_PREFERENCE.map(|c| conditional::coded_etag(&t, c)))
        .collect())
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
pub(super) async fn meta_of(
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
    let conditional_request =
        headers.contains_key(header::IF_MATCH) || headers.contains_key(header::IF_NONE_MATCH);
    let mut known = None;
    if caller.is_some() || conditional_request {
        let meta = meta_of(&app, &caller, &id).await?;
        let tags = volume_etags(&meta)?;
        if !conditional::if_match(&headers, &tags) || conditional::none_match_hits(&headers, &tags)
        {
            return Err(Error::new(
                ErrorKind::PreconditionFailed,
                format!("volume {id} does not meet the request's If-Match / If-None-Match"),
            )
            .into());
        }
        known = Some(meta);
    }
    // With the mesh it kept, if no other volume keeps it.
    if crate::app::sources::delete_volume(&*app.store, &id, known)
        .await
        .map_err(Error::from)?
    {
        Ok(StatusCode::NO_CONTENT.into_response())
    } else {
        Err(Error::not_found("volume", &id).into())
    }
}

/// The part of a volume's sha256 its ETags carry.
pub(super) fn etag_sha(sha256: &str) -> &str {
    &sha256[..16.min(sha256.len())]
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
        .admit(
            if metas
                .values()
                .any(|m| crate::volume::levelset::DISTANCE_KINDS.contains(&m.kind))
            {
                crate::app::distance::csg_cost(&metas)
            } else {
                cost::csg(&metas, &expr)
            },
            "this CSG expression",
        )
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
    if crate::volume::levelset::DISTANCE_KINDS.contains(&meta.kind) {
        let _memory = app
            .admit(
                cost::read_only(&meta, 0),
                &format!("statistics of volume {id}"),
            )
            .await?;
        let st = crate::app::distance::stats_stored_with(
            &*app.store,
            &id,
            &crate::cancel::Control::new(),
        )
        .await?;
        return Ok(axum::Json(st).into_response());
    }
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
