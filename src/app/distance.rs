//! Operations on stored distance volumes, and between them and bit volumes: CSG of distance
//! volumes (min/max), `threshold` (a distance volume's voxels below a level, as bits), `sdf`
//! (the exact signed distance transform of a bit volume, in a sparse band) and their
//! statistics. Pure functions are in `volume::{csg, levelset, stats}`; here they are run on
//! the store, under a [`Control`], with their costs for the memory budget. Definitions:
//! `docs/methods.md`, "Operations on distance volumes".

use std::collections::HashMap;
use std::sync::Arc;

use serde_json::{Value, json};

use super::cost;
use super::error::{Error, Result};
use super::ops::{
    Label, blocking_with, load, load_bits, require, store_derived, store_derived_volume,
};
use super::request::CsgExpr;
use super::store::{VolumeMeta, VolumeStore};
use crate::cancel::Control;
use crate::grid::Grid;
use crate::volume::csg::{self, CsgError, CsgOp};
use crate::volume::levelset::{self, DISTANCE_KINDS, MAX_BAND, SDF_ACCEPTS};
use crate::volume::stats::DistanceStats;
use crate::volume::{BitVolume, Sparse, Volume};

/// A stored distance volume (a dense one as sparse bricks), for `what`.
pub async fn load_distance(store: &dyn VolumeStore, id: &str, what: &str) -> Result<Sparse<f32>> {
    let v = load(store, id).await?;
    require(&v, DISTANCE_KINDS, what)
        .and_then(|()| Ok(levelset::into_distance(v, what)?))
        .map_err(|e| e.context(format!("volume {id}")))
}

/// Does the expression name a distance volume (so that it is distance CSG, which
/// [`check_csg`] then holds every operand to)?
pub async fn is_distance_csg(store: &dyn VolumeStore, expr: &CsgExpr) -> Result<bool> {
    for id in expr.volume_ids() {
        if let Some(m) = store.get(&id).await?
            && DISTANCE_KINDS.contains(&m.kind)
        {
            return Ok(true);
        }
    }
    Ok(false)
}

/// Checks distance CSG before anything is read: every operand a distance volume
/// (`wrong-volume-kind` for a bit volume among them), all on one grid, no xor.
pub async fn check_csg(
    store: &dyn VolumeStore,
    expr: &CsgExpr,
    _limits: &crate::limits::Limits,
) -> Result<()> {
    fn has_xor(e: &CsgExpr) -> bool {
        match e {
            CsgExpr::Volume(_) => false,
            CsgExpr::Op { op, operands } => *op == CsgOp::Xor || operands.iter().any(has_xor),
        }
    }
    let mut first: Option<Grid> = None;
    for id in expr.volume_ids() {
        let meta = csg_operand(store, &id, DISTANCE_KINDS, "CSG with a distance volume").await?;
        match first {
            None => first = Some(meta.grid),
            Some(g) if g != meta.grid => {
                return Err(Error::from(CsgError::DifferentGrids {
                    a: g.dims,
                    b: meta.grid.dims,
                    oa: g.origin,
                    ob: meta.grid.origin,
                    sa: g.voxel_size,
                    sb: meta.grid.voxel_size,
                })
                .context(format!("volume {id}")));
            }
            Some(_) => {}
        }
    }
    if has_xor(expr) {
        return Err(CsgError::NotForDistance(
            "xor has no distance form; distance volumes combine by union, intersection or difference".into(),
        )
        .into());
    }
    Ok(())
}

/// Evaluates a CSG expression over distance volumes already loaded.
pub fn eval_csg_with(
    expr: &CsgExpr,
    vols: &HashMap<String, Arc<Sparse<f32>>>,
    ctl: &Control,
) -> Result<Sparse<f32>> {
    fn eval(
        e: &CsgExpr,
        vols: &HashMap<String, Arc<Sparse<f32>>>,
        ctl: &Control,
    ) -> Result<Arc<Sparse<f32>>> {
        match e {
            CsgExpr::Volume(id) => vols
                .get(id)
                .cloned()
                .ok_or_else(|| Error::not_found("volume", id)),
            CsgExpr::Op { op, operands } => {
                let vs = operands
                    .iter()
                    .map(|o| eval(o, vols, ctl))
                    .collect::<Result<Vec<_>>>()?;
                let refs: Vec<&Sparse<f32>> = vs.iter().map(|v| &**v).collect();
                Ok(Arc::new(csg::apply_distance_with::<Error>(
                    *op, &refs, ctl,
                )?))
            }
        }
    }
    let v = eval(expr, vols, ctl)?;
    ctl.complete();
    Ok(Arc::try_unwrap(v).unwrap_or_else(|v| (*v).clone()))
}

/// Distance CSG over stored volumes (each read once), stored.
pub async fn csg_stored_with(
    store: &dyn VolumeStore,
    expr: CsgExpr,
    label: Label,
    ctl: &Control,
) -> Result<VolumeMeta> {
    let mut vols = HashMap::new();
    for id in expr.volume_ids() {
        let v = load_distance(store, &id, "CSG with a distance volume").await?;
        vols.insert(id, Arc::new(v));
    }
    let provenance = expr.to_json();
    let v = blocking_with(ctl, move |ctl| eval_csg_with(&expr, &vols, ctl)).await?;
    ctl.check()?;
    store_derived_volume(store, Volume::SparseDistance(v), label, "csg", provenance).await
}

/// Distance CSG's memory: every operand loaded, and a result of at most their bricks together
/// with its encoding.
pub fn csg_cost(metas: &HashMap<String, VolumeMeta>) -> u64 {
    let loads = metas.values().map(cost::load).fold(0, u64::saturating_add);
    let out = metas
        .values()
        .map(cost::stored_decoded_bytes)
        .fold(0, u64::saturating_add);
    loads.saturating_add(out.saturating_mul(2))
}

/// A level for `threshold`: any finite number (as f32: what the voxels are compared with).
pub fn check_level(level: f64) -> Result<f32> {
    let l = level as f32;
    if !l.is_finite() {
        return Err(Error::invalid(format!(
            "level={level} is not a finite number (as f32)"
        )));
    }
    Ok(l)
}

/// How a threshold was made.
pub fn threshold_provenance(of: &str, level: f32) -> Value {
    json!({ "threshold": { "of": of, "level": level } })
}

/// `threshold` of a stored distance volume, stored as a bit volume.
pub async fn threshold_stored_with(
    store: &dyn VolumeStore,
    id: &str,
    level: f32,
    label: Label,
    ctl: &Control,
) -> Result<VolumeMeta> {
    let v = load_distance(store, id, "threshold").await?;
    let out: BitVolume = blocking_with(ctl, move |ctl| {
        Ok(levelset::threshold_with(&v, level, ctl)?)
    })
    .await?;
    ctl.check()?;
    store_derived(
        store,
        out,
        label,
        "threshold",
        threshold_provenance(id, level),
    )
    .await
}

/// `threshold`'s memory: the loaded volume, and the bit result with a working copy and its
/// encoding.
pub fn threshold_cost(meta: &VolumeMeta) -> u64 {
    cost::load(meta).saturating_add(cost::bits_bytes(&meta.grid).saturating_mul(3))
}

/// A band for `sdf`: 1..=[`MAX_BAND`] voxels.
pub fn check_band(band: u32) -> Result<()> {
    if !(1..=MAX_BAND).contains(&band) {
        return Err(Error::invalid(format!(
            "band={band}: the band is 1..={MAX_BAND} voxels"
        )));
    }
    Ok(())
}

/// How a distance transform was made.
pub fn sdf_provenance(of: &str, band: u32) -> Value {
    json!({ "sdf": { "of": of, "band": band } })
}

/// The signed distance transform of a stored bit volume, stored as a sparse distance volume.
pub async fn sdf_stored_with(
    store: &dyn VolumeStore,
    id: &str,
    band: u32,
    label: Label,
    ctl: &Control,
) -> Result<VolumeMeta> {
    check_band(band)?;
    let b = load_bits(store, id, SDF_ACCEPTS, "the distance transform").await?;
    let out = blocking_with(ctl, move |ctl| {
        Ok(levelset::sdf_of_bits_with(&b, band, ctl)?)
    })
    .await?;
    ctl.check()?;
    store_derived_volume(
        store,
        Volume::SparseDistance(out),
        label,
        "sdf",
        sdf_provenance(id, band),
    )
    .await
}

/// `sdf`'s memory: the loaded bit volume, two u16 squared distances per voxel of the grid
/// padded by one, and a result of at most every brick (4 bytes a voxel) with its encoding.
pub fn sdf_cost(meta: &VolumeMeta) -> u64 {
    let padded = meta
        .grid
        .dims
        .iter()
        .map(|&d| u64::from(d) + 2)
        .fold(1u64, u64::saturating_mul);
    let bricks = meta
        .grid
        .dims
        .iter()
        .map(|&d| u64::from(d.div_ceil(8)) * 8)
        .fold(1u64, u64::saturating_mul);
    cost::load(meta)
        .saturating_add(padded.saturating_mul(4))
        .saturating_add(bricks.saturating_mul(8))
}

/// Statistics of a stored distance volume.
pub async fn stats_stored_with(
    store: &dyn VolumeStore,
    id: &str,
    ctl: &Control,
) -> Result<DistanceStats> {
    let v = load_distance(store, id, "statistics").await?;
    blocking_with(ctl, move |_| Ok(crate::volume::stats::distance_stats(&v))).await
}

/// A CSG operand's metadata: `not-found` when there is none, `wrong-volume-kind` (naming the
/// operand) when its kind is not in `accepts`.
pub(crate) async fn csg_operand(
    store: &dyn VolumeStore,
    id: &str,
    accepts: &'static [crate::volume::VolumeKind],
    what: &str,
) -> Result<VolumeMeta> {
    let meta = store
        .get(id)
        .await?
        .ok_or_else(|| Error::not_found("volume", id))?;
    meta.kind
        .require(accepts, what)
        .map_err(|e| Error::from(e).context(format!("volume {id}")))?;
    Ok(meta)
}
