//! One chunk of OBJ text read into vertices and triangles: the `v` and `f` lines (every other
//! statement skipped), each face's indices resolved by [`resolve_index`] and fan-triangulated,
//! the triangles counted against the limit as they are made. Not here: how the text is cut into
//! chunks and the chunks added up (`obj/mod.rs`), how a line's tokens and numbers are scanned
//! (`lexer.rs`).

use std::sync::atomic::{AtomicUsize, Ordering};

use super::lexer::Line;
use crate::mesh::{MeshError, bad_position, fan, malformed};

/// Where the OBJ vertex index `n` (as written) points, 0-based: 1-based from the file's start
/// when positive, relative to the `defined` vertices read before its line when negative. `total`
/// is the file's vertex count when known; when not, any index a `u32` holds is accepted here and
/// forward references are checked once the count is known. `Err`: the message (after `line N: `).
///
/// The one place an index is resolved: the chunk reader and the tests' reference reader both
/// call it.
pub(super) fn resolve_index(n: i64, defined: i64, total: Option<usize>) -> Result<usize, String> {
    let abs = if n > 0 { n - 1 } else { defined + n };
    let out = match total {
        Some(total) => abs >= total as i64,
        None => abs > u32::MAX as i64,
    };
    if n == 0 || abs < 0 || out {
        let has = match total {
            Some(t) => format!("the file has {t} vertices"),
            None => format!("{defined} vertices are defined before this line"),
        };
        return Err(format!("vertex index {n} is out of range ({has})"));
    }
    Ok(abs as usize)
}

/// What one chunk read.
pub(super) struct Chunk {
    pub(super) positions: Vec<[f64; 3]>,
    pub(super) triangles: Vec<[u32; 3]>,
    /// The largest index used before its vertex was defined, with its line and as written.
    pub(super) forward: Option<(usize, i64, usize)>,
    /// The first vertex (its index in the file) that `Mesh::new` would refuse.
    pub(super) bad: Option<usize>,
}

/// Triangles made so far by every chunk of a block, against the limit.
pub(super) struct Shared {
    pub(super) triangles: AtomicUsize,
    pub(super) max_triangles: usize,
}

impl Shared {
    /// Adds `n` triangles a chunk made; an error once the total is over the limit.
    pub(super) fn add(&self, n: usize) -> Result<(), MeshError> {
        let total = self.triangles.fetch_add(n, Ordering::Relaxed) + n;
        if total > self.max_triangles {
            return Err(MeshError::CountOverLimit {
                format: "OBJ",
                what: "triangles or more (`f` lines read so far)",
                count: total as u64,
                limit: self.max_triangles as u64,
            });
        }
        Ok(())
    }
}

/// Triangles a chunk makes between two reports to [`Shared`].
pub(super) const REPORT_EVERY: usize = 1 << 12;

/// Parses one chunk whose first vertex is number `vbase` and first line `lbase` (0-based) of a
/// file with `total` vertices (when known: else indices past the vertices read so far are
/// kept in `forward`, checked at the end).
///
/// One pass over the bytes, a line at a time (the line ends found by `memchr`): a line's
/// tokens are the runs of bytes that are not ASCII whitespace; a `v` or `f` line's numbers are
/// read as they are scanned, plain decimals and short indices on the spot and anything else as
/// a whole token by the standard parser ([`Line::float`], [`Line::index`]: what `str::parse`
/// gives, bit for bit); the rest of a line is skipped once what matters of it is read.
pub(super) fn parse_chunk(
    text: &[u8],
    vbase: usize,
    lbase: usize,
    nv: usize,
    total: Option<usize>,
    shared: &Shared,
) -> Result<Chunk, MeshError> {
    let mut positions = Vec::with_capacity(nv);
    let mut triangles = Vec::new();
    let mut poly: Vec<u32> = Vec::new();
    let mut forward: Option<(usize, i64, usize)> = None;
    let mut reported = 0;
    let mut bad = None;
    let mut ends = memchr::memchr_iter(b'\n', text);
    let mut start = 0;
    let mut i = 0;
    loop {
        let end = ends.next();
        let mut line = Line {
            text,
            end: end.unwrap_or(text.len()),
            at: start,
        };
        let err = |what: &str| malformed("OBJ", format!("line {}: {what}", lbase + i + 1));
        match line.keyword() {
            b'v' => {
                let mut p = [0.0; 3];
                for c in &mut p {
                    *c = match line.float() {
                        Some(Ok(v)) => v,
                        Some(Err(t)) => {
                            return Err(err(&format!(
                                "{:?} is not a number",
                                String::from_utf8_lossy(t)
                            )));
                        }
                        None => return Err(err("a vertex needs x, y and z")),
                    };
                }
                if bad.is_none() && bad_position(&p) {
                    bad = Some(vbase + positions.len());
                }
                positions.push(p);
            }
            b'f' => {
                let defined = (vbase + positions.len()) as i64;
                poly.clear();
                while let Some(n) = line.index() {
                    let n = n.map_err(|t| {
                        err(&format!(
                            "{:?} is not a vertex index",
                            String::from_utf8_lossy(t)
                        ))
                    })?;
                    let abs = resolve_index(n, defined, total).map_err(|m| err(&m))?;
                    if abs as i64 >= defined && forward.is_none_or(|f| abs > f.2) {
                        forward = Some((lbase + i + 1, n, abs));
                    }
                    poly.push(abs as u32);
                }
                fan(&poly, &mut triangles);
                if triangles.len() - reported >= REPORT_EVERY {
                    shared.add(triangles.len() - reported)?;
                    reported = triangles.len();
                }
            }
            _ => {} // comments, vt, vn, o, g, s, usemtl, mtllib, l, p, ...
        }
        match end {
            Some(e) => (start, i) = (e + 1, i + 1),
            None => break,
        }
    }
    shared.add(triangles.len() - reported)?;
    Ok(Chunk {
        positions,
        triangles,
        forward,
        bad,
    })
}
