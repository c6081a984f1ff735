//! glTF 2.0 (`.gltf` JSON and `.glb`): every triangle primitive of the default scene (all scenes
//! when none is marked default, every mesh when there are no scenes), node transforms applied,
//! skins ignored (bind pose). Buffers come from the GLB chunk or `data:` URIs; other URIs are read
//! only when [`ExternalResources::BesideFile`] allows it, and never outside that directory.

use std::borrow::Cow;

use base64::Engine as _;
use gltf::accessor::{DataType, Dimensions};
use gltf::mesh::Mode;

use super::attributes::NO_MATERIAL;
use super::gltf_materials::{self, UvSpec};
use super::stream::Stream;
use super::{Attributes, ExternalResources, HEAD, LoadOptions, Mesh, MeshError, malformed};

type Mat4 = [[f64; 4]; 4];
const IDENTITY: Mat4 = [
    [1., 0., 0., 0.],
    [0., 1., 0., 0.],
    [0., 0., 1., 0.],
    [0., 0., 0., 1.],
];
/// Node hierarchies deeper than this are refused (they are cycles or garbage).
const MAX_DEPTH: usize = 256;

/// GLB: 12-byte header (magic, version, total length), then chunks of 8-byte header and data.
const GLB_HEADER: usize = 12;
const CHUNK_HEADER: usize = 8;

pub(super) fn parse(s: &mut Stream, opts: &LoadOptions) -> Result<Mesh, MeshError> {
    // The gltf crate asserts on some malformed accessors; a panic must become an error, not a
    // dead worker. (The stream is not used again after one.)
    let mut s = std::panic::AssertUnwindSafe(s);
    std::panic::catch_unwind(move || {
        let s = &mut **s;
        let (doc, bin) = if s.peek(GLB_HEADER)?.starts_with(b"glTF") {
            document(glb_bytes(s, opts)?)?
        } else if s.is_compressed() {
            (document_from_stream(s)?, None)
        } else {
            document(s.rest()?)?
        };
        parse_document(&doc, bin.as_deref(), opts)
    })
    .unwrap_or_else(|_| Err(malformed("glTF", "malformed accessor or buffer data")))
}

/// The bytes of a GLB: its header's length is checked first (a compressed file is never
/// decoded past it), and in a compressed file the JSON chunk is read and checked against the
/// limits before the BIN chunk is decoded.
fn glb_bytes<'s>(s: &'s mut Stream, opts: &LoadOptions) -> Result<&'s [u8], MeshError> {
    s.fill_to(GLB_HEADER + CHUNK_HEADER)?;
    let head = s.available();
    if head.len() < GLB_HEADER {
        return Err(malformed("glTF", "truncated GLB header"));
    }
    let u32_at = |b: &[u8], i: usize| u32::from_le_bytes(b[i..i + 4].try_into().unwrap());
    let length = u32_at(head, 8) as usize;
    let json_len = (head.len() >= GLB_HEADER + CHUNK_HEADER).then(|| u32_at(head, GLB_HEADER));
    if length < GLB_HEADER + CHUNK_HEADER {
        return Err(malformed(
            "glTF",
            format!("GLB header says the file has {length} bytes, too few for a JSON chunk"),
        ));
    }
    // In memory, or all of it decoded with the first bytes: read as it is.
    s.fill_to(HEAD)?;
    if s.at_end() {
        return s.rest();
    }
    if length as u64 > s.limit() {
        return Err(MeshError::TooLarge(s.limit()));
    }
    if let Some(json_len) = json_len {
        let json_end = GLB_HEADER + CHUNK_HEADER + json_len as usize;
        if json_end <= length {
            let a = s.peek(json_end)?;
            if let Some(json) = a.get(GLB_HEADER + CHUNK_HEADER..json_end) {
                let doc = json_document(json)?;
                check_limits(&doc, opts)?;
            }
        }
    }
    // Not a byte past the length the header gives (anything after it is ignored).
    let a = s.peek(length)?;
    Ok(&a[..a.len().min(length)])
}

/// A GLB's BIN chunk (`None`: a .gltf, or a GLB without one).
type Bin<'a> = Option<Cow<'a, [u8]>>;

/// The glTF document of a .gltf or a GLB's JSON chunk, or of a whole GLB with its BIN chunk
/// (as `gltf::Glb::from_slice` gives it: borrowed from `bytes`, so a GLB's geometry is read
/// where it lies, never copied).
fn document(bytes: &[u8]) -> Result<(gltf::Gltf, Bin<'_>), MeshError> {
    let bad = |e: gltf::json::Error| malformed("glTF", e.to_string());
    if bytes.starts_with(b"glTF") {
        let glb = gltf::Glb::from_slice(bytes).map_err(|e| malformed("glTF", e.to_string()))?;
        let root = gltf::json::deserialize::from_slice(&glb.json).map_err(bad)?;
        Ok((validated(root, None)?, glb.bin))
    } else {
        Ok((json_document(bytes)?, None))
    }
}

/// The glTF document of JSON text (a .gltf, or a GLB's JSON chunk).
fn json_document(bytes: &[u8]) -> Result<gltf::Gltf, MeshError> {
    let root = gltf::json::deserialize::from_slice(bytes)
        .map_err(|e: gltf::json::Error| malformed("glTF", e.to_string()))?;
    validated(root, None)
}

/// The document of a compressed .gltf, deserialized as it is decoded: what it holds is kept,
/// not its whitespace.
fn document_from_stream(s: &mut Stream) -> Result<gltf::Gltf, MeshError> {
    let mut r = StreamRead { s, failed: None };
    let root: Result<gltf::json::Root, _> = gltf::json::deserialize::from_reader(&mut r);
    match (root, r.failed) {
        (_, Some(e)) => Err(e),
        (Err(e), None) => Err(malformed("glTF", e.to_string())),
        (Ok(root), None) => validated(root, None),
    }
}

/// The spec's validation of a document (gltf's own), except that POSITION min/max may be
/// missing: required by the spec but often missing in real files, and nothing here needs them.
/// Vertex attributes of a semantic gltf-json does not know are dropped first: application-specific
/// ones (`_s`, `_t`: names starting with `_` are legal, and trimesh writes them) and any other
/// (only POSITION is read; gltf-json without its `extras` feature calls them all invalid).
fn validated(mut root: gltf::json::Root, blob: Option<Vec<u8>>) -> Result<gltf::Gltf, MeshError> {
    use gltf::json::validation::{Checked, Validate};
    for mesh in &mut root.meshes {
        for prim in &mut mesh.primitives {
            prim.attributes
                .retain(|k, _| matches!(k, Checked::Valid(_)));
        }
    }
    // gltf-json 1.4's validation indexes the accessors by each POSITION attribute unchecked
    // (and panics on a bad index): those indices are checked first.
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            for a in prim.attributes.values() {
                if a.value() >= root.accessors.len() {
                    return Err(malformed(
                        "glTF",
                        format!(
                            "mesh {m} primitive {p}: accessor {} does not exist",
                            a.value()
                        ),
                    ));
                }
            }
        }
    }
    let mut errs = Vec::new();
    root.validate(&root, gltf::json::Path::new, &mut |path, e| {
        errs.push((path(), e))
    });
    let only_min_max = errs.iter().all(|(p, _)| {
        let p = p.to_string();
        p.ends_with(".min") || p.ends_with(".max")
    });
    if !only_min_max {
        return Err(malformed("glTF", gltf::Error::Validation(errs).to_string()));
    }
    Ok(gltf::Gltf {
        document: gltf::Document::from_json_without_validation(root),
        blob,
    })
}

/// A [`Stream`] as [`std::io::Read`]; its own error (over the limit, bad gzip) is kept aside.
struct StreamRead<'s, 'a> {
    s: &'s mut Stream<'a>,
    failed: Option<MeshError>,
}

impl std::io::Read for StreamRead<'_, '_> {
    fn read(&mut self, out: &mut [u8]) -> std::io::Result<usize> {
        if let Err(e) = self.s.fill_to(out.len().min(1 << 16)) {
            self.failed = Some(e.clone());
            return Err(std::io::Error::other(e));
        }
        let a = self.s.available();
        let n = a.len().min(out.len());
        out[..n].copy_from_slice(&a[..n]);
        self.s.consume(n);
        Ok(n)
    }
}

/// Node visits across all scenes at most, beyond twice the nodes of the file: a hierarchy with
/// shared subtrees (not a tree, as the spec demands) would otherwise multiply without bound.
const EXTRA_NODE_VISITS: usize = 1 << 16;

/// The meshes the scene instances, with their world transforms, in the order they are read.
fn instances(doc: &gltf::Document) -> Result<Vec<(gltf::Mesh<'_>, Mat4)>, MeshError> {
    let scenes: Vec<_> = match doc.default_scene() {
        Some(s) => vec![s],
        None => doc.scenes().collect(),
    };
    let mut out = Vec::new();
    if scenes.is_empty() {
        out.extend(doc.meshes().map(|m| (m, IDENTITY)));
        return Ok(out);
    }
    let budget = doc.nodes().len().saturating_mul(2) + EXTRA_NODE_VISITS;
    let mut visits = 0usize;
    fn walk<'d>(
        node: gltf::Node<'d>,
        parent: &Mat4,
        depth: usize,
        visits: &mut usize,
        budget: usize,
        out: &mut Vec<(gltf::Mesh<'d>, Mat4)>,
    ) -> Result<(), MeshError> {
        if depth > MAX_DEPTH {
            return Err(malformed(
                "glTF",
                format!("node hierarchy deeper than {MAX_DEPTH} (a cycle?)"),
            ));
        }
        *visits += 1;
        if *visits > budget {
            return Err(malformed(
                "glTF",
                format!(
                    "the scenes instance more than {budget} nodes (the node hierarchy is not a tree)"
                ),
            ));
        }
        let local = node.transform().matrix().map(|c| c.map(|v| v as f64));
        let world = mul(parent, &local);
        if let Some(m) = node.mesh() {
            out.push((m, world));
        }
        for c in node.children() {
            walk(c, &world, depth + 1, visits, budget, out)?;
        }
        Ok(())
    }
    for s in scenes {
        for n in s.nodes() {
            walk(n, &IDENTITY, 0, &mut visits, budget, &mut out)?;
        }
    }
    Ok(out)
}

/// What the document's accessors and buffers declare, against the limits, before any buffer is
/// read: the triangles and vertices of every instanced triangle primitive, and buffer sizes.
fn check_limits(doc: &gltf::Document, opts: &LoadOptions) -> Result<(), MeshError> {
    let mut bytes = 0u64;
    for b in doc.buffers() {
        bytes = bytes.saturating_add(b.length() as u64);
    }
    if bytes > opts.max_decompressed_bytes {
        return Err(MeshError::TooLarge(opts.max_decompressed_bytes));
    }
    let (mut triangles, mut vertices) = (0u64, 0u64);
    for (mesh, _) in instances(doc)? {
        for prim in mesh.primitives() {
            let Some(pos) = prim.get(&gltf::Semantic::Positions) else {
                continue;
            };
            let n = prim.indices().map_or(pos.count(), |i| i.count()) as u64;
            triangles += match prim.mode() {
                Mode::Triangles => n / 3,
                Mode::TriangleStrip | Mode::TriangleFan => n.saturating_sub(2),
                _ => continue,
            };
            vertices += pos.count() as u64;
        }
        if triangles > opts.max_triangles as u64 {
            return Err(MeshError::CountOverLimit {
                format: "glTF",
                what: "triangles or more declared by the accessors of the scene",
                count: triangles,
                limit: opts.max_triangles as u64,
            });
        }
        if vertices > opts.max_vertices() as u64 {
            return Err(MeshError::CountOverLimit {
                format: "glTF",
                what: "vertices or more declared by the accessors of the scene",
                count: vertices,
                limit: opts.max_vertices() as u64,
            });
        }
    }
    Ok(())
}

fn parse_document(
    doc: &gltf::Gltf,
    bin: Option<&[u8]>,
    opts: &LoadOptions,
) -> Result<Mesh, MeshError> {
    let external = &opts.external;
    check_limits(doc, opts)?;
    let mut buffers: Vec<Cow<[u8]>> = Vec::new();
    for b in doc.buffers() {
        let data = match b.source() {
            gltf::buffer::Source::Bin => bin.map(Cow::Borrowed).ok_or_else(|| {
                malformed(
                    "glTF",
                    format!(
                        "buffer {} refers to a GLB BIN chunk that is missing",
                        b.index()
                    ),
                )
            })?,
            gltf::buffer::Source::Uri(uri) => Cow::Owned(read_uri(uri, external)?),
        };
        if data.len() < b.length() {
            return Err(malformed(
                "glTF",
                format!(
                    "buffer {} holds {} bytes, less than its byteLength {}",
                    b.index(),
                    data.len(),
                    b.length()
                ),
            ));
        }
        buffers.push(data);
    }

    let mut out = Collector {
        positions: vec![],
        triangles: vec![],
        skipped_modes: vec![],
        colors: vec![],
        material: vec![],
        any_material: false,
        specs: vec![],
        uv: vec![],
    };
    if doc.materials().len() >= usize::from(u16::MAX) {
        return Err(malformed(
            "glTF",
            format!(
                "{} materials, more than the {} a mesh may have",
                doc.materials().len(),
                u16::MAX - 1
            ),
        ));
    }
    let (table, encoded, specs) = gltf_materials::materials(doc, &buffers, opts.textures)?;
    out.specs = specs;
    // The images are decoded while the geometry is read, each on one thread (igea-subdiv4's
    // 4096² PNG about 0.16 s, its million triangles' accessors about 0.07 s); an image's error
    // is reported before the geometry's, as when one followed the other.
    let (images, geometry) = rayon::join(
        || gltf_materials::decode(&encoded, opts.max_texture_bytes),
        || -> Result<(), MeshError> {
            for (m, world) in instances(doc)? {
                out.mesh(&m, &world, &buffers)?;
            }
            Ok(())
        },
    );
    let images = images?;
    geometry?;
    drop(encoded);
    if out.triangles.is_empty() {
        let why = if out.skipped_modes.is_empty() {
            " (no triangle primitives in the scene)".to_string()
        } else {
            format!(
                " (unsupported primitive modes only: {})",
                out.skipped_modes.join(", ")
            )
        };
        return Err(MeshError::NoTriangles(why));
    }
    if !out.skipped_modes.is_empty() {
        tracing::warn!(modes = ?out.skipped_modes, "glTF primitives that are not triangles were skipped");
    }
    let mut attributes = Attributes::default();
    if !out.colors.is_empty() {
        attributes.colors = Some(out.colors);
    }
    if out.any_material {
        // The document's materials in order; glTF's default material after them when a
        // primitive has none (its id: the table's length).
        attributes.set_materials(table, out.material);
        if !out.uv.is_empty() {
            attributes.uv = Some(super::Uv::Vertices(out.uv));
            attributes.images = images;
        }
    }
    Mesh::new(out.positions, out.triangles)?.with_attributes(attributes)
}

fn read_uri(uri: &str, external: &ExternalResources) -> Result<Vec<u8>, MeshError> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let (_, payload) = rest
            .split_once(";base64,")
            .ok_or_else(|| malformed("glTF", "only base64 data URIs are supported for buffers"))?;
        return base64::engine::general_purpose::STANDARD
            .decode(payload.trim())
            .map_err(|e| malformed("glTF", format!("bad base64 in a data URI: {e}")));
    }
    if let ExternalResources::Archive(a) = external {
        return a
            .get(&percent_decode(uri))
            .map(<[u8]>::to_vec)
            .ok_or_else(|| {
                malformed(
                    "glTF",
                    format!("buffer {uri:?} is not in the uploaded archive"),
                )
            });
    }
    let ExternalResources::BesideFile(dir) = external else {
        return Err(MeshError::ExternalRefused {
            uri: uri.to_string(),
        });
    };
    let Some(path) = super::beside(dir, &percent_decode(uri)) else {
        return Err(MeshError::ExternalRefused {
            uri: uri.to_string(),
        });
    };
    std::fs::read(&path)
        .map_err(|e| MeshError::Io(format!("{} (glTF buffer): {e}", path.display())))
}

fn percent_decode(s: &str) -> String {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' && i + 2 < b.len() {
            let hex = |c: u8| (c as char).to_digit(16);
            if let (Some(h), Some(l)) = (hex(b[i + 1]), hex(b[i + 2])) {
                out.push((h * 16 + l) as u8);
                i += 3;
                continue;
            }
        }
        out.push(b[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

struct Collector {
    positions: Vec<[f64; 3]>,
    triangles: Vec<[u32; 3]>,
    skipped_modes: Vec<String>,
    /// `COLOR_0` per position (white for a primitive without it), once a primitive had it;
    /// empty while none has.
    colors: Vec<[f32; 4]>,
    /// Each triangle's material index ([`NO_MATERIAL`]: none); `any_material`: some had one.
    material: Vec<u16>,
    any_material: bool,
    /// Each material's texture coordinates ([`gltf_materials::materials`]).
    specs: Vec<Option<UvSpec>>,
    /// Each position's texture coordinates (zeros without a texture), once a primitive's
    /// material had a texture; empty while none has.
    uv: Vec<[f32; 2]>,
}

impl Collector {
    fn mesh(
        &mut self,
        mesh: &gltf::Mesh,
        m: &Mat4,
        buffers: &[Cow<[u8]>],
    ) -> Result<(), MeshError> {
        for prim in mesh.primitives() {
            let mode = prim.mode();
            if !matches!(
                mode,
                Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
            ) {
                self.skipped_modes.push(format!("{mode:?}"));
                continue;
            }
            let where_ = format!("mesh {} primitive {}", mesh.index(), prim.index());
            let pos = prim
                .get(&gltf::Semantic::Positions)
                .ok_or_else(|| malformed("glTF", format!("{where_} has no POSITION attribute")))?;
            check_accessor(&pos, DataType::F32, &[Dimensions::Vec3], &where_)?;
            let idx = prim.indices();
            if let Some(a) = &idx {
                check_accessor(a, a.data_type(), &[Dimensions::Scalar], &where_)?;
                if !matches!(a.data_type(), DataType::U8 | DataType::U16 | DataType::U32) {
                    return Err(malformed(
                        "glTF",
                        format!("{where_}: indices must be unsigned integers"),
                    ));
                }
            }
            let reader = prim.reader(|b| buffers.get(b.index()).map(|d| &d[..]));
            let positions: Vec<[f32; 3]> = reader
                .read_positions()
                .ok_or_else(|| {
                    malformed(
                        "glTF",
                        format!("{where_}: POSITION accessor lies outside its buffer"),
                    )
                })?
                .collect();
            // A triangle list's indices are read straight into triangles; strips and fans
            // unroll theirs below.
            let mut tris: Vec<[u32; 3]> = Vec::new();
            let mut indices: Vec<u32> = Vec::new();
            match (reader.read_indices(), mode) {
                (None, _) if idx.is_some() => {
                    return Err(malformed(
                        "glTF",
                        format!("{where_}: index accessor lies outside its buffer"),
                    ));
                }
                (Some(i), Mode::Triangles) => {
                    let mut it = i.into_u32();
                    tris.reserve(it.size_hint().0 / 3);
                    while let (Some(a), Some(b), Some(c)) = (it.next(), it.next(), it.next()) {
                        tris.push([a, b, c]);
                    }
                }
                (None, Mode::Triangles) => {
                    let n = positions.len() as u32 / 3;
                    tris.extend((0..n).map(|k| [3 * k, 3 * k + 1, 3 * k + 2]));
                }
                (Some(i), _) => indices = i.into_u32().collect(),
                (None, _) => indices = (0..positions.len() as u32).collect(),
            }
            let out_of_range = |i: &&u32| **i as usize >= positions.len();
            if let Some(&bad) = (tris.iter().flatten().find(out_of_range))
                .or_else(|| indices.iter().find(out_of_range))
            {
                return Err(MeshError::IndexOutOfRange {
                    triangle: 0,
                    index: bad as u64,
                    vertices: positions.len(),
                });
            }
            let colors: Option<Vec<[f32; 4]>> = match prim.get(&gltf::Semantic::Colors(0)) {
                None => None,
                Some(a) => {
                    // glTF's COLOR_0: float, or normalized unsigned bytes or shorts; RGB or RGBA.
                    let ty = a.data_type();
                    if !matches!(ty, DataType::F32 | DataType::U8 | DataType::U16) {
                        return Err(malformed(
                            "glTF",
                            format!(
                                "{where_}: COLOR_0 is {ty:?}, not float, unsigned byte or unsigned short"
                            ),
                        ));
                    }
                    check_accessor(&a, ty, &[Dimensions::Vec3, Dimensions::Vec4], &where_)?;
                    if a.count() != positions.len() {
                        return Err(malformed(
                            "glTF",
                            format!(
                                "{where_}: COLOR_0 has {} entries for {} positions",
                                a.count(),
                                positions.len()
                            ),
                        ));
                    }
                    Some(
                        reader
                            .read_colors(0)
                            .ok_or_else(|| {
                                malformed(
                                    "glTF",
                                    format!("{where_}: COLOR_0 accessor lies outside its buffer"),
                                )
                            })?
                            .into_rgba_f32()
                            // Floats outside [0, 1] (the specification's range) are clamped.
                            .map(|c| c.map(|v| if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) }))
                            .collect(),
                    )
                }
            };
            // Held only once a primitive has colours (the earlier ones then white).
            match colors {
                Some(c) => {
                    if self.colors.is_empty() {
                        self.colors = vec![[1.0f32; 4]; self.positions.len()];
                    }
                    self.colors.extend(c);
                }
                None if !self.colors.is_empty() => self
                    .colors
                    .extend(std::iter::repeat_n([1.0f32; 4], positions.len())),
                None => {}
            }
            let material = match prim.material().index() {
                Some(i) => {
                    self.any_material = true;
                    i as u16
                }
                None => NO_MATERIAL,
            };
            let base = self.positions.len() as u32;
            self.positions
                .extend(positions.iter().map(|p| transform(m, p)));
            match mode {
                Mode::Triangles => {}
                Mode::TriangleStrip => super::unroll_strip(&indices, &mut tris),
                _ => super::fan(&indices, &mut tris),
            }
            let spec = self.specs.get(usize::from(material)).copied().flatten();
            match spec {
                Some(spec) => {
                    // Read straight into the mesh's array (per position, through `spec`).
                    if self.uv.is_empty() {
                        self.uv = vec![[0.0; 2]; base as usize];
                    }
                    let read = reader.read_tex_coords(spec.set).map(|t| {
                        self.uv.extend(t.into_f32().map(|c| spec.apply(c)));
                    });
                    if read.is_none() || self.uv.len() != self.positions.len() {
                        return Err(malformed(
                            "glTF",
                            format!(
                                "{where_}: its material's texture reads TEXCOORD_{}, which the primitive lacks (or has not one per position)",
                                spec.set
                            ),
                        ));
                    }
                }
                None if !self.uv.is_empty() => self
                    .uv
                    .extend(std::iter::repeat_n([0.0f32; 2], positions.len())),
                None => {}
            }
            self.material
                .extend(std::iter::repeat_n(material, tris.len()));
            if self.triangles.is_empty() && base == 0 {
                // The first primitive's triangles are kept as they are (no copy).
                self.triangles = tris;
            } else {
                self.triangles
                    .extend(tris.into_iter().map(|t| t.map(|i| base + i)));
            }
        }
        Ok(())
    }
}

fn check_accessor(
    a: &gltf::Accessor,
    ty: DataType,
    dims: &[Dimensions],
    where_: &str,
) -> Result<(), MeshError> {
    if a.data_type() != ty || !dims.contains(&a.dimensions()) {
        return Err(malformed(
            "glTF",
            format!(
                "{where_}: accessor {} is {:?} {:?}, expected {:?} {:?}",
                a.index(),
                a.data_type(),
                a.dimensions(),
                ty,
                dims
            ),
        ));
    }
    if a.sparse().is_some() {
        return Err(malformed(
            "glTF",
            format!("{where_}: sparse accessors are not supported"),
        ));
    }
    if a.count() == 0 {
        return Err(malformed(
            "glTF",
            format!("{where_}: accessor {} is empty", a.index()),
        ));
    }
    let elem = a.size();
    if let Some(view) = a.view() {
        let stride = view.stride().unwrap_or(elem);
        let need = (a.count() - 1)
            .checked_mul(stride)
            .and_then(|v| v.checked_add(elem))
            .and_then(|v| v.checked_add(a.offset()));
        if stride < elem || need.is_none_or(|n| n > view.length()) {
            return Err(malformed(
                "glTF",
                format!(
                    "{where_}: accessor {} does not fit its bufferView",
                    a.index()
                ),
            ));
        }
        if view
            .offset()
            .checked_add(view.length())
            .is_none_or(|e| e > view.buffer().length())
        {
            return Err(malformed(
                "glTF",
                format!(
                    "{where_}: bufferView {} does not fit its buffer",
                    view.index()
                ),
            ));
        }
    } else {
        return Err(malformed(
            "glTF",
            format!("{where_}: accessor {} has no bufferView", a.index()),
        ));
    }
    Ok(())
}

fn mul(a: &Mat4, b: &Mat4) -> Mat4 {
    // Column-major: m[col][row].
    let mut r = [[0.0; 4]; 4];
    for c in 0..4 {
        for row in 0..4 {
            r[c][row] = (0..4).map(|k| a[k][row] * b[c][k]).sum();
        }
    }
    r
}

fn transform(m: &Mat4, p: &[f32; 3]) -> [f64; 3] {
    let v = [p[0] as f64, p[1] as f64, p[2] as f64, 1.0];
    let mut o = [0.0; 4];
    for (row, out) in o.iter_mut().enumerate() {
        *out = (0..4).map(|k| m[k][row] * v[k]).sum();
    }
    if o[3] != 1.0 && o[3] != 0.0 {
        [o[0] / o[3], o[1] / o[3], o[2] / o[3]]
    } else {
        [o[0], o[1], o[2]]
    }
}
