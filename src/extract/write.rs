//! Mesh files: OBJ (text, positions as Rust's shortest round-trip decimals), binary STL
//! (float32, as the format has it) and binary little-endian PLY (float64 positions, uint32
//! indices). Written to any `Write`, piece by piece.

use std::io::{self, Write};

use super::TriMesh;

/// The mesh formats written.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MeshFormat {
    Obj,
    Stl,
    Ply,
}

impl MeshFormat {
    pub const ALL: [MeshFormat; 3] = [MeshFormat::Obj, MeshFormat::Stl, MeshFormat::Ply];

    pub fn as_str(self) -> &'static str {
        match self {
            MeshFormat::Obj => "obj",
            MeshFormat::Stl => "stl",
            MeshFormat::Ply => "ply",
        }
    }

    pub fn media_type(self) -> &'static str {
        match self {
            MeshFormat::Obj => "model/obj",
            MeshFormat::Stl => "model/stl",
            MeshFormat::Ply => "application/x-ply",
        }
    }

    pub fn parse(s: &str) -> Result<MeshFormat, String> {
        MeshFormat::ALL
            .into_iter()
            .find(|f| f.as_str() == s)
            .ok_or_else(|| format!("mesh format must be obj, stl or ply, got {s:?}"))
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
                "{}: the mesh format is taken from the extension: .obj, .stl or .ply",
                p.display()
            )
        })
    }

    /// Bytes [`write`] produces for `m` (exact for STL and PLY, an upper bound for OBJ).
    pub fn size_bound(self, vertices: u64, triangles: u64) -> u64 {
        match self {
            MeshFormat::Obj => 256 + vertices * 80 + triangles * 40,
            MeshFormat::Stl => 84 + triangles * 50,
            MeshFormat::Ply => 256 + vertices * 24 + triangles * 13,
        }
    }
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
            for p in &m.positions {
                writeln!(w, "v {} {} {}", p[0], p[1], p[2])?;
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
            write!(
                w,
                "ply\nformat binary_little_endian 1.0\ncomment voxd\n\
                 element vertex {}\nproperty double x\nproperty double y\nproperty double z\n\
                 element face {}\nproperty list uchar uint vertex_indices\nend_header\n",
                m.positions.len(),
                m.triangles.len()
            )?;
            for p in &m.positions {
                for c in p {
                    w.write_all(&c.to_le_bytes())?;
                }
            }
            for t in &m.triangles {
                w.write_all(&[3])?;
                for i in t {
                    w.write_all(&i.to_le_bytes())?;
                }
            }
        }
    }
    w.flush()
}
