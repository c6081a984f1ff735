//! The viewer page (issue 33): `GET /v1/volumes/{id}/view` serves one static page that shows
//! the volume's extracted mesh in 3D (three.js, rotate and zoom, an algorithm switch), its grid
//! and counts, and a slice slider over the PNG previews; `GET /v1/viewer/{file}` serves the
//! three.js files it imports. Everything is embedded in the binary (three.js vendored from npm
//! by `scripts/vendor-three.sh`, MIT, its licence beside it and served too), so the page works
//! without internet. The page holds no data: it fetches the volume through the API with the
//! caller's key (given after `#key=`), so neither route needs a key itself.

use axum::extract::Path;
use axum::http::{HeaderValue, header};
use axum::response::{IntoResponse, Response};

use super::super::problem::Problem;
use crate::app::ErrorKind;

const PAGE: &str = include_str!("../../../assets/viewer/index.html");

/// The files under `/v1/viewer/`: name, media type, bytes.
const FILES: &[(&str, &str, &[u8])] = &[
    (
        "three.module.min.js",
        "text/javascript",
        include_bytes!("../../../assets/viewer/vendor/three.module.min.js"),
    ),
    (
        "three.core.min.js",
        "text/javascript",
        include_bytes!("../../../assets/viewer/vendor/three.core.min.js"),
    ),
    (
        "OrbitControls.js",
        "text/javascript",
        include_bytes!("../../../assets/viewer/vendor/OrbitControls.js"),
    ),
    (
        "LICENSE-three.txt",
        "text/plain; charset=utf-8",
        include_bytes!("../../../assets/viewer/vendor/LICENSE-three.txt"),
    ),
];

/// Scripts, styles and images from this origin only (the import map is inline), nothing framed.
const CSP: &str = "default-src 'self'; script-src 'self' 'unsafe-inline'; \
                   style-src 'unsafe-inline'; img-src 'self' blob:; frame-ancestors 'none'";

pub async fn page(Path(id): Path<String>) -> Result<Response, Problem> {
    // Ids are voxd's hex; anything else names no volume (and is never echoed into the page).
    if id.is_empty()
        || id.len() > 128
        || !id.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'-')
    {
        return Err(Problem::new(
            ErrorKind::NotFound,
            format!("no volume {id:?}"),
        ));
    }
    let mut r = PAGE.into_response();
    let h = r.headers_mut();
    h.insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("text/html; charset=utf-8"),
    );
    h.insert(
        header::CONTENT_SECURITY_POLICY,
        HeaderValue::from_static(CSP),
    );
    h.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-cache"));
    Ok(r)
}

pub async fn file(Path(name): Path<String>) -> Result<Response, Problem> {
    let Some((_, media, bytes)) = FILES.iter().find(|f| f.0 == name) else {
        return Err(Problem::new(
            ErrorKind::NotFound,
            format!("no viewer file {name:?}"),
        ));
    };
    let mut r = bytes.into_response();
    let h = r.headers_mut();
    h.insert(header::CONTENT_TYPE, HeaderValue::from_static(media));
    // The files change only with the binary.
    h.insert(
        header::CACHE_CONTROL,
        HeaderValue::from_static("public, max-age=86400"),
    );
    Ok(r)
}
