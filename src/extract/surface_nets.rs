//! `algorithm=surface-nets`: one vertex per surface component of each dual cell (the cube
//! between eight voxel centres), one quad per grid edge whose two voxels differ — Gibson's
//! surface nets, with the non-manifold cases split.
//!
//! * **Inside.** A bit volume's set voxels; a distance volume's negative values (sign bit
//!   set); a density volume's values over half
//!   its full value (level max/2: more than half of the voxel's samples covered). Outside the grid is outside.
//! * **Topology.** The quads are the boundary faces of the inside voxels (each face is the
//!   grid edge between its two voxel centres); a face's corners are lattice points, each the
//!   centre of a dual cell. A dual cell gets one vertex per *sheet* of the boundary around its
//!   lattice point (`cubes::sheet_with`): faces linked across each half-edge from the point —
//!   the two boundary faces there, or where the edge is *pinched* (its two inside voxels are
//!   diagonal), the two faces of each inside voxel (inside read as 6-connected), unless either
//!   cell at the edge's ends joins those two voxels through its other corners: then the two
//!   faces of each outside voxel. That choice is made once per edge, so both cells agree, and
//!   it keeps any two cells from sharing more than one quad edge: every edge of the mesh is in
//!   exactly two triangles, once in each direction, and every vertex is a disk.
//! * **Positions.** Distance and density volumes: the mean of the sheet's crossing points, each
//!   on the segment between its face's two voxel centres at the linear interpolation's zero,
//!   pulled into [1/64, 63/64] of the segment. Bit volumes: the mean of the faces' centres, then
//!   `RELAX` rounds of Gibson's constrained relaxation, each round Taubin's two
//!   steps (towards the mean of the vertex's neighbours by λ = 0.5, then by μ = −0.526), so the
//!   steps are smoothed away without the shrinking of plain averaging; every vertex is clamped
//!   to its cell shrunk by 1/16 voxel after each step. The rounds work in f32 on each vertex's
//!   offset from its lattice point.
//! * Each quad is split along its shorter diagonal, counter-clockwise seen from outside.

use rayon::prelude::*;
use std::borrow::Cow;

use super::TriMesh;
use super::slabs::Slabs;
use crate::cancel::{Canceled, Control};
use crate::volume::{BitVolume, Volume};

/// Faces per run of the quad mesh's parallel build (about; runs end at slab boundaries). At
/// 2¹⁷ igea's 917K faces at 518³ made 7 runs, 4 on one of two threads and 3 on the other;
/// 2¹⁶ makes 14 (the runs' median 0.089 → 0.067 s, eight alternations; 2¹⁵ was no better).
const RUN_FACES: usize = 1 << 16;

/// Rounds of constrained relaxation for bit volumes.
pub const RELAX: usize = 12;

/// The scalar field a mesh is taken from: inside voxels, and for distance and density volumes
/// a value per voxel whose zero is the surface (negative inside).
pub struct Field<'a> {
    pub inside: Cow<'a, BitVolume>,
    value: Option<Value<'a>>,
    /// The value outside the grid.
    outside: f64,
}

/// A voxel's value.
type Value<'a> = Box<dyn Fn(u32, u32, u32) -> f64 + Sync + 'a>;

/// The inside voxels of `v` (see the module's "Inside").
pub fn inside(v: &Volume) -> Cow<'_, BitVolume> {
    let g = *v.grid();
    let from = |inside: &dyn Fn(u32, u32, u32) -> bool| {
        let mut b = BitVolume::new(g);
        for x in 0..g.dims[0] {
            for y in 0..g.dims[1] {
                let col = b.column_mut(x, y);
                for z in 0..g.dims[2] {
                    if inside(x, y, z) {
                        col[(z / 64) as usize] |= 1 << (z % 64);
                    }
                }
            }
        }
        Cow::Owned(b)
    };
    match v {
        Volume::Bits(b) => Cow::Borrowed(b),
        Volume::Density(d) => from(&|x, y, z| 2 * u32::from(d.get(x, y, z)) > u32::from(d.max())),
        Volume::Distance(d) => from(&|x, y, z| d.get(x, y, z).is_sign_negative()),
        Volume::SparseDistance(d) if !d.background().is_sign_negative() => {
            Cow::Owned(sparse_inside(d))
        }
        Volume::SparseDistance(d) => {
            let r = d.reader();
            from(&|x, y, z| r.get(x, y, z).is_sign_negative())
        }
        other => Cow::Owned(super::occupancy(other)),
    }
}

/// The negative voxels of a sparse distance volume whose background is not negative, brick by
/// brick (its tiles when their value is negative, its bricks' negative voxels) instead of a
/// tree lookup per voxel.
fn sparse_inside(d: &crate::volume::Sparse<f32>) -> BitVolume {
    use crate::volume::sparse::BRICK;
    let g = *d.grid();
    let dims = g.dims;
    let mut b = BitVolume::new(g);
    let mut fill = |at: [u32; 3], neg: &dyn Fn(usize) -> bool| {
        for dx in 0..BRICK {
            let x = at[0] * BRICK + dx;
            for dy in 0..BRICK {
                let y = at[1] * BRICK + dy;
                if x >= dims[0] || y >= dims[1] {
                    continue;
                }
                let col = b.column_mut(x, y);
                for dz in 0..BRICK {
                    let z = at[2] * BRICK + dz;
                    if z < dims[2] && neg(((dx * BRICK + dy) * BRICK + dz) as usize) {
                        col[(z / 64) as usize] |= 1 << (z % 64);
                    }
                }
            }
        }
    };
    if d.tile_value().is_sign_negative() {
        for at in d.tiles() {
            fill(at, &|_| true);
        }
    }
    for (at, values) in d.bricks() {
        fill(at, &|i| values[i].is_sign_negative());
    }
    b
}

impl<'a> Field<'a> {
    /// The field of `v`.
    pub fn of(v: &'a Volume) -> Field<'a> {
        Field::new(v, inside(v))
    }

    /// A bit volume's field (no values).
    pub fn bits(inside: Cow<'a, BitVolume>) -> Field<'a> {
        Field {
            inside,
            value: None,
            outside: 1.0,
        }
    }

    /// The field of `v` with its inside voxels already taken ([`inside`]).
    pub fn new(v: &'a Volume, inside: Cow<'a, BitVolume>) -> Field<'a> {
        let (value, outside): (Option<Value<'a>>, f64) = match v {
            Volume::Density(d) => {
                let half = f64::from(d.max()) / 2.0;
                (
                    Some(Box::new(move |x, y, z| half - f64::from(d.get(x, y, z)))),
                    half,
                )
            }
            Volume::Distance(d) => (
                Some(Box::new(move |x, y, z| f64::from(d.get(x, y, z)))),
                f64::INFINITY,
            ),
            Volume::SparseDistance(d) => {
                let r = d.reader();
                (
                    Some(Box::new(move |x, y, z| f64::from(r.get(x, y, z)))),
                    f64::INFINITY,
                )
            }
            _ => (None, 1.0),
        };
        Field {
            inside,
            value,
            outside,
        }
    }

    fn value(&self, p: [i64; 3]) -> f64 {
        let d = self.inside.dims();
        let f = self.value.as_ref().expect("a valued field");
        if (0..3).all(|a| p[a] >= 0 && p[a] < i64::from(d[a])) {
            f(p[0] as u32, p[1] as u32, p[2] as u32)
        } else {
            self.outside
        }
    }
}

/// A unit boundary face: across axis `a` at plane `k`, cell (u, v) on axes a+1, a+2; `plus`:
/// the inside voxel is below (facing +a).
#[derive(Clone, Copy, Default)]
pub(super) struct Face {
    pub(super) a: usize,
    k: u32,
    u: u32,
    v: u32,
    pub(super) plus: bool,
}

impl Face {
    /// Its corner (u + du, v + dv): a lattice point.
    pub(super) fn point(&self, du: u32, dv: u32) -> [u32; 3] {
        let mut p = [0; 3];
        p[self.a] = self.k;
        p[(self.a + 1) % 3] = self.u + du;
        p[(self.a + 2) % 3] = self.v + dv;
        p
    }
    /// The face's grid edge: its lower voxel (the other is one step along `a`); `None` for a
    /// face on the grid's lower side (its outside voxel is off the grid: no edge between voxel
    /// centres crosses it).
    pub(super) fn lower(&self) -> Option<[u32; 3]> {
        let mut p = self.point(0, 0);
        p[self.a] = p[self.a].checked_sub(1)?;
        Some(p)
    }
    fn inside(&self) -> [u32; 3] {
        let mut p = self.point(0, 0);
        if self.plus {
            p[self.a] -= 1;
        }
        p
    }
}

/// Column (x, y) of `bits`; none (no words) outside the grid.
fn column_or_none(bits: &BitVolume, x: i64, y: i64) -> &[u64] {
    let d = bits.dims();
    if x < 0 || y < 0 || x >= i64::from(d[0]) || y >= i64::from(d[1]) {
        &[]
    } else {
        bits.column(x as u32, y as u32)
    }
}

/// Word `w` of a column from [`column_or_none`] (0 past its end).
fn word(c: &[u64], w: usize) -> u64 {
    c.get(w).copied().unwrap_or(0)
}

/// The faces whose lowest lattice x is `x`, appended to `out` (the tests' view of
/// [`for_faces_at`]).
#[cfg(test)]
pub(super) fn faces_at(bits: &BitVolume, x: u32, out: &mut Vec<Face>) {
    for_faces_at(bits, x, |f| out.push(f));
}

/// Each face whose lowest lattice x is `x`, given to `emit` as it is found — row by row (y),
/// word by word along z, and in each word the faces across x, then y, then z — so a run makes
/// each face's quad at once instead of first collecting the plane's faces into an array.
#[inline(always)]
pub(super) fn for_faces_at(bits: &BitVolume, x: u32, mut emit: impl FnMut(Face)) {
    let d = bits.dims();
    let wpc = bits.words_per_column();
    let col = |x: i64, y: i64| column_or_none(bits, x, y);
    for y in 0..=d[1] {
        let c = col(i64::from(x), i64::from(y));
        let cx = col(i64::from(x) - 1, i64::from(y));
        let cy = col(i64::from(x), i64::from(y) - 1);
        for w in 0..wpc {
            let base = (w * 64) as u32;
            let cw = word(c, w);
            let (bx, by) = (word(cx, w), word(cy, w));
            // Empty, with the words before it along x and y and the voxel below it (seven in
            // ten of igea-subdiv4 518³'s words): no face.
            let carry = if w > 0 { word(c, w - 1) >> 63 } else { 0 };
            if cw | bx | by | carry == 0 {
                continue;
            }
            // Across x at plane x (voxel x − 1 below), and across y at plane y.
            for (a, below) in [(0, bx), (1, by)] {
                let mut t = below ^ cw;
                while t != 0 {
                    let z = base + t.trailing_zeros();
                    t &= t - 1;
                    let plus = below >> (z - base) & 1 == 1;
                    let (u, v) = if a == 0 { (y, z) } else { (z, x) };
                    if (a == 0 && y < d[1]) || (a == 1 && x < d[0]) {
                        emit(Face {
                            a,
                            k: if a == 0 { x } else { y },
                            u,
                            v,
                            plus,
                        });
                    }
                }
            }
            // Across z, within the column (x, y) when it is in the grid.
            if x < d[0] && y < d[1] {
                let below = cw << 1 | carry;
                let mut t = below ^ cw;
                while t != 0 {
                    let k = base + t.trailing_zeros();
                    t &= t - 1;
                    emit(Face {
                        a: 2,
                        k,
                        u: x,
                        v: y,
                        plus: below >> (k - base) & 1 == 1,
                    });
                }
                // The top face of the last voxel.
                if w + 1 == wpc && d[2].is_multiple_of(64) && cw >> 63 == 1 {
                    emit(Face {
                        a: 2,
                        k: d[2],
                        u: x,
                        v: y,
                        plus: true,
                    });
                }
            }
        }
    }
}

/// The surface nets mesh of `field`, in lattice units.
pub fn surface_nets(field: &Field<'_>, ctl: &Control) -> Result<TriMesh, Canceled> {
    let Net {
        cells,
        quads,
        sums,
        offsets,
        ..
    } = net(field, false, &ctl.stage(0.0, 0.7))?;
    let t0 = std::time::Instant::now();
    let positions: Vec<[f64; 3]> = if field.value.is_none() {
        // Each vertex's mean of its faces' centres (its offset), relaxed.
        relax(offsets, &quads, &cells, RELAX, &ctl.stage(0.7, 0.95))?
    } else {
        // Each vertex's mean of its crossings.
        sums.par_iter()
            .map(|s| [s[0] / s[3], s[1] / s[3], s[2] / s[3]])
            .collect()
    };
    let t1 = std::time::Instant::now();
    // Freed first: the triangles take these pages, not fresh ones.
    drop((cells, sums));
    // Each quad split along its shorter diagonal (the first when they are equal).
    // Not zeroed first: the pages kept from `cells` would be cleared by one thread.
    let mut triangles: Vec<[u32; 3]> = Vec::with_capacity(2 * quads.len());
    triangles.spare_capacity_mut()[..2 * quads.len()]
        .par_chunks_mut(2)
        .zip(quads.par_iter())
        .for_each(|(pair, q)| {
            let p = q.map(|i| positions[i as usize]);
            let d2 = |a: [f64; 3], b: [f64; 3]| (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>();
            let split = if d2(p[0], p[2]) <= d2(p[1], p[3]) {
                [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]
            } else {
                [[q[0], q[1], q[3]], [q[1], q[2], q[3]]]
            };
            pair[0].write(split[0]);
            pair[1].write(split[1]);
        });
    // SAFETY: the first 2 · quads entries were written just above, a pair per quad.
    unsafe { triangles.set_len(2 * quads.len()) };
    let out = TriMesh {
        positions,
        triangles,
        colors: vec![],
    };
    tracing::debug!(
        relax_s = (t1 - t0).as_secs_f64(),
        split_s = t1.elapsed().as_secs_f64(),
        "surface nets"
    );
    ctl.complete();
    Ok(out)
}

/// The quad mesh surface nets, marching cubes and dual contouring are made from: a quad per
/// boundary face (its corners the sheets of its four lattice points, counter-clockwise seen
/// from outside), each face's crossing point, and for a valued field each vertex's sum of its
/// faces' crossing points (and their count), for a bit volume each vertex's mean of its faces'
/// centres (`slabs::sheet_offsets`).
pub(super) struct Net {
    /// The boundary faces, in order of their lowest lattice x (empty unless asked for).
    pub faces: Vec<Face>,
    pub quads: Vec<[u32; 4]>,
    /// Each face's crossing point (empty unless asked for).
    pub crossings: Vec<[f64; 3]>,
    /// Each vertex's sum of its crossings and their count (a valued field only, else empty).
    pub(super) sums: Vec<[f64; 4]>,
    /// Each vertex's mean of its faces' centres less its lattice point, lane 3 zero (a bit
    /// volume only, else empty).
    pub(super) offsets: Vec<[f32; 4]>,
    /// Each vertex's lattice point (the centre of its dual cell).
    pub cells: Vec<[u32; 3]>,
    pub vertices: usize,
}

/// The [`Net`] of `field`; its `faces` and `crossings` are left empty unless `full` (surface
/// nets needs only the quads and the crossings' sums or the faces' centres).
pub(super) fn net(field: &Field<'_>, full: bool, ctl: &Control) -> Result<Net, Canceled> {
    net_in_runs(field, full, ctl, RUN_FACES)
}

/// The [`Net`] of `field`, built in runs of about `run_faces` faces.
pub(super) fn net_in_runs(
    field: &Field<'_>,
    full: bool,
    ctl: &Control,
    run_faces: usize,
) -> Result<Net, Canceled> {
    let bits: &BitVolume = &field.inside;
    let t0 = std::time::Instant::now();
    // The faces are counted plane by plane first (and found again by each run, where they are
    // used at once: no array of them unless asked for), in the pass that finds the pinched
    // edges; then the pinches are decided.
    let (counts, edges) = super::faces::plane_counts_and_pinches(bits, &ctl.stage(0.0, 0.2))?;
    let joins = super::pinches::Joins::decide(bits, &edges);
    drop(edges);
    let t1 = std::time::Instant::now();
    // Faces before each plane.
    let mut before = Vec::with_capacity(counts.len() + 1);
    before.push(0usize);
    for c in &counts {
        before.push(before.last().expect("a count") + c);
    }
    let total = *before.last().expect("a count");
    let ctl2 = ctl.stage(0.2, 1.0);
    let counter = ctl2.counter(total as u64);
    // The faces in runs of whole lattice slabs, one run a task: each numbers its vertices from
    // its first slab on, and the runs are joined where they share a slab. The runs depend on
    // the faces only, not on the threads, so the sums (and the mesh) are the same on any
    // machine. A cut is a plane: the first at or after the run's share of the faces, and no
    // run is empty (no faces: no runs).
    let runs = total.div_ceil(run_faces.max(1)).max(1);
    let mut cuts = vec![0usize];
    for r in 1..runs {
        let i = total * r / runs;
        let x = before.partition_point(|&b| b < i);
        if before[x] < total && before[x] > before[*cuts.last().expect("a cut")] {
            cuts.push(x);
        }
    }
    let planes = counts.len();
    if before[*cuts.last().expect("a cut")] < total {
        cuts.push(planes);
    }
    // Each run fills its faces' quads (and faces and crossings) in place; the quads are not
    // zeroed first (a block the allocator kept would be cleared by one thread, 15 MB at igea
    // 518³).
    let mut quads: Vec<[u32; 4]> = Vec::with_capacity(total);
    let mut faces = vec![Face::default(); if full { total } else { 0 }];
    let mut crossings = vec![[0.0f64; 3]; if full { total } else { 0 }];
    // Each run numbers its vertices into its own part of one array of lattice points (and of
    // shapes, for a bit volume), with room for all it can have (`slabs::room`): the runs'
    // parts are then moved together in place, in one block of memory where arrays of their
    // own took as much again, in small pages, one fault each.
    let last = bits.dims()[0];
    let valued = field.value.is_some();
    let rooms: Vec<usize> = cuts
        .windows(2)
        .map(|w| {
            // Numbered up to the next run's first slab.
            let upto = (w[1] as u32).min(last) as usize;
            super::slabs::room(before[upto + 1] - before[w[0].saturating_sub(1)])
        })
        .collect();
    let room_total: usize = rooms.iter().sum();
    let mut cells = vec![[0u32; 3]; room_total];
    let mut shapes = vec![0u32; if valued { 0 } else { room_total }];
    let mut jobs = Vec::new();
    let (mut q_rest, mut f_rest, mut c_rest) = (
        &mut quads.spare_capacity_mut()[..total],
        &mut faces[..],
        &mut crossings[..],
    );
    let (mut p_rest, mut s_rest) = (&mut cells[..], &mut shapes[..]);
    for (w, &room) in cuts.windows(2).zip(&rooms) {
        let len = before[w[1]] - before[w[0]];
        let (q, qr) = std::mem::take(&mut q_rest).split_at_mut(len);
        let (f, fr) = std::mem::take(&mut f_rest).split_at_mut(if full { len } else { 0 });
        let (c, cr) = std::mem::take(&mut c_rest).split_at_mut(if full { len } else { 0 });
        let (p, pr) = std::mem::take(&mut p_rest).split_at_mut(room);
        let (sh, shr) = std::mem::take(&mut s_rest).split_at_mut(if valued { 0 } else { room });
        (q_rest, f_rest, c_rest, p_rest, s_rest) = (qr, fr, cr, pr, shr);
        jobs.push((w[0] as u32..w[1] as u32, q, f, c, p, sh));
    }
    // The runs' parts cover every quad (the `set_len` below relies on it).
    assert!(q_rest.is_empty(), "the runs hold every face");
    let t2 = std::time::Instant::now();
    let parts = jobs
        .into_par_iter()
        .map(|(planes, q, f, c, p, sh)| {
            let upto = planes.end.min(last);
            run(field, &joins, planes, upto, q, f, c, p, sh, &counter)
        })
        .collect::<Result<Vec<Run>, Canceled>>()?;
    // SAFETY: the runs' parts of the spare capacity cover its first `total` entries (asserted
    // above), and each run wrote every entry of its part (`run` asserts it).
    unsafe { quads.set_len(total) };
    let t3 = std::time::Instant::now();
    // Join the runs: run r's vertices from `shared` on are the first of run r + 1's.
    let mut starts = Vec::with_capacity(parts.len());
    let mut start = 0u32;
    // Allocated once (grown by `extend`, the copies took a tenth of the build).
    let total = parts.iter().map(|p| p.count).sum::<usize>()
        - parts[..parts.len().saturating_sub(1)]
            .iter()
            .map(|p| p.count - p.shared)
            .sum::<usize>();
    let mut sums = Vec::with_capacity(if valued { total } else { 0 });
    // Each run's kept vertices: where its part of `shapes` begins, and how many.
    let mut kept = Vec::with_capacity(parts.len());
    // Where the next run's part of `cells` (and `shapes`) begins, and where its vertices go.
    let (mut from, mut to) = (0usize, 0usize);
    let mut carry: Vec<[f64; 4]> = Vec::new();
    let n = parts.len();
    for (r, (mut part, room)) in parts.into_iter().zip(rooms).enumerate() {
        starts.push(start);
        // The shared slab's sums are split between the two runs; its offsets are the same in
        // both (they depend on the blocks only).
        for (s, c) in part.sums.iter_mut().zip(&carry) {
            *s = [0, 1, 2, 3].map(|k| c[k] + s[k]);
        }
        let mut keep = part.count;
        if r + 1 < n {
            if valued {
                carry = part.sums.split_off(part.shared);
            }
            keep = part.shared;
            start += part.shared as u32;
        }
        sums.extend(part.sums);
        // Moved down (never up: `to` ≤ `from`), so nothing not yet moved is overwritten.
        cells.copy_within(from..from + keep, to);
        kept.push((from, keep));
        from += room;
        to += keep;
    }
    // The offsets from the shapes, each run's in parallel (one pass over fresh pages by
    // both threads, where one thread made them all in the loop above: the join took
    // 0.0068–0.0072 s at igea 518³, now 0.0046–0.0051 s).
    // Not zeroed first (a kept block would be cleared by one thread).
    let mut offsets: Vec<[f32; 4]> = Vec::with_capacity(if valued { 0 } else { to });
    if !valued {
        let spare = &mut offsets.spare_capacity_mut()[..to];
        let parts = crate::split_lengths(spare, kept.iter().map(|&(_, keep)| keep));
        parts
            .into_par_iter()
            .zip(kept)
            .for_each(|(out, (from, keep))| {
                for (o, &c) in out.iter_mut().zip(&shapes[from..from + keep]) {
                    o.write(super::slabs::shape_offset(c));
                }
            });
        // SAFETY: the parts cover the first `to` entries (their lengths are the runs' kept
        // vertices, summing to `to`), and each entry of a part of length `keep` was written
        // from one of the `keep` shapes of `shapes[from..from + keep]` (a slice of exactly that
        // length, or a panic) just above.
        unsafe { offsets.set_len(to) };
    }
    drop(shapes);
    cells.truncate(to);
    let lens = cuts.windows(2).map(|w| before[w[1]] - before[w[0]]);
    let jobs: Vec<_> = crate::split_lengths(&mut quads, lens)
        .into_iter()
        .zip(starts)
        .collect();
    jobs.into_par_iter().for_each(|(q, offset)| {
        for v in q.iter_mut().flatten() {
            *v += offset;
        }
    });
    tracing::debug!(
        counts_and_pinches_s = (t1 - t0).as_secs_f64(),
        cuts_s = (t2 - t1).as_secs_f64(),
        runs_s = (t3 - t2).as_secs_f64(),
        join_s = t3.elapsed().as_secs_f64(),
        faces = total,
        "net"
    );
    ctl.complete();
    Ok(Net {
        faces,
        quads,
        crossings,
        vertices: cells.len(),
        sums,
        offsets,
        cells,
    })
}

/// A run of faces' part of a [`Net`], its vertices numbered from its first slab on.
struct Run {
    /// Each vertex's sum of crossings (a valued field only).
    sums: Vec<[f64; 4]>,
    /// Vertices numbered (their lattice points and shapes are in the run's part of the arrays
    /// it was given).
    count: usize,
    /// The first vertex of slab `upto` (shared with the next run).
    shared: usize,
}

/// The [`Run`] of the faces of lattice planes `planes` (found here, plane by plane),
/// numbering the slabs from the first plane's up to `upto`; their quads (vertices numbered
/// from the run's first) go to `quads`, the faces and crossings to `faces` and `crossings`
/// unless they are empty, and its vertices' lattice points and shapes to `points` and
/// `shapes` (the latter for a bit volume; both with room for every vertex: `slabs::room`).
#[allow(clippy::too_many_arguments)]
fn run(
    field: &Field<'_>,
    joins: &super::pinches::Joins,
    planes: std::ops::Range<u32>,
    upto: u32,
    quads: &mut [std::mem::MaybeUninit<[u32; 4]>],
    faces: &mut [Face],
    crossings: &mut [[f64; 3]],
    points: &mut [[u32; 3]],
    shapes: &mut [u32],
    counter: &crate::cancel::Counter,
) -> Result<Run, Canceled> {
    let valued = field.value.is_some();
    let mut slabs = Slabs::new(&field.inside, joins, planes.start, !valued, points, shapes);
    let mut sums: Vec<[f64; 4]> = Vec::new();
    let mut i = 0;
    for x in planes {
        counter.check()?;
        // The faces' corners are in lattice slabs x and x + 1.
        slabs.reach(x + 1);
        if valued && sums.len() < slabs.count {
            sums.resize(slabs.count, [0.0; 4]);
        }
        let first = i;
        for_faces_at(&field.inside, x, |f| {
            if !faces.is_empty() {
                faces[i] = f;
            }
            let ring = slabs.quad(&f);
            // The crossing point, for the crossings asked for and a valued field's sums (a bit
            // volume's surface nets needs neither).
            if valued || !crossings.is_empty() {
                let c = crossing(field, &f);
                if !crossings.is_empty() {
                    crossings[i] = c;
                }
                if valued {
                    for id in ring {
                        let sum = &mut sums[id as usize];
                        for k in 0..3 {
                            sum[k] += c[k];
                        }
                        sum[3] += 1.0;
                    }
                }
            }
            quads[i].write(ring);
            i += 1;
        });
        counter.add((i - first) as u64);
    }
    // Every entry written (`net_in_runs` relies on it: the quads are not zeroed).
    assert_eq!(i, quads.len(), "the planes' faces fill the run");
    slabs.reach(upto);
    if valued {
        sums.resize(slabs.count, [0.0; 4]);
    }
    // The last slab numbered is `upto` (the faces' slabs are below it).
    Ok(Run {
        sums,
        shared: slabs.last_start,
        count: slabs.count,
    })
}

/// The crossing point of face `f` on the segment between its two voxel centres: the face's
/// centre for a bit volume, else where the two values interpolate to zero (the midpoint when
/// the outside one is infinite), kept within [1/64, 63/64] of the segment.
fn crossing(field: &Field<'_>, f: &Face) -> [f64; 3] {
    let mut c = [0.0; 3];
    c[(f.a + 1) % 3] = f64::from(f.u) + 0.5;
    c[(f.a + 2) % 3] = f64::from(f.v) + 0.5;
    c[f.a] = f64::from(f.k);
    if field.value.is_some() {
        let inn = f.inside().map(i64::from);
        let mut out = inn;
        out[f.a] += if f.plus { 1 } else { -1 };
        let (vi, vo) = (field.value(inn), field.value(out));
        let t = if vo.is_infinite() {
            0.5
        } else {
            let (a, b) = (vi.abs(), vo.abs());
            if a + b > 0.0 { a / (a + b) } else { 0.5 }
        };
        let t = t.clamp(1.0 / 64.0, 63.0 / 64.0);
        let ci = f64::from(inn[f.a] as i32) + 0.5;
        c[f.a] = ci + t * if f.plus { 1.0 } else { -1.0 };
    }
    c
}

/// Each vertex's corners of `quads` (of `n` vertices), as `4·quad + corner`: vertex v's are
/// `corners[start[v]..start[v + 1]]`, in the order of the quads.
pub(super) fn corners_by_vertex(n: usize, quads: &[[u32; 4]]) -> (Vec<u32>, Vec<u32>) {
    let mut start = vec![0u32; n + 1];
    for q in quads {
        for &v in q {
            start[v as usize + 1] += 1;
        }
    }
    for i in 0..n {
        start[i + 1] += start[i];
    }
    let mut fill = start.clone();
    let mut corners = vec![0u32; start[n] as usize];
    for (i, q) in quads.iter().enumerate() {
        for (j, &v) in q.iter().enumerate() {
            corners[fill[v as usize] as usize] = (4 * i + j) as u32;
            fill[v as usize] += 1;
        }
    }
    (start, corners)
}

/// Gibson's constrained relaxation: `rounds` times, every vertex to the mean of its quad
/// neighbours, clamped to its dual cell (the unit cube about its lattice point) shrunk by 1/16
/// (run by `relax::relax`).
fn relax(
    mut now: Vec<[f32; 4]>,
    quads: &[[u32; 4]],
    cells: &[[u32; 3]],
    rounds: usize,
    ctl: &Control,
) -> Result<Vec<[f64; 3]>, Canceled> {
    let t0 = std::time::Instant::now();
    let graph = super::relax::Graph::of(quads, cells, true);
    let t1 = std::time::Instant::now();
    // The rounds work on each vertex's offset from its lattice point, in f32: half the memory
    // traffic of f64 positions, with a rounding error of at most 2⁻²⁴ voxel per step, whatever
    // the grid's size.
    let threads = rayon::current_num_threads();
    super::relax::relax(&graph, &mut now, rounds, threads, ctl)?;
    // Freed first: the positions take the graph's pages (`crate::alloc` keeps them), not fresh
    // ones.
    drop(graph);
    let positions = now
        .par_iter()
        .zip(cells)
        .map(|(o, c)| [0, 1, 2].map(|k| f64::from(c[k]) + f64::from(o[k])))
        .collect();
    tracing::debug!(
        graph_s = (t1 - t0).as_secs_f64(),
        steps_s = t1.elapsed().as_secs_f64(),
        "relax"
    );
    Ok(positions)
}
