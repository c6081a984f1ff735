//! `GET` and `DELETE /v1/jobs/{id}`: a job's state, and cancelling it.

use axum::extract::Path;
use axum::response::{IntoResponse, Response};
use serde_json::Value;

use super::super::problem::Problem;
use super::AppState;
use crate::app::Error;
use crate::app::queue::JobRecord;

/// A job as the API shows it: its record, with the error as a problem document.
pub fn view(mut r: JobRecord) -> Value {
    let problem = r.error.take().map(Problem::from);
    let mut v = serde_json::to_value(r).expect("a job record serialises");
    if let Some(p) = problem {
        v["problem"] = serde_json::to_value(p).expect("a problem serialises");
    }
    v
}

pub async fn get(
    axum::extract::State(app): AppState,
    Path(id): Path<String>,
) -> Result<Response, Problem> {
    let r = app
        .queue
        .get(&id)
        .await?
        .ok_or_else(|| Error::not_found("job", &id))?;
    Ok(axum::Json(view(r)).into_response())
}

pub async fn cancel(
    axum::extract::State(app): AppState,
    Path(id): Path<String>,
) -> Result<Response, Problem> {
    let r = app
        .queue
        .cancel(&id)
        .await?
        .ok_or_else(|| Error::not_found("job", &id))?;
    Ok(axum::Json(view(r)).into_response())
}
