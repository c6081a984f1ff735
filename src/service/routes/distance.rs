//! `/v1/volumes/{id}/threshold` and `/v1/volumes/{id}/sdf`: between distance volumes and bit
//! volumes (`app::distance`). Each is checked (parameters, then the volume's kind) before its
//! memory is admitted and the work starts; the result is stored like a morphology's.

use axum::extract::Path;
use axum::response::Response;
use serde::Deserialize;

use super::super::extract::Query;
use super::super::problem::Problem;
use super::volumes::{Caller, meta_of, tenant};
use super::{AppState, created};
use crate::app::{Error, distance, ops};
use crate::cancel::Control;
use crate::volume::levelset::{DEFAULT_BAND, DISTANCE_KINDS, SDF_ACCEPTS};

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ThresholdQuery {
    level: Option<f64>,
    name: Option<String>,
}

pub async fn threshold(
    axum::extract::State(app): AppState,
    caller: Caller,
    Path(id): Path<String>,
    Query(q): Query<ThresholdQuery>,
) -> Result<Response, Problem> {
    if let Some(n) = &q.name {
        super::check_name(n, &app.limits)?;
    }
    let level = q
        .level
        .ok_or_else(|| Error::invalid("give level=L (world units; 0 gives the solid)"))?;
    let level = distance::check_level(level)?;
    let src = meta_of(&app, &caller, &id).await?;
    src.kind
        .require(DISTANCE_KINDS, "threshold")
        .map_err(|e| Error::from(e).context(format!("volume {id}")))?;
    let _memory = app
        .admit(
            distance::threshold_cost(&src),
            &format!("the threshold of volume {id}"),
        )
        .await?;
    let label = ops::Label {
        name: q.name,
        owner: tenant(&caller),
    };
    let meta =
        distance::threshold_stored_with(&*app.store, &id, level, label, &Control::new()).await?;
    Ok(created(&meta))
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SdfQuery {
    band: Option<u32>,
    name: Option<String>,
}

pub async fn sdf(
    axum::extract::State(app): AppState,
    caller: Caller,
    Path(id): Path<String>,
    Query(q): Query<SdfQuery>,
) -> Result<Response, Problem> {
    if let Some(n) = &q.name {
        super::check_name(n, &app.limits)?;
    }
    let band = q.band.unwrap_or(DEFAULT_BAND);
    distance::check_band(band)?;
    let src = meta_of(&app, &caller, &id).await?;
    src.kind
        .require(SDF_ACCEPTS, "the distance transform")
        .map_err(|e| Error::from(e).context(format!("volume {id}")))?;
    let _memory = app
        .admit(
            distance::sdf_cost(&src),
            &format!("the distance transform of volume {id}"),
        )
        .await?;
    let label = ops::Label {
        name: q.name,
        owner: tenant(&caller),
    };
    let meta = distance::sdf_stored_with(&*app.store, &id, band, label, &Control::new()).await?;
    Ok(created(&meta))
}
