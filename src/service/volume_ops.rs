//! Operations on stored volumes: `POST /v1/volumes/csg` and `/v1/volumes/intersect` (boolean
//! algebra, src/volume/csg.rs) and `POST /v1/volumes/{id}/morphology` (src/volume/morph.rs).
//! They run synchronously: word operations are fast next to a voxelization, and each stored
//! operand is read and decoded once per request.

use std::collections::HashMap;
use std::sync::Arc;

use axum::extract::{Query, State};
use axum::http::{HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde_json::{Value, json};

use super::App;
use super::problem::{Kind, Problem};
use super::store::{SourceInfo, VolumeMeta};
use crate::codec::vxl;
use crate::volume::csg::{self, CsgError, CsgOp};
use crate::volume::{BitVolume, Volume};

const MAX_DEPTH: usize = 32;
const MAX_OPERANDS: usize = 256;

fn bad(d: impl Into<String>) -> Problem {
    Problem::new(Kind::InvalidParameter, d)
}

fn csg_problem(e: CsgError) -> Problem {
    match e {
        CsgError::Misaligned { .. } => Problem::new(Kind::MisalignedGrids, e.to_string()),
        CsgError::NoOverlap => Problem::new(Kind::EmptyIntersection, e.to_string()),
        CsgError::NoOperands => bad(e.to_string()),
    }
}

/// Loads stored bit volumes by id, each once.
struct Loader<'a> {
    app: &'a App,
    cache: HashMap<String, Arc<BitVolume>>,
}

impl Loader<'_> {
    fn get(&mut self, id: &str) -> Result<Arc<BitVolume>, Problem> {
        if let Some(v) = self.cache.get(id) {
            return Ok(v.clone());
        }
        let v = read_any(self.app, id)?;
        let Volume::Bits(b) = v else {
            return Err(Problem::new(
                Kind::WrongVolumeKind,
                format!(
                    "volume {id} is a density volume; CSG combines bit volumes (solid, surface, conservative, interior)"
                ),
            ));
        };
        let b = Arc::new(b);
        self.cache.insert(id.to_string(), b.clone());
        Ok(b)
    }

    fn eval(&mut self, e: &Value, depth: usize) -> Result<Arc<BitVolume>, Problem> {
        if depth > MAX_DEPTH {
            return Err(bad(format!(
                "the expression is nested deeper than {MAX_DEPTH}"
            )));
        }
        match e {
            Value::String(id) => self.get(id),
            Value::Object(o) => {
                let op = o
                    .get("op")
                    .and_then(Value::as_str)
                    .ok_or_else(|| bad("every expression node needs \"op\""))?;
                let op = CsgOp::from_name(op).ok_or_else(|| {
                    bad(format!(
                        "op {op:?} is not one of union, intersection, difference, xor"
                    ))
                })?;
                let operands = o
                    .get("operands")
                    .and_then(Value::as_array)
                    .ok_or_else(|| bad("every expression node needs an \"operands\" array"))?;
                if operands.is_empty() || operands.len() > MAX_OPERANDS {
                    return Err(bad(format!(
                        "an operation takes 1 to {MAX_OPERANDS} operands"
                    )));
                }
                let vols: Vec<Arc<BitVolume>> = operands
                    .iter()
                    .map(|x| self.eval(x, depth + 1))
                    .collect::<Result<_, _>>()?;
                let refs: Vec<&BitVolume> = vols.iter().map(|v| &**v).collect();
                Ok(Arc::new(csg::apply(op, &refs).map_err(csg_problem)?))
            }
            other => Err(bad(format!(
                "an operand is a volume id (string) or an {{\"op\", \"operands\"}} object, not {other}"
            ))),
        }
    }
}

/// A stored volume of either kind.
fn read_any(app: &App, id: &str) -> Result<Volume, Problem> {
    let bytes = app
        .store
        .read(id)
        .map_err(|e| Problem::new(Kind::Internal, e.to_string()))?
        .ok_or_else(|| Problem::new(Kind::NotFound, format!("no volume with id {id:?}")))?;
    vxl::decode(&bytes)
        .map(|(v, _)| v)
        .map_err(|e| Problem::new(Kind::Internal, format!("stored volume {id}: {e}")))
}

fn json_body(body: &[u8]) -> Result<Value, Problem> {
    serde_json::from_slice(body).map_err(|e| bad(format!("the body is not JSON: {e}")))
}

pub async fn csg(
    State(app): State<Arc<App>>,
    Query(q): Query<HashMap<String, String>>,
    body: axum::body::Bytes,
) -> Result<Response, Problem> {
    let expr = json_body(&body)?;
    let name = q.get("name").cloned();
    let app2 = app.clone();
    let meta = tokio::task::spawn_blocking(move || -> Result<VolumeMeta, Problem> {
        let v = Loader {
            app: &app2,
            cache: HashMap::new(),
        }
        .eval(&expr, 0)?;
        store_derived(&app2, (*v).clone(), name, "csg", expr)
    })
    .await
    .map_err(|e| Problem::new(Kind::Internal, e.to_string()))??;
    let mut r = (StatusCode::CREATED, axum::Json(&meta)).into_response();
    r.headers_mut().insert(
        header::LOCATION,
        HeaderValue::from_str(&format!("/v1/volumes/{}", meta.id)).expect("ascii"),
    );
    Ok(r)
}

/// Stores a volume computed from others, with `provenance` saying how.
fn store_derived(
    app: &App,
    v: BitVolume,
    name: Option<String>,
    method: &str,
    provenance: Value,
) -> Result<VolumeMeta, Problem> {
    let g = *v.grid();
    let solid = v.count_ones();
    let bytes = vxl::encode(&Volume::Bits(v), &Default::default())
        .map_err(|e| Problem::new(Kind::Internal, e.to_string()))?;
    let expr_bytes = serde_json::to_vec(&provenance).unwrap_or_default();
    let meta = VolumeMeta {
        id: app.new_id(),
        name,
        kind: "bits".into(),
        method: method.into(),
        grid: g,
        solid_voxels: solid,
        volume: solid as f64 * g.voxel_size.powi(3),
        source: SourceInfo {
            format: method.into(),
            sha256: super::hex_sha256(&expr_bytes),
            triangles: 0,
        },
        diagnostics: None,
        fill: None,
        engine: "cpu".into(),
        created: super::jobs::rfc3339(std::time::SystemTime::now()),
        bytes: bytes.len() as u64,
        sha256: super::hex_sha256(&bytes),
        provenance: Some(provenance),
    };
    app.store.put(meta.clone(), &bytes).map_err(|e| match e {
        super::store::StoreError::Full { .. } => Problem::new(Kind::StorageFull, e.to_string()),
        other => Problem::new(Kind::Internal, other.to_string()),
    })?;
    Ok(meta)
}

fn created(meta: &VolumeMeta) -> Response {
    let mut r = (StatusCode::CREATED, axum::Json(meta)).into_response();
    r.headers_mut().insert(
        header::LOCATION,
        HeaderValue::from_str(&format!("/v1/volumes/{}", meta.id)).expect("ascii"),
    );
    r
}

pub async fn morphology(
    State(app): State<Arc<App>>,
    axum::extract::Path(id): axum::extract::Path<String>,
    Query(q): Query<HashMap<String, String>>,
    body: axum::body::Bytes,
) -> Result<Response, Problem> {
    use crate::volume::morph::{self, Kernel, MorphOp};
    let spec = json_body(&body)?;
    let op = spec
        .get("op")
        .and_then(Value::as_str)
        .and_then(MorphOp::from_name)
        .ok_or_else(|| bad("\"op\" must be dilate, erode, open or close"))?;
    let kernel = match spec.get("kernel") {
        None => Kernel::Cube,
        Some(k) => k
            .as_str()
            .and_then(Kernel::from_name)
            .ok_or_else(|| bad("\"kernel\" must be cube, cross or sphere"))?,
    };
    let radius = spec
        .get("radius")
        .and_then(Value::as_u64)
        .filter(|&r| r <= morph::MAX_RADIUS as u64)
        .ok_or_else(|| {
            bad(format!(
                "\"radius\" must be a whole number from 0 to {}",
                morph::MAX_RADIUS
            ))
        })? as u32;
    let grow = match spec.get("grow") {
        None => false,
        Some(g) => g
            .as_bool()
            .ok_or_else(|| bad("\"grow\" must be true or false"))?,
    };
    let name = q.get("name").cloned();
    let app2 = app.clone();
    let meta = tokio::task::spawn_blocking(move || -> Result<VolumeMeta, Problem> {
        let v = Loader { app: &app2, cache: HashMap::new() }.get(&id)?;
        if grow && matches!(op, MorphOp::Dilate | MorphOp::Close) {
            let g = morph::padded(v.grid(), radius);
            if g.voxel_count() > app2.config.max_voxels {
                return Err(Problem::new(Kind::GridTooLarge, format!("the grown grid {:?} has {} voxels, over the limit of {}", g.dims, g.voxel_count(), app2.config.max_voxels)));
            }
        }
        let out = morph::apply(&v, op, radius, kernel, grow);
        let provenance = json!({ "morphology": { "of": id, "op": format!("{op:?}").to_lowercase(), "radius": radius, "kernel": format!("{kernel:?}").to_lowercase(), "grow": grow } });
        store_derived(&app2, out, name, "morphology", provenance)
    })
    .await
    .map_err(|e| Problem::new(Kind::Internal, e.to_string()))??;
    Ok(created(&meta))
}

pub async fn intersect(
    State(app): State<Arc<App>>,
    body: axum::body::Bytes,
) -> Result<Response, Problem> {
    let v = json_body(&body)?;
    let (Some(a), Some(b)) = (
        v.get("a").and_then(Value::as_str),
        v.get("b").and_then(Value::as_str),
    ) else {
        return Err(bad(
            "the body must be {\"a\": \"<volume id>\", \"b\": \"<volume id>\"}",
        ));
    };
    let (a, b) = (a.to_string(), b.to_string());
    let out = tokio::task::spawn_blocking(move || -> Result<Value, Problem> {
        let mut l = Loader { app: &app, cache: HashMap::new() };
        let (va, vb) = (l.get(&a)?, l.get(&b)?);
        let n = csg::overlap_count(&va, &vb).map_err(csg_problem)?;
        Ok(json!({ "a": a, "b": b, "voxels": n, "volume": n as f64 * va.grid().voxel_size.powi(3) }))
    })
    .await
    .map_err(|e| Problem::new(Kind::Internal, e.to_string()))??;
    Ok(axum::Json(out).into_response())
}

pub async fn stats(
    State(app): State<Arc<App>>,
    axum::extract::Path(id): axum::extract::Path<String>,
) -> Result<Response, Problem> {
    let st =
        tokio::task::spawn_blocking(move || -> Result<crate::volume::stats::Stats, Problem> {
            let v = Loader {
                app: &app,
                cache: HashMap::new(),
            }
            .get(&id)?;
            Ok(crate::volume::stats::stats(&v))
        })
        .await
        .map_err(|e| Problem::new(Kind::Internal, e.to_string()))??;
    Ok(axum::Json(st).into_response())
}

/// Points and rays per query request at most.
const MAX_QUERIES: usize = 100_000;

fn triple(v: &Value, what: &str) -> Result<[f64; 3], Problem> {
    let a = v
        .as_array()
        .filter(|a| a.len() == 3)
        .ok_or_else(|| bad(format!("{what} must be [x, y, z]")))?;
    let mut out = [0.0; 3];
    for (o, x) in out.iter_mut().zip(a) {
        *o = x
            .as_f64()
            .filter(|f| f.is_finite())
            .ok_or_else(|| bad(format!("{what} must hold three finite numbers")))?;
    }
    Ok(out)
}

pub async fn query(
    State(app): State<Arc<App>>,
    axum::extract::Path(id): axum::extract::Path<String>,
    body: axum::body::Bytes,
) -> Result<Response, Problem> {
    use crate::volume::query::{point_value, ray};
    let spec = json_body(&body)?;
    let empty = vec![];
    let points = spec
        .get("points")
        .map(|p| {
            p.as_array()
                .ok_or_else(|| bad("\"points\" must be an array"))
        })
        .transpose()?
        .unwrap_or(&empty);
    let rays = spec
        .get("rays")
        .map(|r| r.as_array().ok_or_else(|| bad("\"rays\" must be an array")))
        .transpose()?
        .unwrap_or(&empty);
    if points.len() + rays.len() > MAX_QUERIES {
        return Err(bad(format!(
            "at most {MAX_QUERIES} points and rays per request"
        )));
    }
    let points: Vec<[f64; 3]> = points
        .iter()
        .map(|p| triple(p, "a point"))
        .collect::<Result<_, _>>()?;
    let rays: Vec<([f64; 3], [f64; 3])> = rays
        .iter()
        .map(|r| {
            Ok((
                triple(r.get("origin").unwrap_or(&Value::Null), "a ray origin")?,
                triple(
                    r.get("direction").unwrap_or(&Value::Null),
                    "a ray direction",
                )?,
            ))
        })
        .collect::<Result<_, Problem>>()?;
    let out = tokio::task::spawn_blocking(move || -> Result<Value, Problem> {
        let v = read_any(&app, &id)?;
        let pts: Vec<Value> = points
            .iter()
            .map(|&p| {
                let x = point_value(&v, p);
                json!({ "inside": x > 0, "value": x })
            })
            .collect();
        let mut hits = Vec::with_capacity(rays.len());
        for (o, d) in rays {
            let h =
                ray(&v, o, d).ok_or_else(|| bad("a ray direction must be a non-zero vector"))?;
            hits.push(serde_json::to_value(h).unwrap_or_default());
        }
        Ok(json!({ "points": pts, "rays": hits }))
    })
    .await
    .map_err(|e| Problem::new(Kind::Internal, e.to_string()))??;
    Ok(axum::Json(out).into_response())
}

pub async fn normals(
    State(app): State<Arc<App>>,
    axum::extract::Path(id): axum::extract::Path<String>,
    Query(q): Query<HashMap<String, String>>,
) -> Result<Response, Problem> {
    let raw = q
        .get("points")
        .ok_or_else(|| bad("give points=x,y,z;x,y,z;... (world coordinates)"))?;
    let points: Vec<[f64; 3]> = raw
        .split(';')
        .filter(|p| !p.trim().is_empty())
        .map(|p| {
            let v: Vec<f64> = p
                .split(',')
                .filter_map(|c| c.trim().parse::<f64>().ok())
                .filter(|f| f.is_finite())
                .collect();
            <[f64; 3]>::try_from(v).map_err(|_| bad(format!("{p:?} is not x,y,z")))
        })
        .collect::<Result<_, _>>()?;
    if points.len() > MAX_QUERIES {
        return Err(bad(format!("at most {MAX_QUERIES} points per request")));
    }
    let out = tokio::task::spawn_blocking(move || -> Result<Value, Problem> {
        let v = read_any(&app, &id)?;
        let normals: Vec<Value> = points
            .iter()
            .map(|&p| json!(crate::volume::normals::normal_at(&v, p)))
            .collect();
        Ok(json!({ "normals": normals }))
    })
    .await
    .map_err(|e| Problem::new(Kind::Internal, e.to_string()))??;
    Ok(axum::Json(out).into_response())
}

/// Largest preview, in pixels.
const MAX_PREVIEW_PIXELS: u64 = 1 << 24;

pub async fn preview(
    State(app): State<Arc<App>>,
    axum::extract::Path(id): axum::extract::Path<String>,
    Query(q): Query<HashMap<String, String>>,
) -> Result<Response, Problem> {
    use crate::volume::preview::{self, Projection};
    let axis = match q.get("axis").map(String::as_str).unwrap_or("z") {
        "x" => 0,
        "y" => 1,
        "z" => 2,
        a => return Err(bad(format!("axis={a:?} is not x, y or z"))),
    };
    let slice = q
        .get("slice")
        .map(|s| {
            s.parse::<u32>()
                .map_err(|_| bad(format!("slice={s:?} is not a whole number")))
        })
        .transpose()?;
    let mode = match (slice, q.get("projection").map(String::as_str)) {
        (Some(_), Some(_)) => return Err(bad("give slice or projection, not both")),
        (Some(_), None) => None,
        (None, None | Some("max")) => Some(Projection::Max),
        (None, Some("sum")) => Some(Projection::Sum),
        (None, Some(p)) => return Err(bad(format!("projection={p:?} is not max or sum"))),
    };
    let png = tokio::task::spawn_blocking(move || -> Result<Vec<u8>, Problem> {
        let v = read_any(&app, &id)?;
        let d = v.grid().dims;
        let pixels: u64 = (0..3).filter(|&a| a != axis).map(|a| d[a] as u64).product();
        if pixels > MAX_PREVIEW_PIXELS {
            return Err(bad(format!(
                "the picture would have {pixels} pixels, over the limit of {MAX_PREVIEW_PIXELS}"
            )));
        }
        let pic = match (slice, mode) {
            (Some(k), _) => preview::slice(&v, axis, k)
                .ok_or_else(|| bad(format!("slice {k} is outside the grid (0..{})", d[axis])))?,
            (None, Some(m)) => preview::projection(&v, axis, m),
            (None, None) => unreachable!("mode is set when slice is not"),
        };
        Ok(crate::codec::png::encode_gray(
            pic.width,
            pic.height,
            &pic.pixels,
        ))
    })
    .await
    .map_err(|e| Problem::new(Kind::Internal, e.to_string()))??;
    let mut r = png.into_response();
    r.headers_mut()
        .insert(header::CONTENT_TYPE, HeaderValue::from_static("image/png"));
    Ok(r)
}
