//! Mesh files: OBJ (text, positions as Rust's shortest round-trip decimals), binary STL
//! (float32, as the format has it), binary little-endian PLY (float64 positions, uint32
//! indices) and GLB (binary glTF 2.0: one mesh of one indexed triangle primitive, float32
//! positions with their bounds, uint32 indices). Written to any `Write`, piece by piece.

use std::io::{self, Write};

use super::TriMesh;

/// The mesh formats written.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MeshFormat {
    Obj,
    Stl,
    Ply,
    Glb,
}

impl MeshFormat {
    pub const ALL: [MeshFormat; 4] = [
        MeshFormat::Obj,
        MeshFormat::Stl,
        MeshFormat::Ply,
        MeshFormat::Glb,
    ];

    pub fn as_str(self) -> &'static str {
        match self {
            MeshFormat::Obj => "obj",
            MeshFormat::Stl => "stl",
            MeshFormat::Ply => "ply",
            MeshFormat::Glb => "glb",
        }
    }

    pub fn media_type(self) -> &'static str {
        match self {
            MeshFormat::Obj => "model/obj",
            MeshFormat::Stl => "model/stl",
            MeshFormat::Ply => "model/ply",
            MeshFormat::Glb => "model/gltf-binary",
        }
    }

    pub fn parse(s: &str) -> Result<MeshFormat, String> {
        MeshFormat::ALL
            .into_iter()
            .find(|f| f.as_str() == s)
            .ok_or_else(|| format!("mesh format must be one of glb, obj, stl, ply, got {s:?}"))
    }

    /// The format named by a file's extension.
    pub fn of_path(p: &std::path::Path) -> Result<MeshFormat, String> {
        let ext = p
            .extension()
            .and_then(|e| e.to_str())
            .unwrap_or("")
            .to_ascii_lowercase();
        MeshFormat::parse(&ext).map_err(|_| {
            format!(
                "{}: the mesh format is taken from the extension: .glb, .obj, .stl or .ply",
                p.display()
            )
        })
    }

    /// Bytes [`write`] produces for a mesh of `vertices` and `triangles` (an upper bound),
    /// with vertex colours when `colours`.
    pub fn size_bound(self, vertices: u64, triangles: u64, colours: bool) -> u64 {
        let c = u64::from(colours);
        match self {
            MeshFormat::Obj => 256 + vertices * (80 + 30 * c) + triangles * 40,
            MeshFormat::Stl => 84 + triangles * 50,
            MeshFormat::Ply => 256 + 64 * c + vertices * (24 + 4 * c) + triangles * 13,
            MeshFormat::Glb => 1024 + vertices * (12 + 16 * c) + triangles * 12,
        }
    }
}

/// The exact bytes [`write`] writes for `m` as `format`; `None` for OBJ (decimal text).
pub fn encoded_len(m: &TriMesh, format: MeshFormat) -> Option<u64> {
    let (v, t) = (m.positions.len() as u64, m.triangles.len() as u64);
    match format {
        MeshFormat::Obj => None,
        MeshFormat::Stl => Some(84 + 50 * t),
        MeshFormat::Ply => Some(ply_header(m).len() as u64 + (24 + 4 * coloured(m)) * v + 13 * t),
        MeshFormat::Glb => Some(12 + 8 + glb_json(m).len() as u64 + 8 + glb_bin(m)),
    }
}

/// 1 when `m` has vertex colours.
fn coloured(m: &TriMesh) -> u64 {
    u64::from(!m.colors.is_empty())
}

/// The GLB's binary chunk: positions, indices, and the colours (linear f32 RGBA) when any.
fn glb_bin(m: &TriMesh) -> u64 {
    let (v, t) = (m.positions.len() as u64, m.triangles.len() as u64);
    12 * v + 12 * t + 16 * v * coloured(m)
}

fn ply_header(m: &TriMesh) -> String {
    let colour = if m.colors.is_empty() {
        ""
    } else {
        "property uchar red\nproperty uchar green\nproperty uchar blue\nproperty uchar alpha\n"
    };
    format!(
        "ply\nformat binary_little_endian 1.0\ncomment voxd\n\
         element vertex {}\nproperty double x\nproperty double y\nproperty double z\n{colour}\
         element face {}\nproperty list uchar uint vertex_indices\nend_header\n",
        m.positions.len(),
        m.triangles.len()
    )
}

/// The float32 positions' bounds, which glTF requires of a POSITION accessor.
fn bounds(m: &TriMesh) -> ([f32; 3], [f32; 3]) {
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for p in &m.positions {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a] as f32);
            hi[a] = hi[a].max(p[a] as f32);
        }
    }
    if m.positions.is_empty() {
        (lo, hi) = ([0.0; 3], [0.0; 3]);
    }
    (lo, hi)
}

/// The GLB's JSON chunk, padded with spaces to a multiple of 4 bytes: positions (view 0) then
/// indices (view 1) in the one binary buffer, then the vertex colours (view 2, `COLOR_0`, linear
/// as glTF defines it) when any. (Every view's length is a multiple of 4, so the binary chunk
/// needs no padding.)
fn glb_json(m: &TriMesh) -> String {
    let (v, t) = (m.positions.len() as u64, m.triangles.len() as u64);
    let (lo, hi) = bounds(m);
    let mut j = serde_json::json!({
        "asset": {"version": "2.0", "generator": "voxd"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "mode": 4}]}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": v, "type": "VEC3",
             "min": lo, "max": hi},
            {"bufferView": 1, "componentType": 5125, "count": 3 * t, "type": "SCALAR"}
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 12 * v, "target": 34962},
            {"buffer": 0, "byteOffset": 12 * v, "byteLength": 12 * t, "target": 34963}
        ],
        "buffers": [{"byteLength": glb_bin(m)}]
    });
    if !m.colors.is_empty() {
        j["meshes"][0]["primitives"][0]["attributes"]["COLOR_0"] = 2.into();
        j["accessors"].as_array_mut().expect("an array").push(
            serde_json::json!({"bufferView": 2, "componentType": 5126, "count": v, "type": "VEC4"}),
        );
        j["bufferViews"].as_array_mut().expect("an array").push(
            serde_json::json!({"buffer": 0, "byteOffset": 12 * v + 12 * t, "byteLength": 16 * v, "target": 34962}),
        );
    }
    let mut j = j.to_string();
    while !j.len().is_multiple_of(4) {
        j.push(' ');
    }
    j
}

/// Writes `m` as `format` to `w`.
pub fn write(m: &TriMesh, format: MeshFormat, w: &mut impl Write) -> io::Result<()> {
    let mut w = io::BufWriter::with_capacity(1 << 16, w);
    match format {
        MeshFormat::Obj => {
            writeln!(
                w,
                "# voxd: {} vertices, {} triangles",
                m.positions.len(),
                m.triangles.len()
            )?;
            if m.colors.is_empty() {
                for p in &m.positions {
                    writeln!(w, "v {} {} {}", p[0], p[1], p[2])?;
                }
            } else {
                // The vertex colour extension (`v x y z r g b`, sRGB in [0, 1]).
                for (p, c) in m.positions.iter().zip(&m.colors) {
                    let f = |b: u8| f32::from(b) / 255.0;
                    writeln!(
                        w,
                        "v {} {} {} {} {} {}",
                        p[0],
                        p[1],
                        p[2],
                        f(c[0]),
                        f(c[1]),
                        f(c[2])
                    )?;
                }
            }
            for t in &m.triangles {
                writeln!(w, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1)?;
            }
        }
        MeshFormat::Stl => {
            let mut header = [b' '; 80];
            let text = b"voxd binary STL";
            header[..text.len()].copy_from_slice(text);
            w.write_all(&header)?;
            w.write_all(&(m.triangles.len() as u32).to_le_bytes())?;
            for t in &m.triangles {
                let p = t.map(|i| m.positions[i as usize]);
                let e1 = [0, 1, 2].map(|a| p[1][a] - p[0][a]);
                let e2 = [0, 1, 2].map(|a| p[2][a] - p[0][a]);
                let n = [
                    e1[1] * e2[2] - e1[2] * e2[1],
                    e1[2] * e2[0] - e1[0] * e2[2],
                    e1[0] * e2[1] - e1[1] * e2[0],
                ];
                let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
                let n = if len > 0.0 { n.map(|c| c / len) } else { n };
                for c in n {
                    w.write_all(&(c as f32).to_le_bytes())?;
                }
                for q in p {
                    for c in q {
                        w.write_all(&(c as f32).to_le_bytes())?;
                    }
                }
                w.write_all(&[0, 0])?;
            }
        }
        MeshFormat::Ply => {
            w.write_all(ply_header(m).as_bytes())?;
            for (i, p) in m.positions.iter().enumerate() {
                for c in p {
                    w.write_all(&c.to_le_bytes())?;
                }
                if let Some(c) = m.colors.get(i) {
                    w.write_all(c)?;
                }
            }
            for t in &m.triangles {
                w.write_all(&[3])?;
                for i in t {
                    w.write_all(&i.to_le_bytes())?;
                }
            }
        }
        MeshFormat::Glb => {
            let json = glb_json(m);
            let bin = glb_bin(m);
            let total = 12 + 8 + json.len() as u64 + 8 + bin;
            let total = u32::try_from(total).map_err(|_| {
                io::Error::new(
                    io::ErrorKind::InvalidInput,
                    format!("a GLB holds at most 4 GiB; this mesh would be {total} bytes"),
                )
            })?;
            w.write_all(b"glTF")?;
            w.write_all(&2u32.to_le_bytes())?;
            w.write_all(&total.to_le_bytes())?;
            w.write_all(&(json.len() as u32).to_le_bytes())?;
            w.write_all(b"JSON")?;
            w.write_all(json.as_bytes())?;
            w.write_all(&(bin as u32).to_le_bytes())?;
            w.write_all(b"BIN\0")?;
            for p in &m.positions {
                for c in p {
                    w.write_all(&(*c as f32).to_le_bytes())?;
                }
            }
            for t in &m.triangles {
                for i in t {
                    w.write_all(&i.to_le_bytes())?;
                }
            }
            let lin = crate::mesh::texture::srgb_to_linear_table();
            for c in &m.colors {
                for k in 0..3 {
                    w.write_all(&lin[usize::from(c[k])].to_le_bytes())?;
                }
                w.write_all(&(f32::from(c[3]) / 255.0).to_le_bytes())?;
            }
        }
    }
    w.flush()
}
