//! `solid`: voxel (x, y, k) is set iff the ray from its centre towards −z crosses the mesh an odd
//! number of times.
//!
//! For each triangle and each column (x, y) whose centre lies inside the triangle's xy projection,
//! the crossing depth z(x, y) is found and one bit is toggled at the lowest voxel whose centre is
//! strictly above it; a prefix XOR up each column then turns toggles into parity.
//!
//! Tie rules (all integer, on the 1/256-voxel lattice of [`crate::engine::GridMesh`]):
//! - Triangles with zero projected area are skipped.
//! - Column in triangle: the triangle is oriented counter-clockwise in xy; with edge functions
//!   `w = (b − a) × (p − a)` a centre is inside iff every `w > 0`, or `w == 0` on an edge whose
//!   direction d has `d.y > 0 || (d.y == 0 && d.x < 0)`. This equals testing the point pushed by
//!   an infinitesimal (−1, −δ), so a centre on an edge or vertex shared by triangles on both sides
//!   counts exactly once.
//! - Depth: voxel k is flipped iff its centre is strictly above the plane,
//!   `(2k + 1) · 128 · A > w0 z0 + w1 z1 + w2 z2` with `A = w0 + w1 + w2` (twice the area).

use std::ops::Range;

use super::{axis_bounds, centre_range, for_each_band, widen};
use crate::cancel::{Canceled, Control};
use crate::engine::{FIXED_HALF, FIXED_ONE, GridMesh};
use crate::volume::{BitVolume, tail_mask};

pub(super) fn voxelize(mesh: &GridMesh, ctl: &Control) -> Result<BitVolume, Canceled> {
    let mut vol = BitVolume::new(mesh.grid);
    let [nx, ny, nz] = mesh.grid.dims;
    let wpc = vol.words_per_column();
    let x_range = |v: &[[i64; 3]; 3]| covered_rows(v, nx, ny);
    for_each_band(mesh, &mut vol, x_range, ctl, |band, tris, words| {
        for &t in tris {
            toggle_crossings(
                &widen(&mesh.triangles[t as usize]),
                band.clone(),
                [ny, nz],
                wpc,
                words,
            );
        }
        let tail = tail_mask(nz);
        for col in words.chunks_exact_mut(wpc) {
            prefix_xor_column(col, tail);
        }
    })?;
    Ok(vol)
}

/// The inclusive range of x-rows whose column centres a triangle's xy box holds, `None` when it
/// holds no column centre of an X × Y grid.
fn covered_rows(v: &[[i64; 3]; 3], nx: u32, ny: u32) -> Option<(u32, u32)> {
    let (lo, hi) = axis_bounds(v, 0);
    let (ylo, yhi) = axis_bounds(v, 1);
    centre_range(ylo, yhi, ny)?;
    centre_range(lo, hi, nx)
}

/// Edge function pieces of a CCW triangle: `w(p) = ex · (p.y − a.y) − ey · (p.x − a.x)`, and the
/// bias that makes `w >= bias` the inside test with the tie rule.
struct Edge {
    a: [i64; 3],
    ex: i64,
    ey: i64,
    bias: i64,
}

impl Edge {
    fn new(a: [i64; 3], b: [i64; 3]) -> Edge {
        let (ex, ey) = (b[0] - a[0], b[1] - a[1]);
        let included = ey > 0 || (ey == 0 && ex < 0);
        Edge {
            a,
            ex,
            ey,
            bias: if included { 0 } else { 1 },
        }
    }
    fn at(&self, px: i64, py: i64) -> i64 {
        self.ex * (py - self.a[1]) - self.ey * (px - self.a[0])
    }
}

/// Orients the triangle counter-clockwise in xy; `None` for zero projected area.
fn oriented(v: [[i64; 3]; 3]) -> Option<([[i64; 3]; 3], i64)> {
    oriented_signed(v).map(|(v, a, _)| (v, a))
}

/// [`oriented`] and +1 when the triangle had to be turned (it faced down), else −1.
fn oriented_signed(mut v: [[i64; 3]; 3]) -> Option<([[i64; 3]; 3], i64, i32)> {
    let area2 =
        (v[1][0] - v[0][0]) * (v[2][1] - v[0][1]) - (v[1][1] - v[0][1]) * (v[2][0] - v[0][0]);
    match area2 {
        0 => None,
        a if a < 0 => {
            v.swap(1, 2);
            Some((v, -a, 1))
        }
        a => Some((v, a, -1)),
    }
}

/// Lowest voxel index whose centre is strictly above the plane through the (oriented) triangle
/// at a column centre with barycentric edge values `w` (`w[i]` weighs vertex i): the toggle
/// position. May be negative (the whole column) or ≥ Z (nothing).
fn first_voxel_above(v: &[[i64; 3]; 3], w: [i64; 3], area2: i64) -> i64 {
    let num: i128 = (0..3).map(|i| w[i] as i128 * v[i][2] as i128).sum();
    // (2k+1)·128·A > num  ⇔  2k+1 > m' where m = floor(num / (128·A))  ⇔  k ≥ ceil(m / 2).
    let den = FIXED_HALF as i128 * area2 as i128;
    // The same floor in i64 when both fit (small triangles near the origin: most of them),
    // which is several times cheaper than i128's division.
    let m = match (i64::try_from(num), i64::try_from(den)) {
        (Ok(n), Ok(d)) => n.div_euclid(d) as i128,
        _ => num.div_euclid(den),
    };
    (m + 1).div_euclid(2) as i64
}

fn toggle_crossings(
    v: &[[i64; 3]; 3],
    band: Range<u32>,
    [ny, nz]: [u32; 2],
    wpc: usize,
    words: &mut [u64],
) {
    let start = band.start;
    for_each_crossing(v, band, ny, |x, y, k, _| {
        if k < nz as i64 {
            let k = k.max(0) as usize;
            let col = (x - start) as usize * ny as usize + y as usize;
            words[col * wpc + k / 64] ^= 1 << (k % 64);
        }
    });
}

/// Calls `f(x, y, k, sign)` for every column (x in `xs`, y < `ny`) whose centre lies inside the
/// triangle's projection (tie rule above), with `k` the first voxel above the triangle there and
/// `sign` = +1 when the triangle faces down (n_z < 0: the ray towards −z leaves through it, as it
/// leaves a closed outward-oriented mesh), −1 when it faces up.
fn for_each_crossing(
    v: &[[i64; 3]; 3],
    xs: Range<u32>,
    ny: u32,
    f: impl FnMut(u32, u32, i64, i32),
) {
    crossings::<true>(v, xs, ny, f)
}

/// [`for_each_crossing`], with `k` found only when `DEPTH` (else 0: for counts per column,
/// which need no depth, and the depth is a 128-bit division).
fn crossings<const DEPTH: bool>(
    v: &[[i64; 3]; 3],
    xs: Range<u32>,
    ny: u32,
    mut f: impl FnMut(u32, u32, i64, i32),
) {
    let Some((v, area2, sign)) = oriented_signed(*v) else {
        return;
    };
    let (xlo, xhi) = axis_bounds(&v, 0);
    let (ylo, yhi) = axis_bounds(&v, 1);
    let (Some((x0, x1)), Some((y0, y1))) =
        (centre_range(xlo, xhi, u32::MAX), centre_range(ylo, yhi, ny))
    else {
        return;
    };
    let (x0, x1) = (x0.max(xs.start), x1.min(xs.end - 1));
    if x0 > x1 {
        return;
    }
    // Edge i is opposite vertex i, so its function is vertex i's barycentric weight × A.
    let edges = [
        Edge::new(v[1], v[2]),
        Edge::new(v[2], v[0]),
        Edge::new(v[0], v[1]),
    ];
    let py0 = y0 as i64 * FIXED_ONE + FIXED_HALF;
    for x in x0..=x1 {
        let px = x as i64 * FIXED_ONE + FIXED_HALF;
        let mut w = [0, 1, 2].map(|i| edges[i].at(px, py0));
        for y in y0..=y1 {
            if (0..3).all(|i| w[i] >= edges[i].bias) {
                let k = if DEPTH {
                    first_voxel_above(&v, w, area2)
                } else {
                    0
                };
                f(x, y, k, sign);
            }
            for i in 0..3 {
                w[i] += edges[i].ex * FIXED_ONE;
            }
        }
    }
}

/// The signed crossings of one x-row's columns (see [`signed_crossings`]).
#[derive(Default)]
pub(crate) struct RowCrossings {
    /// Column y's crossings are `crossings[starts[y]..starts[y + 1]]`.
    starts: Vec<u32>,
    /// (k, sign), sorted by k within a column.
    crossings: Vec<(i32, i32)>,
    /// (y, k, sign) as the triangles give them, before they are put in order.
    found: Vec<(u32, i32, i32)>,
}

impl RowCrossings {
    /// Column y's crossings, (k, sign) by k: the sign of a triangle the ray towards −z crosses
    /// from voxel k up (k ≥ 0: one from below the grid is at 0; none from Z up is kept). The
    /// signed count at voxel z is the sum of the signs of the crossings with k ≤ z.
    pub(crate) fn column(&self, y: u32) -> &[(i32, i32)] {
        &self.crossings[self.starts[y as usize] as usize..self.starts[y as usize + 1] as usize]
    }

    /// Puts `found` in order: by column (a counting sort), then by k.
    fn sort(&mut self, ny: u32) {
        self.starts.clear();
        self.starts.resize(ny as usize + 2, 0);
        for &(y, _, _) in &self.found {
            self.starts[y as usize + 2] += 1;
        }
        for y in 2..self.starts.len() {
            self.starts[y] += self.starts[y - 1];
        }
        // starts[y + 1] is now where column y begins; it ends there once filled.
        self.crossings.clear();
        self.crossings.resize(self.found.len(), (0, 0));
        for &(y, k, s) in &self.found {
            let at = &mut self.starts[y as usize + 1];
            self.crossings[*at as usize] = (k, s);
            *at += 1;
        }
        self.starts.truncate(ny as usize + 1);
        for y in 0..ny {
            let c = &mut self.crossings
                [self.starts[y as usize] as usize..self.starts[y as usize + 1] as usize];
            if c.len() > 1 {
                c.sort_unstable_by_key(|&(k, _)| k);
            }
        }
    }
}

/// Signed crossings: `decide(x, row, row_words)` is called once per x-row with the row's
/// crossings ([`RowCrossings`]): along each column, the triangles that the ray from a voxel's
/// centre towards −z crosses, each with its sign (see [`for_each_crossing`]), under the same
/// tie rules as `solid`, so the signed count (the sum of the signs of the crossings below a
/// voxel) is odd exactly where `solid` is set. For a closed mesh (as a chain: every edge used as
/// often in each direction) it is the winding number at the centre. `decide` writes the row's
/// bits into `row_words` (Y columns of the volume's words). `ctl` is checked per band and hears
/// each band done (`decide` may check it per row).
pub(crate) fn signed_crossings(
    mesh: &GridMesh,
    ctl: &Control,
    decide: impl Fn(u32, &RowCrossings, &mut [u64]) + Sync,
) -> Result<BitVolume, Canceled> {
    let mut vol = BitVolume::new(mesh.grid);
    let [nx, ny, nz] = mesh.grid.dims;
    let wpc = vol.words_per_column();
    let x_range = |v: &[[i64; 3]; 3]| covered_rows(v, nx, ny);
    let row_words = ny as usize * wpc;
    for_each_band(mesh, &mut vol, x_range, ctl, |band, tris, words| {
        let mut row = RowCrossings::default();
        // Triangles per row of the band, so that each is set up once per row it covers.
        let mut rows: Vec<Vec<u32>> = vec![Vec::new(); band.len()];
        for &t in tris {
            if let Some((x0, x1)) = x_range(&widen(&mesh.triangles[t as usize])) {
                for x in x0.max(band.start)..=x1.min(band.end - 1) {
                    rows[(x - band.start) as usize].push(t);
                }
            }
        }
        for x in band.clone() {
            row.found.clear();
            for &t in &rows[(x - band.start) as usize] {
                for_each_crossing(
                    &widen(&mesh.triangles[t as usize]),
                    x..x + 1,
                    ny,
                    |_, y, k, s| {
                        if k < nz as i64 {
                            row.found.push((y, k.max(0) as i32, s));
                        }
                    },
                );
            }
            row.sort(ny);
            let r = (x - band.start) as usize * row_words;
            decide(x, &row, &mut words[r..r + row_words]);
        }
    })?;
    Ok(vol)
}

/// Columns of `grid` (X × Y) whose centre is covered by an odd number of triangles of `mesh`
/// under `solid`'s tie rules, whatever their height: along such a column the ray towards −z from
/// above the mesh ends inside, so the mesh has a hole there. Triangles with a coordinate beyond
/// the lattice's range are left out (a voxelization that meets them fails with an error anyway).
pub fn odd_parity_columns(mesh: &crate::mesh::Mesh, grid: &crate::grid::Grid) -> u64 {
    let [nx, ny, _] = grid.dims;
    let snap = |&p: &[f64; 3]| {
        let v = crate::engine::snap::to_lattice(grid, p);
        v[..2]
            .iter()
            .all(|c| c.abs() <= crate::engine::MAX_FIXED as f64)
            .then(|| [v[0] as i64, v[1] as i64, 0])
    };
    let snapped: Vec<Option<[i64; 3]>> = mesh.positions().iter().map(snap).collect();
    let mut bits = vec![0u64; (nx as usize * ny as usize).div_ceil(64)];
    for t in mesh.triangles() {
        let v = t.map(|i| snapped[i as usize]);
        let (Some(a), Some(b), Some(c)) = (v[0], v[1], v[2]) else {
            continue;
        };
        crossings::<false>(&[a, b, c], 0..nx, ny, |x, y, _, _| {
            let i = x as usize * ny as usize + y as usize;
            bits[i / 64] ^= 1 << (i % 64);
        });
    }
    bits.iter().map(|w| w.count_ones() as u64).sum()
}

/// Turns toggles into parity: bit k becomes the XOR of toggles at 0..=k. Bits above Z are cleared.
fn prefix_xor_column(col: &mut [u64], tail: u64) {
    let mut carry = 0u64;
    for w in col.iter_mut() {
        let mut x = *w;
        x ^= x << 1;
        x ^= x << 2;
        x ^= x << 4;
        x ^= x << 8;
        x ^= x << 16;
        x ^= x << 32;
        x ^= carry;
        carry = if x >> 63 == 1 { u64::MAX } else { 0 };
        *w = x;
    }
    if let Some(last) = col.last_mut() {
        *last &= tail;
    }
}

/// The crossing test of one column centre with one triangle, for oracles and other engines'
/// tests: `Some(k)` with the first voxel above the triangle when the column centre (x, y) is
/// inside its projection under the tie rule, else `None`.
pub fn crossing_voxel(tri: &[[i32; 3]; 3], x: u32, y: u32) -> Option<i64> {
    let (v, area2) = oriented(widen(tri))?;
    let edges = [
        Edge::new(v[1], v[2]),
        Edge::new(v[2], v[0]),
        Edge::new(v[0], v[1]),
    ];
    let (px, py) = (
        x as i64 * FIXED_ONE + FIXED_HALF,
        y as i64 * FIXED_ONE + FIXED_HALF,
    );
    let w = [0, 1, 2].map(|i| edges[i].at(px, py));
    (0..3)
        .all(|i| w[i] >= edges[i].bias)
        .then(|| first_voxel_above(&v, w, area2))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prefix_xor_carries_across_words() {
        let mut col = [1u64 << 3, 1u64 << 1, 0];
        prefix_xor_column(&mut col, (1 << 10) - 1);
        assert_eq!(col[0], !0u64 << 3);
        assert_eq!(col[1], 1); // bits 64 (set) then toggled off from bit 65
        assert_eq!(col[2], 0);
        let mut col = [1u64 << 63, 0];
        prefix_xor_column(&mut col, (1 << 5) - 1);
        assert_eq!(col, [1 << 63, 0b11111]);
    }

    #[test]
    fn depth_rounding() {
        // Flat triangle at z = 1.5 voxels (384): centres 0.5 and 1.5 are not above, 2.5 is.
        let z = 384;
        let tri = [[0, 0, z], [2560, 0, z], [0, 2560, z]];
        assert_eq!(crossing_voxel(&tri, 0, 0), Some(2));
        let tri = [[0, 0, 383], [2560, 0, 383], [0, 2560, 383]];
        assert_eq!(crossing_voxel(&tri, 0, 0), Some(1));
        let tri = [[0, 0, -1000], [2560, 0, -1000], [0, 2560, -1000]];
        assert_eq!(crossing_voxel(&tri, 1, 1), Some(-4));
    }
}
