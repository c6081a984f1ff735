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
//! it is decoded (the next one while one is parsed), so its text is never held whole. Vertices and triangles are counted as they
//! are read and the file is refused once either is over the limits.

use std::sync::atomic::{AtomicUsize, Ordering};

use rayon::prelude::*;

use super::stream::{Stream, line_blocks};
use super::{LoadOptions, Mesh, MeshError, bad_position, check_position, fan, malformed};

/// Bytes per block of a compressed file (small, so little of the inflating and parsing is not
/// overlapped: the first block's inflating and the last one's parsing), and the longest line
/// one may have.
const BLOCK: usize = 4 << 20;
const MAX_LINE: usize = 16 << 20;

pub(super) fn parse(s: &mut Stream, opts: &LoadOptions) -> Result<Mesh, MeshError> {
    let mut st = State {
        positions: Vec::new(),
        triangles: Vec::new(),
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
    Ok(Mesh::checked(st.positions, st.triangles))
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

/// The `v` lines (as [`is_vertex_line`] tells them) and the newlines of a chunk.
fn count_lines(c: &[u8]) -> (usize, usize) {
    let (mut vertices, mut newlines, mut start) = (0, 0, 0);
    for end in memchr::memchr_iter(b'\n', c) {
        vertices += is_vertex_line(&c[start..end]) as usize;
        newlines += 1;
        start = end + 1;
    }
    vertices += is_vertex_line(&c[start..]) as usize;
    (vertices, newlines)
}

struct Chunk {
    positions: Vec<[f64; 3]>,
    triangles: Vec<[u32; 3]>,
    /// The largest index used before its vertex was defined, with its line and as written.
    forward: Option<(usize, i64, usize)>,
    /// The first vertex (its index in the file) that `Mesh::new` would refuse.
    bad: Option<usize>,
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
    max_vertices: usize,
    max_triangles: usize,
}

impl State {
    /// Parses one block of whole lines (chunks of it in parallel). `whole`: the block is the
    /// whole file.
    fn block(&mut self, bytes: &[u8], whole: bool) -> Result<(), MeshError> {
        let parts = chunks(bytes);
        let counts: Vec<(usize, usize)> = parts.par_iter().map(|c| count_lines(c)).collect();
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
///
/// One pass over the bytes, a line at a time (the line ends found by `memchr`): a line's
/// tokens are the runs of bytes that are not ASCII whitespace; a `v` or `f` line's numbers are
/// read as they are scanned, plain decimals and short indices on the spot and anything else as
/// a whole token by the standard parser ([`Line::float`], [`Line::index`]: what `str::parse`
/// gives, bit for bit); the rest of a line is skipped once what matters of it is read.
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

/// The tokens of one line, read from the left. The line is `text[..end]` from where reading
/// started; `text` goes on past it (to the end of the chunk), so eight bytes at a time can be
/// looked at near the line's end: the `\n` at `end` is neither a digit nor part of a token, so
/// no run found that way goes past the line.
struct Line<'a> {
    text: &'a [u8],
    end: usize,
    /// Where the next token is looked for.
    at: usize,
}

const ONES: u64 = 0x0101_0101_0101_0101;
const HIGHS: u64 = ONES * 0x80;

/// The eight bytes of `t` from `i` as a little-endian word (the first byte lowest), if there
/// are eight.
#[inline]
fn word(t: &[u8], i: usize) -> Option<u64> {
    let w: [u8; 8] = t.get(i..i + 8)?.try_into().ok()?;
    Some(u64::from_le_bytes(w))
}

/// How many of the bytes of `w` (from its lowest) are ASCII digits before the first that is
/// not, and `w` with every byte XORed with `b'0'` (a digit byte then holds its value).
#[inline]
fn leading_digits(w: u64) -> (usize, u64) {
    let t = w ^ (ONES * b'0' as u64); // b'0'..=b'9' become 0..=9, every other byte 10 or more
    // The high bit of a byte is set when its low seven bits are 10 or more (adding 0x76 to at
    // most 0x7f carries into no other byte), or when it was set already.
    let not_digit = (((t & !HIGHS) + ONES * 0x76) | t) & HIGHS;
    ((not_digit.trailing_zeros() / 8) as usize, t)
}

/// The number written by the first `n` (1 to 8) digit values of `t` (as [`leading_digits`]
/// gives them): the other bytes are shifted out and zeros (leading zeros of the number)
/// shifted in, then the eight digits are combined in three multiplications (as the standard
/// library's float parser does).
#[inline]
fn digits_value(t: u64, n: usize) -> u64 {
    debug_assert!((1..=8).contains(&n));
    let v = t << (8 * (8 - n));
    let v = v * 10 + (v >> 8); // pairs of digits, in every other byte
    let v1 = (v & 0x0000_00ff_0000_00ff).wrapping_mul(100 + (1_000_000 << 32));
    let v2 = ((v >> 16) & 0x0000_00ff_0000_00ff).wrapping_mul(1 + (10_000 << 32));
    (v1.wrapping_add(v2) >> 32) as u32 as u64
}

/// 10^0 to 10^19, the powers of ten that u64 holds.
const POW10_U64: [u64; 20] = {
    let mut p = [1u64; 20];
    let mut i = 1;
    while i < 20 {
        p[i] = p[i - 1] * 10;
        i += 1;
    }
    p
};

impl<'a> Line<'a> {
    /// Moves past the whitespace at `at`.
    #[inline]
    fn skip_space(&mut self) {
        while self.at < self.end && self.text[self.at].is_ascii_whitespace() {
            self.at += 1;
        }
    }

    /// The end of the token that `i` is in (or starts): the first whitespace from `i` on, or
    /// the end of the line.
    #[inline]
    fn token_end(&self, mut i: usize) -> usize {
        let t = self.text;
        while i < self.end {
            let Some(w) = word(t, i) else {
                while i < self.end && !t[i].is_ascii_whitespace() {
                    i += 1;
                }
                return i;
            };
            // The first byte below 0x21 (every whitespace is): the lowest flag of this
            // classic test is exact (a borrow only reaches the bytes above the one it came from).
            let low = w.wrapping_sub(ONES * 0x21) & !w & HIGHS;
            if low == 0 {
                i += 8;
                continue;
            }
            i += (low.trailing_zeros() / 8) as usize;
            if i >= self.end || t[i].is_ascii_whitespace() {
                return i.min(self.end);
            }
            i += 1; // a control byte that is not whitespace: part of the token
        }
        self.end
    }

    /// Whether a token that was being read ends at `i` (whitespace or the end of the line).
    #[inline]
    fn ends_token(&self, i: usize) -> bool {
        i >= self.end || self.text[i].is_ascii_whitespace()
    }

    /// The ASCII digits from `i`: how many, and the number they write (modulo 2^64 when
    /// there are more than 19).
    #[inline]
    fn digits(&self, mut i: usize) -> (usize, u64) {
        let (start, t) = (i, self.text);
        let mut m: u64 = 0;
        while let Some(w) = word(t, i) {
            let (n, d) = leading_digits(w);
            if n > 0 {
                m = m
                    .wrapping_mul(POW10_U64[n])
                    .wrapping_add(digits_value(d, n));
                i += n;
            }
            if n < 8 {
                return (i - start, m);
            }
        }
        while i < self.end && t[i].is_ascii_digit() {
            m = m.wrapping_mul(10).wrapping_add((t[i] - b'0') as u64);
            i += 1;
        }
        (i - start, m)
    }

    /// Reads the first token: `b'v'` or `b'f'` when it is that one letter, else 0.
    #[inline]
    fn keyword(&mut self) -> u8 {
        self.skip_space();
        if self.at < self.end {
            let k = self.text[self.at];
            if (k == b'v' || k == b'f') && self.ends_token(self.at + 1) {
                self.at += 1;
                return k;
            }
        }
        0
    }

    /// The next token's start, whether it has a minus sign, and the run of digits after its
    /// sign (as [`Self::digits`] reads it), or `None` at the end of the line. Always inlined:
    /// left to the compiler it was not, and the parse of spot took 12 % longer.
    #[inline(always)]
    fn signed_digits(&mut self) -> Option<Signed> {
        self.skip_space();
        let (t, start) = (self.text, self.at);
        if start >= self.end {
            return None;
        }
        let neg = t[start] == b'-';
        let first = start + (neg || t[start] == b'+') as usize;
        let (count, value) = self.digits(first);
        Some(Signed {
            start,
            neg,
            end: first + count,
            count,
            value,
        })
    }

    /// The token from `start` (through `i`, where its fast reading stopped), moving past it:
    /// for the standard parsers.
    #[inline]
    fn whole_token(&mut self, start: usize, i: usize) -> &'a [u8] {
        self.at = self.token_end(i);
        &self.text[start..self.at]
    }

    /// The next token as a number (`Err`: the token, which is not one), or `None` at the end
    /// of the line, bit for bit what `str::parse::<f64>` makes of the token.
    ///
    /// A plain decimal (`[+-]digits[.digits]`, 19 digits at most, whose digits as an integer
    /// are at most 2^53 and with at most 22 after the point), what OBJ files are made of, is
    /// read as it is scanned: the digits and the power of ten are both exact in f64, so their
    /// quotient is the correctly rounded value, which is what the standard parser computes for
    /// them too (its own fast path). Any other token (exponents, more digits, `inf`, `nan`,
    /// garbage) goes to the standard parser.
    #[inline]
    fn float(&mut self) -> Option<Result<f64, &'a [u8]>> {
        let Signed {
            start,
            neg,
            end: mut i,
            count: whole,
            value: mut m,
        } = self.signed_digits()?;
        let mut frac = 0;
        if i < self.end && self.text[i] == b'.' {
            let (n, f) = self.digits(i + 1);
            // Only used when there are 19 digits or fewer in all (so 10^n does not matter
            // otherwise).
            m = m.wrapping_mul(POW10_U64[n.min(19)]).wrapping_add(f);
            (frac, i) = (n, i + 1 + n);
        }
        let digits = whole + frac;
        // A plain decimal, as above (19 digits cannot overflow u64).
        if self.ends_token(i) && digits > 0 && digits <= 19 && m <= 1 << 53 && frac <= 22 {
            self.at = i;
            // `-v` is `v` with the sign bit set (v is not negative): set without a branch, as
            // the signs of coordinates are as good as random.
            let v = m as f64 / POW10[frac];
            return Some(Ok(f64::from_bits(v.to_bits() | (neg as u64) << 63)));
        }
        let tok = self.whole_token(start, i);
        Some(std_parse(tok).ok_or(tok))
    }

    /// The vertex index of the next token (what comes before its first `/`; `Err`: the token,
    /// whose index is not a number, as `str::parse::<i64>` reads it), or `None` at the end of
    /// the line. Up to 18 digits with an optional sign are read as they are scanned, anything
    /// else by the standard parser.
    #[inline]
    fn index(&mut self) -> Option<Result<i64, &'a [u8]>> {
        let Signed {
            start,
            neg,
            end: i,
            count,
            value,
        } = self.signed_digits()?;
        if count > 0 && count <= 18 && (self.ends_token(i) || self.text[i] == b'/') {
            self.at = self.token_end(i);
            let n = value as i64;
            return Some(Ok(if neg { -n } else { n }));
        }
        let tok = self.whole_token(start, i);
        let idx = tok.split(|&c| c == b'/').next().unwrap_or(tok);
        Some(std_parse(idx).ok_or(tok))
    }
}

/// What [`Line::signed_digits`] read of a token.
struct Signed {
    start: usize,
    neg: bool,
    /// Where the digits after the sign end.
    end: usize,
    /// How many digits, and the number they write (modulo 2^64 past 19 of them).
    count: usize,
    value: u64,
}

/// 10^0 to 10^22, the powers of ten that f64 holds exactly.
const POW10: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
    1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
];

/// `t` read by the standard parser (`str::parse`), `None` where it refuses it: the tokens
/// that [`Line::float`] and [`Line::index`] do not read themselves.
fn std_parse<T: std::str::FromStr>(t: &[u8]) -> Option<T> {
    std::str::from_utf8(t).ok()?.parse().ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The chunk reader before its hand-written scanner and number parsers (tokens by
    /// `split`, numbers by `str::parse`): what the new one must give, error for error.
    fn parse_chunk_std(
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
        let bad = positions.iter().position(bad_position).map(|i| vbase + i);
        Ok(Chunk {
            positions,
            triangles,
            forward,
            bad,
        })
    }

    /// A small deterministic generator (xorshift64*), so failures reproduce.
    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> u64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
        }
        fn below(&mut self, n: usize) -> usize {
            (self.next() % n as u64) as usize
        }
        fn pick<'a>(&mut self, of: &[&'a str]) -> &'a str {
            of[self.below(of.len())]
        }
    }

    fn std_f64(t: &[u8]) -> Option<f64> {
        std::str::from_utf8(t).ok()?.parse().ok()
    }

    /// A line holding the token `t`.
    fn line(t: &[u8]) -> Line<'_> {
        Line {
            text: t,
            end: t.len(),
            at: 0,
        }
    }

    /// What [`Line::float`] makes of the token `t`.
    fn read_float(t: &[u8]) -> Option<f64> {
        line(t).float()?.ok()
    }

    /// What [`Line::index`] makes of the token `t`.
    fn read_index(t: &[u8]) -> Option<i64> {
        line(t).index()?.ok()
    }

    /// The plain decimals that [`Line::float`] reads itself, written plainly over a whole token
    /// (`None` for any other token): the test counts the tokens it takes, so that it is known
    /// to exercise that path, and checks its value too.
    fn plain_decimal(t: &[u8]) -> Option<f64> {
        let (neg, d) = match t.first()? {
            b'-' => (true, &t[1..]),
            b'+' => (false, &t[1..]),
            _ => (false, t),
        };
        let mut m: u64 = 0;
        let mut i = 0;
        while i < d.len() && d[i].is_ascii_digit() {
            m = m.wrapping_mul(10).wrapping_add((d[i] - b'0') as u64);
            i += 1;
        }
        let whole = i;
        let mut frac = 0;
        if i < d.len() && d[i] == b'.' {
            i += 1;
            let start = i;
            while i < d.len() && d[i].is_ascii_digit() {
                m = m.wrapping_mul(10).wrapping_add((d[i] - b'0') as u64);
                i += 1;
            }
            frac = i - start;
        }
        // 19 digits cannot overflow u64 (so the wrapping above never wraps when this holds).
        let digits = whole + frac;
        if i != d.len() || digits == 0 || digits > 19 || m > 1 << 53 || frac > 22 {
            return None;
        }
        let v = m as f64 / POW10[frac];
        Some(if neg { -v } else { v })
    }

    fn digits(r: &mut Rng, n: usize) -> String {
        (0..n).map(|_| (b'0' + r.below(10) as u8) as char).collect()
    }

    /// A token like those of OBJ files and their corners: signs, points, exponents, long
    /// digit runs, special values and garbage.
    fn number_token(r: &mut Rng) -> String {
        match r.below(8) {
            0 => r
                .pick(&[
                    "inf",
                    "-inf",
                    "+inf",
                    "Infinity",
                    "-infinity",
                    "NaN",
                    "nan",
                    "-nan",
                    "+",
                    "-",
                    ".",
                    "-.",
                    "+.",
                    "",
                    "e5",
                    ".e1",
                    "1e",
                    "1e+",
                    "0x10",
                    "1_0",
                    "1,5",
                    "--1",
                    "+-1",
                    "1.2.3",
                    "١",
                    "1\u{a0}",
                    "1\x0b",
                    "1.5\x00",
                ])
                .to_string(),
            1 => {
                let v = f64::from_bits(r.next());
                match r.below(4) {
                    0 => format!("{v}"),
                    1 => format!("{v:e}"),
                    2 => format!("{v:.7}"),
                    _ => format!("{:?}", v as f32),
                }
            }
            2 => {
                // Subnormals and values near the ends of the range.
                let v = f64::from_bits(r.next() % (1 << 53));
                let w = f64::MAX / (1 + r.below(1000)) as f64;
                format!("{}", if r.below(2) == 0 { v } else { w })
            }
            _ => {
                let sign = r.pick(&["", "", "-", "+"]);
                let most = if r.below(4) == 0 { 25 } else { 4 };
                let n = r.below(most);
                let whole = digits(r, n);
                let point = r.pick(&["", ".", ".", "."]);
                let most = if r.below(4) == 0 { 30 } else { 9 };
                let n = r.below(most);
                let frac = digits(r, n);
                let exp = match r.below(6) {
                    0 => format!("e{}", r.below(40) as i64 - 20),
                    1 => format!("E+{}", r.below(400)),
                    _ => String::new(),
                };
                format!("{sign}{whole}{point}{frac}{exp}")
            }
        }
    }

    #[test]
    fn floats_read_as_std_reads_them() {
        let fixed = [
            "0",
            "-0",
            "+0",
            "-0.0",
            "0.",
            "-.0",
            ".5",
            "5.",
            "+.5",
            "-5.",
            "0.0081780",
            "-0.0496510",
            "1.7976931348623157e308",
            "4.9e-324",
            "9007199254740992",
            "9007199254740993",
            "9007199254740993.0",
            "0.9007199254740993",
            "1234567890123456789",
            "12345678901234567890",
            "0.1",
            "0.2",
            "0.3",
            "3.14159265358979",
            "0.0000000000000000000001",
            "0.00000000000000000000001",
            "1e22",
            "1e23",
        ];
        for t in fixed {
            let (a, b) = (read_float(t.as_bytes()), std_f64(t.as_bytes()));
            assert_eq!(a.map(f64::to_bits), b.map(f64::to_bits), "{t:?}");
        }
        let mut r = Rng(0x9e37_79b9_7f4a_7c15);
        let mut fast = 0;
        for _ in 0..300_000 {
            let t = number_token(&mut r);
            let (a, b) = (read_float(t.as_bytes()), std_f64(t.as_bytes()));
            // NaN == NaN by bits: the standard parser's NaN is one value.
            assert_eq!(a.map(f64::to_bits), b.map(f64::to_bits), "{t:?}");
            if let Some(p) = plain_decimal(t.as_bytes()) {
                assert_eq!(Some(p.to_bits()), b.map(f64::to_bits), "{t:?}");
                fast += 1;
            }
        }
        // The fast path is taken for most of them (so it is what is being tested).
        assert!(fast > 100_000, "{fast}");
        // Not UTF-8: refused like the standard parser refuses it.
        assert_eq!(read_float(b"1\xff"), None);
        assert_eq!(read_float(b"\xff"), None);
    }

    #[test]
    fn indices_read_as_std_reads_them() {
        let std_i64 = |t: &[u8]| -> Option<i64> { std::str::from_utf8(t).ok()?.parse().ok() };
        let mut r = Rng(7);
        let fixed = [
            "",
            "+",
            "-",
            "0",
            "-0",
            "+0",
            "1",
            "+1",
            "-1",
            "007",
            "1a",
            "--1",
            "+-1",
            "999999999999999999",
            "9223372036854775807",
            "9223372036854775808",
            "-9223372036854775808",
            "-9223372036854775809",
            "1.0",
            " 1",
            "\u{ff}",
        ];
        let mut tokens: Vec<String> = fixed.iter().map(|t| t.to_string()).collect();
        for _ in 0..100_000 {
            let sign = r.pick(&["", "", "-", "+", "--"]);
            let most = if r.below(8) == 0 { 22 } else { 8 };
            let n = r.below(most);
            let tail = r.pick(&["", "", "", "", "x", "."]);
            tokens.push(format!("{sign}{}{tail}", digits(&mut r, n)));
        }
        for t in tokens {
            // A line's token has no whitespace around it (" 1" is the token "1").
            let token = t.as_bytes().trim_ascii();
            assert_eq!(read_index(t.as_bytes()), std_i64(token), "{t:?}");
        }
    }

    /// Random OBJ text: vertices written many ways, faces with every index form (some out of
    /// range, zero, negative, malformed), other statements, blank lines, odd whitespace.
    fn obj_text(r: &mut Rng) -> Vec<u8> {
        let mut s = String::new();
        let mut vertices = 0i64;
        for _ in 0..r.below(60) {
            let ws = |r: &mut Rng| r.pick(&[" ", " ", " ", "  ", "\t", " \t ", "\x0c", "\r"]);
            let lead = r.pick(&["", "", "", "", " ", "\t", "\r"]);
            s += lead;
            match r.below(10) {
                0..=3 => {
                    s += "v";
                    for _ in 0..[3, 3, 3, 3, 3, 4, 6, 2, 0][r.below(9)] {
                        s += ws(r);
                        s += &if r.below(30) == 0 {
                            number_token(r)
                        } else {
                            let v = (r.next() % 2_000_001) as f64 / 1e6 - 1.0;
                            format!("{v}")
                        };
                    }
                    vertices += 1;
                }
                4..=6 => {
                    s += r.pick(&["f", "f", "f", "f", "fo", "F"]);
                    for _ in 0..r.below(6) {
                        s += ws(r);
                        let n = match r.below(12) {
                            0 => 0,
                            1 => -(r.below(vertices as usize + 2) as i64),
                            2 => vertices + 1 + r.below(3) as i64,
                            _ => 1 + r.below(vertices.max(1) as usize) as i64,
                        };
                        s += &match r.below(12) {
                            0 => format!("{n}/{n}"),
                            1 => format!("{n}//{n}"),
                            2 => format!("{n}/1/2"),
                            3 => format!("+{n}"),
                            4 if r.below(4) == 0 => r
                                .pick(&[
                                    "x", "/1", "1x", "-", "", "+/", "-/2", "1x/2", "1/x",
                                    "1/\x0b2", "1\x0b", "\x00", "1/2\x01x",
                                ])
                                .into(),
                            // Long digit runs, around where the fast path hands over.
                            5 if r.below(4) == 0 => {
                                let sign = r.pick(&["", "-", "+"]);
                                let n = 16 + r.below(6);
                                let tail = r.pick(&["", "/1", "//2", "x"]);
                                format!("{sign}{}{tail}", digits(r, n))
                            }
                            _ => format!("{n}"),
                        };
                    }
                }
                7 => {
                    s += r.pick(&[
                        "# v 1 2 3",
                        "vt 0.5 0.5",
                        "vn 0 0 1",
                        "o a",
                        "g b",
                        "s 1",
                        "l 1 2",
                        "v",
                        "f",
                        "g a\\",
                        "# \\ x",
                    ])
                }
                _ => {}
            }
            if r.below(3) == 0 {
                s += ws(r);
            }
            s += r.pick(&["\n", "\n", "\n", "\r\n", "\n\n"]);
        }
        if r.below(2) == 0 {
            s.pop();
        }
        s.into_bytes()
    }

    type Parsed = Result<
        (
            Vec<[u64; 3]>,
            Vec<[u32; 3]>,
            Option<(usize, i64, usize)>,
            Option<usize>,
        ),
        MeshError,
    >;

    /// A chunk reader: [`parse_chunk`] or [`parse_chunk_std`].
    type Reader =
        fn(&[u8], usize, usize, usize, Option<usize>, &Shared) -> Result<Chunk, MeshError>;

    fn run(
        f: Reader,
        text: &[u8],
        vbase: usize,
        total: Option<usize>,
        max_triangles: usize,
    ) -> Parsed {
        let shared = Shared {
            triangles: AtomicUsize::new(0),
            max_triangles,
        };
        f(text, vbase, 3, 0, total, &shared).map(|c| {
            (
                c.positions.iter().map(|p| p.map(f64::to_bits)).collect(),
                c.triangles,
                c.forward,
                c.bad,
            )
        })
    }

    #[test]
    fn chunks_read_as_before() {
        let mut r = Rng(0x5eed);
        let (mut ok, mut errors) = (0, 0);
        for case in 0..20_000 {
            let text = obj_text(&mut r);
            let vbase = [0, 0, 5, 1 << 20][r.below(4)];
            let total = [None, None, Some(vbase + 10), Some(vbase + 100)][r.below(4)];
            let max = [usize::MAX, usize::MAX, 3][r.below(3)];
            let new = run(parse_chunk, &text, vbase, total, max);
            let old = run(parse_chunk_std, &text, vbase, total, max);
            assert_eq!(
                new,
                old,
                "case {case}: {:?}",
                String::from_utf8_lossy(&text)
            );
            if new.is_ok() { ok += 1 } else { errors += 1 }
        }
        // Both outcomes are well represented.
        assert!(ok > 1000 && errors > 1000, "{ok} {errors}");
    }

    #[test]
    fn line_counts_as_before() {
        let mut r = Rng(99);
        for _ in 0..5000 {
            let text = obj_text(&mut r);
            let old = (
                text.split(|&b| b == b'\n')
                    .filter(|l| is_vertex_line(l))
                    .count(),
                text.iter().filter(|&&b| b == b'\n').count(),
            );
            assert_eq!(
                count_lines(&text),
                old,
                "{:?}",
                String::from_utf8_lossy(&text)
            );
            let continued =
                text.windows(2).any(|w| w == b"\\\n") || text.windows(3).any(|w| w == b"\\\r\n");
            assert_eq!(has_continued_lines(&text), continued);
        }
        assert!(has_continued_lines(b"v 1 \\\r\n2 3\n"));
        assert!(!has_continued_lines(b"# a \\ b\n"));
    }
}
