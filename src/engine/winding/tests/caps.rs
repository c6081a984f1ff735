//! The caps close a mesh's boundary: closed as a chain, long cycles in chunks.
//!
//! Not here: what the fill makes of the caps (`blocks`, `bounds`).

use super::*;

#[test]
fn caps_close_the_boundary() {
    // An octahedron without two faces: caps make it closed again (every edge balanced).
    let m = octahedron();
    let open = Mesh::new(m.positions().to_vec(), m.triangles()[2..].to_vec()).unwrap();
    let (apexes, caps) = closing_caps(&open);
    assert_eq!(apexes.len(), 1);
    assert_eq!(caps.len(), 4);
    let mut p = open.positions().to_vec();
    p.extend(apexes);
    let mut t = open.triangles().to_vec();
    t.extend(caps);
    let closed = Mesh::new(p, t).unwrap();
    let d = closed.diagnostics();
    assert_eq!((d.boundary_edges, d.non_manifold_edges), (0, 0));
}

#[test]
fn long_cycles_are_capped_in_chunks() {
    // A bumpy sheet has one boundary cycle of 160 edges: capped in 20 chunks of 8, then the
    // 20 chords in 3, then those 3; the result is closed, and its winding number is an integer
    // everywhere.
    let (p, t) = sheet(40);
    let open = Mesh::new(p, t).unwrap();
    let (apexes, caps) = closing_caps(&open);
    assert_eq!(apexes.len(), 20 + 3 + 1);
    let mut p = open.positions().to_vec();
    p.extend(apexes);
    let mut t = open.triangles().to_vec();
    t.extend(caps);
    let closed = Mesh::new(p, t).unwrap();
    // Closed as a chain (collinear chunks make degenerate, non-manifold fans): no boundary.
    assert_eq!(closing_caps(&closed).1.len(), 0);
    let tris: Vec<_> = (0..closed.triangles().len())
        .map(|i| closed.triangle(i))
        .collect();
    for q in [
        [0.3, 0.6, 0.05],
        [0.5, 0.5, -0.3],
        [2.0, 0.1, 0.0],
        [0.2, 0.9, 0.4],
    ] {
        let w = exact_winding_number(tris.iter().copied(), q);
        assert!((w - w.round()).abs() < 1e-9, "{q:?}: {w}");
    }
}
