//! The boundary faces of a bit volume, merged into rectangles, and the count that bounds the
//! triangles made of them — both from the volume's column words, 64 voxels at a time.
//!
//! The faces across axis a at plane k (between voxel layers k − 1 and k; outside the grid is
//! unset) are held as rows of bits:
//!
//! | a | rows along | bits along | row r of plane k, facing +a (set below, unset above)  |
//! |---|------------|------------|-------------------------------------------------------|
//! | x | y          | z          | column (k − 1, r) & !column (k, r)                    |
//! | y | x          | z          | column (r, k − 1) & !column (r, k)                    |
//! | z | x          | y          | bit k − 1 and not bit k of each column (x = r, y), gathered 64 planes at a time |
//!
//! and merged greedily: the first run of ones in a row, extended over the following rows while
//! they hold the whole run.

use super::cubes::Rect;
use crate::cancel::{Canceled, Control};
use crate::volume::BitVolume;

/// Rows of bits: `rows` rows of `wpr` words.
struct Rows {
    wpr: usize,
    words: Vec<u64>,
}

impl Rows {
    fn new(rows: usize, bits: usize) -> Rows {
        let wpr = bits.div_ceil(64);
        Rows {
            wpr,
            words: vec![0; rows * wpr],
        }
    }
    fn rows(&self) -> usize {
        self.words.len() / self.wpr.max(1)
    }
    fn row(&self, r: usize) -> &[u64] {
        &self.words[r * self.wpr..(r + 1) * self.wpr]
    }
    fn row_mut(&mut self, r: usize) -> &mut [u64] {
        &mut self.words[r * self.wpr..(r + 1) * self.wpr]
    }
}

/// Mask of bits [lo, hi) within word `w` (bits w·64 …).
fn span(w: usize, lo: usize, hi: usize) -> u64 {
    let (a, b) = (lo.max(w * 64) - w * 64, hi.min(w * 64 + 64) - w * 64);
    if b >= 64 {
        u64::MAX << a
    } else {
        (u64::MAX << a) & ((1u64 << b) - 1)
    }
}

/// The first set bit of `row` at or after `from`.
fn next_one(row: &[u64], from: usize) -> Option<usize> {
    let mut w = from / 64;
    if w >= row.len() {
        return None;
    }
    let mut word = row[w] & (u64::MAX << (from % 64));
    loop {
        if word != 0 {
            return Some(w * 64 + word.trailing_zeros() as usize);
        }
        w += 1;
        if w == row.len() {
            return None;
        }
        word = row[w];
    }
}

/// The first clear bit of `row` at or after `from` (bits past the row's end are clear).
fn next_zero(row: &[u64], from: usize) -> usize {
    let mut w = from / 64;
    if w >= row.len() {
        return from;
    }
    let mut word = !row[w] & (u64::MAX << (from % 64));
    loop {
        if word != 0 {
            return w * 64 + word.trailing_zeros() as usize;
        }
        w += 1;
        if w == row.len() {
            return w * 64;
        }
        word = !row[w];
    }
}

/// Greedy rectangles of `m`'s set bits (cleared as they are taken): `emit(r0, r1, b0, b1)` for
/// rows [r0, r1) × bits [b0, b1).
fn merge(m: &mut Rows, mut emit: impl FnMut(u32, u32, u32, u32)) {
    let rows = m.rows();
    for r in 0..rows {
        let mut from = 0;
        while let Some(b0) = next_one(m.row(r), from) {
            let b1 = next_zero(m.row(r), b0);
            let words = b0 / 64..=(b1 - 1) / 64;
            let mut r1 = r + 1;
            while r1 < rows {
                let row = m.row(r1);
                if !words.clone().all(|w| {
                    let s = span(w, b0, b1);
                    row[w] & s == s
                }) {
                    break;
                }
                r1 += 1;
            }
            for rr in r..r1 {
                let row = m.row_mut(rr);
                for w in words.clone() {
                    row[w] &= !span(w, b0, b1);
                }
            }
            emit(r as u32, r1 as u32, b0 as u32, b1 as u32);
            from = b1;
        }
    }
}

/// The boundary faces of `bits` merged into rectangles, axis by axis and plane by plane.
/// Checks `ctl` once a plane.
pub(super) fn rectangles(bits: &BitVolume, ctl: &Control) -> Result<Vec<Rect>, Canceled> {
    let d = bits.dims().map(|n| n as usize);
    let wpc = bits.words_per_column();
    let counter = ctl.counter((d[0] + d[1] + d[2] + 3) as u64);
    let zero = vec![0u64; wpc];
    let column = |x: usize, y: usize, k_minus_1: bool, k: usize, along_x: bool| -> &[u64] {
        // The column at layer k − 1 (or k) along x or y; outside the grid: zeros.
        let l = if k_minus_1 { k.wrapping_sub(1) } else { k };
        let (cx, cy) = if along_x { (l, y) } else { (x, l) };
        if cx >= d[0] || cy >= d[1] {
            &zero
        } else {
            bits.column(cx as u32, cy as u32)
        }
    };
    let mut out = Vec::new();
    let mut emit = |a: usize, k: usize, plus: bool, u0, u1, v0, v1| {
        out.push(Rect {
            a,
            k: k as u32,
            plus,
            u0,
            v0,
            u1,
            v1,
        })
    };
    // Across x and y: rows straight from the columns.
    for a in 0..2 {
        let along_x = a == 0;
        let nrows = if along_x { d[1] } else { d[0] };
        let mut plus = Rows::new(nrows, d[2]);
        let mut minus = Rows::new(nrows, d[2]);
        for k in 0..=d[a] {
            counter.check()?;
            let mut any = false;
            for r in 0..nrows {
                let (x, y) = if along_x { (0, r) } else { (r, 0) };
                let lo = column(x, y, true, k, along_x);
                let hi = column(x, y, false, k, along_x);
                let p = plus.row_mut(r);
                for w in 0..wpc {
                    p[w] = lo[w] & !hi[w];
                }
                let q = minus.row_mut(r);
                for w in 0..wpc {
                    q[w] = hi[w] & !lo[w];
                    any |= lo[w] != hi[w];
                }
            }
            if any {
                for (m, dir) in [(&mut plus, true), (&mut minus, false)] {
                    // a = x: rows y (u, axis b = y), bits z (v, axis c = z).
                    // a = y: rows x (axis c = x), bits z (axis b = z): swapped.
                    merge(m, |r0, r1, b0, b1| {
                        if along_x {
                            emit(a, k, dir, r0, r1, b0, b1)
                        } else {
                            emit(a, k, dir, b0, b1, r0, r1)
                        }
                    });
                }
            }
            counter.add(1);
        }
    }
    // Across z: 64 planes at a time, gathered from word i of every column (and the top bit of
    // word i − 1); plane 64·i + j is row block j.
    let chunks = (d[2] + 1).div_ceil(64);
    let mut plus: Vec<Rows> = (0..64).map(|_| Rows::new(d[0], d[1])).collect();
    let mut minus: Vec<Rows> = (0..64).map(|_| Rows::new(d[0], d[1])).collect();
    for i in 0..chunks {
        counter.check()?;
        let mut used = 0u64;
        for x in 0..d[0] {
            for y in 0..d[1] {
                let col = bits.column(x as u32, y as u32);
                let w = col.get(i).copied().unwrap_or(0);
                let carry = if i > 0 { col[i - 1] >> 63 } else { 0 };
                let below = w << 1 | carry;
                for (planes, mut t) in [(&mut plus, below & !w), (&mut minus, w & !below)] {
                    used |= t;
                    while t != 0 {
                        let j = t.trailing_zeros() as usize;
                        t &= t - 1;
                        planes[j].row_mut(x)[y / 64] |= 1 << (y % 64);
                    }
                }
            }
        }
        for j in 0..64 {
            let k = i * 64 + j;
            if used >> j & 1 == 0 || k > d[2] {
                continue;
            }
            for (planes, dir) in [(&mut plus, true), (&mut minus, false)] {
                merge(&mut planes[j], |r0, r1, b0, b1| {
                    emit(2, k, dir, r0, r1, b0, b1)
                });
            }
        }
        counter.add(64);
    }
    Ok(out)
}

/// An upper bound of the triangles [`super::cubes::cubes`] makes of `bits`, counted without
/// building them: three per boundary face (a rectangle of w × h faces is two triangles, or a
/// fan of at most 2(w + h) ≤ 3wh points) and twelve per pinched edge (two set voxels meeting
/// only along it: its midpoint enters the rings of four faces, each a fan at worst).
pub fn triangle_bound(bits: &BitVolume) -> u64 {
    let (faces, pinches) = boundary_counts(bits);
    3 * faces + 12 * pinches
}

/// The boundary faces of `bits`' set voxels and its pinched edges (two set voxels meeting
/// only along the edge), counted by word operations on the columns.
pub fn boundary_counts(bits: &BitVolume) -> (u64, u64) {
    let (mut faces, mut pinches) = (0u64, 0u64);
    for x in 0..bits.dims()[0] as usize {
        scan_x(bits, x, &mut |_, _, _, f, p| {
            faces += f[0] + f[1];
            pinches += p.iter().map(|m| u64::from(m.count_ones())).sum::<u64>();
        });
    }
    (faces, pinches)
}

/// A lattice edge: its lower end and its axis.
pub(super) type Edge = ([u32; 3], u8);

/// The boundary faces by lattice plane — entry x: the faces whose corners' lowest lattice x is
/// x (across x at plane x, and across y and z within voxel layer x), x in 0 ..= dims x — and
/// every pinched lattice edge (its lower end and axis), in one pass over the columns, voxel
/// layers on the pool's threads.
pub(super) fn plane_counts_and_pinches(
    bits: &BitVolume,
    ctl: &Control,
) -> Result<(Vec<usize>, Vec<Edge>), Canceled> {
    use rayon::prelude::*;
    let d = bits.dims();
    let counter = ctl.counter(u64::from(d[0]));
    let layers = (0..d[0] as usize)
        .into_par_iter()
        .with_min_len(8)
        .map(|x| {
            counter.check()?;
            let (mut here, mut next, mut edges) = (0u64, 0u64, Vec::new());
            scan_x(bits, x, &mut |x, y, w, f, pinched| {
                here += f[0];
                next += f[1];
                // Bit j of word w is the edge at z = 64w + j: along x from (x, y + 1, z + 1),
                // along y from (x + 1, y, z + 1), along z from (x + 1, y + 1, z).
                let lows = [[x, y + 1, 1], [x + 1, y, 1], [x + 1, y + 1, 0]];
                for (axis, (mut t, lo)) in pinched.into_iter().zip(lows).enumerate() {
                    while t != 0 {
                        let z = (w * 64) as u32 + t.trailing_zeros();
                        t &= t - 1;
                        edges.push(([lo[0], lo[1], z + lo[2]], axis as u8));
                    }
                }
            });
            counter.add(1);
            Ok((here as usize, next as usize, edges))
        })
        .collect::<Result<Vec<_>, Canceled>>()?;
    let mut counts = vec![0usize; d[0] as usize + 1];
    let mut edges = Vec::new();
    for (x, (here, next, e)) in layers.into_iter().enumerate() {
        counts[x] += here;
        counts[x + 1] += next;
        edges.extend(e);
    }
    Ok((counts, edges))
}

/// Visits every word `w` of every column (x, y) at `x` with the boundary faces of its voxels
/// counted (each face once: across z within the column, across y with the next column, across
/// x with the next layer, and the grid's first layers' outer faces), as `[faces whose lowest
/// lattice x is x, faces across x at plane x + 1]`, and its pinched edges as bit masks along x,
/// y and z (bit j: the edge whose lower voxel corner has z = 64w + j). Run with the processor's
/// `popcnt` instruction where it has one: x86-64's baseline lacks it, and `count_ones` is then
/// a dozen instructions a word (the pass took twice as long).
fn scan_x(bits: &BitVolume, x: usize, visit: &mut impl FnMut(u32, u32, usize, [u64; 2], [u64; 3])) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("popcnt") {
        // SAFETY: the processor has the instruction (just checked).
        return unsafe { scan_x_popcnt(bits, x, visit) };
    }
    scan_x_any(bits, x, visit)
}

/// [`scan_x_any`] compiled with `popcnt`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "popcnt")]
unsafe fn scan_x_popcnt(
    bits: &BitVolume,
    x: usize,
    visit: &mut impl FnMut(u32, u32, usize, [u64; 2], [u64; 3]),
) {
    scan_x_any(bits, x, visit)
}

/// [`scan_x`] for any processor.
#[inline(always)]
fn scan_x_any(
    bits: &BitVolume,
    x: usize,
    visit: &mut impl FnMut(u32, u32, usize, [u64; 2], [u64; 3]),
) {
    let d = bits.dims().map(|n| n as usize);
    let wpc = bits.words_per_column();
    let col = |x: usize, y: usize| bits.column(x as u32, y as u32);
    // z + 1 of column c's word w (bit j: voxel 64w + j + 1).
    let up = |c: &[u64], w: usize| c[w] >> 1 | c.get(w + 1).map_or(0, |n| n << 63);
    let pinched = |a: u64, b: u64, c: u64, e: u64| (a & e & !b & !c) | (b & c & !a & !e);
    for y in 0..d[1] {
        let c = col(x, y);
        let cx = (x + 1 < d[0]).then(|| col(x + 1, y));
        let cy = (y + 1 < d[1]).then(|| col(x, y + 1));
        let cxy = (x + 1 < d[0] && y + 1 < d[1]).then(|| col(x + 1, y + 1));
        for w in 0..wpc {
            let v = c[w];
            // A word that is empty with the next columns' along x and along y (seven in ten
            // at igea-subdiv4 518³) has no face and no pinch: every term below has a factor
            // v or one of those (`pinched` needs a set voxel among its first two words).
            let (nx, ny) = (cx.map_or(0, |n| n[w]), cy.map_or(0, |n| n[w]));
            if v | nx | ny == 0 {
                continue;
            }
            let u = up(c, w);
            // Faces across z: a voxel set and the one above unset, or the reverse (the
            // lowest voxel's face below counted by the +1 of `below`).
            let below_unset = !(v << 1 | if w > 0 { c[w - 1] >> 63 } else { 0 });
            let mut here = u64::from((v & !u).count_ones() + (v & below_unset).count_ones());
            // Across y and x: differences with the next column (the grid's first and last
            // layers face outside); those across x are at plane x + 1, but the first layer's.
            here += u64::from((v ^ ny).count_ones());
            let next = u64::from((v ^ nx).count_ones());
            if y == 0 {
                here += u64::from(v.count_ones());
            }
            if x == 0 {
                here += u64::from(v.count_ones());
            }
            // Pinched edges along x (columns y, y + 1 at z, z + 1), along y (columns x,
            // x + 1 at z, z + 1) and along z (four columns).
            let along_x = cy.map_or(0, |cy| pinched(v, cy[w], u, up(cy, w)));
            let along_y = cx.map_or(0, |cx| pinched(v, cx[w], u, up(cx, w)));
            let along_z = match (cx, cy, cxy) {
                (Some(cx), Some(cy), Some(cxy)) => pinched(v, cx[w], cy[w], cxy[w]),
                _ => 0,
            };
            visit(
                x as u32,
                y as u32,
                w,
                [here, next],
                [along_x, along_y, along_z],
            );
        }
    }
}
