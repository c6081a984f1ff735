//! One brick's 512 voxels: the least distance over a list of triangles, the band decided
//! exactly, the sign from the solid.

use super::bins::{self, Bins};
use super::local::{Local, Plane};
use super::signs::Signs;
use super::{Brick, in_band_exact};
use crate::engine::geom::lattice;
use crate::engine::snap::{FIXED_HALF, FIXED_ONE};
use crate::engine::{axis_bounds, centre_range, widen};
use crate::volume::sparse::{BRICK, BRICK_VOXELS};

/// Voxel `i` of brick `at`, when it lies inside `dims`.
#[inline]
fn voxel(at: [u32; 3], i: usize, dims: [u32; 3]) -> Option<[u32; 3]> {
    let o = [i as u32 / 64, i as u32 / 8 % 8, i as u32 % 8];
    let p = [0, 1, 2].map(|a| at[a] * BRICK + o[a]);
    (0..3).all(|a| p[a] < dims[a]).then_some(p)
}

#[inline]
fn centre(v: [u32; 3]) -> [i64; 3] {
    v.map(|c| i64::from(c) * FIXED_ONE + FIXED_HALF)
}

/// The squared distance from `p` to the box `[lo, hi]` (a lower bound of the distance to
/// anything inside it), in f64 (exact below 2⁵³).
#[inline]
fn box_distance2(p: [i64; 3], lo: [i64; 3], hi: [i64; 3]) -> f64 {
    let mut s = 0.0;
    for a in 0..3 {
        let d = (lo[a] - p[a]).max(p[a] - hi[a]).max(0) as f64;
        s += d * d;
    }
    s
}

/// Lowers `best2` (squared lattice distances, per voxel of brick `at`) by triangle `tri`.
/// `reach`: when given, no voxel's `best2` exceeds `reach²`, so only the voxels whose centres
/// lie within `reach` of the triangle's bounding box can be lowered and only they are visited
/// (a few hundred of the brick's 512 for a small triangle, where a triangle is in up to 8
/// bricks' lists).
#[inline]
fn lower(
    best2: &mut [f64; BRICK_VOXELS],
    at: [u32; 3],
    dims: [u32; 3],
    tri: &[[i32; 3]; 3],
    reach: Option<i64>,
) {
    let v = widen(tri);
    let bounds = [0, 1, 2].map(|a| axis_bounds(&v, a));
    let (lo, hi) = (bounds.map(|b| b.0), bounds.map(|b| b.1));
    let mut range = [(0u32, 0u32); 3];
    for a in 0..3 {
        let first = at[a] * BRICK;
        let last = (first + BRICK).min(dims[a]) - 1;
        let (l, h) = match reach {
            Some(r) => match centre_range(lo[a] - r, hi[a] + r, dims[a]) {
                Some(c) => c,
                None => return,
            },
            None => (first, last),
        };
        let (l, h) = (l.max(first), h.min(last));
        if l > h {
            return;
        }
        range[a] = (l, h);
    }
    // The distance to the triangle's plane is a lower bound of the distance to it: for large
    // triangles, whose boxes bound nothing, it skips most of the exact evaluations. The unit
    // normal comes from the exact integer normal (one rounding a component), so the plane
    // distance is within 1e-6 lattice units of the exact one (|p − a| < 2³¹); it skips only
    // when even 1e-3 closer would not lower the voxel's value.
    let e = |i: usize| [0, 1, 2].map(|a| v[i][a] - v[0][a]);
    let (e1, e2) = (e(1), e(2));
    let n = [
        e1[1] * e2[2] - e1[2] * e2[1],
        e1[2] * e2[0] - e1[0] * e2[2],
        e1[0] * e2[1] - e1[1] * e2[0],
    ]
    .map(|c| c as f64);
    let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    let unit = (len > 0.0).then(|| n.map(|c| c / len));
    for x in range[0].0..=range[0].1 {
        for y in range[1].0..=range[1].1 {
            for z in range[2].0..=range[2].1 {
                let i = (((x % BRICK) * BRICK + y % BRICK) * BRICK + z % BRICK) as usize;
                let b = &mut best2[i];
                let p = centre([x, y, z]);
                if box_distance2(p, lo, hi) >= *b {
                    continue;
                }
                if let Some(u) = unit {
                    let w = [0, 1, 2].map(|a| (p[a] - v[0][a]) as f64);
                    let pd = (u[0] * w[0] + u[1] * w[1] + u[2] * w[2]).abs() - 1e-3;
                    if pd > 0.0 && pd * pd >= *b {
                        continue;
                    }
                }
                let d2 = lattice::distance2(p, tri);
                if d2 < *b {
                    *b = d2;
                }
            }
        }
    }
}

/// Lowers `best2` (squared lattice distances, per voxel of a brick whose first `n` voxels per
/// axis lie in the grid) by triangle `l`, where no value exceeds `slack²`: only the voxels whose
/// centres lie within `slack` of the triangle's box can be lowered and only they are visited,
/// row (x, y) by row, a row skipped whole when the box is beyond the row's largest value
/// (`rowmax`, kept up to date). For the rest, the distance to the box and to the triangle's
/// plane are lower bounds that skip most exact evaluations. The voxels that pass are gathered
/// (`idx`, scratch) and evaluated eight at a time, without a branch a voxel: evaluated one by
/// one as they were found, the unpredictable branches cost a third of the whole `sdf` command.
#[inline(always)]
fn lower_local(
    best2: &mut [f64; BRICK_VOXELS],
    rowmax: &mut [f64; 64],
    idx: &mut [u16; BRICK_VOXELS + 8],
    l: &Local,
    n: [u32; 3],
    slack: i64,
) {
    let f = FIXED_ONE as f64;
    let sl = slack as f64;
    let mut range = [(0u32, 0u32); 3];
    for a in 0..3 {
        // Centres 256·i (local) within [lo − slack, hi + slack]: exact (integers, powers of 2).
        let first = ((l.lo[a] - sl) / f).ceil().max(0.0);
        let last = ((l.hi[a] + sl) / f).floor().min(f64::from(n[a] - 1));
        if first > last {
            return;
        }
        range[a] = (first as u32, last as u32);
    }
    let gap = |a: usize, c: f64| (l.lo[a] - c).max(c - l.hi[a]).max(0.0);
    let v0 = l.vertex(0);
    let zmask = (u32::MAX >> (31 - range[2].1)) & !((1u32 << range[2].0) - 1);
    // A degenerate triangle has no plane: a zero normal makes its bound −1e-3, which culls
    // nothing.
    let u = l.unit;
    let mut cnt = 0usize;
    let mut hit = 0u64;
    for x in range[0].0..=range[0].1 {
        let px = f64::from(x) * f;
        let dx = gap(0, px);
        for y in range[1].0..=range[1].1 {
            let py = f64::from(y) * f;
            let dy = gap(1, py);
            let dxy2 = dx * dx + dy * dy;
            let row = (x * BRICK + y) as usize;
            if dxy2 >= rowmax[row] {
                continue;
            }
            let plane_xy = u[0] * (px - v0[0]) + u[1] * (py - v0[1]);
            // The voxels of the row that pass both culls, as bits, without a branch each (the
            // culls' outcomes do not predict well); then gathered for the exact evaluations.
            // The distance to the box is a lower bound; so is the plane's (within 1e-6
            // lattice units of the exact one: one rounding per component of the unit normal,
            // |p − v0| < 2³¹), which culls only when even 1e-3 closer would not lower the value.
            // All eight lanes, out-of-range ones masked at the end: the shape that vectorizes.
            let base = row * BRICK as usize;
            let b: &[f64; 8] = best2[base..base + 8].try_into().expect("a row is 8 voxels");
            let mut keep = [false; 8];
            for z in 0..8 {
                let pz = Z[z];
                let dz = max0(max0(l.lo[2] - pz, pz - l.hi[2]), 0.0);
                let pd = abs(plane_xy + u[2] * (pz - v0[2])) - 1e-3;
                keep[z] = (dxy2 + dz * dz < b[z]) & ((pd <= 0.0) | (pd * pd < b[z]));
            }
            let mut pass = 0u32;
            for (z, &k) in keep.iter().enumerate() {
                pass |= u32::from(k) << z;
            }
            pass &= zmask;
            if l.exact {
                // Compacted: the passing voxels' indices appended without a branch each (all
                // eight lanes written, the count advanced by the passing ones).
                let offs = &SPREAD[pass as usize];
                let dst: &mut [u16; 8] = (&mut idx[cnt..cnt + 8])
                    .try_into()
                    .expect("idx keeps eight spare entries");
                for k in 0..8 {
                    dst[k] = base as u16 + u16::from(offs[k]);
                }
                cnt += pass.count_ones() as usize;
                hit |= u64::from(pass != 0) << row;
                continue;
            }
            // A triangle too large for the local f64 evaluation: exactly, voxel by voxel.
            let mut lowered = false;
            while pass != 0 {
                let z = pass.trailing_zeros();
                pass &= pass - 1;
                let i = base + z as usize;
                let d2 = l.distance2([px, py, f64::from(z) * f]);
                if d2 < best2[i] {
                    best2[i] = d2;
                    lowered = true;
                }
            }
            if lowered {
                rowmax[row] = best2[base..base + n[2] as usize]
                    .iter()
                    .fold(0.0, |m, &v| f64::max(m, v));
            }
        }
    }
    if cnt == 0 {
        return;
    }
    // The passing voxels, LN at a time (the last group padded with its last voxel: a second
    // minimum with the same value changes nothing). Eight lanes measured faster than four
    // (two AVX2 vectors a step), padding included.
    let last = idx[cnt - 1];
    let end = cnt.next_multiple_of(LN);
    idx[cnt..end].fill(last);
    for g in idx[..end].chunks_exact(LN) {
        let mut p = [[0.0f64; LN]; 3];
        for k in 0..LN {
            let i = u32::from(g[k]);
            p[0][k] = f64::from(i / 64) * f;
            p[1][k] = f64::from(i / 8 % 8) * f;
            p[2][k] = f64::from(i % 8) * f;
        }
        let d = l.distance2_lanes(&p);
        for k in 0..LN {
            let b = &mut best2[g[k] as usize];
            *b = if d[k] < *b { d[k] } else { *b };
        }
    }
    let nz = n[2] as usize;
    while hit != 0 {
        let row = hit.trailing_zeros() as usize;
        hit &= hit - 1;
        let base = row * BRICK as usize;
        rowmax[row] = best2[base..base + nz]
            .iter()
            .fold(0.0, |m, &v| f64::max(m, v));
    }
}

/// Lanes of one step of the exact evaluation.
const LN: usize = 8;

/// For each 8-bit mask, the positions of its set bits, in order (then zeros).
static SPREAD: [[u8; 8]; 256] = {
    let mut t = [[0u8; 8]; 256];
    let mut m = 0;
    while m < 256 {
        let mut k = 0;
        let mut z = 0;
        while z < 8 {
            if m & (1 << z) != 0 {
                t[m][k] = z as u8;
                k += 1;
            }
            z += 1;
        }
        m += 1;
    }
    t
};

/// Voxel centres along a brick row (local lattice units).
const Z: [f64; 8] = [0.0, 256.0, 512.0, 768.0, 1024.0, 1280.0, 1536.0, 1792.0];

/// `a` or `b`, the larger (NaN-blind, a plain max instruction: no NaN reaches it).
#[inline(always)]
fn max0(a: f64, b: f64) -> f64 {
    if a > b { a } else { b }
}
#[inline(always)]
fn abs(a: f64) -> f64 {
    f64::from_bits(a.to_bits() & !(1u64 << 63))
}

crate::engine::winding::lanes::dispatch! {
    /// Brick `at` in the band `r` (lattice units) over its triangles `list`: stored when it holds
    /// an in-band voxel or both signs, a tile when all its voxels are inside and none in band.
    /// `scale` is the voxel size over 256.
    /// Compiled for the widest instruction set the processor has (its culls vectorize).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn band_brick(
        tris: &[[[i32; 3]; 3]],
        planes: &[Plane],
        list: &[u32],
        signs: &Signs,
        dims: [u32; 3],
        at: [u32; 3],
        r: i64,
        scale: f64,
        background: f32,
    ) -> Option<Brick> = band_brick_body, band_brick_avx512, band_brick_avx2;
}

/// [`band_brick`]'s body, compiled for each instruction set (its culls vectorize).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn band_brick_body(
    tris: &[[[i32; 3]; 3]],
    planes: &[Plane],
    list: &[u32],
    signs: &Signs,
    dims: [u32; 3],
    at: [u32; 3],
    r: i64,
    scale: f64,
    background: f32,
) -> Option<Brick> {
    let n = [0, 1, 2].map(|a| (dims[a] - at[a] * BRICK).min(BRICK));
    // Triangles farther than this settle nothing: the voxel is out of band whatever they are.
    let slack = r + 2;
    let s2 = (slack * slack) as f64;
    let mut best2 = [s2; BRICK_VOXELS];
    let mut rowmax = [s2; 64];
    let mut idx = [0u16; BRICK_VOXELS + 8];
    for &t in list {
        let l = Local::new(&tris[t as usize], &planes[t as usize], at);
        lower_local(&mut best2, &mut rowmax, &mut idx, &l, n, slack);
    }
    let mask = signs.mask(at);
    let (any_in, all_in) = signs.brick(at);
    let rf = r as f64;
    // `distance` is within 2⁻⁵⁰ of the exact value: far from r, the f64 decides.
    let (near_lo, near_hi) = (rf * (1.0 - 1e-9), rf * (1.0 + 1e-9));
    let value = |in_band: bool, inside: bool, d: f64| {
        let out = if in_band {
            (d * scale) as f32
        } else {
            background
        };
        if inside { -out } else { out }
    };
    let mut values = Box::new([background; BRICK_VOXELS]);
    // Every voxel as if the f64 decided its band (no branch: this vectorizes), counting those
    // it cannot decide: they are few (a billionth of the band's width from its edge) and are
    // settled exactly after, with the voxels beyond the grid (a brick at its far faces: never
    // lowered, so never in band), which stay background.
    let mut any_band = false;
    let mut undecided = 0u32;
    for i in 0..BRICK_VOXELS {
        let d = best2[i].sqrt();
        let in_band = d < near_lo;
        undecided += u32::from((d >= near_lo) & (d <= near_hi));
        any_band |= in_band;
        values[i] = value(in_band, Signs::inside(&mask, i), d);
    }
    if undecided > 0 || n != [BRICK; 3] {
        for (i, &b2) in best2.iter().enumerate() {
            let Some(vx) = voxel(at, i, dims) else {
                values[i] = background;
                continue;
            };
            let d = b2.sqrt();
            if (d >= near_lo) & (d <= near_hi) {
                let in_band = in_band_exact(tris, list, centre(vx), r);
                any_band |= in_band;
                values[i] = value(in_band, Signs::inside(&mask, i), d);
            }
        }
    }
    if any_band || (any_in && !all_in) {
        Some(Brick::Stored(at, values))
    } else if all_in {
        Some(Brick::Tile(at))
    } else {
        None
    }
}

/// Brick `at` with every voxel in band (`band=all`): rings of bricks around it, outward, until
/// no triangle not yet seen can be closer to one of its centres than what it has.
pub(super) fn all_brick(
    tris: &[[[i32; 3]; 3]],
    bins: &Bins,
    signs: &Signs,
    dims: [u32; 3],
    at: [u32; 3],
    scale: f64,
) -> Box<[f32; BRICK_VOXELS]> {
    let bd = dims.map(|d| d.div_ceil(BRICK));
    let mut best2 = [f64::INFINITY; BRICK_VOXELS];
    let span = i64::from(BRICK) * FIXED_ONE;
    for r in 0u32.. {
        let lo = at.map(|c| c.saturating_sub(r));
        let hi = [0, 1, 2].map(|a| (at[a] + r).min(bd[a] - 1));
        for bx in lo[0]..=hi[0] {
            for by in lo[1]..=hi[1] {
                let edge = bx.abs_diff(at[0]) == r || by.abs_diff(at[1]) == r;
                let mut bz = lo[2];
                while bz <= hi[2] {
                    for &t in bins.get(bins::key([bx, by, bz], bd)) {
                        lower(&mut best2, at, dims, &tris[t as usize], None);
                    }
                    // Inside the shell, only its two faces in z.
                    bz = if edge || bz >= at[2] + r || r == 0 {
                        bz + 1
                    } else {
                        at[2] + r
                    };
                }
            }
        }
        let whole = (0..3).all(|a| lo[a] == 0 && hi[a] == bd[a] - 1);
        // A triangle in no brick of the cube of rings ≤ r lies beyond one of its faces: at
        // least SPAN·r + 128 from every centre of this brick.
        let bound = (span * i64::from(r) + FIXED_HALF) as f64;
        let worst = (0..BRICK_VOXELS)
            .filter(|&i| voxel(at, i, dims).is_some())
            .map(|i| best2[i])
            .fold(0.0, f64::max);
        if whole || worst <= bound * bound {
            break;
        }
    }
    let mask = signs.mask(at);
    let mut values = Box::new([f32::INFINITY; BRICK_VOXELS]);
    for (i, v) in values.iter_mut().enumerate() {
        if voxel(at, i, dims).is_some() {
            let d = best2[i].sqrt() * scale;
            *v = if Signs::inside(&mask, i) {
                (-d) as f32
            } else {
                d as f32
            };
        }
    }
    values
}

/// Brick `at` out of band everywhere: ±background by its voxels' signs.
pub(super) fn uniform_brick(
    signs: &Signs,
    dims: [u32; 3],
    at: [u32; 3],
    background: f32,
) -> Box<[f32; BRICK_VOXELS]> {
    let mask = signs.mask(at);
    let mut values = Box::new([background; BRICK_VOXELS]);
    for (i, v) in values.iter_mut().enumerate() {
        if voxel(at, i, dims).is_some() && Signs::inside(&mask, i) {
            *v = -background;
        }
    }
    values
}
