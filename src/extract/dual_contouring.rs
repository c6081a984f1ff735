//! `algorithm=dual-contouring` (Ju, Losasso, Schaefer & Warren 2002) from Hermite data
//! ([`crate::engine::hermite`]): the topology of surface nets (one vertex per sheet of each dual
//! cell, pinched edges split, so the mesh is closed, oriented and 2-manifold), each vertex
//! placed where the planes of its sheet's crossings meet.
//!
//! * **Vertex.** The minimiser of its sheet's QEF (`Σ (n_i · (x − p_i))²` over the crossings
//!   of its faces' edges; [`super::qef`]: about the mass point, eigenvalues of `AᵀA` under
//!   0.3% of the largest truncated). Uncrossed edges (open meshes) add their midpoint to the mass
//!   point only.
//! * **Kept in its cell.** The vertex is the QEF's minimiser within its dual cell (the cube
//!   between its eight voxel centres) shrunk by 2⁻¹⁰ voxel on every side ([`Qef::solve_in`]):
//!   the free minimiser when it is inside; else the least-error minimiser on the box's faces,
//!   edges and corners, each solved with those coordinates held. A feature that leaves the cell
//!   keeps the vertex on its planes where the cell meets them (moving it back towards the mass
//!   point, as before, took it off them and tilted its triangles). The shrink keeps any two
//!   cells' boxes apart, so no two vertices coincide.
//! * **Quads to triangles.** Each quad is split along the diagonal whose two triangles both
//!   face the quad's outward axis, if only one split does; else along the one whose triangles
//!   pass nearer the quad's own crossing point (the surface is there: at a sharp edge this is
//!   the diagonal on the edge).
//! * **No crossing triangles.** Where the vertices placed far from their mass points fold
//!   triangles through each other, those vertices move back towards their mass points
//!   ([`super::untangle`]).

use std::borrow::Cow;

use super::TriMesh;
use super::qef::Qef;
use super::surface_nets::{Field, net};
use super::untangle::{Tangle, untangle};
use super::vec3::{cross, dot, sub};
use crate::cancel::{Canceled, Control};
use crate::engine::hermite::Hermite;
use crate::volume::BitVolume;

/// Half the side of the box a vertex is kept in: its dual cell shrunk by 2⁻¹⁰ voxel on every
/// side (exact in f64), so no two cells' boxes touch and two vertices never coincide.
const INSET: f64 = 0.5 - 1.0 / 1024.0;

/// The dual contouring mesh of `bits` (the solid the Hermite data `h` was taken from), in
/// lattice units.
pub fn dual_contouring(bits: &BitVolume, h: &Hermite, ctl: &Control) -> Result<TriMesh, Canceled> {
    let field = Field::bits(Cow::Borrowed(bits));
    let n = net(&field, true, &ctl.stage(0.0, 0.6))?;
    let ctl2 = ctl.stage(0.6, 1.0);
    let counter = ctl2.counter(n.faces.len() as u64);
    // Each face's crossing (lattice units) and normal.
    let mut qefs = vec![Qef::default(); n.vertices];
    let mut crossing = Vec::with_capacity(n.faces.len());
    for (i, (f, q)) in n.faces.iter().zip(&n.quads).enumerate() {
        if i % 65536 == 0 {
            counter.check()?;
            counter.add(65536.min((n.faces.len() - i) as u64));
        }
        let (p, normal) = match f.lower().and_then(|l| h.find(l, f.a)) {
            Some(e) => (e.point(), e.normal),
            // Not in the Hermite data: a face on the grid's boundary (the solid cut by the
            // grid: the edge leaves the grid, where nothing is inside), or a solid other than
            // the one it was taken from. The edge's midpoint, with no normal.
            None => (n.crossings[i], [0.0; 3]),
        };
        for &v in q {
            qefs[v as usize].add(p, normal);
        }
        crossing.push(p);
    }
    let cells: Vec<[f64; 3]> = n.cells.iter().map(|c| c.map(f64::from)).collect();
    let mass: Vec<[f64; 3]> = qefs.iter().map(Qef::mass_point).collect();
    let solved: Vec<[f64; 3]> = qefs
        .iter()
        .zip(&cells)
        .map(|(q, c)| q.solve_in(c.map(|v| v - INSET), c.map(|v| v + INSET)))
        .collect();
    let mut positions = solved.clone();
    let split = |i: usize, positions: &[[f64; 3]]| {
        let (q, f, c) = (n.quads[i], &n.faces[i], crossing[i]);
        let mut dir = [0.0; 3];
        dir[f.a] = if f.plus { 1.0 } else { -1.0 };
        let splits = [
            [[q[0], q[1], q[2]], [q[0], q[2], q[3]]],
            [[q[0], q[1], q[3]], [q[1], q[2], q[3]]],
        ];
        let score = |s: &[[u32; 3]; 2]| {
            let tri = s.map(|t| t.map(|i| positions[i as usize]));
            let out = tri.iter().all(|t| dot(normal(t), dir) > 0.0);
            let near = tri
                .iter()
                .map(|t| distance2(c, t))
                .fold(f64::INFINITY, f64::min);
            (out, near)
        };
        let (a, b) = (score(&splits[0]), score(&splits[1]));
        let pick = if a.0 != b.0 {
            usize::from(b.0)
        } else {
            usize::from(b.1 < a.1)
        };
        splits[pick]
    };
    let mut triangles: Vec<[u32; 3]> = (0..n.quads.len())
        .flat_map(|i| split(i, &positions))
        .collect();
    ctl.check()?;
    let t0 = std::time::Instant::now();
    let (left, moved) = untangle(
        &mut Tangle {
            cells: &n.cells,
            mass: &mass,
            solved: &solved,
            quads: &n.quads,
            positions: &mut positions,
            triangles: &mut triangles,
        },
        split,
    );
    tracing::debug!(
        moved,
        left,
        secs = t0.elapsed().as_secs_f64(),
        "dual contouring untangled"
    );
    ctl.complete();
    Ok(TriMesh {
        positions,
        triangles,
        colors: vec![],
    })
}

fn normal(t: &[[f64; 3]; 3]) -> [f64; 3] {
    cross(sub(t[1], t[0]), sub(t[2], t[0]))
}

/// Squared distance from `p` to triangle `t` (Ericson's closest point, 5.1.5).
pub(super) fn distance2(p: [f64; 3], t: &[[f64; 3]; 3]) -> f64 {
    let [a, b, c] = *t;
    let (ab, ac, ap) = (sub(b, a), sub(c, a), sub(p, a));
    let at = |q: [f64; 3]| dot(sub(p, q), sub(p, q));
    let (d1, d2) = (dot(ab, ap), dot(ac, ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return at(a);
    }
    let bp = sub(p, b);
    let (d3, d4) = (dot(ab, bp), dot(ac, bp));
    if d3 >= 0.0 && d4 <= d3 {
        return at(b);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return at([0, 1, 2].map(|k| a[k] + v * ab[k]));
    }
    let cp = sub(p, c);
    let (d5, d6) = (dot(ab, cp), dot(ac, cp));
    if d6 >= 0.0 && d5 <= d6 {
        return at(c);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return at([0, 1, 2].map(|k| a[k] + w * ac[k]));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return at([0, 1, 2].map(|k| b[k] + w * (c[k] - b[k])));
    }
    let den = 1.0 / (va + vb + vc);
    let (v, w) = (vb * den, vc * den);
    at([0, 1, 2].map(|k| a[k] + ab[k] * v + ac[k] * w))
}
