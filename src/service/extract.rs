//! Extractors whose rejections are problem documents: [`Query`] (a typed query string; the
//! types deny unknown parameters) and [`Json`] (a JSON body within the body limit).

use axum::extract::{FromRequest, FromRequestParts, Request};
use axum::http::request::Parts;
use serde::de::DeserializeOwned;

use super::App;
use super::problem::Problem;
use crate::app::ErrorKind;

/// A query string deserialized into `T` (`#[serde(deny_unknown_fields)]` types refuse unknown
/// parameters); a malformed one is an `invalid-parameter` problem naming the parameter.
pub struct Query<T>(pub T);

impl<T: DeserializeOwned, S: Send + Sync> FromRequestParts<S> for Query<T> {
    type Rejection = Problem;

    async fn from_request_parts(parts: &mut Parts, _: &S) -> Result<Self, Problem> {
        let q = parts.uri.query().unwrap_or("");
        serde_urlencoded::from_str(q)
            .map(Query)
            .map_err(|e| Problem::invalid(format!("query string: {e}")))
    }
}

/// A JSON body deserialized into `T`, read up to the service's body limit.
pub struct Json<T>(pub T);

impl<T: DeserializeOwned> FromRequest<std::sync::Arc<App>> for Json<T> {
    type Rejection = Problem;

    async fn from_request(req: Request, app: &std::sync::Arc<App>) -> Result<Self, Problem> {
        let limit = app.limits.max_body_bytes;
        let bytes = axum::body::to_bytes(req.into_body(), limit)
            .await
            .map_err(|_| {
                Problem::new(
                    ErrorKind::BodyTooLarge,
                    format!("the request body is larger than {limit} bytes"),
                )
            })?;
        serde_json::from_slice(&bytes)
            .map(Json)
            .map_err(|e| Problem::invalid(format!("the body is not the JSON expected: {e}")))
    }
}

/// Deserializes `X,Y,Z` query values.
pub mod triple {
    use serde::{Deserialize, Deserializer};

    pub fn deserialize<'de, D, T>(d: D) -> Result<Option<[T; 3]>, D::Error>
    where
        D: Deserializer<'de>,
        T: std::str::FromStr,
    {
        let s = Option::<String>::deserialize(d)?;
        s.map(|s| crate::names::parse_triple(&s).map_err(serde::de::Error::custom))
            .transpose()
    }
}
