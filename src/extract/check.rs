//! The checks every extracted mesh must pass, and what they measure.

use rayon::slice::ParallelSliceMut;

use super::TriMesh;
use super::vec3::{cross, sub};

/// What [`check`] found.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Report {
    pub vertices: usize,
    pub triangles: usize,
    /// Undirected edges not used exactly once in each direction (0: watertight and consistently
    /// oriented).
    pub bad_edges: usize,
    /// Triangles with a repeated vertex or zero area.
    pub degenerate: usize,
    /// Triangles with the same three vertices as an earlier one (in any order).
    pub duplicates: usize,
    /// Vertices no triangle uses.
    pub unused: usize,
    /// Σ (p0 · (p1 × p2)) / 6 over the triangles: the enclosed volume, positive when the
    /// triangles face outward.
    pub volume: f64,
}

impl Report {
    /// Watertight, consistently oriented, no degenerate or duplicate triangles, no unused
    /// vertex, and enclosing a positive volume (or nothing at all).
    pub fn is_valid(&self) -> bool {
        self.bad_edges == 0
            && self.degenerate == 0
            && self.duplicates == 0
            && self.unused == 0
            && (self.volume > 0.0 || self.triangles == 0)
    }
}

/// Checks `m` (any units; exact for lattice-unit meshes with coordinates below 2¹⁶).
pub fn check(m: &TriMesh) -> Report {
    let mut r = Report {
        vertices: m.positions.len(),
        triangles: m.triangles.len(),
        ..Report::default()
    };
    let mut used = vec![false; m.positions.len()];
    // Each directed edge a → b as its undirected key (min, max) and a direction bit, sorted so
    // that the uses of one edge are side by side.
    let mut edges: Vec<u64> = Vec::with_capacity(3 * m.triangles.len());
    let mut keys: Vec<[u32; 3]> = Vec::with_capacity(m.triangles.len());
    // Six times the volume: a sum of exact products for lattice meshes, divided once.
    let mut six = 0.0;
    for t in &m.triangles {
        for i in 0..3 {
            let (a, b) = (t[i], t[(i + 1) % 3]);
            edges.push((u64::from(a.min(b)) << 32 | u64::from(a.max(b))) << 1 | u64::from(a > b));
            used[a as usize] = true;
        }
        let p = t.map(|i| m.positions[i as usize]);
        let n = cross(sub(p[1], p[0]), sub(p[2], p[0]));
        if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] || n == [0.0; 3] {
            r.degenerate += 1;
        }
        let mut key = *t;
        key.sort_unstable();
        keys.push(key);
        let c = cross(p[1], p[2]);
        six += p[0][0] * c[0] + p[0][1] * c[1] + p[0][2] * c[2];
    }
    keys.par_sort_unstable();
    r.duplicates = keys.windows(2).filter(|w| w[0] == w[1]).count();
    edges.par_sort_unstable();
    // Each undirected edge: exactly one use each way.
    for group in edges.chunk_by(|x, y| x >> 1 == y >> 1) {
        if group != [group[0] & !1, group[0] | 1] {
            r.bad_edges += 1;
        }
    }
    r.unused = used.iter().filter(|&&u| !u).count();
    r.volume = six / 6.0;
    r
}
