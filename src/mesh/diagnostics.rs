//! What is wrong with a mesh, computed on positions merged by exact equality (so UV and normal
//! seams do not count as holes).

use std::hash::BuildHasher;
use std::sync::atomic::{AtomicBool, Ordering};

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::Mesh;
use super::edges::{EdgeUses, edge_groups, threads_for};

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
    /// Edges that their triangles do not use as often in one direction as in the other: the
    /// boundary edges, edges between triangles of opposite orientation, odd fans. 0 on a
    /// closed, consistently oriented mesh, which the winding fill then needs no caps to close.
    /// Absent from diagnoses made before it was counted.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub unoriented_edges: Option<usize>,
    pub bbox_min: [f64; 3],
    pub bbox_max: [f64; 3],
    /// Degenerate triangles dropped at load as copies of a segment or point kept (not counted
    /// in `triangles`); omitted when none were.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub dropped_triangles: u64,
}

fn is_zero(n: &u64) -> bool {
    *n == 0
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

/// For every position, the index of the first position equal to it (-0.0 = 0.0): the classes of
/// [`merged_ids`], each named by its first member instead of numbered in sorted order, found
/// by hashing instead of sorting (what the diagnosis needs: which positions are one vertex).
/// And whether every position is its own (no two are equal), so the ids are the indices.
///
/// Positions are split by hash into parts (of about 64 Ki positions, at least one per thread);
/// each part goes through its positions in order with a table of its own, and reports those
/// equal to an earlier one (few, usually none). The hash is seeded per process, and a part
/// that probes its table far more than a good hash would (positions made to collide) has the
/// classes found by sorting instead: the same ids, in O(n log n) whatever the positions.
fn first_equal(positions: &[[f64; 3]], parts: Option<usize>) -> (Vec<u32>, bool) {
    first_equal_within(positions, 16, parts)
}

/// [`first_equal`], falling back to sorting once a part probes more than `budget` slots per
/// position; `parts` (a power of two up to 64) overrides the split, for the tests.
fn first_equal_within(
    positions: &[[f64; 3]],
    budget: usize,
    parts: Option<usize>,
) -> (Vec<u32>, bool) {
    let key = |p: &[f64; 3]| p.map(|c| if c == 0.0 { 0u64 } else { c.to_bits() });
    let seed = {
        let state = std::hash::RandomState::new();
        [0u64, 1, 2, 3].map(|i| state.hash_one(i))
    };
    // Folded multiplies (as foldhash and ahash mix): every bit of the key reaches the middle
    // and top bits of the product.
    let fold = |a: u64, b: u64| {
        let p = a as u128 * b as u128;
        p as u64 ^ (p >> 64) as u64
    };
    let hash = |k: [u64; 3]| {
        let h = fold(k[0] ^ seed[0], k[1] ^ seed[1]);
        fold(h ^ k[2] ^ seed[2], seed[3] | 1)
    };
    let hashes: Vec<u64> = positions.par_iter().map(|p| hash(key(p))).collect();
    // Parts of about 64 Ki positions (tables of a megabyte, which caches hold), at least one
    // per thread; one for a small mesh.
    let parts = parts
        .unwrap_or_else(|| (positions.len() >> 16).max(threads_for(positions.len())))
        .clamp(1, 64)
        .next_power_of_two();
    let equal: Option<Vec<Vec<(u32, u32)>>> = (0..parts as u64)
        .into_par_iter()
        .map(|part| {
            // Top 6 bits: the part; low bits: the slot; the middle: a fingerprint, compared
            // before the positions are. Slots hold a position's index + 1 (0: empty), at most
            // two thirds of them used.
            let of_part = |h: &u64| (h >> 58) & (parts as u64 - 1) == part;
            let count = hashes.iter().filter(|h| of_part(h)).count();
            let mask = (count + count / 2 + 1).next_power_of_two().max(16) - 1;
            let mut table = vec![(0u32, 0u32); mask + 1];
            let mut equal = Vec::new();
            let mut probes_left = budget.saturating_mul(count).saturating_add(64);
            for (i, h) in hashes.iter().enumerate() {
                if !of_part(h) {
                    continue;
                }
                let fingerprint = (h >> 26) as u32;
                let mut slot = *h as usize & mask;
                loop {
                    probes_left = probes_left.checked_sub(1)?;
                    let (j, f) = table[slot];
                    if j == 0 {
                        table[slot] = (i as u32 + 1, fingerprint);
                        break;
                    }
                    let j = j - 1;
                    if f == fingerprint && key(&positions[j as usize]) == key(&positions[i]) {
                        equal.push((i as u32, j));
                        break;
                    }
                    slot = (slot + 1) & mask;
                }
            }
            Some(equal)
        })
        .collect();
    let Some(equal) = equal else {
        return first_equal_by_sorting(positions);
    };
    let mut ids: Vec<u32> = (0..positions.len() as u32).into_par_iter().collect();
    let distinct = equal.iter().all(Vec::is_empty);
    for (i, j) in equal.into_iter().flatten() {
        ids[i as usize] = j;
    }
    (ids, distinct)
}

/// [`first_equal`] by sorting (key, index) pairs, as [`merged_ids`] does.
fn first_equal_by_sorting(positions: &[[f64; 3]]) -> (Vec<u32>, bool) {
    let key = |p: &[f64; 3]| p.map(|c| if c == 0.0 { 0u64 } else { c.to_bits() });
    let mut keyed: Vec<([u64; 3], u32)> = positions
        .par_iter()
        .enumerate()
        .map(|(i, p)| (key(p), i as u32))
        .collect();
    keyed.par_sort_unstable();
    let mut ids = vec![0u32; positions.len()];
    let mut distinct = true;
    for run in keyed.chunk_by(|a, b| a.0 == b.0) {
        // Sorted by index within the run: the first is the class's first member.
        distinct &= run.len() == 1;
        for &(_, i) in run {
            ids[i as usize] = run[0].1;
        }
    }
    (ids, distinct)
}

/// Boundary (used by one triangle), non-manifold (three or more) and unoriented (used more
/// often in one direction than in the other) edges, on vertex ids `ids` (below `n`; the
/// indices themselves when `distinct`); an edge whose two ends are one vertex is no edge.
///
/// Edges are grouped by their lower end ([`edge_groups`]: counted, then placed, no sort of all of
/// them), the range of lower ends split among the threads.
fn edge_counts(
    triangles: &[[u32; 3]],
    ids: &[u32],
    distinct: bool,
    n: usize,
    parts: Option<usize>,
) -> (usize, usize, usize) {
    let count = |(boundary, non_manifold, unoriented): &mut (usize, usize, usize), e: EdgeUses| {
        match e.uses {
            1 => *boundary += 1,
            2 => {}
            _ => *non_manifold += 1,
        }
        *unoriented += usize::from(e.net != 0);
    };
    // `parts` overrides the split, for the tests.
    let counts = if distinct {
        edge_groups(triangles, |i| i, n, parts, || (0, 0, 0), count)
    } else {
        edge_groups(
            triangles,
            |i| ids[i as usize],
            n,
            parts,
            || (0, 0, 0),
            count,
        )
    };
    counts
        .into_iter()
        .fold((0, 0, 0), |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2))
}

impl MeshDiagnostics {
    pub fn of(mesh: &Mesh) -> MeshDiagnostics {
        Self::split(mesh, None)
    }

    /// [`Self::of`] with the positions and the edges in `parts` parts (`None`: by the mesh's
    /// size and the threads), for the tests.
    fn split(mesh: &Mesh, parts: Option<usize>) -> MeshDiagnostics {
        let (ids, distinct) = first_equal(&mesh.positions, parts);
        let merged = |t: &[u32; 3]| t.map(|i| ids[i as usize]);
        let (boundary, non_manifold, unoriented) =
            edge_counts(&mesh.triangles, &ids, distinct, ids.len(), parts);
        // One pass over the triangles for the rest: the degenerate ones, the vertices used,
        // and the bounding box as [`Mesh::bounds`] folds it: pieces of the triangles folded in
        // order, then the pieces' boxes in order (the same folds, as `min` and `max` are
        // associative, even in which of -0.0 and 0.0 wins a tie).
        let used: Vec<AtomicBool> = (0..ids.len()).map(|_| AtomicBool::new(false)).collect();
        let empty = || (0usize, [f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        let (degenerate, lo, hi) = mesh
            .triangles
            .par_chunks(1 << 14)
            .map(|piece| {
                let (mut degenerate, mut lo, mut hi) = empty();
                for tri in piece {
                    let m = merged(tri);
                    for v in m {
                        used[v as usize].store(true, Ordering::Relaxed);
                    }
                    let [a, b, c] = tri.map(|i| mesh.positions[i as usize]);
                    for p in [a, b, c] {
                        for a in 0..3 {
                            lo[a] = lo[a].min(p[a]);
                            hi[a] = hi[a].max(p[a]);
                        }
                    }
                    let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
                    let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
                    let cross = [
                        u[1] * v[2] - u[2] * v[1],
                        u[2] * v[0] - u[0] * v[2],
                        u[0] * v[1] - u[1] * v[0],
                    ];
                    degenerate +=
                        (m[0] == m[1] || m[1] == m[2] || m[0] == m[2] || cross == [0.0; 3])
                            as usize;
                }
                (degenerate, lo, hi)
            })
            .reduce(empty, |(d, mut lo, mut hi), (e, l, h)| {
                for a in 0..3 {
                    lo[a] = lo[a].min(l[a]);
                    hi[a] = hi[a].max(h[a]);
                }
                (d + e, lo, hi)
            });
        MeshDiagnostics {
            triangles: mesh.triangles.len(),
            vertices: used
                .par_iter()
                .filter(|u| u.load(Ordering::Relaxed))
                .count(),
            degenerate_triangles: degenerate,
            dropped_triangles: mesh.dropped,
            boundary_edges: boundary,
            non_manifold_edges: non_manifold,
            watertight: boundary == 0 && non_manifold == 0,
            unoriented_edges: Some(unoriented),
            bbox_min: lo,
            bbox_max: hi,
        }
    }

    /// The diagnosis as it was computed before [`first_equal`] and [`edge_counts`]: positions
    /// merged by sorting, every edge sorted. What the tests hold the fast one to.
    #[cfg(test)]
    fn by_sorting(mesh: &Mesh) -> MeshDiagnostics {
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
        // With each its direction: +1 from the low id, −1 from the high one.
        const NONE: u64 = u64::MAX;
        let mut edges = vec![(0u64, 0i64); mesh.triangles.len() * 3];
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
                        (NONE, 0)
                    } else {
                        (
                            ((p.min(q) as u64) << 32) | p.max(q) as u64,
                            if p < q { 1 } else { -1 },
                        )
                    };
                }
            });
        edges.par_sort_unstable();
        let real = edges.partition_point(|e| e.0 != NONE);
        let (mut boundary, mut non_manifold, mut unoriented) = (0, 0, 0);
        for run in edges[..real].chunk_by(|a, b| a.0 == b.0) {
            match run.len() {
                1 => boundary += 1,
                2 => {}
                _ => non_manifold += 1,
            }
            unoriented += usize::from(run.iter().map(|e| e.1).sum::<i64>() != 0);
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
            dropped_triangles: mesh.dropped,
            boundary_edges: boundary,
            non_manifold_edges: non_manifold,
            watertight: boundary == 0 && non_manifold == 0,
            unoriented_edges: Some(unoriented),
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
        assert_eq!(d.unoriented_edges, Some(0));
        // One face flipped: still watertight, but its three edges are used twice the same way.
        let m = Mesh::new(
            m.positions.clone(),
            vec![[0, 1, 2], [4, 1, 3], [0, 3, 2], [1, 2, 3]],
        )
        .unwrap();
        let d = m.diagnostics();
        assert!(d.watertight);
        assert_eq!(d.unoriented_edges, Some(3));
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
        // The eight boundary edges, and 0-1: four uses from 0.
        assert_eq!(d.unoriented_edges, Some(9));
    }

    /// Random meshes made to have what the diagnosis counts: coordinates from a few values
    /// (so positions repeat, -0.0 and 0.0 among them), triangles on few vertices (so edges
    /// repeat and corners coincide).
    #[test]
    fn hashing_and_bucketing_give_what_sorting_gives() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = |n: usize| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state % n as u64) as usize
        };
        let values = [0.0, -0.0, 1.0, -1.0, 0.5, 2.0, 1e-300, -3.25];
        for case in 0..3000 {
            let n = 1 + next(40);
            let spread = 1 + next(values.len());
            let positions: Vec<[f64; 3]> = (0..n)
                .map(|_| [0; 3].map(|_| values[next(spread)]))
                .collect();
            let triangles: Vec<[u32; 3]> = (0..1 + next(60))
                .map(|_| [0; 3].map(|_| next(n) as u32))
                .collect();
            let m = Mesh::new(positions, triangles).unwrap();
            let (new, old) = (MeshDiagnostics::of(&m), MeshDiagnostics::by_sorting(&m));
            assert_eq!(new, old, "case {case}: {m:?}");
            // Small meshes go as one part; split, they must give the same.
            let parts = 1 << next(4);
            assert_eq!(
                MeshDiagnostics::split(&m, Some(parts)),
                old,
                "case {case}: {m:?}"
            );
            // PartialEq takes -0.0 for 0.0: the box must be the same bits.
            let bits = |d: &MeshDiagnostics| [d.bbox_min, d.bbox_max].map(|b| b.map(f64::to_bits));
            assert_eq!(bits(&new), bits(&old), "case {case}: {m:?}");
        }
    }

    /// The same on a big mesh (many buckets per thread, long tables): a grid of quads, with
    /// its seam duplicated and a few triangles repeated.
    #[test]
    fn big_grid() {
        let k = 300;
        let mut positions = Vec::new();
        for y in 0..=k {
            for x in 0..=k {
                positions.push([x as f64, y as f64, ((x * y) % 7) as f64 - 3.0]);
            }
        }
        // Column 0 again: a seam of equal positions.
        for y in 0..=k {
            positions.push([0.0, y as f64, -3.0]);
        }
        let at = |x: usize, y: usize| (y * (k + 1) + x) as u32;
        let mut triangles = Vec::new();
        for y in 0..k {
            for x in 0..k {
                let seam = |v: u32, xx: usize, yy: usize| {
                    if xx == 0 && y % 2 == 0 {
                        ((k + 1) * (k + 1) + yy) as u32
                    } else {
                        v
                    }
                };
                let (a, b) = (seam(at(x, y), x, y), at(x + 1, y));
                let (c, d) = (at(x + 1, y + 1), seam(at(x, y + 1), x, y + 1));
                triangles.push([a, b, c]);
                triangles.push([a, c, d]);
            }
        }
        for t in 0..50 {
            triangles.push(triangles[t * 97]);
        }
        let m = Mesh::new(positions, triangles).unwrap();
        let d = MeshDiagnostics::of(&m);
        assert_eq!(d, MeshDiagnostics::by_sorting(&m));
        assert_eq!(MeshDiagnostics::split(&m, Some(1)), d);
        // Sorting instead of hashing (what a part that probes too much falls back to) gives
        // the same ids.
        let hashed = first_equal(&m.positions, None);
        assert!(!hashed.1);
        assert_eq!(first_equal_by_sorting(&m.positions), hashed);
        assert_eq!(first_equal_within(&m.positions, 0, None), hashed);
        let distinct = &m.positions[..(k + 1) * (k + 1)];
        assert_eq!(
            first_equal(distinct, None),
            ((0..distinct.len() as u32).collect(), true)
        );
        assert!(d.non_manifold_edges > 0 && d.boundary_edges > 0);
    }
}
