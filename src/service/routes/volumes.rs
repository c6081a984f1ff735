//! `/v1/volumes…`: listing, metadata, deletion and download of stored volumes, and the
//! operations on them (CSG, overlap, morphology, statistics, queries, normals, previews). Each
//! handler translates into an application call (`app::ops`) and back.

use axum::extract::Path;
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde::Deserialize;
use serde_json::{Value, json};

use super::super::extract::{Json, Query};
use super::super::problem::Problem;
use super::{AppState, VXL_MEDIA_TYPE, created};
use crate::app::{
    CsgExpr, Error, MorphologyRequest, PreviewRequest, PreviewView, QueryRequest, ops,
};
use crate::codec::VolumeFormat;
use crate::volume::preview::Projection;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ListQuery {
    limit: Option<usize>,
    after: Option<String>,
}

pub async fn list(
    axum::extract::State(app): AppState,
    Query(q): Query<ListQuery>,
) -> Result<Response, Problem> {
    let limit = q.limit.unwrap_or(app.limits.default_list_page);
    if !(1..=app.limits.max_list_page).contains(&limit) {
        return Err(Problem::invalid(format!(
            "limit must be between 1 and {}",
            app.limits.max_list_page
        )));
    }
    let (page, more) = app
        .store
        .list(q.after.as_deref(), limit)
        .await
        .map_err(Error::from)?;
    let next = more
        .then(|| page.last())
        .flatten()
        .map(|m| format!("/v1/volumes?after={}&limit={limit}", m.id));
    Ok(axum::Json(json!({ "volumes": page, "next": next })).into_response())
}

pub async fn get(
    axum::extract::State(app): AppState,
    Path(id): Path<String>,
) -> Result<Response, Problem> {
    let meta = app
        .store
        .get(&id)
        .await
        .map_err(Error::from)?
        .ok_or_else(|| Error::not_found("volume", &id))?;
    Ok(axum::Json(meta).into_response())
}

pub async fn delete(
    axum::extract::State(app): AppState,
    Path(id): Path<String>,
) -> Result<Response, Problem> {
    if app.store.delete(&id).await.map_err(Error::from)? {
        Ok(StatusCode::NO_CONTENT.into_response())
    } else {
        Err(Error::not_found("volume", &id).into())
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DataQuery {
    format: Option<String>,
}

pub async fn data(
    axum::extract::State(app): AppState,
    Path(id): Path<String>,
    Query(q): Query<DataQuery>,
    headers: HeaderMap,
) -> Result<Response, Problem> {
    let format = match &q.format {
        None => VolumeFormat::Vxl,
        Some(f) => VolumeFormat::from_name(f).ok_or_else(|| {
            Problem::invalid(format!("format={f:?} is not one of vxl, binvox, npy, raw"))
        })?,
    };
    let meta = app
        .store
        .get(&id)
        .await
        .map_err(Error::from)?
        .ok_or_else(|| Error::not_found("volume", &id))?;
    ops::check_format(&meta.kind, format)?;
    let etag = format!(
        "\"{}-{}\"",
        &meta.sha256[..16.min(meta.sha256.len())],
        format.name()
    );
    let etag_value = HeaderValue::from_str(&etag).map_err(|e| Error::internal(e.to_string()))?;
    if headers
        .get(header::IF_NONE_MATCH)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| v.split(',').any(|t| t.trim() == etag || t.trim() == "*"))
    {
        let mut r = StatusCode::NOT_MODIFIED.into_response();
        r.headers_mut().insert(header::ETAG, etag_value);
        return Ok(r);
    }
    let bytes = ops::download(&*app.store, &id, format).await?;
    let media = match format {
        VolumeFormat::Vxl => VXL_MEDIA_TYPE,
        VolumeFormat::Npy => "application/x-npy",
        VolumeFormat::Binvox => "application/x-binvox",
        VolumeFormat::Raw => "application/octet-stream",
    };
    let name = meta.name.clone().unwrap_or_else(|| id.clone()).replace(
        |c: char| !c.is_ascii_alphanumeric() && c != '-' && c != '_',
        "_",
    );
    let mut r = bytes.into_response();
    let h = r.headers_mut();
    h.insert(header::CONTENT_TYPE, HeaderValue::from_static(media));
    h.insert(header::ETAG, etag_value);
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

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NameQuery {
    name: Option<String>,
}

pub async fn csg(
    axum::extract::State(app): AppState,
    Query(q): Query<NameQuery>,
    Json(expr): Json<Value>,
) -> Result<Response, Problem> {
    let expr = CsgExpr::from_json(&expr, &app.limits)?;
    let meta = ops::csg_stored(&*app.store, expr, q.name).await?;
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
    Json(body): Json<IntersectBody>,
) -> Result<Response, Problem> {
    let overlap = ops::intersect_stored(&*app.store, &body.a, &body.b).await?;
    Ok(axum::Json(overlap).into_response())
}

pub async fn morphology(
    axum::extract::State(app): AppState,
    Path(id): Path<String>,
    Query(q): Query<NameQuery>,
    Json(req): Json<MorphologyRequest>,
) -> Result<Response, Problem> {
    let meta = ops::morphology_stored(&*app.store, &id, req, q.name, app.limits).await?;
    Ok(created(&meta))
}

pub async fn stats(
    axum::extract::State(app): AppState,
    Path(id): Path<String>,
) -> Result<Response, Problem> {
    Ok(axum::Json(ops::stats_stored(&*app.store, &id).await?).into_response())
}

pub async fn query(
    axum::extract::State(app): AppState,
    Path(id): Path<String>,
    Json(req): Json<QueryRequest>,
) -> Result<Response, Problem> {
    let limits = app.limits;
    req.check(&limits)?;
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
                .ok_or_else(|| Error::invalid(format!("{p:?} is not x,y,z")))
        })
        .collect::<Result<_, _>>()?;
    let limits = app.limits;
    ops::check_normal_points(&points, &limits)?;
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
    Path(id): Path<String>,
    Query(q): Query<PreviewQuery>,
) -> Result<Response, Problem> {
    let axis = match q.axis.as_deref().unwrap_or("z") {
        "x" => 0,
        "y" => 1,
        "z" => 2,
        a => return Err(Problem::invalid(format!("axis={a:?} is not x, y or z"))),
    };
    let view = match (q.slice, q.projection.as_deref()) {
        (Some(_), Some(_)) => return Err(Problem::invalid("give slice or projection, not both")),
        (Some(k), None) => PreviewView::Slice(k),
        (None, None | Some("max")) => PreviewView::Projection(Projection::Max),
        (None, Some("sum")) => PreviewView::Projection(Projection::Sum),
        (None, Some(p)) => {
            return Err(Problem::invalid(format!(
                "projection={p:?} is not max or sum"
            )));
        }
    };
    let req = PreviewRequest { axis, view };
    let limits = app.limits;
    let png = ops::with_stored(&*app.store, &id, move |v| {
        ops::preview_png(v, &req, &limits)
    })
    .await?;
    let mut r = png.into_response();
    r.headers_mut()
        .insert(header::CONTENT_TYPE, HeaderValue::from_static("image/png"));
    Ok(r)
}
