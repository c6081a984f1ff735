//! PLY, ASCII and binary (either byte order): `vertex` x/y/z of any numeric type, `face` lists
//! (`vertex_indices` or `vertex_index`) of any size fan-triangulated, and `tristrips` lists
//! unrolled with -1 as the restart marker. Other elements and properties are read and skipped.

use super::{Mesh, MeshError, fan, malformed, unroll_strip};

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
    fn remaining_hint(&self) -> usize;
}

struct Ascii<'a> {
    tokens: std::str::SplitAsciiWhitespace<'a>,
    left: usize,
}

impl Source for Ascii<'_> {
    fn value(&mut self, _ty: Scalar) -> Result<f64, MeshError> {
        let t = self.tokens.next().ok_or_else(|| {
            malformed(
                "PLY",
                "truncated: the body ends before all elements are read",
            )
        })?;
        self.left = self.left.saturating_sub(t.len() + 1);
        t.parse::<f64>()
            .map_err(|_| malformed("PLY", format!("{t:?} is not a number")))
    }
    fn remaining_hint(&self) -> usize {
        self.left
    }
}

struct Binary<'a> {
    data: &'a [u8],
    pos: usize,
    big_endian: bool,
}

impl Source for Binary<'_> {
    fn value(&mut self, ty: Scalar) -> Result<f64, MeshError> {
        let n = ty.size();
        let b = self.data.get(self.pos..self.pos + n).ok_or_else(|| {
            malformed(
                "PLY",
                "truncated: the body ends before all elements are read",
            )
        })?;
        self.pos += n;
        let mut a = [0u8; 8];
        a[..n].copy_from_slice(b);
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
    fn remaining_hint(&self) -> usize {
        self.data.len() - self.pos
    }
}

pub(super) fn parse(bytes: &[u8]) -> Result<Mesh, MeshError> {
    let (elements, encoding, body) = parse_header(bytes)?;
    match encoding {
        Encoding::Ascii => {
            let text = std::str::from_utf8(body)
                .map_err(|_| malformed("PLY", "ASCII body is not valid UTF-8"))?;
            read_body(
                &elements,
                &mut Ascii {
                    tokens: text.split_ascii_whitespace(),
                    left: text.len(),
                },
            )
        }
        e => read_body(
            &elements,
            &mut Binary {
                data: body,
                pos: 0,
                big_endian: e == Encoding::Be,
            },
        ),
    }
}

fn parse_header(bytes: &[u8]) -> Result<(Vec<Element>, Encoding, &[u8]), MeshError> {
    let end = find(bytes, b"end_header").ok_or_else(|| malformed("PLY", "no end_header line"))?;
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
    Ok((elements, encoding, &bytes[body_start..]))
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

fn read_body(elements: &[Element], src: &mut dyn Source) -> Result<Mesh, MeshError> {
    let mut positions: Vec<[f64; 3]> = Vec::new();
    let mut triangles = Vec::new();
    let mut poly: Vec<u32> = Vec::new();
    let mut saw_vertex = false;
    for el in elements {
        // Every record takes at least one byte (binary) or token: a larger count is a lie.
        if el.count > src.remaining_hint() && !el.props.is_empty() {
            return Err(malformed(
                "PLY",
                format!(
                    "element {} claims {} records, more than the file holds",
                    el.name, el.count
                ),
            ));
        }
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
            positions.reserve(el.count);
            Some([x, y, z])
        } else {
            None
        };
        let is_face = el.name == "face";
        let is_strip = el.name == "tristrips";
        let mut vals = [0.0f64; 3];
        for _ in 0..el.count {
            for (pi, p) in el.props.iter().enumerate() {
                match p.list {
                    None => {
                        let v = src.value(p.ty)?;
                        if let Some(xyz) = xyz {
                            if let Some(a) = xyz.iter().position(|&i| i == pi) {
                                vals[a] = v;
                            }
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
                        let wanted = (is_face
                            && (p.name == "vertex_indices" || p.name == "vertex_index"))
                            || (is_strip && p.name == "vertex_indices");
                        poly.clear();
                        for _ in 0..n as usize {
                            let v = src.value(p.ty)?;
                            if wanted {
                                poly.push(index(v, is_strip)?);
                            }
                        }
                        if wanted && is_face {
                            fan(&poly, &mut triangles);
                        } else if wanted {
                            unroll_strip(&poly, &mut triangles);
                        }
                    }
                }
            }
            if xyz.is_some() {
                positions.push(vals);
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
    Mesh::new(positions, triangles)
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
