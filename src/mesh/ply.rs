//! PLY, ASCII and binary (either byte order): `vertex` x/y/z of any numeric type, `face` lists
//! (`vertex_indices` or `vertex_index`) of any size fan-triangulated, and `tristrips` lists
//! unrolled with -1 as the restart marker. Other elements and properties are read and skipped.

//!
//! The header's element counts are checked against the limits (and against the bytes they
//! need) before the body is read, and the body is read as it is decoded: a gzip'd PLY is
//! never held whole.

use super::stream::Stream;
use super::{Attributes, LoadOptions, Mesh, MeshError, malformed};

/// The longest header read (a compressed file's header must end within it).
const MAX_HEADER: usize = 1 << 20;
/// The longest ASCII token (a number) read.
const MAX_TOKEN: usize = 4096;

#[derive(Clone, Copy, Debug)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(s: &str) -> Option<Scalar> {
        Some(match s {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }
    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }
}

#[derive(Debug)]
struct Property {
    name: String,
    ty: Scalar,
    /// Type of the element count for list properties.
    list: Option<Scalar>,
}

#[derive(Debug)]
struct Element {
    name: String,
    count: usize,
    props: Vec<Property>,
}

#[derive(Clone, Copy, PartialEq)]
enum Encoding {
    Ascii,
    Le,
    Be,
}

/// Reads values one at a time from the body.
trait Source {
    fn value(&mut self, ty: Scalar) -> Result<f64, MeshError>;
}

fn truncated() -> MeshError {
    malformed(
        "PLY",
        "truncated: the body ends before all elements are read",
    )
}

/// Whitespace-separated numbers.
struct Ascii<'s, 'a> {
    s: &'s mut Stream<'a>,
}

impl Source for Ascii<'_, '_> {
    fn value(&mut self, _ty: Scalar) -> Result<f64, MeshError> {
        // Skip whitespace.
        loop {
            let a = self.s.peek(1)?;
            if a.is_empty() {
                return Err(truncated());
            }
            match a.iter().position(|b| !b.is_ascii_whitespace()) {
                Some(k) => {
                    self.s.consume(k);
                    break;
                }
                None => {
                    let k = a.len();
                    self.s.consume(k)
                }
            }
        }
        let mut want = 64;
        loop {
            self.s.fill_to(want)?;
            let at_end = self.s.at_end();
            let a = self.s.available();
            let end = match a.iter().position(|b| b.is_ascii_whitespace()) {
                Some(e) => e,
                None if at_end || a.len() > MAX_TOKEN => a.len(),
                None => {
                    want = a.len() * 2;
                    continue;
                }
            };
            let t = &a[..end];
            let v = std::str::from_utf8(t)
                .ok()
                .filter(|_| t.len() <= MAX_TOKEN)
                .and_then(|t| t.parse::<f64>().ok())
                .ok_or_else(|| {
                    let shown = String::from_utf8_lossy(&t[..t.len().min(40)]);
                    malformed("PLY", format!("{shown:?} is not a number"))
                })?;
            self.s.consume(end);
            return Ok(v);
        }
    }
}

struct Binary<'s, 'a> {
    s: &'s mut Stream<'a>,
    big_endian: bool,
}

impl Source for Binary<'_, '_> {
    #[inline]
    fn value(&mut self, ty: Scalar) -> Result<f64, MeshError> {
        let n = ty.size();
        self.s.fill_to(n)?;
        let b = self.s.available().get(..n).ok_or_else(truncated)?;
        let mut a = [0u8; 8];
        a[..n].copy_from_slice(b);
        self.s.consume(n);
        if self.big_endian {
            a[..n].reverse();
        }
        Ok(match ty {
            Scalar::I8 => a[0] as i8 as f64,
            Scalar::U8 => a[0] as f64,
            Scalar::I16 => i16::from_le_bytes([a[0], a[1]]) as f64,
            Scalar::U16 => u16::from_le_bytes([a[0], a[1]]) as f64,
            Scalar::I32 => i32::from_le_bytes(a[..4].try_into().unwrap()) as f64,
            Scalar::U32 => u32::from_le_bytes(a[..4].try_into().unwrap()) as f64,
            Scalar::F32 => f32::from_le_bytes(a[..4].try_into().unwrap()) as f64,
            Scalar::F64 => f64::from_le_bytes(a),
        })
    }
}

pub(super) fn parse(s: &mut Stream, opts: &LoadOptions) -> Result<Mesh, MeshError> {
    // The header, up to and including the line break after end_header.
    let mut want = 64 << 10;
    let end = loop {
        s.fill_to(want)?;
        let a = s.available();
        if let Some(end) = find(a, b"end_header") {
            s.fill_to(end + 12)?;
            break end;
        }
        if s.at_end() || a.len() > MAX_HEADER {
            return Err(malformed("PLY", "no end_header line"));
        }
        want = a.len() * 2;
    };
    let (elements, encoding, body) = parse_header(s.available(), end)?;
    s.consume(body);
    check_counts(&elements, encoding, s, opts)?;
    match encoding {
        Encoding::Ascii => read_body(&elements, &mut Ascii { s }, opts),
        e => read_body(
            &elements,
            &mut Binary {
                s,
                big_endian: e == Encoding::Be,
            },
            opts,
        ),
    }
}

/// The vertex and face counts a header at the start of `head` declares (for the parse's cost
/// estimate, `super::cost`); `None` when the header is not all in `head` or is malformed.
pub(super) fn header_counts(head: &[u8]) -> Option<(u64, u64)> {
    let end = find(head, b"end_header")?;
    let (elements, _, _) = parse_header(head, end).ok()?;
    let count = |name: &str| {
        elements
            .iter()
            .filter(|e| e.name == name)
            .map(|e| e.count as u64)
            .sum::<u64>()
    };
    Some((count("vertex"), count("face") + count("tristrips")))
}

/// The header's counts against the limits, and the bytes they need at least against what the
/// file holds (or, compressed, may still expand to).
fn check_counts(
    elements: &[Element],
    encoding: Encoding,
    s: &Stream,
    opts: &LoadOptions,
) -> Result<(), MeshError> {
    let over = |what, count: usize, limit: usize| MeshError::CountOverLimit {
        format: "PLY",
        what,
        count: count as u64,
        limit: limit as u64,
    };
    let mut need = 0u64;
    let left = s.remaining_bound();
    for el in elements {
        match el.name.as_str() {
            "vertex" if el.count > opts.max_vertices() => {
                return Err(over(
                    "vertices declared by `element vertex`",
                    el.count,
                    opts.max_vertices(),
                ));
            }
            "face" if el.count > opts.max_triangles => {
                return Err(over(
                    "faces declared by `element face`",
                    el.count,
                    opts.max_triangles,
                ));
            }
            "tristrips" if el.count > opts.max_triangles => {
                return Err(over(
                    "strips declared by `element tristrips`",
                    el.count,
                    opts.max_triangles,
                ));
            }
            _ => {}
        }
        // The least a record takes: each scalar (or list length), or in ASCII each token and
        // the whitespace after it (the last one of the file may lack it).
        let record: u64 = el
            .props
            .iter()
            .map(|p| match encoding {
                Encoding::Ascii => 2,
                _ => p.list.unwrap_or(p.ty).size() as u64,
            })
            .sum();
        need = need.saturating_add((el.count as u64).saturating_mul(record));
        if need.saturating_sub(1) > left {
            return Err(if s.at_end() {
                malformed(
                    "PLY",
                    format!(
                        "element {} claims {} records, more than the file holds",
                        el.name, el.count
                    ),
                )
            } else {
                MeshError::TooLarge(s.limit())
            });
        }
    }
    Ok(())
}

/// Parses the header text before `end` (where `end_header` starts); returns the elements, the
/// encoding and where the body starts.
fn parse_header(bytes: &[u8], end: usize) -> Result<(Vec<Element>, Encoding, usize), MeshError> {
    let mut body_start = end + b"end_header".len();
    if bytes.get(body_start) == Some(&b'\r') {
        body_start += 1;
    }
    if bytes.get(body_start) != Some(&b'\n') {
        return Err(malformed("PLY", "end_header must end its line"));
    }
    body_start += 1;
    let header =
        std::str::from_utf8(&bytes[..end]).map_err(|_| malformed("PLY", "header is not text"))?;
    let mut lines = header.lines();
    if lines.next().map(str::trim) != Some("ply") {
        return Err(malformed("PLY", "first line must be `ply`"));
    }
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    for line in lines {
        let t: Vec<&str> = line.split_whitespace().collect();
        match t.as_slice() {
            [] | ["comment", ..] | ["obj_info", ..] => {}
            ["format", f, _version] => {
                encoding = Some(match *f {
                    "ascii" => Encoding::Ascii,
                    "binary_little_endian" => Encoding::Le,
                    "binary_big_endian" => Encoding::Be,
                    other => return Err(malformed("PLY", format!("unknown format {other:?}"))),
                })
            }
            ["element", name, count] => {
                let count = count
                    .parse()
                    .map_err(|_| malformed("PLY", format!("bad element count {count:?}")))?;
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    props: vec![],
                });
            }
            ["property", "list", ct, it, name] => {
                let (Some(ct), Some(it)) = (Scalar::parse(ct), Scalar::parse(it)) else {
                    return Err(malformed("PLY", format!("unknown type in `{line}`")));
                };
                let el = elements
                    .last_mut()
                    .ok_or_else(|| malformed("PLY", "property before any element"))?;
                el.props.push(Property {
                    name: name.to_string(),
                    ty: it,
                    list: Some(ct),
                });
            }
            ["property", ty, name] => {
                let ty = Scalar::parse(ty)
                    .ok_or_else(|| malformed("PLY", format!("unknown type in `{line}`")))?;
                let el = elements
                    .last_mut()
                    .ok_or_else(|| malformed("PLY", "property before any element"))?;
                el.props.push(Property {
                    name: name.to_string(),
                    ty,
                    list: None,
                });
            }
            _ => {
                return Err(malformed(
                    "PLY",
                    format!("cannot read header line `{line}`"),
                ));
            }
        }
    }
    let encoding = encoding.ok_or_else(|| malformed("PLY", "no format line"))?;
    Ok((elements, encoding, body_start))
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

fn read_body<S: Source>(
    elements: &[Element],
    src: &mut S,
    opts: &LoadOptions,
) -> Result<Mesh, MeshError> {
    let mut positions: Vec<[f64; 3]> = Vec::new();
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    // Vertex colours: `red`, `green`, `blue` (all three) and `alpha` (else 1).
    let mut colors: Vec<[f32; 4]> = Vec::new();
    let mut has_color = false;
    let mut saw_vertex = false;
    let max = opts.max_triangles;
    let too_many = |n: usize| MeshError::CountOverLimit {
        format: "PLY",
        what: "triangles or more (counted while reading)",
        count: n as u64,
        limit: max as u64,
    };
    for el in elements {
        let is_vertex = el.name == "vertex";
        let xyz = if is_vertex {
            saw_vertex = true;
            let idx = ["x", "y", "z"].map(|n| {
                el.props
                    .iter()
                    .position(|p| p.name == n && p.list.is_none())
            });
            let [Some(x), Some(y), Some(z)] = idx else {
                return Err(malformed(
                    "PLY",
                    "vertex element needs scalar x, y and z properties",
                ));
            };
            // Bounded by check_counts: the vertex limit and the bytes of the file.
            positions.reserve_exact(el.count);
            Some([x, y, z])
        } else {
            None
        };
        // The vertex element's colour properties: channel of each property index.
        let channel: Vec<Option<usize>> = el
            .props
            .iter()
            .map(|p| {
                let c = ["red", "green", "blue", "alpha"]
                    .iter()
                    .position(|&n| n == p.name);
                c.filter(|_| is_vertex && p.list.is_none())
            })
            .collect();
        let colored = (0..3).all(|c| channel.contains(&Some(c)));
        if colored {
            has_color = true;
            colors.reserve_exact(el.count);
        }
        if el.props.is_empty() {
            // Records without properties take no bytes: nothing to read, whatever the count.
            continue;
        }
        let is_face = el.name == "face";
        let is_strip = el.name == "tristrips";
        let mut vals = [0.0f64; 3];
        let mut rgba = [1.0f32; 4];
        for _ in 0..el.count {
            for (pi, p) in el.props.iter().enumerate() {
                match p.list {
                    None => {
                        let v = src.value(p.ty)?;
                        if let Some(xyz) = xyz
                            && let Some(a) = xyz.iter().position(|&i| i == pi)
                        {
                            vals[a] = v;
                        }
                        if colored && let Some(c) = channel[pi] {
                            rgba[c] = unit(v, p.ty);
                        }
                    }
                    Some(ct) => {
                        let n = src.value(ct)?;
                        if !(0.0..=1e9).contains(&n) || n.fract() != 0.0 {
                            return Err(malformed(
                                "PLY",
                                format!("bad list length {n} in element {}", el.name),
                            ));
                        }
                        let n = n as usize;
                        let wanted = (is_face
                            && (p.name == "vertex_indices" || p.name == "vertex_index"))
                            || (is_strip && p.name == "vertex_indices");
                        if wanted && is_face && n >= 3 && triangles.len() + (n - 2) > max {
                            return Err(too_many(triangles.len() + (n - 2)));
                        }
                        // Triangulated as the indices are read (the fan or strip of
                        // `super::fan` and `super::unroll_strip`), nothing else kept.
                        let (mut a, mut b, mut run) = (0u32, 0u32, 0usize);
                        for _ in 0..n {
                            let v = src.value(p.ty)?;
                            if !wanted {
                                continue;
                            }
                            let i = index(v, is_strip)?;
                            if is_face {
                                match run {
                                    0 => a = i,
                                    1 => {}
                                    _ => triangles.push([a, b, i]),
                                }
                                b = i;
                                run += 1;
                            } else if i == u32::MAX {
                                run = 0;
                            } else {
                                if run >= 2 {
                                    if triangles.len() >= max {
                                        return Err(too_many(triangles.len() + 1));
                                    }
                                    triangles.push(if run % 2 == 0 {
                                        [a, b, i]
                                    } else {
                                        [b, a, i]
                                    });
                                }
                                (a, b) = (b, i);
                                run += 1;
                            }
                        }
                    }
                }
            }
            if xyz.is_some() {
                positions.push(vals);
                if colored {
                    colors.push(rgba);
                }
            }
        }
    }
    if !saw_vertex {
        return Err(malformed("PLY", "no vertex element"));
    }
    if triangles.is_empty() {
        return Err(MeshError::NoTriangles(
            " (no face or tristrips element with polygons)".into(),
        ));
    }
    let attributes = Attributes {
        colors: has_color.then_some(colors),
        colors_srgb: true,
        ..Attributes::default()
    };
    Mesh::new(positions, triangles)?.with_attributes(attributes)
}

/// A colour channel in [0, 1]: an unsigned integer over its type's maximum (`uchar` 255,
/// `ushort` 65535, `uint` 2³² − 1), a float as written, clamped (a signed integer clamps its
/// negatives to 0 over the signed maximum).
fn unit(v: f64, ty: Scalar) -> f32 {
    let max = match ty {
        Scalar::U8 => 255.0,
        Scalar::U16 => 65535.0,
        Scalar::U32 => 4294967295.0,
        Scalar::I8 => 127.0,
        Scalar::I16 => 32767.0,
        Scalar::I32 => 2147483647.0,
        Scalar::F32 | Scalar::F64 => 1.0,
    };
    let u = v / max;
    if u.is_nan() {
        0.0
    } else {
        u.clamp(0.0, 1.0) as f32
    }
}

/// A vertex index from a list; -1 is a strip restart (kept as `u32::MAX`).
fn index(v: f64, strip: bool) -> Result<u32, MeshError> {
    if strip && v == -1.0 {
        return Ok(u32::MAX);
    }
    if v < 0.0 || v >= u32::MAX as f64 || v.fract() != 0.0 {
        return Err(malformed(
            "PLY",
            format!("vertex index {v} is not a valid index"),
        ));
    }
    Ok(v as u32)
}
