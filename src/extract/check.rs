//! The checks every extracted mesh must pass, and what they measure.

use super::TriMesh;
use super::vec3::cross;

/// Are the three points exactly collinear (zero area)? Each component of (b − a) × (c − a) is
/// the orientation determinant of the points projected on a coordinate plane; its sign is
/// taken exactly by Shewchuk's adaptive predicate (the `robust` crate). In plain f64 the cross
/// product of exactly collinear points can come out non-zero.
pub fn collinear(p: [[f64; 3]; 3]) -> bool {
    [(0, 1), (1, 2), (2, 0)].iter().all(|&(i, j)| {
        let c = |q: [f64; 3]| robust::Coord { x: q[i], y: q[j] };
        robust::orient2d(c(p[0]), c(p[1]), c(p[2])) == 0.0
    })
}

/// What [`check`] found.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Report {
    pub vertices: usize,
    pub triangles: usize,
    /// Undirected edges not used exactly once in each direction (0: watertight and consistently
    /// oriented).
    pub bad_edges: usize,
    /// Triangles with a repeated vertex or zero area (corners exactly collinear: [`collinear`]).
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
///
/// The edges and the triangles are sorted into buckets by their lowest vertex (a counting
/// sort: two passes over the triangles), and each bucket, a few entries, is sorted and read
/// on the pool's threads: an undirected edge's uses, and a triangle's copies, are side by side
/// in one bucket.
pub fn check(m: &TriMesh) -> Report {
    let n = m.positions.len();
    let mut r = Report {
        vertices: n,
        triangles: m.triangles.len(),
        ..Report::default()
    };
    let mut used = vec![false; n];
    // Bucket sizes, then starts, by lowest vertex: of the directed edges (each as its
    // undirected key's other end and a direction bit) and of the triangles (each as its
    // other two vertices, sorted).
    let mut edge_at = vec![0usize; n + 1];
    let mut tri_at = vec![0usize; n + 1];
    // Six times the volume: a sum of exact products for lattice meshes, divided once.
    let mut six = 0.0;
    for t in &m.triangles {
        for i in 0..3 {
            let (a, b) = (t[i], t[(i + 1) % 3]);
            edge_at[a.min(b) as usize + 1] += 1;
            used[a as usize] = true;
        }
        tri_at[*t.iter().min().expect("three vertices") as usize + 1] += 1;
        let p = t.map(|i| m.positions[i as usize]);
        if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] || collinear(p) {
            r.degenerate += 1;
        }
        let c = cross(p[1], p[2]);
        six += p[0][0] * c[0] + p[0][1] * c[1] + p[0][2] * c[2];
    }
    for v in 0..n {
        edge_at[v + 1] += edge_at[v];
        tri_at[v + 1] += tri_at[v];
    }
    let mut edges = vec![0u64; 3 * m.triangles.len()];
    let mut keys = vec![0u64; m.triangles.len()];
    {
        let (mut e_fill, mut t_fill) = (edge_at.clone(), tri_at.clone());
        for t in &m.triangles {
            for i in 0..3 {
                let (a, b) = (t[i], t[(i + 1) % 3]);
                let slot = &mut e_fill[a.min(b) as usize];
                edges[*slot] = u64::from(a.max(b)) << 1 | u64::from(a > b);
                *slot += 1;
            }
            let mut key = *t;
            key.sort_unstable();
            let slot = &mut t_fill[key[0] as usize];
            keys[*slot] = u64::from(key[1]) << 32 | u64::from(key[2]);
            *slot += 1;
        }
    }
    // Each undirected edge: exactly one use each way.
    r.bad_edges = per_bucket(&edge_at, &mut edges, |b| {
        b.chunk_by(|x, y| x >> 1 == y >> 1)
            .filter(|g| *g != [g[0] & !1, g[0] | 1])
            .count()
    });
    r.duplicates = per_bucket(&tri_at, &mut keys, |b| {
        b.windows(2).filter(|w| w[0] == w[1]).count()
    });
    r.unused = used.iter().filter(|&&u| !u).count();
    r.volume = six / 6.0;
    r
}

/// Σ `count(bucket)` over the buckets `values[start[v]..start[v + 1]]`, each sorted first, on
/// the pool's threads.
fn per_bucket(
    start: &[usize],
    values: &mut [u64],
    count: impl Fn(&[u64]) -> usize + Sync,
) -> usize {
    use rayon::prelude::*;
    let buckets = start.len() - 1;
    // Parts of whole buckets, about PIECE values each.
    const PIECE: usize = 1 << 16;
    let mut ranges = Vec::new();
    let mut v = 0;
    while v < buckets {
        let mut w = v + 1;
        while w < buckets && start[w] - start[v] < PIECE {
            w += 1;
        }
        ranges.push(v..w);
        v = w;
    }
    let parts = crate::split_lengths(values, ranges.iter().map(|r| start[r.end] - start[r.start]));
    ranges
        .into_par_iter()
        .zip(parts)
        .map(|(vs, part)| {
            let base = start[vs.start];
            vs.map(|v| {
                let b = &mut part[start[v] - base..start[v + 1] - base];
                b.sort_unstable();
                count(b)
            })
            .sum::<usize>()
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testkit::Rng;
    use std::collections::HashMap;

    /// [`check`]'s counts by maps of whole edges and triangles (no buckets).
    fn brute(m: &TriMesh) -> (usize, usize, usize) {
        let mut uses: HashMap<(u32, u32), usize> = HashMap::new();
        let mut tris: HashMap<Vec<u32>, usize> = HashMap::new();
        for t in &m.triangles {
            for i in 0..3 {
                *uses.entry((t[i], t[(i + 1) % 3])).or_default() += 1;
            }
            let mut k = t.to_vec();
            k.sort_unstable();
            *tris.entry(k).or_default() += 1;
        }
        let mut bad = 0;
        for (&(a, b), &k) in &uses {
            if a == b {
                // An edge from a vertex to itself (a collapsed triangle's) is never sound.
                bad += 1;
                continue;
            }
            let back = uses.get(&(b, a)).copied().unwrap_or(0);
            // Each undirected edge once: from its lower end, or from the upper with no use back.
            if (a < b || back == 0) && !(k == 1 && back == 1) {
                bad += 1;
            }
        }
        let dups = tris.values().map(|k| k - 1).sum();
        let unused = (0..m.positions.len() as u32)
            .filter(|v| !m.triangles.iter().any(|t| t.contains(v)))
            .count();
        (bad, dups, unused)
    }

    fn octahedron() -> TriMesh {
        let (positions, triangles) = crate::testkit::octahedron();
        TriMesh {
            positions,
            triangles,
            colors: vec![],
        }
    }

    #[test]
    fn a_closed_outward_mesh_is_valid_and_its_volume_exact() {
        let r = check(&octahedron());
        assert!(r.is_valid(), "{r:?}");
        assert_eq!(r.volume, 4.0 / 3.0);
        assert_eq!((r.vertices, r.triangles), (6, 8));
    }

    /// Exactly collinear corners (on the line t·(1, 2, 3): checked with exact rationals when the
    /// case was found) whose f64 cross product is not zero, and a triangle one ulp off that
    /// line.
    #[test]
    fn zero_area_is_decided_exactly() {
        use super::super::vec3::sub;
        let line = [
            [
                -0.008188605403378395,
                -0.01637721080675679,
                -0.024565816210135184,
            ],
            [-11.826470525275433, -23.652941050550865, -35.4794115758263],
            [-0.83028683049195, -1.6605736609839, -2.49086049147585],
        ];
        assert_ne!(
            cross(sub(line[1], line[0]), sub(line[2], line[0])),
            [0.0; 3]
        );
        assert!(collinear(line));
        let mut off = line;
        off[2][2] = f64::from_bits(off[2][2].to_bits() + 1);
        assert!(!collinear(off));
        let m = TriMesh {
            positions: line.to_vec(),
            triangles: vec![[0, 1, 2]],
            colors: vec![],
        };
        assert_eq!(check(&m).degenerate, 1);
    }

    #[test]
    fn every_defect_is_counted_as_by_whole_maps() {
        // Random damage to an octahedron and to its copies: flipped, dropped, repeated and
        // collapsed triangles, and stray vertices; each count against the brute force.
        let mut rng = Rng::new(41);
        for case in 0..300 {
            let mut m = octahedron();
            // Copies of it (disjoint vertices), so the buckets hold several edges.
            for c in 1..=(case % 4) as u32 {
                let o = octahedron();
                m.positions.extend(
                    o.positions
                        .iter()
                        .map(|p| p.map(|x| x + 3.0 * f64::from(c))),
                );
                m.triangles
                    .extend(o.triangles.iter().map(|t| t.map(|v| v + 6 * c)));
            }
            for _ in 0..rng.below(4) {
                let i = rng.below(m.triangles.len());
                match rng.below(5) {
                    0 => m.triangles[i].swap(0, 1),
                    1 => {
                        m.triangles.remove(i);
                    }
                    2 => {
                        let t = m.triangles[i];
                        m.triangles.push([t[1], t[2], t[0]]);
                    }
                    3 => m.triangles[i][2] = m.triangles[i][0],
                    _ => m.positions.push([9.0; 3]),
                }
            }
            let r = check(&m);
            let (bad, dups, unused) = brute(&m);
            assert_eq!(
                (r.bad_edges, r.duplicates, r.unused),
                (bad, dups, unused),
                "case {case}"
            );
            let collapsed = m
                .triangles
                .iter()
                .filter(|t| t[0] == t[1] || t[1] == t[2] || t[0] == t[2]);
            assert_eq!(r.degenerate, collapsed.count(), "case {case}");
            let sound = bad == 0 && dups == 0 && unused == 0 && r.degenerate == 0;
            assert_eq!(r.is_valid(), sound && r.volume > 0.0, "case {case}: {r:?}");
        }
    }
}
