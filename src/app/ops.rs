//! Operations on volumes — CSG, morphology, overlap, statistics, point and ray queries, normals,
//! previews, format conversion — in two layers: pure functions on volumes in memory (what the
//! command line calls on files) and async functions on a [`VolumeStore`] (what the service
//! calls), which read each operand once, compute on the blocking pool and store results.

use std::collections::HashMap;
use std::sync::Arc;

use serde::Serialize;
use serde_json::{Value, json};

use super::error::{Error, ErrorKind, Result};
use super::metadata::{self, Origin};
use super::request::{CsgExpr, MorphologyRequest, PreviewRequest, PreviewView, QueryRequest};
use super::store::{ByteStream, VolumeMeta, VolumeStore};
use crate::cancel::Control;
use crate::codec::{VolumeFormat, vxl};
use crate::grid::Grid;
use crate::limits::Limits;
use crate::volume::morph::{self, MorphOp};
use crate::volume::{BitVolume, Volume, VolumeKind, VoxelValue, csg};

/// The engine name derived volumes record.
pub(crate) const DERIVED_ENGINE: &str = "cpu";

/// Runs CPU work on rayon's global pool (the CPU engine's), off the async runtime. The work runs
/// on a pool thread, so the parallel loops inside it are split among the pool's threads
/// directly: called from any other thread, each of them would be handed to the pool and waited
/// for, two thread switches per loop, which on small jobs cost more than the loops. Not for
/// work that blocks on anything but the CPU (files, the GPU): that goes to tokio's blocking pool.
pub async fn blocking<T: Send + 'static>(
    f: impl FnOnce() -> Result<T> + Send + 'static,
) -> Result<T> {
    on_pool(None, f).await
}

/// [`blocking`] on `pool` (`None`: rayon's global pool). A panic in `f` is an internal error.
pub async fn on_pool<T: Send + 'static>(
    pool: Option<&rayon::ThreadPool>,
    f: impl FnOnce() -> Result<T> + Send + 'static,
) -> Result<T> {
    let (tx, rx) = tokio::sync::oneshot::channel();
    let task = move || {
        let _ = tx.send(std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)));
    };
    match pool {
        Some(p) => p.spawn(task),
        None => rayon::spawn(task),
    }
    match rx.await {
        Ok(Ok(r)) => r,
        Ok(Err(panic)) => {
            let msg = panic
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "no message".into());
            Err(Error::internal(format!("the operation panicked: {msg}")))
        }
        Err(_) => Err(Error::internal("the operation's thread went away")),
    }
}

/// Refuses `v` unless `accepts` (an operation's `ACCEPTS`) holds its kind.
pub fn require(v: &Volume, accepts: &'static [VolumeKind], what: &str) -> Result<()> {
    Ok(v.kind().require(accepts, what)?)
}

/// The bit volume, or why another kind cannot be used for `what` (`CSG`, `morphology`: the
/// operations that take [`crate::volume::BITS_ONLY`]).
pub fn require_bits(v: Volume, what: &str) -> Result<BitVolume> {
    Ok(v.into_bits(what)?)
}

/// Runs CPU work on the blocking pool under `ctl`; dropping the returned future (a client that
/// went away, a request that timed out) cancels the work at its next check point.
pub async fn blocking_with<T: Send + 'static>(
    ctl: &Control,
    f: impl FnOnce(&Control) -> Result<T> + Send + 'static,
) -> Result<T> {
    let guard = ctl.cancel_on_drop();
    let c = ctl.clone();
    let r = blocking(move || f(&c)).await;
    guard.disarm();
    r
}

/// Evaluates a CSG expression over volumes already loaded (`volumes` holds every id it names).
pub fn eval_csg(expr: &CsgExpr, volumes: &HashMap<String, Arc<BitVolume>>) -> Result<BitVolume> {
    eval_csg_with(expr, volumes, &Control::none())
}

/// [`eval_csg`], checking `ctl` before every operand of every operation and reporting the
/// operands combined.
pub fn eval_csg_with(
    expr: &CsgExpr,
    volumes: &HashMap<String, Arc<BitVolume>>,
    ctl: &Control,
) -> Result<BitVolume> {
    eval_tree(expr, volumes, ctl, csg::apply_with::<Error>)
}

/// Evaluates a CSG expression over volumes of any type `V` already loaded (`volumes` holds every
/// id it names), each operation by `apply` under its share of `ctl` (by operands combined).
pub fn eval_tree<V: Clone>(
    expr: &CsgExpr,
    volumes: &HashMap<String, Arc<V>>,
    ctl: &Control,
    apply: impl Fn(csg::CsgOp, &[&V], &Control) -> Result<V>,
) -> Result<V> {
    /// One operation of the tree: its operator, operands and share of the progress.
    type Apply<'a, V> = &'a dyn Fn(csg::CsgOp, &[&V], &Control) -> Result<V>;
    fn operands(e: &CsgExpr) -> usize {
        match e {
            CsgExpr::Volume(_) => 0,
            CsgExpr::Op { operands: o, .. } => o.len() + o.iter().map(operands).sum::<usize>(),
        }
    }
    fn walk<V>(
        e: &CsgExpr,
        vols: &HashMap<String, Arc<V>>,
        apply: Apply<V>,
        ctl: &Control,
        total: f64,
        done: &mut usize,
    ) -> Result<Arc<V>> {
        match e {
            CsgExpr::Volume(id) => vols
                .get(id)
                .cloned()
                .ok_or_else(|| Error::not_found("volume", id)),
            CsgExpr::Op { op, operands } => {
                let vs: Vec<Arc<V>> = operands
                    .iter()
                    .map(|o| walk(o, vols, apply, ctl, total, done))
                    .collect::<Result<_>>()?;
                let refs: Vec<&V> = vs.iter().map(|v| &**v).collect();
                let (lo, hi) = (*done, *done + operands.len());
                *done = hi;
                let part = ctl.stage(lo as f64 / total, hi as f64 / total);
                Ok(Arc::new(apply(*op, &refs, &part)?))
            }
        }
    }
    let total = operands(expr).max(1) as f64;
    let v = walk(expr, volumes, &apply, ctl, total, &mut 0)?;
    ctl.complete();
    Ok(Arc::try_unwrap(v).unwrap_or_else(|v| (*v).clone()))
}

/// The grid a morphology result lives on, checked against the voxel limit before any work.
pub fn morphology_grid(v: &Grid, req: &MorphologyRequest, limits: &Limits) -> Result<Grid> {
    req.check(limits)?;
    if req.grow && matches!(req.op, MorphOp::Dilate | MorphOp::Close) {
        let g = morph::padded(v, req.radius);
        if g.voxel_count() > limits.max_voxels {
            return Err(Error::new(
                ErrorKind::GridTooLarge,
                format!(
                    "the grown grid {:?} has {} voxels, over the limit of {}",
                    g.dims,
                    g.voxel_count(),
                    limits.max_voxels
                ),
            ));
        }
        return Ok(g);
    }
    Ok(*v)
}

/// Morphology within the limits.
pub fn morphology(v: &BitVolume, req: &MorphologyRequest, limits: &Limits) -> Result<BitVolume> {
    morphology_with(v, req, limits, &Control::none())
}

/// [`morphology`], checking `ctl` per x-plane of each pass and reporting progress there.
pub fn morphology_with(
    v: &BitVolume,
    req: &MorphologyRequest,
    limits: &Limits,
    ctl: &Control,
) -> Result<BitVolume> {
    morphology_grid(v.grid(), req, limits)?;
    Ok(morph::apply_with(
        v, req.op, req.radius, req.kernel, req.grow, ctl,
    )?)
}

/// How a morphology result was made (its provenance).
pub fn morphology_provenance(of: &str, req: &MorphologyRequest) -> Value {
    json!({ "morphology": {
        "of": of,
        "op": req.op.name(),
        "radius": req.radius,
        "kernel": req.kernel.name(),
        "grow": req.grow,
    }})
}

/// Shared voxels of two volumes on aligned grids, and their world volume.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Overlap {
    pub a: String,
    pub b: String,
    pub voxels: u64,
    pub volume: f64,
}

/// The answers of a query: per point, inside and the voxel's value; per ray, what it crossed.
#[derive(Clone, Debug, Serialize)]
pub struct QueryAnswer {
    pub points: Vec<PointAnswer>,
    pub rays: Vec<crate::volume::query::RayHit>,
}

/// A point's answer: whether its voxel is occupied, and the voxel's value in its own type (0/1
/// for bits, 0..=max for density: numbers, as always).
#[derive(Clone, Copy, Debug, Serialize)]
pub struct PointAnswer {
    pub inside: bool,
    pub value: VoxelValue,
    /// Distance volumes: the trilinear interpolation of the voxel-centre samples at the point
    /// (samples outside the grid: the background), absent where a sample is infinite.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub distance: Option<f64>,
    /// Distance volumes: the interpolant's gradient there (per world unit).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gradient: Option<[f64; 3]>,
}

pub fn query(v: &Volume, q: &QueryRequest, limits: &Limits) -> Result<QueryAnswer> {
    use crate::volume::query::{ACCEPTS, point_value, ray};
    require(v, ACCEPTS, "a query")?;
    q.check(limits)?;
    let distance = match v {
        Volume::SparseDistance(s) => Some(std::borrow::Cow::Borrowed(s)),
        Volume::Distance(_) => Some(std::borrow::Cow::Owned(
            crate::volume::levelset::into_distance(v.clone(), "a query")?,
        )),
        _ => None,
    };
    let points = q
        .points
        .iter()
        .map(|&p| {
            let (inside, value) = point_value(v, p);
            let interp = distance
                .as_ref()
                .and_then(|s| crate::volume::query::interpolate(s, p));
            PointAnswer {
                inside,
                value,
                distance: interp.map(|i| i.0),
                gradient: interp.map(|i| i.1),
            }
        })
        .collect();
    let rays = q
        .rays
        .iter()
        .map(|r| {
            ray(v, r.origin, r.direction)
                .ok_or_else(|| Error::invalid("a ray direction must be a non-zero vector"))
        })
        .collect::<Result<_>>()?;
    Ok(QueryAnswer { points, rays })
}

/// Refuses more points than a request may ask normals for.
pub fn check_normal_points(points: &[[f64; 3]], limits: &Limits) -> Result<()> {
    if points.len() > limits.max_queries {
        return Err(Error::invalid(format!(
            "at most {} points per request",
            limits.max_queries
        )));
    }
    Ok(())
}

/// Outward normals at world points (`None` where the gradient vanishes).
pub fn normals_at(
    v: &Volume,
    points: &[[f64; 3]],
    limits: &Limits,
) -> Result<Vec<Option<[f64; 3]>>> {
    require(v, crate::volume::normals::ACCEPTS, "normals")?;
    check_normal_points(points, limits)?;
    Ok(points
        .iter()
        .map(|&p| crate::volume::normals::normal_at(v, p))
        .collect())
}

/// A preview picture as PNG, within the pixel limit.
pub fn preview_png(v: &Volume, req: &PreviewRequest, limits: &Limits) -> Result<Vec<u8>> {
    use crate::volume::preview;
    require(v, preview::ACCEPTS, "a preview")?;
    let d = v.grid().dims;
    let pixels: u64 = (0..3)
        .filter(|&a| a != req.axis)
        .map(|a| d[a] as u64)
        .product();
    // Both depend on the stored volume's dims, not on the request's form: a picture too large
    // for this grid (422), a slice this grid does not have (404).
    if pixels > limits.max_preview_pixels {
        return Err(Error::new(
            ErrorKind::GridTooLarge,
            format!(
                "the picture would have {pixels} pixels, over the limit of {}",
                limits.max_preview_pixels
            ),
        ));
    }
    let colour = match req.view {
        PreviewView::Slice(k) => preview::colour(v, req.axis, Some(k)),
        PreviewView::Projection(preview::Projection::Max) => preview::colour(v, req.axis, None),
        PreviewView::Projection(_) => None,
    };
    if let Some(pic) = colour {
        return Ok(crate::codec::png::encode_rgb(
            pic.width,
            pic.height,
            &pic.pixels,
        ));
    }
    let pic = match req.view {
        PreviewView::Slice(k) => preview::slice(v, req.axis, k).ok_or_else(|| {
            Error::new(
                ErrorKind::NotFound,
                format!(
                    "no slice {k} across {}: the grid has slices 0..{}",
                    ["x", "y", "z"][req.axis],
                    d[req.axis]
                ),
            )
        })?,
        PreviewView::Projection(m) => preview::projection(v, req.axis, m),
    };
    Ok(crate::codec::png::encode_gray(
        pic.width,
        pic.height,
        &pic.pixels,
    ))
}

/// Can `format` hold a volume of `kind` (its row of [`crate::codec::FORMATS`])? A refusal is
/// an invalid parameter (the format asked for), naming the formats that do hold the kind.
pub fn check_format(kind: VolumeKind, format: VolumeFormat) -> Result<()> {
    if format.holds().contains(&kind) {
        return Ok(());
    }
    let held: Vec<&str> = format.holds().iter().map(|k| k.describe()).collect();
    let can: Vec<&str> = crate::codec::FORMATS
        .iter()
        .filter(|f| f.holds.contains(&kind))
        .map(|f| f.name)
        .collect();
    let can = match can.split_last() {
        Some((last, rest)) if !rest.is_empty() => format!("{} or {last}", rest.join(", ")),
        _ => can.concat(),
    };
    Err(Error::invalid(format!(
        "{} holds {}; download a {kind} volume as {can}",
        format.name(),
        held.join(" or ")
    )))
}

/// Refuses a conversion whose output would be larger than the voxel budget, before any of it
/// is made: binvox pads the grid to a cube (a 4096×1×1 grid becomes 4096³ voxels), and npy and
/// raw write every voxel of a sparse volume (4 bytes each for a distance). `.vxl` and `.vdb`
/// are sparse where the volume is: not bounded here.
pub fn check_conversion(grid: &Grid, format: VolumeFormat, limits: &Limits) -> Result<()> {
    let voxels: u128 = match format {
        // Sparse: as large as the volume's set voxels, at most.
        VolumeFormat::Vxl | VolumeFormat::Vdb | VolumeFormat::Indices | VolumeFormat::Points => {
            return Ok(());
        }
        VolumeFormat::Vox => {
            return crate::codec::vox::check_world(grid.dims).map_err(|e| {
                Error::new(
                    ErrorKind::GridTooLarge,
                    format!("as vox: {e}; download it as vxl, or voxelize at a coarser resolution"),
                )
            });
        }
        VolumeFormat::Binvox => u128::from(*grid.dims.iter().max().expect("three dims")).pow(3),
        _ => grid.dims.iter().map(|&d| u128::from(d)).product(),
    };
    if voxels > u128::from(limits.max_voxels) {
        return Err(Error::new(
            ErrorKind::GridTooLarge,
            format!(
                "as {} this {}x{}x{} volume would have {voxels} voxels, over the limit of {}; download it as vxl or npy",
                format.name(),
                grid.dims[0],
                grid.dims[1],
                grid.dims[2],
                crate::limits::describe_voxels(limits.max_voxels)
            ),
        ));
    }
    Ok(())
}

/// [`check_dense`] then [`check_conversion`]: what a download of a volume of `kind` in `format`
/// must pass.
pub fn check_download(
    kind: VolumeKind,
    grid: &Grid,
    format: VolumeFormat,
    limits: &Limits,
) -> Result<()> {
    check_dense(kind, grid, format, limits)?;
    check_conversion(grid, format, limits)
}

/// A dense copy of a sparse distance volume (`.npy`, `.raw`) is refused when its grid is over
/// the dense limit (`max_voxels`), with its size in bytes against the limit's (4 bytes a voxel),
/// and pointed at the formats that stay sparse.
pub fn check_dense(
    kind: VolumeKind,
    grid: &Grid,
    format: VolumeFormat,
    limits: &Limits,
) -> Result<()> {
    let dense = matches!(format, VolumeFormat::Npy | VolumeFormat::Raw);
    if kind == VolumeKind::SparseDistance && dense {
        let voxels: u128 = grid.dims.iter().map(|&d| u128::from(d)).product();
        if voxels > u128::from(limits.max_voxels) {
            let per = u128::from(crate::codec::npy::value_bytes(kind));
            return Err(Error::new(
                ErrorKind::GridTooLarge,
                format!(
                    "as {} this {}x{}x{} sparse distance volume would be dense: {voxels} voxels, {} bytes of float32, over the dense limit of {} ({} bytes); download it as vdb or vxl",
                    format.name(),
                    grid.dims[0],
                    grid.dims[1],
                    grid.dims[2],
                    voxels * per,
                    crate::limits::describe_voxels(limits.max_voxels),
                    u128::from(limits.max_voxels) * per
                ),
            ));
        }
    }
    Ok(())
}

/// What a conversion to `format` loses, said as a warning (binvox pads to a cube, npy and raw
/// drop the grid's origin and voxel size).
pub fn conversion_warning(grid: &Grid, format: VolumeFormat) -> Option<String> {
    let d = grid.dims;
    match format {
        VolumeFormat::Binvox if d[0] != d[1] || d[1] != d[2] => Some(format!(
            "binvox is cubic; the {}x{}x{} grid is padded with empty voxels to {n}x{n}x{n}",
            d[0],
            d[1],
            d[2],
            n = d.iter().max().expect("three dims")
        )),
        VolumeFormat::Vox => Some(format!(
            "vox keeps only the voxels, placed centred on MagicaVoxel's ground in models of at most 256³: the grid's origin {:?} and voxel size {} are not stored (keep the .vxl for them)",
            grid.origin, grid.voxel_size
        )),
        VolumeFormat::Npy | VolumeFormat::Raw | VolumeFormat::Indices => Some(format!(
            "{} keeps only the voxels: the grid's origin {:?} and voxel size {} are not stored (keep the .vxl for them)",
            format.name(),
            grid.origin,
            grid.voxel_size
        )),
        _ => None,
    }
}

// ---- on a store ----

/// A stored volume of either kind.
pub async fn load(store: &dyn VolumeStore, id: &str) -> Result<Volume> {
    let bytes = store
        .read(id)
        .await?
        .ok_or_else(|| Error::not_found("volume", id))?;
    let id = id.to_string();
    blocking(move || {
        vxl::decode(&bytes)
            .map(|(v, _)| v)
            .map_err(|e| Error::internal(format!("stored volume {id}: {e}")))
    })
    .await
}

/// A stored bit volume, for `what`, an operation that takes `accepts` (bit volumes only).
pub async fn load_bits(
    store: &dyn VolumeStore,
    id: &str,
    accepts: &'static [VolumeKind],
    what: &str,
) -> Result<BitVolume> {
    let v = load(store, id).await?;
    require(&v, accepts, what)
        .and_then(|()| require_bits(v, what))
        .map_err(|e| e.context(format!("volume {id}")))
}

/// What a stored volume is called and who owns it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Label {
    pub name: Option<String>,
    /// The tenant that owns it ([`VolumeMeta::owner`]).
    pub owner: Option<String>,
}

/// Stores a volume computed from others.
pub async fn store_derived(
    store: &dyn VolumeStore,
    v: BitVolume,
    label: Label,
    method: &'static str,
    provenance: Value,
) -> Result<VolumeMeta> {
    store_derived_volume(store, Volume::Bits(v), label, method, provenance).await
}

/// [`store_derived`] for a volume of any kind.
pub async fn store_derived_volume(
    store: &dyn VolumeStore,
    v: Volume,
    label: Label,
    method: &'static str,
    provenance: Value,
) -> Result<VolumeMeta> {
    let Label { name, owner } = label;
    let built = blocking(move || {
        metadata::build(
            &v,
            &Origin::Derived {
                method,
                provenance: &provenance,
                materials: &[],
            },
            name,
            DERIVED_ENGINE,
        )
    })
    .await?;
    let mut built = built;
    built.meta.owner = owner;
    store.put(built.meta.clone(), built.vxl).await?;
    Ok(built.meta)
}

/// Evaluates a CSG expression over stored volumes (each read once) and stores the result.
/// Dropping the future cancels the evaluation at its next check point.
pub async fn csg_stored(
    store: &dyn VolumeStore,
    expr: CsgExpr,
    label: Label,
) -> Result<VolumeMeta> {
    csg_stored_with(store, expr, label, &Control::new()).await
}

/// Checks a CSG expression's cost before anything is read: every node's result grid (from the
/// operands' stored grids) must be within the voxel limit, and the voxels all nodes produce
/// together within [`Limits::max_csg_work`] grids of that size.
pub async fn check_csg(store: &dyn VolumeStore, expr: &CsgExpr, limits: &Limits) -> Result<()> {
    if super::distance::is_distance_csg(store, expr).await? {
        return super::distance::check_csg(store, expr, limits).await;
    }
    let mut grids = HashMap::new();
    for id in expr.volume_ids() {
        let meta = super::distance::csg_operand(store, &id, csg::ACCEPTS, "CSG").await?;
        grids.insert(id, meta.grid);
    }
    fn grid_of(
        e: &CsgExpr,
        grids: &HashMap<String, Grid>,
        limits: &Limits,
        work: &mut u128,
    ) -> Result<Grid> {
        match e {
            CsgExpr::Volume(id) => Ok(grids[id]),
            CsgExpr::Op { op, operands } => {
                let gs = operands
                    .iter()
                    .map(|o| grid_of(o, grids, limits, work))
                    .collect::<Result<Vec<_>>>()?;
                let g = csg::result_grid(*op, &gs)?;
                let n = g.voxel_count();
                if n > limits.max_voxels {
                    return Err(Error::new(
                        ErrorKind::GridTooLarge,
                        format!(
                            "the {} of these volumes lives on a {:?} grid of {n} voxels, over the limit of {}",
                            op.name(),
                            g.dims,
                            crate::limits::describe_voxels(limits.max_voxels)
                        ),
                    ));
                }
                *work += u128::from(n) * operands.len() as u128;
                Ok(g)
            }
        }
    }
    let mut work = 0u128;
    grid_of(expr, &grids, limits, &mut work)?;
    let budget = u128::from(limits.max_voxels) * u128::from(limits.max_csg_work);
    if work > budget {
        return Err(Error::invalid(format!(
            "the expression would combine {work} voxels in all, over the limit of {} × {}",
            limits.max_csg_work,
            crate::limits::describe_voxels(limits.max_voxels)
        )));
    }
    Ok(())
}

/// [`csg_stored`] under `ctl` (cancel, deadline, progress).
pub async fn csg_stored_with(
    store: &dyn VolumeStore,
    expr: CsgExpr,
    label: Label,
    ctl: &Control,
) -> Result<VolumeMeta> {
    if super::distance::is_distance_csg(store, &expr).await? {
        return super::distance::csg_stored_with(store, expr, label, ctl).await;
    }
    let mut metas = vec![];
    for id in expr.volume_ids() {
        metas.push(super::distance::csg_operand(store, &id, csg::ACCEPTS, "CSG").await?);
    }
    if metas
        .iter()
        .any(|m| m.kind == crate::volume::VolumeKind::Channels)
    {
        return super::carry::csg_stored_with(store, expr, metas, label, ctl).await;
    }
    let mut vols = HashMap::new();
    for id in expr.volume_ids() {
        let v = load_bits(store, &id, csg::ACCEPTS, "CSG").await?;
        vols.insert(id, Arc::new(v));
    }
    let provenance = expr.to_json();
    let v = blocking_with(ctl, move |ctl| eval_csg_with(&expr, &vols, ctl)).await?;
    ctl.check()?;
    store_derived(store, v, label, "csg", provenance).await
}

/// Morphology of a stored volume, stored. Dropping the future cancels the work at its next
/// check point.
pub async fn morphology_stored(
    store: &dyn VolumeStore,
    id: &str,
    req: MorphologyRequest,
    label: Label,
    limits: Limits,
) -> Result<VolumeMeta> {
    morphology_stored_with(store, id, req, label, limits, &Control::new()).await
}

/// [`morphology_stored`] under `ctl` (cancel, deadline, progress).
pub async fn morphology_stored_with(
    store: &dyn VolumeStore,
    id: &str,
    req: MorphologyRequest,
    label: Label,
    limits: Limits,
    ctl: &Control,
) -> Result<VolumeMeta> {
    req.check(&limits)?;
    let meta = super::distance::csg_operand(store, id, morph::ACCEPTS, "morphology").await?;
    if meta.kind == crate::volume::VolumeKind::Channels {
        return super::carry::morphology_stored_with(store, meta, req, label, limits, ctl).await;
    }
    let v = load_bits(store, id, morph::ACCEPTS, "morphology").await?;
    let out = blocking_with(ctl, move |ctl| morphology_with(&v, &req, &limits, ctl)).await?;
    ctl.check()?;
    store_derived(
        store,
        out,
        label,
        "morphology",
        morphology_provenance(id, &req),
    )
    .await
}

/// Shared voxels of two stored volumes; nothing is stored.
pub async fn intersect_stored(store: &dyn VolumeStore, a: &str, b: &str) -> Result<Overlap> {
    let va = load_bits(store, a, csg::ACCEPTS, "CSG").await?;
    let vb = if a == b {
        va.clone()
    } else {
        load_bits(store, b, csg::ACCEPTS, "CSG").await?
    };
    let (a, b) = (a.to_string(), b.to_string());
    blocking(move || {
        let n = csg::overlap_count(&va, &vb)?;
        Ok(Overlap {
            a,
            b,
            voxels: n,
            volume: va.grid().volume_of(n),
        })
    })
    .await
}

/// Statistics of a stored bit volume. Dropping the future cancels the work at its next check
/// point.
pub async fn stats_stored(
    store: &dyn VolumeStore,
    id: &str,
) -> Result<crate::volume::stats::Stats> {
    stats_stored_with(store, id, &Control::new()).await
}

/// [`stats_stored`] under `ctl` (cancel, deadline, progress).
pub async fn stats_stored_with(
    store: &dyn VolumeStore,
    id: &str,
    ctl: &Control,
) -> Result<crate::volume::stats::Stats> {
    let v = load_bits(store, id, crate::volume::stats::ACCEPTS, "statistics").await?;
    blocking_with(ctl, move |ctl| {
        Ok(crate::volume::stats::stats_with(&v, ctl)?)
    })
    .await
}

/// Runs `f` on a stored volume of either kind on the blocking pool.
pub async fn with_stored<T: Send + 'static>(
    store: &dyn VolumeStore,
    id: &str,
    f: impl FnOnce(&Volume) -> Result<T> + Send + 'static,
) -> Result<T> {
    let v = load(store, id).await?;
    blocking(move || f(&v)).await
}

/// A download: its length when known before encoding, and its bytes as they are produced.
pub struct Download {
    pub len: Option<u64>,
    pub body: ByteStream,
}

/// A stored volume in `format`, as a stream. `.vxl` streams the stored bytes (checked as they
/// pass, [`crate::store::verified`]); any other format decodes the volume once (what its codec
/// needs) and encodes it a piece at a time on the blocking pool, at most a few chunks ahead of
/// the client: a client that stops reading stops the encoder, and one that goes away ends it.
///
/// `meta` is the volume's catalogue entry, which the caller has already read (for its ETag and
/// checks, `attributes`' among them: [`super::attributes::check`]): it is not read again.
pub async fn download(
    store: &dyn VolumeStore,
    meta: &VolumeMeta,
    format: VolumeFormat,
    attributes: Option<String>,
) -> Result<Download> {
    let id = meta.id.as_str();
    if format == VolumeFormat::Vxl {
        let body = store
            .read_stream(id)
            .await?
            .ok_or_else(|| Error::not_found("volume", id))?;
        return Ok(Download {
            len: Some(meta.bytes),
            body,
        });
    }
    let stored = store
        .read(id)
        .await?
        .ok_or_else(|| Error::not_found("volume", id))?;
    let name = id.to_string();
    let v = blocking(move || {
        let (v, _) = vxl::decode(&stored)
            .map_err(|e| Error::internal(format!("stored volume {name}: {e}")))?;
        let v = super::attributes::select(v, format, attributes.as_deref())?;
        format.check(&v)?;
        Ok(v)
    })
    .await?;
    let len = format.encoded_len(&v);
    let name = id.to_string();
    let body = super::stream::from_writer(move |w| {
        format.write(&v, w).inspect_err(|e| {
            if e.kind() != std::io::ErrorKind::BrokenPipe {
                tracing::error!("encoding volume {name} as {}: {e}", format.name())
            }
        })
    });
    Ok(Download { len, body })
}
