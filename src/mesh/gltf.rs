//! glTF 2.0 (`.gltf` JSON and `.glb`): every triangle primitive of the default scene (all scenes
//! when none is marked default, every mesh when there are no scenes), node transforms applied,
//! skins ignored (bind pose). Buffers come from the GLB chunk or `data:` URIs; other URIs are read
//! only when [`ExternalResources::BesideFile`] allows it, and never outside that directory.

use std::path::{Component, Path};

use base64::Engine as _;
use gltf::accessor::{DataType, Dimensions};
use gltf::mesh::Mode;

use super::{ExternalResources, Mesh, MeshError, malformed};

type Mat4 = [[f64; 4]; 4];
const IDENTITY: Mat4 = [
    [1., 0., 0., 0.],
    [0., 1., 0., 0.],
    [0., 0., 1., 0.],
    [0., 0., 0., 1.],
];
/// Node hierarchies deeper than this are refused (they are cycles or garbage).
const MAX_DEPTH: usize = 256;

pub(super) fn parse(bytes: &[u8], external: &ExternalResources) -> Result<Mesh, MeshError> {
    // The gltf crate asserts on some malformed accessors; a panic must become an error, not a
    // dead worker.
    std::panic::catch_unwind(|| parse_inner(bytes, external))
        .unwrap_or_else(|_| Err(malformed("glTF", "malformed accessor or buffer data")))
}

fn parse_inner(bytes: &[u8], external: &ExternalResources) -> Result<Mesh, MeshError> {
    // POSITION min/max are required by the spec but often missing in real files, and nothing here
    // needs them: accept a file whose only validation errors are those.
    let doc = match gltf::Gltf::from_slice(bytes) {
        Ok(d) => d,
        Err(gltf::Error::Validation(errs))
            if errs.iter().all(|(p, _)| {
                let p = p.to_string();
                p.ends_with(".min") || p.ends_with(".max")
            }) =>
        {
            gltf::Gltf::from_slice_without_validation(bytes)
                .map_err(|e| malformed("glTF", e.to_string()))?
        }
        Err(e) => return Err(malformed("glTF", e.to_string())),
    };
    let mut buffers: Vec<Vec<u8>> = Vec::new();
    for b in doc.buffers() {
        let data = match b.source() {
            gltf::buffer::Source::Bin => doc.blob.clone().ok_or_else(|| {
                malformed(
                    "glTF",
                    format!(
                        "buffer {} refers to a GLB BIN chunk that is missing",
                        b.index()
                    ),
                )
            })?,
            gltf::buffer::Source::Uri(uri) => read_uri(uri, external)?,
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
    };
    let scenes: Vec<_> = match doc.default_scene() {
        Some(s) => vec![s],
        None => doc.scenes().collect(),
    };
    if scenes.is_empty() {
        for m in doc.meshes() {
            out.mesh(&m, &IDENTITY, &buffers)?;
        }
    } else {
        for s in scenes {
            for n in s.nodes() {
                out.node(&n, &IDENTITY, &buffers, 0)?;
            }
        }
    }
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
    Mesh::new(out.positions, out.triangles)
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
    let ExternalResources::BesideFile(dir) = external else {
        return Err(MeshError::ExternalRefused {
            uri: uri.to_string(),
        });
    };
    let decoded = percent_decode(uri);
    let rel = Path::new(&decoded);
    let inside = !decoded.contains(':')
        && rel
            .components()
            .all(|c| matches!(c, Component::Normal(_) | Component::CurDir));
    if !inside {
        return Err(MeshError::ExternalRefused {
            uri: uri.to_string(),
        });
    }
    let path = dir.join(rel);
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
}

impl Collector {
    fn node(
        &mut self,
        node: &gltf::Node,
        parent: &Mat4,
        buffers: &[Vec<u8>],
        depth: usize,
    ) -> Result<(), MeshError> {
        if depth > MAX_DEPTH {
            return Err(malformed(
                "glTF",
                format!("node hierarchy deeper than {MAX_DEPTH} (a cycle?)"),
            ));
        }
        let local = node.transform().matrix().map(|c| c.map(|v| v as f64));
        let world = mul(parent, &local);
        if let Some(m) = node.mesh() {
            self.mesh(&m, &world, buffers)?;
        }
        for c in node.children() {
            self.node(&c, &world, buffers, depth + 1)?;
        }
        Ok(())
    }

    fn mesh(&mut self, mesh: &gltf::Mesh, m: &Mat4, buffers: &[Vec<u8>]) -> Result<(), MeshError> {
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
            let reader = prim.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
            let positions: Vec<[f32; 3]> = reader
                .read_positions()
                .ok_or_else(|| {
                    malformed(
                        "glTF",
                        format!("{where_}: POSITION accessor lies outside its buffer"),
                    )
                })?
                .collect();
            let indices: Vec<u32> = match reader.read_indices() {
                Some(i) => i.into_u32().collect(),
                None if idx.is_some() => {
                    return Err(malformed(
                        "glTF",
                        format!("{where_}: index accessor lies outside its buffer"),
                    ));
                }
                None => (0..positions.len() as u32).collect(),
            };
            if let Some(&bad) = indices.iter().find(|&&i| i as usize >= positions.len()) {
                return Err(MeshError::IndexOutOfRange {
                    triangle: 0,
                    index: bad as u64,
                    vertices: positions.len(),
                });
            }
            let base = self.positions.len() as u32;
            self.positions
                .extend(positions.iter().map(|p| transform(m, p)));
            let mut tris = Vec::new();
            match mode {
                Mode::Triangles => tris.extend(indices.chunks_exact(3).map(|c| [c[0], c[1], c[2]])),
                Mode::TriangleStrip => super::unroll_strip(&indices, &mut tris),
                _ => super::fan(&indices, &mut tris),
            }
            self.triangles
                .extend(tris.into_iter().map(|t| t.map(|i| base + i)));
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
