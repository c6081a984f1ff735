//! The caps: triangles that close a mesh's boundary. The boundary, taken as a chain (each edge
//! counted +1 in the direction a triangle uses it, −1 in the other, on positions merged by exact
//! equality), is a set of closed cycles; [`closing_caps`] fans each from centroids so that the
//! mesh plus its caps is a closed chain, whose winding number the crossing count gives exactly.
//! Also the chain's directed edges ([`chain_boundary`]), which the boundary hierarchy is built
//! over.
//!
//! Not here: what the fill does with the caps (their hierarchy, [`super::trees`]; the intervals
//! of their winding number, [`super::certifier`]).

use std::borrow::Cow;

use crate::mesh::{Mesh, edge_groups, merged_ids};

/// The mesh closed by its caps ([`closing_caps`]: their apexes follow the mesh's positions, their
/// triangles its triangles), and the caps. A mesh that needs none (closed, its edges' uses
/// cancelling) is itself, not a copy.
pub(super) fn closed_by_caps(mesh: &Mesh) -> (Cow<'_, Mesh>, Vec<[u32; 3]>) {
    let (apexes, caps) = closing_caps(mesh);
    if caps.is_empty() && apexes.is_empty() {
        return (Cow::Borrowed(mesh), caps);
    }
    let mut positions = mesh.positions().to_vec();
    positions.extend_from_slice(&apexes);
    let mut triangles = mesh.triangles().to_vec();
    triangles.extend_from_slice(&caps);
    let closed = Mesh::new(positions, triangles).expect("caps index the mesh's own positions");
    (Cow::Owned(closed), caps)
}

/// Triangles (and their apex positions, to be appended after the mesh's positions) whose boundary
/// is minus the mesh's boundary chain: each boundary cycle is capped by [`cap_cycle`].
pub fn closing_caps(mesh: &Mesh) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let ids = merged_ids(mesh);
    // One representative position index per merged id.
    let mut rep = vec![u32::MAX; ids.iter().copied().max().map_or(0, |m| m as usize + 1)];
    for (i, &id) in ids.iter().enumerate() {
        if rep[id as usize] == u32::MAX {
            rep[id as usize] = i as u32;
        }
    }
    // The directed uses of each undirected edge, summed ([`edge_groups`]): those whose uses do
    // not cancel are the boundary chain.
    let chains = edge_groups(
        mesh.triangles(),
        |i| ids[i as usize],
        rep.len(),
        None,
        Vec::new,
        |chain: &mut Vec<(u32, u32, u32)>, e| {
            if e.net != 0 {
                let (from, to) = if e.net > 0 {
                    (e.lo, e.hi)
                } else {
                    (e.hi, e.lo)
                };
                chain.push((from, to, e.net.unsigned_abs() as u32));
            }
        },
    );
    // The boundary chain as directed edges with multiplicity, in an adjacency list (in the
    // order of (lower, higher) end).
    let mut out: std::collections::HashMap<u32, Vec<u32>> = std::collections::HashMap::new();
    let mut remaining = 0usize;
    for &(from, to, times) in chains.iter().flatten() {
        for _ in 0..times {
            out.entry(from).or_default().push(to);
            remaining += 1;
        }
    }
    let positions = mesh.positions();
    let (mut apexes, mut caps) = (Vec::new(), Vec::new());
    let mut starts: Vec<u32> = out.keys().copied().collect();
    starts.sort_unstable();
    // Every vertex of a cycle (a chain's boundary) has as many edges in as out, so a walk along
    // unused edges from a vertex always returns to it.
    for s in starts {
        while out.get(&s).is_some_and(|v| !v.is_empty()) {
            let mut cycle = vec![s];
            let mut v = s;
            loop {
                let next = out
                    .get_mut(&v)
                    .and_then(|e| e.pop())
                    .expect("balanced cycle");
                remaining -= 1;
                if next == s {
                    break;
                }
                cycle.push(next);
                v = next;
            }
            let cycle: Vec<u32> = cycle.iter().map(|&v| rep[v as usize]).collect();
            cap_cycle(&cycle, positions, &mut apexes, &mut caps);
        }
    }
    debug_assert_eq!(remaining, 0);
    (apexes, caps)
}

/// Caps a cycle of position indices (edges `cycle[i] → cycle[i + 1]`, the last back to the
/// first) with triangles whose boundary is minus the cycle. A long cycle is not fanned from one
/// point (its long, thin triangles would make every nearby query expensive): it is cut into chunks
/// of `CHUNK` consecutive edges, each chunk plus the chord back to its start is fanned from its
/// own centroid, and the cycle of chords (`CHUNK` times shorter) is capped the same way. The fans
/// give −(chunk edges) + (chords), the chords' cap −(chords): −(cycle) in total, with triangles
/// about as large as the features they span.
fn cap_cycle(
    cycle: &[u32],
    positions: &[[f64; 3]],
    apexes: &mut Vec<[f64; 3]>,
    caps: &mut Vec<[u32; 3]>,
) {
    const CHUNK: usize = 8;
    let n = cycle.len();
    let mut fan = |poly: &[u32], apexes: &mut Vec<[f64; 3]>| {
        // A cycle of two vertices (a→b→a) bounds nothing.
        if poly.len() < 3 {
            return;
        }
        let mut c = [0.0; 3];
        for &v in poly {
            let p = positions[v as usize];
            for a in 0..3 {
                c[a] += p[a] / poly.len() as f64;
            }
        }
        let apex = (positions.len() + apexes.len()) as u32;
        apexes.push(c);
        for (i, &a) in poly.iter().enumerate() {
            let b = poly[(i + 1) % poly.len()];
            // Edge a→b closed by the cap triangle (apex, b, a).
            caps.push([apex, b, a]);
        }
    };
    if n <= CHUNK {
        fan(cycle, apexes);
        return;
    }
    let mut coarse = Vec::with_capacity(n.div_ceil(CHUNK));
    for start in (0..n).step_by(CHUNK) {
        let end = (start + CHUNK).min(n);
        let poly: Vec<u32> = (start..=end).map(|i| cycle[i % n]).collect();
        fan(&poly, apexes);
        coarse.push(cycle[start]);
    }
    cap_cycle(&coarse, positions, apexes, caps);
}

/// The directed edges of the chain boundary of `tris` (indices into one position list, each
/// edge as often as its multiplicity).
pub(super) fn chain_boundary(tris: &[[u32; 3]]) -> Vec<[u32; 2]> {
    let mut edges: Vec<(u64, i32)> = tris
        .iter()
        .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
        .filter(|(a, b)| a != b)
        .map(|(a, b)| {
            let key = ((a.min(b) as u64) << 32) | a.max(b) as u64;
            (key, if a < b { 1 } else { -1 })
        })
        .collect();
    edges.sort_unstable_by_key(|e| e.0);
    let mut out = Vec::new();
    for run in edges.chunk_by(|a, b| a.0 == b.0) {
        let net: i32 = run.iter().map(|e| e.1).sum();
        let (lo, hi) = ((run[0].0 >> 32) as u32, run[0].0 as u32);
        for _ in 0..net.unsigned_abs() {
            out.push(if net > 0 { [lo, hi] } else { [hi, lo] });
        }
    }
    out
}
