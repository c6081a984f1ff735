//! STL, binary and ASCII. A file is binary when its length is exactly `84 + 50 n` for the
//! triangle count n in its header, whatever its first bytes say (many binary STLs begin with
//! "solid").

use super::degenerate::Repeats;
use super::stream::{Stream, after_last_newline, line_blocks};
use super::{HEAD, LoadOptions, Mesh, MeshError, malformed};

pub(super) fn looks_binary(bytes: &[u8]) -> bool {
    bytes.len() >= 84 && {
        let n = u32::from_le_bytes(bytes[80..84].try_into().unwrap()) as u64;
        84 + 50 * n == bytes.len() as u64
    }
}

/// Whether the first bytes of a file whose length is not known yet (a gzip stream) look like a
/// binary STL: a triangle count, the records that fit in `head` have finite coordinates, and
/// they are not plain text.
pub(super) fn plausible_binary_head(head: &[u8]) -> bool {
    if head.len() < 84 + 50 {
        return false;
    }
    let n = u32::from_le_bytes(head[80..84].try_into().unwrap()) as usize;
    let records: Vec<&[u8]> = head[84..].chunks_exact(50).take(n.min(64)).collect();
    n > 0
        && records.iter().all(|r| {
            r[..48]
                .chunks_exact(4)
                .all(|c| f32::from_le_bytes(c.try_into().unwrap()).is_finite())
        })
        && records
            .iter()
            .flat_map(|r| r.iter())
            .any(|&b| b >= 0x80 || (b < 0x20 && !b"\t\n\r".contains(&b)))
}

/// Whether `b` is text that starts with "solid": all of it valid UTF-8 when `complete`, else
/// (the first bytes of a longer file) valid up to a character cut at the end, and without NUL
/// bytes (which binary records are full of).
fn ascii_like(b: &[u8], complete: bool) -> bool {
    if !complete && b.contains(&0) {
        return false;
    }
    let text = match std::str::from_utf8(b) {
        Ok(t) => t,
        Err(e) if !complete && e.error_len().is_none() => {
            std::str::from_utf8(&b[..e.valid_up_to()]).unwrap()
        }
        Err(_) => return false,
    };
    text.trim_start().starts_with("solid")
}

pub(super) fn parse(s: &mut Stream, opts: &LoadOptions) -> Result<Mesh, MeshError> {
    s.fill_to(HEAD)?;
    let max = opts.max_triangles as u64;
    let head = s.available();
    let text = ascii_like(head, s.at_end());
    if head.len() < 84 && s.at_end() {
        if text {
            return parse_ascii(s, opts);
        }
        return Err(malformed(
            "STL",
            format!(
                "truncated: {} bytes is shorter than the 84-byte binary header",
                head.len()
            ),
        ));
    }
    // Here the file has at least 84 bytes (a compressed one was decoded to HEAD or its end).
    let n = u32::from_le_bytes(head[80..84].try_into().unwrap()) as u64;
    let want = 84 + 50 * n;
    // A binary STL of an allowed size is read whole (it is exactly `want` bytes); one byte more
    // tells that the file is longer. Larger counts are not inflated: refused unless the file is
    // text (ASCII STL, whose bytes 80..84 are just characters), and text with facets in its
    // first bytes is read as ASCII as it is decoded.
    let ascii_facets = text && head.windows(5).any(|w| w == b"facet");
    // A compressed binary STL is read record by record as it is decoded (its degenerate
    // copies dropped as they come), never whole: a gigabyte of decoded records costs the mesh
    // they hold, not the gigabyte.
    if n <= max && !s.at_end() && !text {
        return parse_binary_stream(s, n);
    }
    if n <= max && !s.at_end() && !ascii_facets {
        s.fill_to(want as usize + 1)?;
    }
    let len = s.available().len() as u64;
    if s.at_end() && len == want {
        if n > max {
            return Err(MeshError::TooManyTriangles {
                count: n as usize,
                limit: opts.max_triangles,
            });
        }
        return parse_binary(s.available());
    }
    if text {
        return parse_ascii(s, opts);
    }
    if !s.at_end() && n > max {
        return Err(MeshError::CountOverLimit {
            format: "STL",
            what: "triangles declared in the binary header",
            count: n,
            limit: max,
        });
    }
    let has = if s.at_end() {
        format!("the file has {len} bytes")
    } else {
        "the file is longer".to_string()
    };
    Err(malformed(
        "STL",
        format!(
            "truncated or padded binary STL: header says {n} triangles ({want} bytes) but {has}"
        ),
    ))
}

fn parse_binary(bytes: &[u8]) -> Result<Mesh, MeshError> {
    let n = (bytes.len() - 84) / 50;
    if 3 * n as u64 > u32::MAX as u64 {
        return Err(malformed("STL", "more than 4 billion vertices"));
    }
    let mut soup = Soup::default();
    for rec in bytes[84..].chunks_exact(50) {
        soup.push(record(rec));
    }
    soup.mesh(" (binary STL with a triangle count of 0)")
}

/// The three corners of a binary STL record.
fn record(rec: &[u8]) -> [[f64; 3]; 3] {
    std::array::from_fn(|v| {
        let o = 12 + 12 * v;
        std::array::from_fn(|i| {
            f32::from_le_bytes(rec[o + 4 * i..o + 4 * i + 4].try_into().unwrap()) as f64
        })
    })
}

/// The `n` records of a binary STL whose header is at hand, read as they are decoded; the file
/// must end right after them.
fn parse_binary_stream(s: &mut Stream, n: u64) -> Result<Mesh, MeshError> {
    if 3 * n > u32::MAX as u64 {
        return Err(malformed("STL", "more than 4 billion vertices"));
    }
    s.consume(84);
    let mut soup = Soup::default();
    let mut left = n as usize;
    while left > 0 {
        s.fill_to(50 * left.min(1 << 14))?;
        let at_hand = s.available();
        let take = (at_hand.len() / 50).min(left);
        if take == 0 {
            let len = 84 + 50 * (n as usize - left) + at_hand.len();
            return Err(malformed(
                "STL",
                format!(
                    "truncated or padded binary STL: header says {n} triangles ({} bytes) but the file has {len} bytes",
                    84 + 50 * n
                ),
            ));
        }
        for rec in at_hand[..50 * take].chunks_exact(50) {
            soup.push(record(rec));
        }
        s.consume(50 * take);
        left -= take;
    }
    if !s.peek(1)?.is_empty() {
        return Err(malformed(
            "STL",
            format!(
                "truncated or padded binary STL: header says {n} triangles ({} bytes) but the file is longer",
                84 + 50 * n
            ),
        ));
    }
    soup.mesh(" (binary STL with a triangle count of 0)")
}

/// A triangle soup as STL is: three positions per triangle, degenerate copies dropped.
#[derive(Default)]
struct Soup {
    positions: Vec<[f64; 3]>,
    repeats: Repeats,
}

impl Soup {
    #[inline]
    fn push(&mut self, t: [[f64; 3]; 3]) {
        if self.repeats.keep(&t) {
            self.positions.extend_from_slice(&t);
        }
    }

    fn mesh(self, empty: &str) -> Result<Mesh, MeshError> {
        if self.positions.is_empty() {
            return Err(MeshError::NoTriangles(empty.into()));
        }
        let n = self.positions.len() as u32 / 3;
        let mut mesh = Mesh::new(
            self.positions,
            (0..n).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect(),
        )?;
        mesh.dropped = self.repeats.dropped;
        Ok(mesh)
    }
}

/// ASCII blocks of a compressed file: about this many bytes, lines at most `MAX_LINE`.
const BLOCK: usize = 8 << 20;
const MAX_LINE: usize = 1 << 20;

/// ASCII STL, read line by line as it is decoded; stops once there are more facets than
/// triangles allowed.
fn parse_ascii(s: &mut Stream, opts: &LoadOptions) -> Result<Mesh, MeshError> {
    let mut positions: Vec<[f64; 3]> = Vec::new();
    let mut in_facet = 0usize; // vertices seen in the current facet, or 0 outside one
    let mut open = false;
    let mut ended = false;
    let mut lineno = 0usize;
    let mut repeats = Repeats::default();
    let max = opts.max_triangles;
    line_blocks(s, "STL", BLOCK, MAX_LINE, after_last_newline, |block, _| {
        for line in block.split_inclusive(|&b| b == b'\n') {
            lineno += 1;
            let mut tok = line
                .split(|b| b.is_ascii_whitespace())
                .filter(|t| !t.is_empty());
            match tok.next() {
                Some(b"facet") => {
                    if open {
                        return Err(malformed(
                            "STL",
                            format!("line {lineno}: facet inside a facet"),
                        ));
                    }
                    if positions.len() / 3 >= max {
                        return Err(MeshError::CountOverLimit {
                            format: "STL",
                            what: "facets or more (counted while reading)",
                            count: positions.len() as u64 / 3 + 1,
                            limit: max as u64,
                        });
                    }
                    open = true;
                    in_facet = 0;
                }
                Some(b"vertex") => {
                    if !open {
                        return Err(malformed(
                            "STL",
                            format!("line {lineno}: vertex outside a facet"),
                        ));
                    }
                    if in_facet == 3 {
                        return Err(malformed(
                            "STL",
                            format!(
                                "line {lineno}: a facet must have exactly 3 vertices, found more"
                            ),
                        ));
                    }
                    let mut c = [0.0; 3];
                    for v in c.iter_mut() {
                        *v = tok
                            .next()
                            .and_then(|t| std::str::from_utf8(t).ok())
                            .and_then(|t| t.parse::<f64>().ok())
                            .ok_or_else(|| {
                                malformed(
                                    "STL",
                                    format!("line {lineno}: vertex needs three numbers"),
                                )
                            })?;
                    }
                    positions.push(c);
                    in_facet += 1;
                }
                Some(b"endfacet") => {
                    if !open || in_facet != 3 {
                        return Err(malformed(
                            "STL",
                            format!(
                                "line {lineno}: a facet must have exactly 3 vertices, found {in_facet}"
                            ),
                        ));
                    }
                    open = false;
                    let t = positions.len() - 3;
                    if !repeats.keep(&[positions[t], positions[t + 1], positions[t + 2]]) {
                        positions.truncate(t);
                    }
                }
                Some(b"endsolid") => ended = true,
                _ => {}
            }
        }
        Ok(())
    })?;
    if open || !ended {
        return Err(malformed(
            "STL",
            "truncated ASCII STL: missing endfacet/endsolid",
        ));
    }
    if positions.is_empty() {
        return Err(MeshError::NoTriangles(" (ASCII STL without facets)".into()));
    }
    let n = positions.len() as u32 / 3;
    let mut mesh = Mesh::new(
        positions,
        (0..n).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect(),
    )?;
    mesh.dropped = repeats.dropped;
    Ok(mesh)
}
