//! `GET` and `DELETE /v1/jobs/{id}`: a job's state, and cancelling it.

use axum::extract::Path;
use axum::response::{IntoResponse, Response};
use serde_json::Value;

use super::super::problem::Problem;
use super::AppState;
use super::volumes::{Caller, sees};
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

/// Job `id`'s record, if `caller` may see it: another tenant's job is `not-found`.
async fn visible(app: &crate::service::App, caller: &Caller, id: &str) -> Result<JobRecord, Error> {
    app.queue
        .get(id)
        .await?
        .filter(|r| sees(caller, r.owner.as_deref()))
        .ok_or_else(|| Error::not_found("job", id))
}

pub async fn get(
    axum::extract::State(app): AppState,
    caller: Caller,
    Path(id): Path<String>,
) -> Result<Response, Problem> {
    let r = visible(&app, &caller, &id).await?;
    Ok(axum::Json(view(r)).into_response())
}

pub async fn cancel(
    axum::extract::State(app): AppState,
    caller: Caller,
    Path(id): Path<String>,
) -> Result<Response, Problem> {
    // Only a job the caller may see may be canceled.
    if caller.is_some() {
        visible(&app, &caller, &id).await?;
    }
    let r = app
        .queue
        .cancel(&id)
        .await?
        .ok_or_else(|| Error::not_found("job", &id))?;
    Ok(axum::Json(view(r)).into_response())
}
