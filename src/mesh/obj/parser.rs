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
    /// Vertex colours (`v x y z r g b`), one per position, once a vertex of the chunk had one
    /// (the others white); empty when none had.
    pub(super) colors: Vec<[f32; 4]>,
    /// The `usemtl` names of the chunk, in the order of their first use.
    pub(super) names: Vec<Vec<u8>>,
    /// Each triangle's material: an index into `names`, or [`INHERITED`] (made before the
    /// chunk's first `usemtl`: the material in force where the chunk starts). Empty when the
    /// chunk has no `usemtl`.
    pub(super) material: Vec<u16>,
    /// The material in force at the chunk's end (an index into `names`, or [`INHERITED`]).
    pub(super) last: u16,
    /// The `mtllib` lines' file names.
    pub(super) libs: Vec<Vec<u8>>,
    /// With [`Shared::uv`]: the `vt` lines' (u, v), and each triangle's corners' indices into
    /// the file's texture coordinates ([`NO_UV`] for a corner written without one), once a
    /// corner of the chunk had one (else empty).
    pub(super) texcoords: Vec<[f32; 2]>,
    pub(super) corners: Vec<[u32; 3]>,
    /// The largest texture coordinate index used before its `vt` line, with its line and as
    /// written (checked once the count is known).
    pub(super) uv_forward: Option<(usize, i64, usize)>,
}

/// A face corner written without a texture coordinate (`a` or `a//c`).
pub(super) const NO_UV: u32 = u32::MAX;

/// A triangle made before its chunk's first `usemtl`.
pub(super) const INHERITED: u16 = u16::MAX;

/// Triangles made so far by every chunk of a block, against the limit.
pub(super) struct Shared {
    pub(super) triangles: AtomicUsize,
    pub(super) max_triangles: usize,
    /// Are texture coordinates kept (`vt` lines and the faces' `a/b` indices)? Only where a
    /// material library, and so a texture, can be read: a file on the command line or a zip.
    pub(super) uv: bool,
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
#[allow(clippy::too_many_arguments)]
pub(super) fn parse_chunk(
    text: &[u8],
    vbase: usize,
    tbase: usize,
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
    let mut colors: Vec<[f32; 4]> = Vec::new();
    let mut names: Vec<Vec<u8>> = Vec::new();
    let mut material: Vec<u16> = Vec::new();
    let mut current = INHERITED;
    let mut libs: Vec<Vec<u8>> = Vec::new();
    let mut texcoords: Vec<[f32; 2]> = Vec::new();
    let mut corners: Vec<[u32; 3]> = Vec::new();
    let mut poly_uv: Vec<u32> = Vec::new();
    let mut uv_forward: Option<(usize, i64, usize)> = None;
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
                // The colour extension: exactly three more numbers (`v x y z r g b`); one more
                // (`w`) or any other count is not a colour.
                let mut rgb = [0.0f64; 3];
                let mut more = 0;
                while more < 4 {
                    match line.float() {
                        Some(Ok(v)) => {
                            if more < 3 {
                                rgb[more] = v;
                            }
                            more += 1;
                        }
                        _ => break,
                    }
                }
                if more == 3 {
                    if colors.is_empty() {
                        colors = vec![[1.0; 4]; positions.len()];
                    }
                    let unit = |v: f64| {
                        if v.is_nan() {
                            0.0
                        } else {
                            v.clamp(0.0, 1.0) as f32
                        }
                    };
                    colors.push([unit(rgb[0]), unit(rgb[1]), unit(rgb[2]), 1.0]);
                } else if !colors.is_empty() {
                    colors.push([1.0; 4]);
                }
                positions.push(p);
            }
            b't' if shared.uv => {
                // `vt u [v [w]]`: v is 0 when missing, w is ignored.
                let mut uv = [0.0f32; 2];
                for (k, c) in uv.iter_mut().enumerate() {
                    match line.float() {
                        Some(Ok(v)) if v.is_finite() => *c = v as f32,
                        None if k == 1 => {}
                        _ => return Err(err("a texture coordinate needs a finite u (and v)")),
                    }
                }
                texcoords.push(uv);
            }
            b'f' => {
                let defined = (vbase + positions.len()) as i64;
                let defined_uv = (tbase + texcoords.len()) as i64;
                poly.clear();
                poly_uv.clear();
                loop {
                    // With texture coordinates kept, each corner's `vt` index too.
                    let next = if shared.uv {
                        line.corner()
                    } else {
                        line.index().map(|r| r.map(|n| (n, None)))
                    };
                    let Some(c) = next else { break };
                    let (n, t) = c.map_err(|tok| {
                        err(&format!(
                            "{:?} is not a vertex index",
                            String::from_utf8_lossy(tok)
                        ))
                    })?;
                    let abs = resolve_index(n, defined, total).map_err(|m| err(&m))?;
                    if abs as i64 >= defined && forward.is_none_or(|f| abs > f.2) {
                        forward = Some((lbase + i + 1, n, abs));
                    }
                    poly.push(abs as u32);
                    if !shared.uv {
                        continue;
                    }
                    let t = match t {
                        Some(t) => {
                            let abs = resolve_index(t, defined_uv, None).map_err(|m| {
                                err(&m
                                    .replace("vertex index", "texture coordinate index")
                                    .replace("vertices", "texture coordinates"))
                            })?;
                            if abs as i64 >= defined_uv && uv_forward.is_none_or(|f| abs > f.2) {
                                uv_forward = Some((lbase + i + 1, t, abs));
                            }
                            abs as u32
                        }
                        None => NO_UV,
                    };
                    poly_uv.push(t);
                }
                let before = triangles.len();
                fan(&poly, &mut triangles);
                // Kept once a corner had coordinates (the triangles before without).
                if !corners.is_empty() || poly_uv.iter().any(|&t| t != NO_UV) {
                    corners.resize(before, [NO_UV; 3]);
                    fan(&poly_uv, &mut corners);
                }
                if !names.is_empty() {
                    material.resize(triangles.len(), current);
                }
                if triangles.len() - reported >= REPORT_EVERY {
                    shared.add(triangles.len() - reported)?;
                    reported = triangles.len();
                }
            }
            b'u' => {
                let name = line.rest();
                if names.is_empty() {
                    // The triangles so far take the material in force at the chunk's start.
                    material = vec![INHERITED; triangles.len()];
                }
                current = match names.iter().position(|n| n == name) {
                    Some(i) => i as u16,
                    None if names.len() + 1 >= usize::from(INHERITED) => {
                        return Err(err("more than 65534 material names"));
                    }
                    None => {
                        names.push(name.to_vec());
                        (names.len() - 1) as u16
                    }
                };
            }
            b'm' => {
                for name in line.rest().split(|b| b.is_ascii_whitespace()) {
                    if !name.is_empty() && libs.len() < 64 {
                        libs.push(name.to_vec());
                    }
                }
            }
            _ => {} // comments, vt, vn, o, g, s, l, p, ...
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
        colors,
        names,
        material,
        last: current,
        libs,
        texcoords,
        corners,
        uv_forward,
    })
}
