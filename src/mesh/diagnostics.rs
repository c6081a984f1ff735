//! What is wrong with a mesh, computed on positions merged by exact equality (so UV and normal
//! seams do not count as holes).

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::Mesh;

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MeshDiagnostics {
    pub triangles: usize,
    /// Distinct positions used by triangles.
    pub vertices: usize,
    /// Triangles of zero area: two merged corners coincide, or the f64 cross product is zero.
    pub degenerate_triangles: usize,
    /// Edges used by exactly one triangle.
    pub boundary_edges: usize,
    /// Edges used by three or more triangles.
    pub non_manifold_edges: usize,
    /// No boundary and no non-manifold edges.
    pub watertight: bool,
    pub bbox_min: [f64; 3],
    pub bbox_max: [f64; 3],
}

/// For every position, the number of its class under exact equality (-0.0 = 0.0): positions
/// that are equal get the same id, ids run from 0 without gaps.
pub(crate) fn merged_ids(mesh: &Mesh) -> Vec<u32> {
    // Sort (key, index) pairs and number the distinct keys.
    let key = |p: &[f64; 3]| p.map(|c| if c == 0.0 { 0u64 } else { c.to_bits() });
    let mut keyed: Vec<([u64; 3], u32)> = mesh
        .positions
        .par_iter()
        .enumerate()
        .map(|(i, p)| (key(p), i as u32))
        .collect();
    keyed.par_sort_unstable();
    let mut remap = vec![0u32; mesh.positions.len()];
    let mut distinct = 0u32;
    for (i, (k, idx)) in keyed.iter().enumerate() {
        if i > 0 && keyed[i - 1].0 != *k {
            distinct += 1;
        }
        remap[*idx as usize] = distinct;
    }
    remap
}

impl MeshDiagnostics {
    pub fn of(mesh: &Mesh) -> MeshDiagnostics {
        let remap = merged_ids(mesh);
        let distinct = remap.iter().copied().max().unwrap_or(0);
        let merged = |t: &[u32; 3]| t.map(|i| remap[i as usize]);
        let degenerate = mesh
            .triangles
            .par_iter()
            .enumerate()
            .filter(|(t, tri)| {
                let m = merged(tri);
                let [a, b, c] = mesh.triangle(*t);
                let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
                let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
                let cross = [
                    u[1] * v[2] - u[2] * v[1],
                    u[2] * v[0] - u[0] * v[2],
                    u[0] * v[1] - u[1] * v[0],
                ];
                m[0] == m[1] || m[1] == m[2] || m[0] == m[2] || cross == [0.0; 3]
            })
            .count();
        // Three undirected edges per triangle, as (low id, high id) in one u64, written in
        // place (one allocation of the exact size, no per-thread pieces to concatenate). An
        // edge whose ends merged into one vertex is no edge: u64::MAX, which no real edge can
        // be (its low id is below its high one), sorted last and dropped.
        const NONE: u64 = u64::MAX;
        let mut edges = vec![0u64; mesh.triangles.len() * 3];
        edges
            .par_chunks_mut(3)
            .zip(mesh.triangles.par_iter())
            .for_each(|(out, tri)| {
                let m = merged(tri);
                for (o, (p, q)) in out
                    .iter_mut()
                    .zip([(m[0], m[1]), (m[1], m[2]), (m[2], m[0])])
                {
                    *o = if p == q {
                        NONE
                    } else {
                        ((p.min(q) as u64) << 32) | p.max(q) as u64
                    };
                }
            });
        edges.par_sort_unstable();
        let real = edges.partition_point(|&e| e != NONE);
        let (mut boundary, mut non_manifold) = (0, 0);
        for run in edges[..real].chunk_by(|a, b| a == b) {
            match run.len() {
                1 => boundary += 1,
                2 => {}
                _ => non_manifold += 1,
            }
        }
        let mut used = vec![false; distinct as usize + 1];
        for t in &mesh.triangles {
            for v in merged(t) {
                used[v as usize] = true;
            }
        }
        let (bbox_min, bbox_max) = mesh.bounds();
        MeshDiagnostics {
            triangles: mesh.triangles.len(),
            vertices: used.iter().filter(|&&u| u).count(),
            degenerate_triangles: degenerate,
            boundary_edges: boundary,
            non_manifold_edges: non_manifold,
            watertight: boundary == 0 && non_manifold == 0,
            bbox_min,
            bbox_max,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tetrahedron_with_split_seam_is_watertight() {
        // Vertex 4 duplicates vertex 0 (a UV seam): merged, the tetrahedron is closed.
        let p = vec![
            [0.0; 3],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
            [-0.0, 0.0, 0.0],
        ];
        let m = Mesh::new(p, vec![[0, 2, 1], [4, 1, 3], [0, 3, 2], [1, 2, 3]]).unwrap();
        let d = m.diagnostics();
        assert_eq!(
            (
                d.vertices,
                d.boundary_edges,
                d.non_manifold_edges,
                d.degenerate_triangles
            ),
            (4, 0, 0, 0)
        );
        assert!(d.watertight);
    }

    #[test]
    fn open_and_non_manifold() {
        let p = vec![
            [0.0; 3],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
            [2.0, 0.0, 0.0],
        ];
        // Three triangles share edge 0-1; one triangle is a zero-area sliver.
        let m = Mesh::new(p, vec![[0, 1, 2], [0, 1, 3], [0, 1, 4], [0, 1, 5]]).unwrap();
        let d = m.diagnostics();
        assert_eq!(d.non_manifold_edges, 1);
        assert_eq!(d.boundary_edges, 8);
        assert_eq!(d.degenerate_triangles, 1);
        assert!(!d.watertight);
    }
}
