//! Wavefront OBJ: every object and group, polygons fan-triangulated, points and lines ignored,
//! material libraries never opened.
//!
//! Read in parallel: the text is cut at line breaks into chunks, vertex lines are counted per chunk
//! so relative (negative) indices resolve, then chunks parse independently. `v` and `f` (with
//! `a`, `a/b`, `a//c`, `a/b/c` and negative indices) matter; every other statement is skipped.
//! A backslash at the end of a line joins it with the next. The tests hold this reader to `tobj`
//! on real files; it is 3–5× faster than `tobj` and its errors name the line.
//!
//! A file in memory is parsed as one block; a gzip'd one in blocks of about [`BLOCK`] bytes as
//! it is decoded, so its text is never held whole. Vertices and triangles are counted as they
//! are read and the file is refused once either is over the limits.

use std::sync::atomic::{AtomicUsize, Ordering};

use rayon::prelude::*;

use super::stream::{Stream, line_blocks};
use super::{LoadOptions, Mesh, MeshError, fan, malformed};

/// Bytes per block of a compressed file, and the longest line one may have.
const BLOCK: usize = 16 << 20;
const MAX_LINE: usize = 16 << 20;

pub(super) fn parse(s: &mut Stream, opts: &LoadOptions) -> Result<Mesh, MeshError> {
    let mut st = State {
        positions: Vec::new(),
        triangles: Vec::new(),
        lines: 0,
        forward: None,
        max_vertices: opts.max_vertices(),
        max_triangles: opts.max_triangles,
    };
    let mut first = true;
    line_blocks(
        s,
        "OBJ",
        BLOCK,
        MAX_LINE,
        end_of_joined_lines,
        |block, last| {
            // The whole file in one block: every index can be checked as it is read.
            let whole = first && last;
            first = false;
            if block.windows(2).any(|w| w == b"\\\n") || block.windows(3).any(|w| w == b"\\\r\n") {
                st.block(&join_continued_lines(block), whole)
            } else {
                st.block(block, whole)
            }
        },
    )?;
    let total = st.positions.len();
    if let Some((line, n, abs)) = st.forward {
        if abs >= total {
            return Err(malformed(
                "OBJ",
                format!(
                    "line {line}: vertex index {n} is out of range (the file has {total} vertices)"
                ),
            ));
        }
    }
    if st.triangles.is_empty() {
        return Err(MeshError::NoTriangles(
            " (no `f` lines with three or more vertices)".into(),
        ));
    }
    Mesh::new(st.positions, st.triangles)
}

/// The end of the last line of `b` that a backslash does not continue onto the next.
fn end_of_joined_lines(b: &[u8]) -> Option<usize> {
    let mut end = b.len();
    while let Some(i) = b[..end].iter().rposition(|&c| c == b'\n') {
        let before = &b[..i];
        let continued = before.ends_with(b"\\") || before.ends_with(b"\\\r");
        if !continued {
            return Some(i + 1);
        }
        end = i;
    }
    None
}

/// Replaces every backslash-newline with a space.
fn join_continued_lines(bytes: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        match &bytes[i..] {
            [b'\\', b'\n', ..] => (out.push(b' '), i += 2),
            [b'\\', b'\r', b'\n', ..] => (out.push(b' '), i += 3),
            [b, ..] => (out.push(*b), i += 1),
            [] => unreachable!(),
        };
    }
    out
}

/// Chunk boundaries at line starts.
fn chunks(bytes: &[u8]) -> Vec<&[u8]> {
    let want = (rayon::current_num_threads() * 4).max(1);
    let size = (bytes.len() / want).max(1 << 20);
    let mut out = Vec::new();
    let mut start = 0;
    while start < bytes.len() {
        let mut end = (start + size).min(bytes.len());
        while end < bytes.len() && bytes[end - 1] != b'\n' {
            end += 1;
        }
        out.push(&bytes[start..end]);
        start = end;
    }
    out
}

fn is_vertex_line(line: &[u8]) -> bool {
    let l = line.trim_ascii_start();
    l.len() > 2 && l[0] == b'v' && (l[1] == b' ' || l[1] == b'\t')
}

struct Chunk {
    positions: Vec<[f64; 3]>,
    triangles: Vec<[u32; 3]>,
    /// The largest index used before its vertex was defined, with its line and as written.
    forward: Option<(usize, i64, usize)>,
}

/// What the blocks read so far add up to.
struct State {
    positions: Vec<[f64; 3]>,
    triangles: Vec<[u32; 3]>,
    /// Lines before the next block.
    lines: usize,
    /// The largest (0-based) index a face used before its vertex was read, its line (1-based)
    /// and how it was written: checked once the file's vertex count is known.
    forward: Option<(usize, i64, usize)>,
    max_vertices: usize,
    max_triangles: usize,
}

impl State {
    /// Parses one block of whole lines (chunks of it in parallel). `whole`: the block is the
    /// whole file.
    fn block(&mut self, bytes: &[u8], whole: bool) -> Result<(), MeshError> {
        let parts = chunks(bytes);
        let counts: Vec<(usize, usize)> = parts
            .par_iter()
            .map(|c| {
                (
                    c.split(|&b| b == b'\n')
                        .filter(|l| is_vertex_line(l))
                        .count(),
                    c.iter().filter(|&&b| b == b'\n').count(),
                )
            })
            .collect();
        let mut bases = Vec::with_capacity(parts.len());
        let (mut v, mut l) = (self.positions.len(), self.lines);
        for &(nv, nl) in &counts {
            bases.push((v, l));
            v += nv;
            l += nl;
        }
        if v > self.max_vertices {
            return Err(MeshError::CountOverLimit {
                format: "OBJ",
                what: "vertices or more (`v` lines read so far)",
                count: v as u64,
                limit: self.max_vertices as u64,
            });
        }
        if v > u32::MAX as usize {
            return Err(malformed("OBJ", "more than 4 billion vertices"));
        }
        // Vertices defined by the end of this block: all of them when it is the whole file.
        let known = v;
        let limits = Shared {
            triangles: AtomicUsize::new(self.triangles.len()),
            max_triangles: self.max_triangles,
        };
        let parsed: Vec<Chunk> = parts
            .par_iter()
            .zip(bases.par_iter())
            .zip(counts.par_iter())
            .map(|((c, &(vbase, lbase)), &(nv, _))| {
                parse_chunk(c, vbase, lbase, nv, whole.then_some(known), &limits)
            })
            .collect::<Result<_, _>>()?;
        self.positions.reserve_exact(known - self.positions.len());
        self.triangles
            .reserve(parsed.iter().map(|c| c.triangles.len()).sum());
        for c in parsed {
            self.positions.extend_from_slice(&c.positions);
            self.triangles.extend_from_slice(&c.triangles);
            if let Some(f) = c.forward {
                if self.forward.is_none_or(|g| f.2 > g.2) {
                    self.forward = Some(f);
                }
            }
        }
        self.lines = l;
        Ok(())
    }
}

/// Triangles made so far by every chunk of a block, against the limit.
struct Shared {
    triangles: AtomicUsize,
    max_triangles: usize,
}

impl Shared {
    /// Adds `n` triangles a chunk made; an error once the total is over the limit.
    fn add(&self, n: usize) -> Result<(), MeshError> {
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
const REPORT_EVERY: usize = 1 << 12;

/// Parses one chunk whose first vertex is number `vbase` and first line `lbase` (0-based) of a
/// file with `total` vertices (when known: else indices past the vertices read so far are
/// kept in `forward`, checked at the end).
fn parse_chunk(
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
    for (i, raw) in text.split(|&b| b == b'\n').enumerate() {
        let line = raw.trim_ascii();
        let err = |what: &str| malformed("OBJ", format!("line {}: {what}", lbase + i + 1));
        let mut tok = line
            .split(|b| b.is_ascii_whitespace())
            .filter(|t| !t.is_empty());
        match tok.next() {
            Some(b"v") => {
                let mut p = [0.0; 3];
                for c in &mut p {
                    let t = tok.next().ok_or_else(|| err("a vertex needs x, y and z"))?;
                    *c = std::str::from_utf8(t)
                        .ok()
                        .and_then(|s| s.parse().ok())
                        .ok_or_else(|| {
                            err(&format!("{:?} is not a number", String::from_utf8_lossy(t)))
                        })?;
                }
                positions.push(p);
            }
            Some(b"f") => {
                let defined = (vbase + positions.len()) as i64;
                poly.clear();
                for t in tok {
                    let idx = t.split(|&b| b == b'/').next().unwrap_or(t);
                    let n: i64 = std::str::from_utf8(idx)
                        .ok()
                        .and_then(|s| s.parse().ok())
                        .ok_or_else(|| {
                            err(&format!(
                                "{:?} is not a vertex index",
                                String::from_utf8_lossy(t)
                            ))
                        })?;
                    // 1-based from the start, or negative: relative to the vertices defined so far.
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
                        return Err(err(&format!("vertex index {n} is out of range ({has})")));
                    }
                    if abs >= defined && forward.is_none_or(|f| abs as usize > f.2) {
                        forward = Some((lbase + i + 1, n, abs as usize));
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
    }
    shared.add(triangles.len() - reported)?;
    Ok(Chunk {
        positions,
        triangles,
        forward,
    })
}
