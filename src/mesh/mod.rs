//! Triangle meshes: loading (OBJ, glTF/GLB, STL, PLY, each optionally gzip'd), validation and
//! diagnostics. A [`Mesh`] that exists is valid: at least one triangle, finite coordinates of
//! sane size, every index in range. Nothing here knows about grids or voxels.

pub mod archive;
mod attributes;
pub mod binary;
pub mod cost;
mod degenerate;
mod diagnostics;
mod edges;
mod gltf;
mod gltf_materials;
mod obj;
mod ply;
mod stl;
mod stream;
#[cfg(test)]
mod streaming_tests;
pub mod texture;

use std::path::{Path, PathBuf};

use rayon::prelude::*;

use stream::Stream;

pub use attributes::{Attributes, Material, Uv};
pub use diagnostics::MeshDiagnostics;
pub(crate) use diagnostics::merged_ids;
pub(crate) use edges::edge_groups;

/// Coordinates beyond this magnitude are refused: f64 has no sub-unit precision left there and
/// such values are almost always garbage (uninitialised floats, unit mix-ups).
pub const MAX_ABS_COORDINATE: f64 = 1e15;

/// A triangle mesh: positions and triangles indexing them.
#[derive(Clone, Debug, PartialEq)]
pub struct Mesh {
    positions: Vec<[f64; 3]>,
    triangles: Vec<[u32; 3]>,
    /// Degenerate triangles the loader dropped as copies of one it kept (`degenerate`).
    dropped: u64,
    /// Colours and materials the loader kept (`attributes`).
    attributes: Attributes,
}

#[derive(Clone, Debug, thiserror::Error, PartialEq)]
pub enum MeshError {
    #[error("cannot read {0}")]
    Io(String),
    #[error(
        "cannot tell the mesh format; use a known extension (.obj .gltf .glb .stl .ply, optionally .gz) or name the format"
    )]
    UnknownFormat,
    #[error("{format}: {detail}")]
    Malformed {
        format: &'static str,
        detail: String,
    },
    #[error("the mesh has no triangles{0}")]
    NoTriangles(String),
    #[error("vertex {vertex} has a non-finite coordinate {value:?}")]
    NonFinite { vertex: usize, value: [f64; 3] },
    #[error("vertex {vertex} has coordinate {value:e}, beyond the limit of ±{limit:e}", limit = MAX_ABS_COORDINATE)]
    HugeCoordinate { vertex: usize, value: f64 },
    #[error("triangle {triangle} uses vertex index {index}, but the mesh has {vertices} vertices")]
    IndexOutOfRange {
        triangle: usize,
        index: u64,
        vertices: usize,
    },
    #[error(
        "glTF buffer {uri:?} points outside the file; external resources are not read here (embed buffers as data URIs or upload a .glb)"
    )]
    ExternalRefused { uri: String },
    #[error("the mesh has {count} triangles, over the limit of {limit}")]
    TooManyTriangles { count: usize, limit: usize },
    #[error("the decompressed mesh is larger than the limit of {0} bytes")]
    TooLarge(u64),
    /// A count that the file declares before its data (a binary STL's triangle count, a PLY
    /// element count, the glTF accessors of a scene) or that it reaches while being read (OBJ
    /// and ASCII STL lines, PLY faces), over what [`LoadOptions`] allows: the file is refused
    /// before the data it announces is read or allocated. The same kind of problem as
    /// [`MeshError::TooManyTriangles`]: vertices are bounded by [`LoadOptions::max_vertices`],
    /// derived from the triangle limit.
    #[error("{format}: {count} {what}, over the limit of {limit}")]
    CountOverLimit {
        format: &'static str,
        /// What was counted, e.g. "triangles declared in the header".
        what: &'static str,
        count: u64,
        limit: u64,
    },
}

/// `dir` joined with the relative path `rel`, when `rel` stays inside `dir` (only plain names
/// and `.`: no `..`, no root, no drive or URI scheme); the rule for every file a mesh read from
/// disk refers to (glTF buffers, OBJ material libraries and textures).
fn beside(dir: &Path, rel: &str) -> Option<PathBuf> {
    let path = Path::new(rel);
    let inside = !rel.contains(':')
        && path.components().all(|c| {
            matches!(
                c,
                std::path::Component::Normal(_) | std::path::Component::CurDir
            )
        });
    inside.then(|| dir.join(path))
}

fn malformed(format: &'static str, detail: impl Into<String>) -> MeshError {
    MeshError::Malformed {
        format,
        detail: detail.into(),
    }
}

crate::named_enum! {
    /// Mesh file formats.
    pub enum Format: "mesh format" {
        Obj = "obj",
        Gltf = "gltf",
        Glb = "glb",
        Stl = "stl",
        Ply = "ply",
    }
}

impl Format {
    /// The format named `s`, case-insensitively (file extensions and `--format` are matched
    /// this way; `FromStr` is exact, as for every named set).
    pub fn from_name(s: &str) -> Option<Format> {
        Format::ALL
            .into_iter()
            .find(|f| f.name().eq_ignore_ascii_case(s))
    }

    /// From a file name, ignoring a trailing `.gz`.
    pub fn from_path(path: &Path) -> Option<Format> {
        let name = path.file_name()?.to_str()?.to_ascii_lowercase();
        let name = name.strip_suffix(".gz").unwrap_or(&name);
        Format::from_name(Path::new(name).extension()?.to_str()?)
    }

    /// From the first bytes of an (uncompressed) file.
    pub fn sniff(bytes: &[u8]) -> Option<Format> {
        if bytes.starts_with(b"glTF") {
            return Some(Format::Glb);
        }
        if bytes.starts_with(b"ply\n") || bytes.starts_with(b"ply\r\n") {
            return Some(Format::Ply);
        }
        if stl::looks_binary(bytes) {
            return Some(Format::Stl);
        }
        let head = &bytes[..bytes.len().min(4096)];
        let text = String::from_utf8_lossy(head);
        let t = text.trim_start();
        if t.starts_with('{') {
            return Some(Format::Gltf);
        }
        if t.starts_with("solid") && text.contains("facet") {
            return Some(Format::Stl);
        }
        if text
            .lines()
            .any(|l| l.starts_with("v ") || l.starts_with("f "))
        {
            return Some(Format::Obj);
        }
        None
    }
}

/// Whether a glTF may read buffers from files.
#[derive(Clone, Debug, PartialEq)]
pub enum ExternalResources {
    /// Only GLB chunks and `data:` URIs; any other URI is an error. The service always uses this.
    Deny,
    /// Relative paths that stay inside this directory (the one holding the .gltf) may be read.
    BesideFile(PathBuf),
    /// The other files of a zip upload, by paths relative to the mesh's place in it.
    Archive(std::sync::Arc<archive::Archive>),
}

#[derive(Clone, Debug)]
pub struct LoadOptions {
    pub external: ExternalResources,
    pub max_triangles: usize,
    /// Limit on the bytes a `.gz` may expand to.
    pub max_decompressed_bytes: u64,
    /// Limit on the bytes of a mesh's decoded textures (4 a texel), all images together.
    pub max_texture_bytes: u64,
    /// Whether base colour textures are read and decoded (glTF images, OBJ `map_Kd`): only
    /// colour needs them. Without, materials keep their names and base colours, no texture is
    /// read (nor its limit spent, nor a bad one refused) and the parse's memory estimate counts
    /// none ([`cost::estimate`]).
    pub textures: bool,
}

impl LoadOptions {
    /// Vertices a mesh may have: three per allowed triangle (a triangle soup, as STL is) and
    /// 65,536 more that no triangle needs to use.
    pub fn max_vertices(&self) -> usize {
        self.max_triangles.saturating_mul(3).saturating_add(1 << 16)
    }
}

impl Default for LoadOptions {
    fn default() -> Self {
        LoadOptions {
            external: ExternalResources::Deny,
            max_triangles: crate::limits::Limits::LOCAL.max_triangles,
            max_decompressed_bytes: crate::limits::Limits::LOCAL.max_decompressed_bytes,
            max_texture_bytes: crate::limits::Limits::LOCAL.max_texture_bytes,
            textures: true,
        }
    }
}

/// Reads a mesh file; the format comes from the extension, else from the content. Buffers of a
/// `.gltf` may be read from beside it.
pub fn load_file(path: &Path, max_triangles: usize) -> Result<Mesh, MeshError> {
    let bytes =
        std::fs::read(path).map_err(|e| MeshError::Io(format!("{}: {e}", path.display())))?;
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let opts = LoadOptions {
        external: ExternalResources::BesideFile(dir),
        max_triangles,
        ..Default::default()
    };
    load_bytes(&bytes, Format::from_path(path), &opts)
}

/// Parses mesh bytes (gzip'd or not). `format` wins over sniffing when given.
///
/// Every count a file declares is checked against `opts` before the data it announces is
/// allocated, and a gzip'd file is decoded only as far as the loader reads it, never past
/// `max_decompressed_bytes`: its format is sniffed and its header checked on the first 64 KiB,
/// and OBJ, ASCII STL and PLY are parsed as they are decoded, so a decompression bomb costs
/// the memory of the mesh it holds (within the limits), not of its decoded text.
pub fn load_bytes(
    bytes: &[u8],
    format: Option<Format>,
    opts: &LoadOptions,
) -> Result<Mesh, MeshError> {
    load_bytes_as(bytes, format, opts).map(|(m, _)| m)
}

/// [`load_bytes`], with the format the mesh was read as (`format`, else sniffed: of the mesh
/// inside a gzip'd file, not `gzip`).
pub fn load_bytes_as(
    bytes: &[u8],
    format: Option<Format>,
    opts: &LoadOptions,
) -> Result<(Mesh, Format), MeshError> {
    if archive::is_zip(bytes) {
        let (data, named, _, files) = archive::open(bytes, opts.max_decompressed_bytes)?;
        if archive::is_zip(&data) {
            return Err(MeshError::Malformed {
                format: "zip",
                detail: "the mesh in the archive is itself a zip".into(),
            });
        }
        let inner = LoadOptions {
            external: ExternalResources::Archive(files),
            ..opts.clone()
        };
        return load_stream(
            &mut Stream::of(&data, opts.max_decompressed_bytes),
            named.or(format),
            &inner,
        );
    }
    load_stream(
        &mut Stream::of(bytes, opts.max_decompressed_bytes),
        format,
        opts,
    )
}

/// The container mesh bytes come in, as a volume's `source.compression` names it: `gzip`,
/// `zip`, or none.
pub fn container(bytes: &[u8]) -> Option<String> {
    if is_gzip(bytes) {
        Some("gzip".into())
    } else if archive::is_zip(bytes) {
        Some("zip".into())
    } else {
        None
    }
}

/// Whether mesh bytes are gzip'd (the loaders inflate them).
pub fn is_gzip(bytes: &[u8]) -> bool {
    bytes.starts_with(&[0x1f, 0x8b])
}

fn load_stream(
    s: &mut Stream,
    format: Option<Format>,
    opts: &LoadOptions,
) -> Result<(Mesh, Format), MeshError> {
    let format = match format {
        Some(f) => f,
        None => sniff_stream(s)?.ok_or(MeshError::UnknownFormat)?,
    };
    let mut mesh = match format {
        Format::Obj => obj::parse(s, opts)?,
        Format::Gltf | Format::Glb => gltf::parse(s, opts)?,
        Format::Stl => stl::parse(s, opts)?,
        Format::Ply => ply::parse(s, opts)?,
    };
    // STL drops its copies as it reads (a triangle soup: a dropped triangle's corners are not
    // kept either); the indexed formats here, where only the triangle goes.
    let mut repeats = degenerate::Repeats::default();
    repeats.filter(
        &mesh.positions,
        &mut mesh.triangles,
        mesh.attributes.material.as_mut(),
        match mesh.attributes.uv.as_mut() {
            Some(Uv::Corners(c)) => Some(c),
            // Per vertex: dropping a triangle leaves its vertices' coordinates as they are.
            _ => None,
        },
    );
    mesh.dropped += repeats.dropped;
    if mesh.triangles.len() > opts.max_triangles {
        return Err(MeshError::TooManyTriangles {
            count: mesh.triangles.len(),
            limit: opts.max_triangles,
        });
    }
    Ok((mesh, format))
}

/// How much of a compressed file is decoded to sniff its format and read its header.
const HEAD: usize = 64 << 10;

/// [`Format::sniff`] on the whole file when it is at hand, else on its first [`HEAD`] bytes,
/// where a binary STL (told apart by its length otherwise) is recognised by its records.
fn sniff_stream(s: &mut Stream) -> Result<Option<Format>, MeshError> {
    s.fill_to(HEAD)?;
    let complete = s.at_end();
    let head = s.available();
    Ok(Format::sniff(head)
        .or_else(|| (!complete && stl::plausible_binary_head(head)).then_some(Format::Stl)))
}

impl Mesh {
    /// Builds a validated mesh.
    pub fn new(positions: Vec<[f64; 3]>, triangles: Vec<[u32; 3]>) -> Result<Mesh, MeshError> {
        if triangles.is_empty() {
            return Err(MeshError::NoTriangles(String::new()));
        }
        // The first bad vertex and the first bad triangle, looked for in parallel (a big mesh
        // has millions of each), reported as a front-to-back scan would.
        if let Some(i) = positions
            .par_iter()
            .with_min_len(crate::PAR_PIECE)
            .position_first(bad_position)
        {
            check_position(i, &positions[i])?;
        }
        let n = positions.len();
        let out = |tri: &[u32; 3]| tri.iter().any(|&i| i as usize >= n);
        if let Some(t) = triangles
            .par_iter()
            .with_min_len(crate::PAR_PIECE)
            .position_first(out)
        {
            let i = *triangles[t].iter().find(|&&i| i as usize >= n).unwrap();
            return Err(MeshError::IndexOutOfRange {
                triangle: t,
                index: i as u64,
                vertices: n,
            });
        }
        Ok(Mesh {
            positions,
            triangles,
            dropped: 0,
            attributes: Attributes::default(),
        })
    }

    /// This mesh with `attributes` (checked against it: [`Attributes::check`]).
    pub fn with_attributes(mut self, attributes: Attributes) -> Result<Mesh, MeshError> {
        attributes.check(self.positions.len(), self.triangles.len())?;
        self.attributes = attributes;
        Ok(self)
    }

    /// The colours and materials its file carried.
    pub fn attributes(&self) -> &Attributes {
        &self.attributes
    }

    /// A mesh whose loader has made the checks of [`Mesh::new`] itself: at least one
    /// triangle, [`check_position`] on every position, every index in range.
    fn checked(positions: Vec<[f64; 3]>, triangles: Vec<[u32; 3]>) -> Mesh {
        debug_assert_eq!(
            Mesh::new(positions.clone(), triangles.clone()).as_ref(),
            Ok(&Mesh {
                positions: positions.clone(),
                triangles: triangles.clone(),
                dropped: 0,
                attributes: Attributes::default(),
            })
        );
        Mesh {
            positions,
            triangles,
            dropped: 0,
            attributes: Attributes::default(),
        }
    }

    pub fn positions(&self) -> &[[f64; 3]] {
        &self.positions
    }
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }
    /// Degenerate triangles dropped at load as copies of a segment or point already kept
    /// (see `degenerate`); 0 for a mesh built with [`Mesh::new`].
    pub fn dropped_triangles(&self) -> u64 {
        self.dropped
    }
    pub fn triangle(&self, t: usize) -> [[f64; 3]; 3] {
        self.triangles[t].map(|i| self.positions[i as usize])
    }

    /// Bounding box of the vertices used by triangles.
    pub fn bounds(&self) -> ([f64; 3], [f64; 3]) {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for tri in &self.triangles {
            for &i in tri {
                let p = self.positions[i as usize];
                for a in 0..3 {
                    lo[a] = lo[a].min(p[a]);
                    hi[a] = hi[a].max(p[a]);
                }
            }
        }
        (lo, hi)
    }

    pub fn diagnostics(&self) -> MeshDiagnostics {
        MeshDiagnostics::of(self)
    }

    /// The same mesh with every triangle's orientation reversed.
    pub fn flipped(&self) -> Mesh {
        let triangles = self.triangles.iter().map(|t| [t[0], t[2], t[1]]).collect();
        Mesh {
            positions: self.positions.clone(),
            triangles,
            dropped: self.dropped,
            attributes: self.attributes.clone(),
        }
    }
}

/// Whether [`Mesh::new`] refuses a position: a coordinate that is not finite or is huge.
#[inline]
fn bad_position(p: &[f64; 3]) -> bool {
    p.iter()
        .any(|c| !c.is_finite() || c.abs() > MAX_ABS_COORDINATE)
}

/// The error of [`Mesh::new`] for position `i`, if it has one.
fn check_position(i: usize, p: &[f64; 3]) -> Result<(), MeshError> {
    if p.iter().any(|c| !c.is_finite()) {
        return Err(MeshError::NonFinite {
            vertex: i,
            value: *p,
        });
    }
    if let Some(&c) = p.iter().find(|c| c.abs() > MAX_ABS_COORDINATE) {
        return Err(MeshError::HugeCoordinate {
            vertex: i,
            value: c,
        });
    }
    Ok(())
}

/// Fan-triangulates a polygon of vertex indices (what OBJ and PLY readers do with n-gons).
fn fan(poly: &[u32], out: &mut Vec<[u32; 3]>) {
    for i in 1..poly.len().saturating_sub(1) {
        out.push([poly[0], poly[i], poly[i + 1]]);
    }
}

/// Unrolls a triangle strip; `u32::MAX` (PLY's -1) restarts the strip. Odd triangles are
/// reversed so the strip keeps one orientation.
fn unroll_strip(strip: &[u32], out: &mut Vec<[u32; 3]>) {
    for run in strip.split(|&i| i == u32::MAX) {
        for i in 0..run.len().saturating_sub(2) {
            let (a, b, c) = (run[i], run[i + 1], run[i + 2]);
            out.push(if i % 2 == 0 { [a, b, c] } else { [b, a, c] });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sniffing() {
        assert_eq!(Format::sniff(b"glTF\x02\0\0\0"), Some(Format::Glb));
        assert_eq!(Format::sniff(b"ply\nformat ascii 1.0\n"), Some(Format::Ply));
        assert_eq!(Format::sniff(b"  {\"asset\":{}}"), Some(Format::Gltf));
        assert_eq!(
            Format::sniff(b"solid x\nfacet normal 0 0 1\n"),
            Some(Format::Stl)
        );
        assert_eq!(Format::sniff(b"# c\nv 0 0 0\n"), Some(Format::Obj));
        assert_eq!(Format::sniff(b"hello"), None);
        assert_eq!(
            Format::from_path(Path::new("a/b.OBJ.gz")),
            Some(Format::Obj)
        );
        assert_eq!(Format::from_path(Path::new("b.glb")), Some(Format::Glb));
        assert_eq!(Format::from_path(Path::new("b.txt")), None);
    }

    #[test]
    fn validation() {
        let p = vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        assert!(Mesh::new(p.clone(), vec![[0, 1, 2]]).is_ok());
        assert!(matches!(
            Mesh::new(p.clone(), vec![]),
            Err(MeshError::NoTriangles(_))
        ));
        assert!(matches!(
            Mesh::new(p.clone(), vec![[0, 1, 3]]),
            Err(MeshError::IndexOutOfRange { index: 3, .. })
        ));
        let mut q = p.clone();
        q[1][2] = f64::NAN;
        assert!(matches!(
            Mesh::new(q, vec![[0, 1, 2]]),
            Err(MeshError::NonFinite { vertex: 1, .. })
        ));
        let mut q = p;
        q[2][0] = 1e300;
        assert!(matches!(
            Mesh::new(q, vec![[0, 1, 2]]),
            Err(MeshError::HugeCoordinate { vertex: 2, .. })
        ));
    }

    #[test]
    fn strips_and_fans() {
        let mut out = vec![];
        unroll_strip(&[0, 1, 2, 3, u32::MAX, 4, 5, 6], &mut out);
        assert_eq!(out, vec![[0, 1, 2], [2, 1, 3], [4, 5, 6]]);
        out.clear();
        fan(&[0, 1, 2, 3, 4], &mut out);
        assert_eq!(out, vec![[0, 1, 2], [0, 2, 3], [0, 3, 4]]);
    }
}
