//! Wavefront OBJ: every object and group, polygons fan-triangulated, points and lines ignored,
//! material libraries never opened. Kept besides: vertex colours (`v x y z r g b`, the common
//! extension: exactly six numbers) and each triangle's `usemtl` name.
//!
//! Read in parallel: the text is cut at line breaks into chunks, vertex lines are counted per chunk
//! so relative (negative) indices resolve, then chunks parse independently. `v` and `f` (with
//! `a`, `a/b`, `a//c`, `a/b/c` and negative indices) matter; every other statement is skipped.
//! A backslash at the end of a line joins it with the next. The tests hold this reader to `tobj`
//! on real files; it is 3–5× faster than `tobj` and its errors name the line.
//!
//! A file in memory is parsed as one block; a gzip'd one in blocks of about [`BLOCK`] bytes as
//! it is decoded (the next one while one is parsed), so its text is never held whole. Vertices
//! and triangles are counted as they are read and the file is refused once either is over the
//! limits.
//!
//! The reader is three files: this one cuts the text into blocks and chunks and adds up what the
//! chunks read (and checks forward references once the vertex count is known); `parser` reads
//! one chunk's `v` and `f` lines, resolving each index with `parser::resolve_index`; `lexer` scans a
//! line's tokens and reads its numbers. Not here: the shared mesh checks (`mesh/mod.rs`), the
//! streaming and gzip plumbing (`mesh/stream.rs`).

mod lexer;
mod mtl;
mod parser;
#[cfg(test)]
mod tests;
mod textures;

use rayon::prelude::*;
use std::sync::atomic::AtomicUsize;

use super::stream::{Stream, line_blocks};
use super::{
    Attributes, ExternalResources, LoadOptions, Mesh, MeshError, check_position, malformed,
};
use parser::{Chunk, Shared, parse_chunk};

/// Bytes per block of a compressed file (small, so little of the inflating and parsing is not
/// overlapped: the first block's inflating and the last one's parsing), and the longest line
/// one may have.
const BLOCK: usize = 4 << 20;
const MAX_LINE: usize = 16 << 20;

pub(super) fn parse(s: &mut Stream, opts: &LoadOptions) -> Result<Mesh, MeshError> {
    let mut st = State {
        positions: Vec::new(),
        triangles: Vec::new(),
        colors: Vec::new(),
        names: Vec::new(),
        material: Vec::new(),
        any_material: false,
        current: DEFAULT,
        libs: Vec::new(),
        uv: !matches!(opts.external, ExternalResources::Deny),
        texcoords: Vec::new(),
        corners: Vec::new(),
        uv_forward: None,
        lines: 0,
        forward: None,
        bad: None,
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
            if has_continued_lines(block) {
                st.block(&join_continued_lines(block), whole)
            } else {
                st.block(block, whole)
            }
        },
    )?;
    let total = st.positions.len();
    if let Some((line, n, abs)) = st.forward
        && abs >= total
    {
        return Err(malformed(
            "OBJ",
            format!(
                "line {line}: vertex index {n} is out of range (the file has {total} vertices)"
            ),
        ));
    }
    if st.triangles.is_empty() {
        return Err(MeshError::NoTriangles(
            " (no `f` lines with three or more vertices)".into(),
        ));
    }
    // What `Mesh::new` would check, already checked: the first bad position was noted as the
    // vertices were read, and every index was checked against the vertex count above.
    if let Some(i) = st.bad {
        check_position(i, &st.positions[i])?;
    }
    let mut attributes = Attributes::default();
    if !st.colors.is_empty() {
        attributes.colors = Some(st.colors);
        attributes.colors_srgb = true;
    }
    if let Some((line, n, abs)) = st.uv_forward
        && abs >= st.texcoords.len()
    {
        return Err(malformed(
            "OBJ",
            format!(
                "line {line}: texture coordinate index {n} is out of range (the file has {} texture coordinates)",
                st.texcoords.len()
            ),
        ));
    }
    if st.any_material {
        // The `usemtl` names in the order of their first use; OBJ's default material (faces
        // before any `usemtl`) after them when used. Base colours and textures from the
        // `mtllib` files beside the OBJ when it is read from a file or a zip (`mtl`); white
        // otherwise.
        let (table, maps, images) = textures::table(&st.names, &st.libs, opts, &st.texcoords)?;
        if !images.is_empty() {
            st.corners.resize(st.triangles.len(), [parser::NO_UV; 3]);
            attributes.uv = Some(super::Uv::Corners(textures::corner_uvs(
                &st.material,
                &st.corners,
                &st.texcoords,
                &maps,
            )));
            attributes.images = images;
        }
        attributes.set_materials(table, st.material);
    }
    Mesh::checked(st.positions, st.triangles).with_attributes(attributes)
}

/// OBJ's default material (faces before any `usemtl`) while the table is gathered.
const DEFAULT: u16 = super::attributes::NO_MATERIAL;

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

/// Whether a backslash ends a line of `b`. Backslashes are rare in OBJ text: the bytes are
/// looked at pairwise only when there is one (a memchr scan, where the pairwise look at the
/// 42 MB of a big mesh took 38 ms of a single core).
fn has_continued_lines(b: &[u8]) -> bool {
    memchr::memchr(b'\\', b).is_some()
        && (b.windows(2).any(|w| w == b"\\\n") || b.windows(3).any(|w| w == b"\\\r\n"))
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

fn is_texcoord_line(line: &[u8]) -> bool {
    let l = line.trim_ascii_start();
    l.len() > 3 && l.starts_with(b"vt") && (l[2] == b' ' || l[2] == b'\t')
}

/// What a chunk holds before it is parsed: its `v` lines (as [`is_vertex_line`] tells them),
/// its newlines and, when `uv`, its `vt` lines (else 0).
#[derive(Clone, Copy, Debug)]
struct Counts {
    vertices: usize,
    newlines: usize,
    texcoords: usize,
}

fn count_lines(c: &[u8], uv: bool) -> Counts {
    let mut n = Counts {
        vertices: 0,
        newlines: 0,
        texcoords: 0,
    };
    let mut start = 0;
    let mut line = |l: &[u8]| {
        n.vertices += is_vertex_line(l) as usize;
        if uv {
            n.texcoords += is_texcoord_line(l) as usize;
        }
    };
    for end in memchr::memchr_iter(b'\n', c) {
        line(&c[start..end]);
        n.newlines += 1;
        start = end + 1;
    }
    line(&c[start..]);
    n
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
    /// The first vertex that `Mesh::new` would refuse (non-finite or huge).
    bad: Option<usize>,
    /// Vertex colours, once a vertex had one (the others white); else empty.
    colors: Vec<[f32; 4]>,
    /// The `usemtl` names in the order of their first use.
    names: Vec<Vec<u8>>,
    /// Each triangle's material (into `names`, or [`DEFAULT`]), once a `usemtl` was read.
    material: Vec<u16>,
    any_material: bool,
    /// The material in force at the end of the blocks read so far.
    current: u16,
    /// The `mtllib` file names.
    libs: Vec<Vec<u8>>,
    /// Are texture coordinates kept ([`parser::Shared::uv`])? Then the `vt` lines read so far,
    /// each triangle's corners' indices into them, and the largest index used before its line
    /// (as `forward`).
    uv: bool,
    texcoords: Vec<[f32; 2]>,
    corners: Vec<[u32; 3]>,
    uv_forward: Option<(usize, i64, usize)>,
    max_vertices: usize,
    max_triangles: usize,
}

impl State {
    /// Parses one block of whole lines (chunks of it in parallel). `whole`: the block is the
    /// whole file.
    fn block(&mut self, bytes: &[u8], whole: bool) -> Result<(), MeshError> {
        let parts = chunks(bytes);
        let uv = self.uv;
        let counts: Vec<Counts> = parts.par_iter().map(|c| count_lines(c, uv)).collect();
        let mut bases = Vec::with_capacity(parts.len());
        let (mut v, mut l, mut t) = (self.positions.len(), self.lines, self.texcoords.len());
        for n in &counts {
            bases.push((v, t, l));
            v += n.vertices;
            l += n.newlines;
            t += n.texcoords;
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
            uv,
        };
        let parsed: Vec<Chunk> = parts
            .par_iter()
            .zip(bases.par_iter())
            .zip(counts.par_iter())
            .map(|((c, &(vbase, tbase, lbase)), n)| {
                parse_chunk(
                    c,
                    vbase,
                    tbase,
                    lbase,
                    n.vertices,
                    whole.then_some(known),
                    &limits,
                )
            })
            .collect::<Result<_, _>>()?;
        self.positions.reserve_exact(known - self.positions.len());
        self.triangles
            .reserve(parsed.iter().map(|c| c.triangles.len()).sum());
        for c in parsed {
            if !c.colors.is_empty() {
                if self.colors.is_empty() {
                    self.colors = vec![[1.0; 4]; self.positions.len()];
                }
                self.colors.extend_from_slice(&c.colors);
            } else if !self.colors.is_empty() {
                self.colors
                    .extend(std::iter::repeat_n([1.0; 4], c.positions.len()));
            }
            if !c.names.is_empty() {
                if !self.any_material {
                    self.material = vec![DEFAULT; self.triangles.len()];
                    self.any_material = true;
                }
                let mut ids = Vec::with_capacity(c.names.len());
                for n in &c.names {
                    let id = match self.names.iter().position(|m| m == n) {
                        Some(i) => i,
                        None if self.names.len() + 1 >= usize::from(DEFAULT) => {
                            return Err(malformed("OBJ", "more than 65534 material names"));
                        }
                        None => {
                            self.names.push(n.clone());
                            self.names.len() - 1
                        }
                    };
                    ids.push(id as u16);
                }
                let at_start = self.current;
                let global = |m: u16| {
                    if m == parser::INHERITED {
                        at_start
                    } else {
                        ids[usize::from(m)]
                    }
                };
                self.material.extend(c.material.iter().map(|&m| global(m)));
                self.current = global(c.last);
            } else if self.any_material {
                self.material
                    .extend(std::iter::repeat_n(self.current, c.triangles.len()));
            }
            for l in c.libs {
                if self.libs.len() < 64 && !self.libs.contains(&l) {
                    self.libs.push(l);
                }
            }
            self.positions.extend_from_slice(&c.positions);
            self.triangles.extend_from_slice(&c.triangles);
            self.texcoords.extend_from_slice(&c.texcoords);
            // Each triangle's corners once some had coordinates (those before without).
            if !c.corners.is_empty() || !self.corners.is_empty() {
                let before = self.triangles.len() - c.triangles.len();
                self.corners.resize(before, [parser::NO_UV; 3]);
                self.corners.extend_from_slice(&c.corners);
                self.corners
                    .resize(self.triangles.len(), [parser::NO_UV; 3]);
            }
            if let Some(f) = c.uv_forward
                && self.uv_forward.is_none_or(|g| f.2 > g.2)
            {
                self.uv_forward = Some(f);
            }
            self.bad = self.bad.or(c.bad);
            if let Some(f) = c.forward
                && self.forward.is_none_or(|g| f.2 > g.2)
            {
                self.forward = Some(f);
            }
        }
        self.lines = l;
        Ok(())
    }
}
