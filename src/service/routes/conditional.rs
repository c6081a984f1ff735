//! HTTP semantics of the volume routes (RFC 9110, 9111): the content coding a response is sent
//! in, its ETag, the conditional headers (`If-Match`, `If-None-Match`, `If-Range`) and byte
//! ranges.
//!
//! The handler, not the compression layer, picks the content coding of a volume's metadata and
//! downloads ([`negotiate`]) and applies it ([`encode`]): the ETag depends on the coding, and a
//! `304` is decided before any body exists, so the coding must be known there and be the one the
//! `200` would use. Replicating the layer's choice (its `Accept-Encoding` parsing, its size and
//! media-type predicate) outside it would be two sources of truth; one decision, made here and
//! marked on the response ([`Negotiated`]) so that the layer leaves it alone, is one.

use axum::body::Body;
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use bytes::Bytes;
use futures_util::{Stream, StreamExt, TryStreamExt};

use crate::app::{Error, ErrorKind};

/// A content coding the service sends.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Coding {
    Identity,
    Gzip,
    Zstd,
}

impl Coding {
    /// Every coding, preferred first where `Accept-Encoding` ranks codings equally.
    pub const BY_PREFERENCE: [Coding; 3] = [Coding::Zstd, Coding::Gzip, Coding::Identity];

    fn token(self) -> &'static str {
        match self {
            Coding::Identity => "identity",
            Coding::Gzip => "gzip",
            Coding::Zstd => "zstd",
        }
    }
}

/// Marks a response whose content coding the handler chose: the compression layer skips it.
#[derive(Clone, Copy, Debug)]
pub struct Negotiated;

/// What volume metadata and downloads are sent with: the representation varies with
/// `Accept-Encoding`, and a cache may keep it but must ask again before using it (a volume never
/// changes under its id, but it may be deleted, and with API keys every read is checked).
pub const CACHE_CONTROL: &str = "private, no-cache";

/// The coding to send a representation in: the highest `q` of `Accept-Encoding` among zstd,
/// gzip (when `compressible`) and identity (acceptable unless refused by `identity;q=0` or
/// `*;q=0`); ties go to zstd, then gzip. No header: identity. Nothing acceptable: identity
/// (RFC 9110 §12.5.3 allows it rather than a 406).
pub fn negotiate(headers: &HeaderMap, compressible: bool) -> Coding {
    let mut prefs: Vec<(String, f32)> = Vec::new();
    for v in headers.get_all(header::ACCEPT_ENCODING) {
        let Ok(v) = v.to_str() else { continue };
        for item in v.split(',') {
            let mut parts = item.split(';');
            let name = parts.next().unwrap_or("").trim().to_ascii_lowercase();
            if name.is_empty() {
                continue;
            }
            let q = parts
                .filter_map(|p| p.split_once('='))
                .find(|(k, _)| k.trim().eq_ignore_ascii_case("q"))
                .map_or(Some(1.0), |(_, q)| q.trim().parse::<f32>().ok())
                .filter(|q| (0.0..=1.0).contains(q))
                .unwrap_or(0.0);
            let name = if name == "x-gzip" {
                "gzip".into()
            } else {
                name
            };
            prefs.push((name, q));
        }
    }
    let q_of = |name: &str| prefs.iter().find(|(n, _)| n == name).map(|(_, q)| *q);
    let star = q_of("*");
    let q = |c: Coding| match c {
        Coding::Identity => q_of("identity")
            .or(star.filter(|s| *s == 0.0))
            .unwrap_or(1.0),
        Coding::Gzip | Coding::Zstd if !compressible => 0.0,
        c => q_of(c.token()).or(star).unwrap_or(0.0),
    };
    let mut best = (Coding::Identity, 0.0);
    for c in Coding::BY_PREFERENCE {
        if q(c) > best.1 {
            best = (c, q(c));
        }
    }
    best.0
}

/// The ETag of a representation whose identity ETag is `etag` (`"…"`) under `coding`.
pub fn coded_etag(etag: &str, coding: Coding) -> String {
    match coding {
        Coding::Identity => etag.to_string(),
        c => format!("{}+{}\"", etag.trim_end_matches('"'), c.token()),
    }
}

/// The entity tags of a list header (`If-Match`, `If-None-Match`): `(weak, "opaque")`, or
/// `None` for `*`.
fn tags(headers: &HeaderMap, name: header::HeaderName) -> Option<Vec<(bool, String)>> {
    let values: Vec<&str> = headers
        .get_all(name)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .collect();
    if values.is_empty() {
        return Some(vec![]);
    }
    let mut out = vec![];
    for t in values.iter().flat_map(|v| v.split(',')).map(str::trim) {
        if t == "*" {
            return None;
        }
        match t.strip_prefix("W/") {
            Some(s) => out.push((true, s.to_string())),
            None if !t.is_empty() => out.push((false, t.to_string())),
            None => {}
        }
    }
    Some(out)
}

/// Does `If-Match` hold for a representation tagged `current`? Absent: yes. `*`: yes (the
/// representation exists). Otherwise strong comparison: a weak tag never matches.
pub fn if_match(headers: &HeaderMap, current: &[String]) -> bool {
    if !headers.contains_key(header::IF_MATCH) {
        return true;
    }
    match tags(headers, header::IF_MATCH) {
        None => true,
        Some(list) => list
            .iter()
            .any(|(weak, t)| !weak && current.iter().any(|c| c == t)),
    }
}

/// Does `If-None-Match` name a representation tagged one of `current` (weak comparison), or
/// `*`? Then a GET is answered `304`, a DELETE `412`.
pub fn none_match_hits(headers: &HeaderMap, current: &[String]) -> bool {
    if !headers.contains_key(header::IF_NONE_MATCH) {
        return false;
    }
    match tags(headers, header::IF_NONE_MATCH) {
        None => true,
        Some(list) => list.iter().any(|(_, t)| current.contains(t)),
    }
}

/// What a `Range` header asks of a representation of `len` bytes.
#[derive(Debug, PartialEq, Eq)]
pub enum Ranged {
    /// No range, or one the service ignores (another unit, bad syntax, several ranges):
    /// the whole representation, `200`.
    Whole,
    /// Bytes `start..=end`: `206`.
    Part { start: u64, end: u64 },
    /// `416`.
    Unsatisfiable,
}

/// The range `headers` ask of a `len`-byte representation tagged `etag`. Only a single range
/// is served; several are answered with the whole representation (RFC 9110 §14.2 lets a server
/// ignore `Range`). An `If-Range` that is not `etag`, compared strongly (a date never
/// matches: no `Last-Modified` is sent), also gives the whole.
pub fn range(headers: &HeaderMap, len: u64, etag: &str) -> Ranged {
    let Some(spec) = headers.get(header::RANGE).and_then(|v| v.to_str().ok()) else {
        return Ranged::Whole;
    };
    if let Some(cond) = headers.get(header::IF_RANGE)
        && cond.to_str().ok().map(str::trim) != Some(etag)
    {
        return Ranged::Whole;
    }
    let Some((unit, set)) = spec.split_once('=') else {
        return Ranged::Whole;
    };
    let specs: Vec<&str> = set
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .collect();
    if !unit.trim().eq_ignore_ascii_case("bytes") || specs.len() != 1 {
        return Ranged::Whole;
    }
    let Some((a, b)) = specs[0].split_once('-') else {
        return Ranged::Whole;
    };
    let num = |s: &str| -> Option<u64> {
        (!s.is_empty() && s.bytes().all(|c| c.is_ascii_digit()))
            .then(|| s.parse().ok())
            .flatten()
    };
    let (start, end) = match (a.trim(), b.trim()) {
        ("", n) => match num(n) {
            Some(0) => return Ranged::Unsatisfiable,
            Some(n) => (len.saturating_sub(n), len.saturating_sub(1)),
            None => return Ranged::Whole,
        },
        (a, "") => match num(a) {
            Some(a) => (a, len.saturating_sub(1)),
            None => return Ranged::Whole,
        },
        (a, b) => match (num(a), num(b)) {
            (Some(a), Some(b)) if a <= b => (a, b.min(len.saturating_sub(1))),
            _ => return Ranged::Whole,
        },
    };
    if len == 0 || start >= len {
        return Ranged::Unsatisfiable;
    }
    Ranged::Part { start, end }
}

/// Bytes `start..=end` of a stream: the chunks before are dropped as they come, and the stream
/// ends (dropping its source, which stops a conversion) once `end` is passed.
pub fn slice<E: Send + 'static>(
    body: impl Stream<Item = Result<Bytes, E>> + Send + 'static,
    start: u64,
    end: u64,
) -> impl Stream<Item = Result<Bytes, E>> + Send + 'static {
    body.scan(0u64, move |pos, c| {
        let out = match c {
            Err(e) => Some(Err(e)),
            Ok(_) if *pos > end => None,
            Ok(b) => {
                let (from, to) = (*pos, *pos + b.len() as u64);
                *pos = to;
                let lo = start.saturating_sub(from).min(b.len() as u64) as usize;
                let hi = (end + 1).saturating_sub(from).min(b.len() as u64) as usize;
                Some(Ok(if lo < hi {
                    b.slice(lo..hi)
                } else {
                    Bytes::new()
                }))
            }
        };
        std::future::ready(out)
    })
    .try_filter(|b| std::future::ready(!b.is_empty()))
}

/// A response whose body is `body` sent in `coding`, with its `Content-Encoding`.
pub fn encode<E>(
    body: impl Stream<Item = Result<Bytes, E>> + Send + 'static,
    coding: Coding,
) -> Response
where
    E: std::error::Error + Send + Sync + 'static,
{
    use async_compression::tokio::bufread::{GzipEncoder, ZstdEncoder};
    use tokio_util::io::{ReaderStream, StreamReader};
    if coding == Coding::Identity {
        return Body::from_stream(body).into_response();
    }
    let reader = || StreamReader::new(body.map_err(std::io::Error::other));
    let mut r = match coding {
        Coding::Identity => unreachable!("sent as it is above"),
        Coding::Gzip => Body::from_stream(ReaderStream::new(GzipEncoder::new(reader()))),
        Coding::Zstd => Body::from_stream(ReaderStream::new(ZstdEncoder::new(reader()))),
    }
    .into_response();
    r.headers_mut().insert(
        header::CONTENT_ENCODING,
        HeaderValue::from_static(coding.token()),
    );
    r
}

/// A request's `If-Match` (strong) and `If-None-Match` (weak) against the representation tagged
/// `etag` of `what` (e.g. "volume ID as npy"): `412 precondition-failed` when `If-Match` fails,
/// a `304` with the representation's headers when `If-None-Match` names it, else `None` (answer
/// with the representation).
pub fn preconditions(
    headers: &HeaderMap,
    etag: &str,
    what: impl FnOnce() -> String,
) -> Result<Option<Response>, Error> {
    let tags = [etag.to_string()];
    if !if_match(headers, &tags) {
        return Err(Error::new(
            ErrorKind::PreconditionFailed,
            format!("{} is {etag}, not If-Match", what()),
        ));
    }
    if none_match_hits(headers, &tags) {
        let mut r = StatusCode::NOT_MODIFIED.into_response();
        representation_headers(&mut r, etag);
        return Ok(Some(r));
    }
    Ok(None)
}

/// The headers every representation of a volume route carries, on `200`, `206` and `304`
/// alike (RFC 9110 §15.4.5): its ETag, `Vary` and `Cache-Control`; and the mark that keeps the
/// compression layer off.
pub fn representation_headers(r: &mut Response, etag: &str) {
    let h = r.headers_mut();
    if let Ok(v) = HeaderValue::from_str(etag) {
        h.insert(header::ETAG, v);
    }
    h.insert(header::VARY, HeaderValue::from_static("accept-encoding"));
    h.insert(
        header::CACHE_CONTROL,
        HeaderValue::from_static(CACHE_CONTROL),
    );
    r.extensions_mut().insert(Negotiated);
}

#[cfg(test)]
mod tests {
    use super::*;

    fn h(pairs: &[(&str, &str)]) -> HeaderMap {
        let mut m = HeaderMap::new();
        for (k, v) in pairs {
            m.append(
                header::HeaderName::from_bytes(k.as_bytes()).unwrap(),
                HeaderValue::from_str(v).unwrap(),
            );
        }
        m
    }

    #[test]
    fn accept_encoding_is_negotiated_by_q() {
        let ae = |v: &str| negotiate(&h(&[("accept-encoding", v)]), true);
        assert_eq!(negotiate(&h(&[]), true), Coding::Identity);
        assert_eq!(ae("gzip"), Coding::Gzip);
        assert_eq!(ae("gzip, deflate, br, zstd"), Coding::Zstd);
        assert_eq!(ae("zstd;q=0.5, gzip"), Coding::Gzip);
        assert_eq!(ae("gzip;q=0.2, identity;q=0.5"), Coding::Identity);
        assert_eq!(ae("GZIP;Q=1.0, zstd;q=0"), Coding::Gzip);
        assert_eq!(ae("*"), Coding::Zstd);
        assert_eq!(ae("*;q=0"), Coding::Identity);
        assert_eq!(ae("identity"), Coding::Identity);
        assert_eq!(ae("br"), Coding::Identity);
        assert_eq!(ae("x-gzip"), Coding::Gzip);
        assert_eq!(ae("gzip;q=2"), Coding::Identity);
        assert_eq!(
            negotiate(&h(&[("accept-encoding", "zstd")]), false),
            Coding::Identity
        );
    }

    #[test]
    fn conditionals_compare_strongly_and_weakly() {
        let cur = ["\"a-npy\"".to_string()];
        assert!(if_match(&h(&[]), &cur));
        assert!(if_match(&h(&[("if-match", "*")]), &cur));
        assert!(if_match(&h(&[("if-match", "\"x\", \"a-npy\"")]), &cur));
        assert!(!if_match(&h(&[("if-match", "W/\"a-npy\"")]), &cur));
        assert!(!if_match(&h(&[("if-match", "\"a-npy+gzip\"")]), &cur));
        assert!(none_match_hits(
            &h(&[("if-none-match", "W/\"a-npy\"")]),
            &cur
        ));
        assert!(none_match_hits(&h(&[("if-none-match", "*")]), &cur));
        assert!(none_match_hits(
            &h(&[("if-none-match", "\"b\""), ("if-none-match", "\"a-npy\"")]),
            &cur
        ));
        assert!(!none_match_hits(
            &h(&[("if-none-match", "\"a-npy+zstd\"")]),
            &cur
        ));
        assert!(!none_match_hits(&h(&[]), &cur));
    }

    #[test]
    fn ranges() {
        let r = |v: &str| range(&h(&[("range", v)]), 100, "\"e\"");
        assert_eq!(range(&h(&[]), 100, "\"e\""), Ranged::Whole);
        assert_eq!(r("bytes=0-9"), Ranged::Part { start: 0, end: 9 });
        assert_eq!(r("bytes=90-"), Ranged::Part { start: 90, end: 99 });
        assert_eq!(r("bytes=-10"), Ranged::Part { start: 90, end: 99 });
        assert_eq!(r("bytes=-1000"), Ranged::Part { start: 0, end: 99 });
        assert_eq!(r("bytes=50-1000"), Ranged::Part { start: 50, end: 99 });
        assert_eq!(r("bytes=100-"), Ranged::Unsatisfiable);
        assert_eq!(r("bytes=-0"), Ranged::Unsatisfiable);
        assert_eq!(r("bytes=0-1,5-6"), Ranged::Whole);
        assert_eq!(r("bytes=9-1"), Ranged::Whole);
        assert_eq!(r("items=0-1"), Ranged::Whole);
        assert_eq!(r("bytes=a-b"), Ranged::Whole);
        assert_eq!(
            range(&h(&[("range", "bytes=0-")]), 0, "\"e\""),
            Ranged::Unsatisfiable
        );
        let ir = |c: &str| range(&h(&[("range", "bytes=1-2"), ("if-range", c)]), 100, "\"e\"");
        assert_eq!(ir("\"e\""), Ranged::Part { start: 1, end: 2 });
        assert_eq!(ir("W/\"e\""), Ranged::Whole);
        assert_eq!(ir("\"f\""), Ranged::Whole);
        assert_eq!(ir("Fri, 04 Dec 2026 17:00:00 GMT"), Ranged::Whole);
    }

    #[tokio::test]
    async fn slices_cut_across_chunks() {
        let data: Vec<u8> = (0..=255).collect();
        let chunks = || {
            futures_util::stream::iter(
                data.chunks(7)
                    .map(|c| Ok::<_, std::io::Error>(Bytes::copy_from_slice(c)))
                    .collect::<Vec<_>>(),
            )
        };
        for (a, b) in [(0, 0), (3, 20), (7, 13), (250, 255), (0, 255), (100, 100)] {
            let got: Vec<Bytes> = slice(chunks(), a, b).try_collect().await.unwrap();
            assert_eq!(got.concat(), &data[a as usize..=b as usize]);
        }
    }
}
