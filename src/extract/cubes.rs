//! `algorithm=cubes`: the exact boundary of a volume's set voxels.
//!
//! 1. **Faces.** For each axis a and plane k (0..=dims[a]), the unit squares between a set and
//!    an unset voxel (outside the grid is unset), facing the unset one: two masks per plane,
//!    +a and −a.
//! 2. **Rectangles.** Each mask is merged greedily into rectangles (rows first, then as many
//!    whole rows as fit). No point inside a rectangle touches any other face (its four voxels on
//!    one side are set, on the other unset), so only rectangle boundaries meet.
//! 3. **No T-junctions.** Every rectangle corner is a vertex; each rectangle's sides are split at
//!    every corner (of any rectangle, in any plane) that lies on them, so two triangles that
//!    meet along a segment share both its ends. A rectangle with no such split points is two
//!    triangles; one with them is a fan about its centre (an interior point, so no triangle of
//!    the fan is degenerate).
//! 4. **Manifold.** Where set voxels touch only along an edge or at a point, the boundary meets
//!    itself there. A vertex is a lattice point *and* a sheet of the boundary around it: the
//!    faces at the point linked across each edge from it (the two boundary faces there, or,
//!    where two set voxels meet only along the edge, the two faces of each voxel: the solid is
//!    read as 6-connected). Each sheet is one fan, so every edge is used by exactly two
//!    triangles, once in each direction, and every vertex is manifold.
//!
//! The enclosed volume is exactly the set voxels' count (lattice units); the surface passes
//! through no voxel centre, so `method=solid` on the same grid sets exactly the same voxels.

use std::collections::HashMap;

use super::TriMesh;
use crate::cancel::{Canceled, Control};
use crate::volume::BitVolume;

/// A merged rectangle of faces: plane `k` across axis `a`, cells [u0, u1) × [v0, v1) along the
/// next two axes (b = a+1, c = a+2 mod 3), facing +a (`plus`) or −a.
#[derive(Clone, Copy, Debug)]
pub(super) struct Rect {
    pub a: usize,
    pub k: u32,
    pub plus: bool,
    pub u0: u32,
    pub v0: u32,
    pub u1: u32,
    pub v1: u32,
}

impl Rect {
    /// Lattice point (u, v) of the rectangle's plane.
    fn point(&self, u: u32, v: u32) -> [u32; 3] {
        let mut p = [0; 3];
        p[self.a] = self.k;
        p[(self.a + 1) % 3] = u;
        p[(self.a + 2) % 3] = v;
        p
    }
    /// The set voxel behind face cell (u, v).
    fn inside(&self, u: u32, v: u32) -> [u32; 3] {
        let mut p = self.point(u, v);
        if self.plus {
            p[self.a] -= 1;
        }
        p
    }
}

pub use super::faces::{boundary_counts, triangle_bound};

/// The boundary of `bits`' set voxels as a watertight, outward-oriented triangle mesh in lattice
/// units. Checks `ctl` plane by plane.
pub fn cubes(bits: &BitVolume, ctl: &Control) -> Result<TriMesh, Canceled> {
    let d = bits.dims();
    let occ = |p: [i64; 3]| {
        (0..3).all(|a| p[a] >= 0 && p[a] < i64::from(d[a]))
            && bits.get(p[0] as u32, p[1] as u32, p[2] as u32)
    };
    let rects = super::faces::rectangles(bits, &ctl.stage(0.0, 0.6))?;
    // Every rectangle corner, as a bit per lattice point ((X + 1)(Y + 1)(Z + 1) bits, the
    // volume's own size).
    let lattice = d.map(|n| u64::from(n) + 1);
    let point_index = |p: [u32; 3]| {
        ((u64::from(p[0]) * lattice[1] + u64::from(p[1])) * lattice[2] + u64::from(p[2])) as usize
    };
    let mut corners = vec![0u64; (lattice[0] * lattice[1] * lattice[2]).div_ceil(64) as usize];
    for r in &rects {
        for (u, v) in [(r.u0, r.v0), (r.u1, r.v0), (r.u1, r.v1), (r.u0, r.v1)] {
            let i = point_index(r.point(u, v));
            corners[i / 64] |= 1 << (i % 64);
        }
    }
    let is_corner = |p: [u32; 3]| {
        let i = point_index(p);
        corners[i / 64] >> (i % 64) & 1 == 1
    };
    // The corners before each word of `corners`: a corner's rank is its slot in `at_corner`.
    let mut before = Vec::with_capacity(corners.len());
    let mut total = 0u32;
    for w in &corners {
        before.push(total);
        total += w.count_ones();
    }
    let rank =
        |i: usize| before[i / 64] + (corners[i / 64] & ((1u64 << (i % 64)) - 1)).count_ones();
    let ctl = ctl.stage(0.6, 1.0);
    let counter = ctl.counter(rects.len() as u64);
    let mut out = TriMesh::default();
    // Vertices by (doubled lattice position, tag): a lattice point's tag is its sheet, an edge
    // midpoint's is 16 + the index of the set voxel whose faces it joins. Every lattice point
    // that is a vertex is a corner: its first sheet's vertex is kept by the corner's rank (the
    // points are visited plane by plane, so these are near each other in memory, where a hash
    // map's slots were not), the rest, and the midpoints, by the map.
    let mut at_corner: Vec<(u8, u32)> = vec![(u8::MAX, 0); total as usize];
    let mut ids: HashMap<([u32; 3], u64), u32, foldhash::fast::RandomState> = HashMap::default();
    let mut ring: Vec<u32> = Vec::new();
    let voxel_index = |v: [u32; 3]| -> u64 {
        (u64::from(v[0]) * u64::from(d[1]) + u64::from(v[1])) * u64::from(d[2]) + u64::from(v[2])
    };
    for (i, r) in rects.iter().enumerate() {
        if i % 4096 == 0 {
            counter.check()?;
            counter.add(4096.min((rects.len() - i) as u64));
        }
        // The boundary, counter-clockwise seen from +a: (u0,v0) → (u1,v0) → (u1,v1) → (u0,v1),
        // with every corner on a side, and the midpoint of every pinched unit edge.
        ring.clear();
        let sides = [
            ((r.u0, r.v0), (1i64, 0i64), r.u1 - r.u0),
            ((r.u1, r.v0), (0, 1), r.v1 - r.v0),
            ((r.u1, r.v1), (-1, 0), r.u1 - r.u0),
            ((r.u0, r.v1), (0, -1), r.v1 - r.v0),
        ];
        let mut vertex = |doubled: [u32; 3], tag: u64, out: &mut TriMesh| -> u32 {
            let next = out.positions.len() as u32;
            if tag < 16 && doubled.iter().all(|c| c % 2 == 0) {
                let slot = &mut at_corner[rank(point_index(doubled.map(|c| c / 2))) as usize];
                if slot.0 == u8::MAX {
                    *slot = (tag as u8, next);
                    out.positions.push(doubled.map(|c| f64::from(c) / 2.0));
                    return next;
                }
                if u64::from(slot.0) == tag {
                    return slot.1;
                }
            }
            *ids.entry((doubled, tag)).or_insert_with(|| {
                out.positions.push(doubled.map(|c| f64::from(c) / 2.0));
                next
            })
        };
        for ((u, v), (du, dv), len) in sides {
            for t in 0..len {
                let at = |t: u32| {
                    (
                        (i64::from(u) + du * i64::from(t)) as u32,
                        (i64::from(v) + dv * i64::from(t)) as u32,
                    )
                };
                let (pu, pv) = at(t);
                let p = r.point(pu, pv);
                if t == 0 || is_corner(p) {
                    // A face cell of the rectangle touching p, and the voxel behind it.
                    let cu = pu.clamp(r.u0, r.u1 - 1);
                    let cv = pv.clamp(r.v0, r.v1 - 1);
                    let tag = u64::from(sheet(&occ, p, r.a, r.inside(cu, cv)));
                    ring.push(vertex(p.map(|c| 2 * c), tag, &mut out));
                }
                // The unit edge to the next point: pinched when the two set voxels around it
                // meet only along it; then its midpoint, one per set voxel, keeps the two
                // voxels' faces apart.
                let (qu, qv) = at(t + 1);
                let q = r.point(qu, qv);
                if pinched(&occ, p, q) {
                    let cell = (
                        pu.min(qu).clamp(r.u0, r.u1 - 1),
                        pv.min(qv).clamp(r.v0, r.v1 - 1),
                    );
                    let mid = [0, 1, 2].map(|k| p[k] + q[k]);
                    let tag = 16 + voxel_index(r.inside(cell.0, cell.1));
                    ring.push(vertex(mid, tag, &mut out));
                }
            }
        }
        if !r.plus {
            ring.reverse();
        }
        if ring.len() == 4 {
            out.triangles.push([ring[0], ring[1], ring[2]]);
            out.triangles.push([ring[0], ring[2], ring[3]]);
        } else {
            let mut c = [0.0; 3];
            c[r.a] = f64::from(r.k);
            c[(r.a + 1) % 3] = (f64::from(r.u0) + f64::from(r.u1)) / 2.0;
            c[(r.a + 2) % 3] = (f64::from(r.v0) + f64::from(r.v1)) / 2.0;
            let ci = out.positions.len() as u32;
            out.positions.push(c);
            for j in 0..ring.len() {
                out.triangles
                    .push([ci, ring[j], ring[(j + 1) % ring.len()]]);
            }
        }
    }
    ctl.complete();
    Ok(out)
}

/// Is the unit lattice edge p–q (one axis apart) pinched: of the four voxels around it, exactly
/// two are set and they are diagonal (they meet only along the edge)?
fn pinched(occ: &impl Fn([i64; 3]) -> bool, p: [u32; 3], q: [u32; 3]) -> bool {
    let e = (0..3).find(|&k| p[k] != q[k]).expect("a unit edge");
    let lo = p[e].min(q[e]);
    let (b, c) = ((e + 1) % 3, (e + 2) % 3);
    let around = |i: i64, j: i64| {
        let mut v = [0i64; 3];
        v[e] = i64::from(lo);
        v[b] = i64::from(p[b]) - 1 + i;
        v[c] = i64::from(p[c]) - 1 + j;
        occ(v)
    };
    // Read lazily: most edges differ from a pinch at the first or second voxel.
    let first = around(0, 0);
    first != around(1, 0) && first == around(1, 1) && first != around(0, 1)
}

/// The sheet of the boundary at lattice point `p` that the face of rectangle-axis `a` with
/// set voxel `inside` belongs to: an id (0..12) shared by exactly the faces at `p` that form one
/// fan around it. (Octant `o` of `p` is the voxel at `p − 1 + (o's bits)`.)
fn sheet(occ: &impl Fn([i64; 3]) -> bool, p: [u32; 3], a: usize, inside: [u32; 3]) -> u8 {
    sheet_with(occ, p, a, inside, |_| 0)
}

/// [`sheet`] with the pinched half-edges `join` (bit e·2 + side) linked by their unset voxels
/// (see [`sheets_for`]); `join` is a function of the block's occupancy.
pub(super) fn sheet_with(
    occ: &impl Fn([i64; 3]) -> bool,
    p: [u32; 3],
    a: usize,
    inside: [u32; 3],
    join: impl FnOnce(u8) -> u8,
) -> u8 {
    let set = block(occ, p);
    let o = (0..3).fold(0u8, |o, k| {
        if k == a {
            o
        } else {
            o | (((inside[k] + 1 - p[k]) as u8) << k)
        }
    });
    let face = face_index(a, o);
    match join(set) {
        0 => SHEETS.get_or_init(sheets)[set as usize][face],
        j => sheets_for(set, j)[face],
    }
}

/// The occupancy of the 2×2×2 block around lattice point `p`: bit o is the voxel at
/// `p − 1 + (o's bits)`.
pub(super) fn block(occ: &impl Fn([i64; 3]) -> bool, p: [u32; 3]) -> u8 {
    let mut set = 0u8;
    for o in 0..8u8 {
        let q = [0, 1, 2].map(|k| i64::from(p[k]) - 1 + i64::from(o >> k & 1));
        if occ(q) {
            set |= 1 << o;
        }
    }
    set
}

/// The internal face of a 2×2×2 block across axis `a` between octant `o` (bit a clear) and
/// `o | 1 << a`, as 0..12: a·4 + o's other two bits.
pub(super) fn face_index(a: usize, o: u8) -> usize {
    let (b, c) = ((a + 1) % 3, (a + 2) % 3);
    a * 4 + usize::from(o >> b & 1) + 2 * usize::from(o >> c & 1)
}

pub(super) static SHEETS: std::sync::OnceLock<Vec<[u8; 12]>> = std::sync::OnceLock::new();

/// For each occupancy of a 2×2×2 block, the sheet (fan) of each of its 12 internal faces that
/// is a boundary face ([`sheets_for`] with no pinch joined).
pub(super) fn sheets() -> Vec<[u8; 12]> {
    (0..256u32).map(|set| sheets_for(set as u8, 0)).collect()
}

/// The sheets of block occupancy `set`. Faces around each of the six half-edges from the
/// centre are linked: the two boundary faces there when there are two; when there are four
/// (two set voxels meeting only along the edge) the two of the same set voxel (the solid read
/// as 6-connected), or, where `join` has the half-edge's bit (e·2 + side), the two of the same
/// unset voxel. Sheets are the linked groups, named by their lowest face.
pub(super) fn sheets_for(set: u8, join: u8) -> [u8; 12] {
    let occupied = |o: u8| set >> o & 1 == 1;
    let mut parent: [u8; 12] = std::array::from_fn(|i| i as u8);
    fn find(parent: &mut [u8; 12], i: u8) -> u8 {
        let mut r = i;
        while parent[r as usize] != r {
            r = parent[r as usize];
        }
        parent[i as usize] = r;
        r
    }
    for e in 0..3 {
        for side in 0..2u8 {
            // The boundary faces around the half-edge along e on `side`, with their set and
            // unset voxels.
            let mut around = Vec::new();
            for a in (0..3).filter(|&a| a != e) {
                for o in (0..8u8).filter(|o| o >> a & 1 == 0 && o >> e & 1 == side) {
                    let o2 = o | 1 << a;
                    if occupied(o) != occupied(o2) {
                        let (v, u) = if occupied(o) { (o, o2) } else { (o2, o) };
                        around.push((face_index(a, o) as u8, v, u));
                    }
                }
            }
            let mut link = |x: u8, y: u8| {
                let (rx, ry) = (find(&mut parent, x), find(&mut parent, y));
                parent[rx.max(ry) as usize] = rx.min(ry);
            };
            let by_unset = join >> (e * 2 + usize::from(side)) & 1 == 1;
            match around.len() {
                2 => link(around[0].0, around[1].0),
                4 => {
                    for i in 0..4 {
                        for j in i + 1..4 {
                            let same = if by_unset {
                                around[i].2 == around[j].2
                            } else {
                                around[i].1 == around[j].1
                            };
                            if same {
                                link(around[i].0, around[j].0);
                            }
                        }
                    }
                }
                _ => {}
            }
        }
    }
    std::array::from_fn(|i| find(&mut parent, i as u8))
}
