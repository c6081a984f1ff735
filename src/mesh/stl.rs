//! STL, binary and ASCII. A file is binary when its length is exactly `84 + 50 n` for the
//! triangle count n in its header, whatever its first bytes say (many binary STLs begin with
//! "solid").

use super::{Mesh, MeshError, malformed};

pub(super) fn looks_binary(bytes: &[u8]) -> bool {
    bytes.len() >= 84 && {
        let n = u32::from_le_bytes(bytes[80..84].try_into().unwrap()) as u64;
        84 + 50 * n == bytes.len() as u64
    }
}

pub(super) fn parse(bytes: &[u8]) -> Result<Mesh, MeshError> {
    if looks_binary(bytes) {
        return parse_binary(bytes);
    }
    // Text that starts with "solid" is ASCII; a binary file whose header happens to start with
    // "solid" but whose size is off is reported as a broken binary file below.
    if let Ok(text) = std::str::from_utf8(bytes) {
        if text.trim_start().starts_with("solid") {
            return parse_ascii(text);
        }
    }
    if bytes.len() < 84 {
        return Err(malformed(
            "STL",
            format!(
                "truncated: {} bytes is shorter than the 84-byte binary header",
                bytes.len()
            ),
        ));
    }
    let n = u32::from_le_bytes(bytes[80..84].try_into().unwrap()) as u64;
    Err(malformed(
        "STL",
        format!(
            "truncated or padded binary STL: header says {n} triangles ({} bytes) but the file has {} bytes",
            84 + 50 * n,
            bytes.len()
        ),
    ))
}

fn parse_binary(bytes: &[u8]) -> Result<Mesh, MeshError> {
    let n = (bytes.len() - 84) / 50;
    let mut positions = Vec::with_capacity(3 * n);
    for rec in bytes[84..].chunks_exact(50) {
        for v in 0..3 {
            let o = 12 + 12 * v;
            let c = |i: usize| {
                f32::from_le_bytes(rec[o + 4 * i..o + 4 * i + 4].try_into().unwrap()) as f64
            };
            positions.push([c(0), c(1), c(2)]);
        }
    }
    if n == 0 {
        return Err(MeshError::NoTriangles(
            " (binary STL with a triangle count of 0)".into(),
        ));
    }
    let triangles = (0..n as u32)
        .map(|t| [3 * t, 3 * t + 1, 3 * t + 2])
        .collect();
    Mesh::new(positions, triangles)
}

fn parse_ascii(text: &str) -> Result<Mesh, MeshError> {
    let mut positions = Vec::new();
    let mut in_facet = 0usize; // vertices seen in the current facet, or 0 outside one
    let mut open = false;
    let mut ended = false;
    for (lineno, line) in text.lines().enumerate() {
        let mut tok = line.split_whitespace();
        match tok.next() {
            Some("facet") => {
                if open {
                    return Err(malformed(
                        "STL",
                        format!("line {}: facet inside a facet", lineno + 1),
                    ));
                }
                open = true;
                in_facet = 0;
            }
            Some("vertex") => {
                if !open {
                    return Err(malformed(
                        "STL",
                        format!("line {}: vertex outside a facet", lineno + 1),
                    ));
                }
                let mut c = [0.0; 3];
                for v in c.iter_mut() {
                    *v = tok
                        .next()
                        .and_then(|t| t.parse::<f64>().ok())
                        .ok_or_else(|| {
                            malformed(
                                "STL",
                                format!("line {}: vertex needs three numbers", lineno + 1),
                            )
                        })?;
                }
                positions.push(c);
                in_facet += 1;
            }
            Some("endfacet") => {
                if !open || in_facet != 3 {
                    return Err(malformed(
                        "STL",
                        format!(
                            "line {}: a facet must have exactly 3 vertices, found {in_facet}",
                            lineno + 1
                        ),
                    ));
                }
                open = false;
            }
            Some("endsolid") => ended = true,
            _ => {}
        }
    }
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
    Mesh::new(
        positions,
        (0..n).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect(),
    )
}
