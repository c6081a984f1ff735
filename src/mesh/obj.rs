//! Wavefront OBJ through `tobj`: every object and group, polygons fan-triangulated, points and
//! lines ignored. Material libraries are never opened.

use super::{Mesh, MeshError, malformed};

pub(super) fn parse(bytes: &[u8]) -> Result<Mesh, MeshError> {
    let opts = tobj::LoadOptions {
        single_index: false,
        triangulate: true,
        ignore_points: true,
        ignore_lines: true,
    };
    let mut reader = std::io::BufReader::new(bytes);
    let (models, _materials) = tobj::load_obj_buf(&mut reader, &opts, |_| Ok(Default::default()))
        .map_err(|e| malformed("OBJ", e.to_string()))?;
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    for m in &models {
        let base = positions.len() as u64;
        let p = &m.mesh.positions;
        if p.len() % 3 != 0 {
            return Err(malformed(
                "OBJ",
                "vertex data is not a whole number of xyz triples",
            ));
        }
        positions.extend(
            p.chunks_exact(3)
                .map(|c| [c[0] as f64, c[1] as f64, c[2] as f64]),
        );
        if m.mesh.indices.len() % 3 != 0 {
            return Err(malformed(
                "OBJ",
                format!(
                    "object {:?} did not triangulate into whole triangles",
                    m.name
                ),
            ));
        }
        for t in m.mesh.indices.chunks_exact(3) {
            let idx = [0, 1, 2].map(|i| base + t[i] as u64);
            if idx.iter().any(|&i| i > u32::MAX as u64) {
                return Err(malformed("OBJ", "more than 4 billion vertices"));
            }
            triangles.push(idx.map(|i| i as u32));
        }
    }
    if triangles.is_empty() {
        return Err(MeshError::NoTriangles(
            " (no `f` lines with three or more vertices)".into(),
        ));
    }
    Mesh::new(positions, triangles)
}
