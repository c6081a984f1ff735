//! `algorithm=marching-cubes`: one vertex per grid edge whose two voxels differ (its crossing
//! point), one polygon per surface piece of each dual cell — the polygons of marching cubes,
//! taken as the dual of [`super::surface_nets`]' quad mesh, so that the ambiguous faces and
//! cells are resolved by one rule on both sides (no holes, no non-manifold edges).
//!
//! * **Vertices**: the crossing point of each boundary face's grid edge (between its two voxel
//!   centres): the zero of the linear interpolation of a distance or density volume's values
//!   (kept within [1/64, 63/64] of the edge), the midpoint for a bit volume.
//! * **Polygons**: for each surface-nets vertex (a sheet of a dual cell), the crossing points of
//!   its quads in order around it. The ambiguity rule is therefore that of surface nets: on a
//!   face whose two inside voxels are diagonal, the inside voxels are kept apart (inside read as
//!   6-connected) unless that would make the two cells' pieces meet twice, in which case they
//!   are joined (`pinches`); a cell's pieces are the linked groups of its faces. This is not
//!   Lewiner's MC33 table (which reproduces the trilinear interpolant's topology inside a cell);
//!   it is a consistent choice per face, which is what watertightness needs.
//! * **Triangles**: a triangle as it is, a quadrilateral split along its shorter diagonal, a
//!   larger polygon fanned around its centroid (an added vertex).

use std::collections::HashMap;

use super::TriMesh;
use super::surface_nets::{Field, net};
use crate::cancel::{Canceled, Control};

/// The marching cubes mesh of `field`, in lattice units.
pub fn marching_cubes(field: &Field<'_>, ctl: &Control) -> Result<TriMesh, Canceled> {
    let n = net(field, true, &ctl.stage(0.0, 0.7))?;
    let ctl = ctl.stage(0.7, 1.0);
    let nv = n.vertices;
    let mut across: HashMap<(u32, u32), u32, foldhash::fast::RandomState> =
        HashMap::with_capacity_and_hasher(4 * n.quads.len(), Default::default());
    let mut first = vec![u32::MAX; nv];
    for (qi, q) in n.quads.iter().enumerate() {
        for j in 0..4 {
            across.insert((q[j], q[(j + 1) % 4]), qi as u32);
            if first[q[j] as usize] == u32::MAX {
                first[q[j] as usize] = qi as u32;
            }
        }
    }
    let mut out = TriMesh {
        positions: n.crossings,
        triangles: Vec::with_capacity(2 * n.quads.len()),
        colors: vec![],
    };
    let counter = ctl.counter(nv as u64);
    let mut ring: Vec<u32> = Vec::new();
    for v in 0..nv as u32 {
        if v % 65536 == 0 {
            counter.check()?;
            counter.add(65536.min(u64::from(nv as u32 - v)));
        }
        ring.clear();
        let start = first[v as usize];
        let mut q = start;
        // Across the quad's edge leaving v: clockwise around v seen from outside (the quads
        // are counter-clockwise); a sheet has at most 12 faces.
        for _ in 0..12 {
            ring.push(q);
            let quad = n.quads[q as usize];
            let i = quad.iter().position(|&w| w == v).expect("v is a corner");
            q = across[&(quad[(i + 1) % 4], v)];
            if q == start {
                break;
            }
        }
        debug_assert_eq!(q, start, "the quads around a vertex close");
        ring.reverse();
        let p = |i: u32| out.positions[i as usize];
        match ring.len() {
            3 => out.triangles.push([ring[0], ring[1], ring[2]]),
            4 => {
                let d2 =
                    |a: [f64; 3], b: [f64; 3]| (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>();
                if d2(p(ring[0]), p(ring[2])) <= d2(p(ring[1]), p(ring[3])) {
                    out.triangles.push([ring[0], ring[1], ring[2]]);
                    out.triangles.push([ring[0], ring[2], ring[3]]);
                } else {
                    out.triangles.push([ring[0], ring[1], ring[3]]);
                    out.triangles.push([ring[1], ring[2], ring[3]]);
                }
            }
            k => {
                let mut c = [0.0; 3];
                for &i in &ring {
                    for (ca, pa) in c.iter_mut().zip(p(i)) {
                        *ca += pa / k as f64;
                    }
                }
                let ci = out.positions.len() as u32;
                out.positions.push(c);
                for j in 0..k {
                    out.triangles.push([ci, ring[j], ring[(j + 1) % k]]);
                }
            }
        }
    }
    ctl.complete();
    Ok(out)
}
