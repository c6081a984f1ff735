//! Triangles binned to the 8³ bricks they can reach: per brick position (a key
//! `(bx·BY + by)·BZ + bz`), the triangles that may lie within the band of one of its voxel
//! centres. Conservative: a brick gets every triangle strictly closer than the band to one of
//! its centres, and maybe more (the triangle's box, dilated by the band, meets the box of the
//! brick's centres; a triangle whose plane is farther than the band from that box is left out).

use rayon::prelude::*;

use crate::engine::snap::FIXED_ONE;
use crate::engine::{axis_bounds, widen};
use crate::volume::sparse::BRICK;

/// A brick's edge in lattice units.
const SPAN: i64 = BRICK as i64 * FIXED_ONE;
/// Its first and last voxel centre, from the brick's low corner.
const FIRST: i64 = FIXED_ONE / 2;
const LAST: i64 = SPAN - FIXED_ONE / 2;

pub fn key(at: [u32; 3], bd: [u32; 3]) -> u64 {
    (u64::from(at[0]) * u64::from(bd[1]) + u64::from(at[1])) * u64::from(bd[2]) + u64::from(at[2])
}

pub fn unkey(k: u64, bd: [u32; 3]) -> [u32; 3] {
    let (by, bz) = (u64::from(bd[1]), u64::from(bd[2]));
    [
        (k / (by * bz)) as u32,
        (k / bz % by) as u32,
        (k % bz) as u32,
    ]
}

/// The bricks triangle `t` may reach within `r` (lattice units), each once, by key.
fn reach(t: &[[i32; 3]; 3], bd: [u32; 3], r: i64, mut f: impl FnMut(u64)) {
    let v = widen(t);
    let mut lo = [0u32; 3];
    let mut hi = [0u32; 3];
    for a in 0..3 {
        let (l, h) = axis_bounds(&v, a);
        // Bricks whose centres [SPAN b + FIRST, SPAN b + LAST] meet [l − r, h + r].
        let b0 = (l - r - LAST).div_euclid(SPAN) + i64::from((l - r - LAST).rem_euclid(SPAN) != 0);
        let b1 = (h + r - FIRST).div_euclid(SPAN);
        let (b0, b1) = (b0.max(0), b1.min(i64::from(bd[a]) - 1));
        if b0 > b1 {
            return;
        }
        (lo[a], hi[a]) = (b0 as u32, b1 as u32);
    }
    let e1 = [0, 1, 2].map(|a| v[1][a] - v[0][a]);
    let e2 = [0, 1, 2].map(|a| v[2][a] - v[0][a]);
    let n = [
        (e1[1] * e2[2] - e1[2] * e2[1]) as f64,
        (e1[2] * e2[0] - e1[0] * e2[2]) as f64,
        (e1[0] * e2[1] - e1[1] * e2[0]) as f64,
    ];
    let nn = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    let few = (0..3).all(|a| hi[a] == lo[a]);
    // The plane test: |n·(c − v0)| − Σ|nᵢ|·h is |n| times a lower bound of the distance from
    // the box of centres (centre c, half extent h) to the plane. In f64 its error is far below
    // a lattice unit (|c − v0| < 2³¹, relative 2⁻⁵⁰); 2 units of margin.
    let half = ((LAST - FIRST) / 2) as f64;
    let spread = half * (n[0].abs() + n[1].abs() + n[2].abs());
    let limit = (r + 2) as f64 * nn;
    for bx in lo[0]..=hi[0] {
        for by in lo[1]..=hi[1] {
            for bz in lo[2]..=hi[2] {
                if !few && nn > 0.0 {
                    let c = [bx, by, bz].map(|b| i64::from(b) * SPAN + (FIRST + LAST) / 2);
                    let w = [0, 1, 2].map(|a| (c[a] - v[0][a]) as f64);
                    let s = (n[0] * w[0] + n[1] * w[1] + n[2] * w[2]).abs() - spread;
                    if s >= limit {
                        continue;
                    }
                }
                f(key([bx, by, bz], bd));
            }
        }
    }
}

/// The bricks whose voxel boxes `[SPAN b, SPAN (b+1)]` meet triangle `t`'s box, clamped into
/// the brick grid (a triangle beside the grid goes to the bricks at its edge).
fn touch(t: &[[i32; 3]; 3], bd: [u32; 3], mut f: impl FnMut(u64)) {
    let v = widen(t);
    let mut lo = [0u32; 3];
    let mut hi = [0u32; 3];
    for a in 0..3 {
        let (l, h) = axis_bounds(&v, a);
        let top = i64::from(bd[a]) - 1;
        let b0 = (l - SPAN).div_euclid(SPAN) + i64::from((l - SPAN).rem_euclid(SPAN) != 0);
        let b1 = h.div_euclid(SPAN);
        (lo[a], hi[a]) = (b0.clamp(0, top) as u32, b1.clamp(0, top) as u32);
    }
    for bx in lo[0]..=hi[0] {
        for by in lo[1]..=hi[1] {
            for bz in lo[2]..=hi[2] {
                f(key([bx, by, bz], bd));
            }
        }
    }
}

/// The candidate bricks of the band `r`, counted: one bit a brick position, set by every
/// triangle's bricks (a pass over the triangles, no list of pairs).
pub fn count(tris: &[[[i32; 3]; 3]], bd: [u32; 3], r: i64) -> u64 {
    use std::sync::atomic::{AtomicU64, Ordering};
    let total = bd.iter().map(|&d| d as usize).product::<usize>();
    let bits: Vec<AtomicU64> = (0..total.div_ceil(64)).map(|_| AtomicU64::new(0)).collect();
    tris.par_iter()
        .with_min_len(crate::PAR_PIECE)
        .for_each(|t| {
            reach(t, bd, r, |k| {
                let w = &bits[(k / 64) as usize];
                let b = 1u64 << (k % 64);
                // Most keys repeat (neighbouring triangles share bricks): a load before the write.
                if w.load(Ordering::Relaxed) & b == 0 {
                    w.fetch_or(b, Ordering::Relaxed);
                }
            })
        });
    bits.iter()
        .map(|w| u64::from(w.load(Ordering::Relaxed).count_ones()))
        .sum()
}

/// Triangle lists by brick.
pub struct Bins {
    /// (key, start, end) in `tris`, by key.
    groups: Vec<(u64, usize, usize)>,
    tris: Vec<u32>,
}

impl Bins {
    /// The triangles that may reach each brick within `r`.
    pub fn new(tris: &[[[i32; 3]; 3]], bd: [u32; 3], r: i64) -> Bins {
        Bins::build(tris, bd, |t, f| reach(t, bd, r, f))
    }

    /// The triangles whose box meets each brick's box (for the ring search of `band=all`).
    pub fn all(tris: &[[[i32; 3]; 3]], bd: [u32; 3]) -> Bins {
        Bins::build(tris, bd, |t, f| touch(t, bd, f))
    }

    fn build(
        tris: &[[[i32; 3]; 3]],
        bd: [u32; 3],
        each: impl Fn(&[[i32; 3]; 3], &mut dyn FnMut(u64)) + Sync,
    ) -> Bins {
        // (key, triangle) packed as key·2³² + triangle: keys are below 2²⁷ (at most 512
        // bricks an axis, 4096³ voxels), triangles below 2³²; one u64 sorts faster than a pair.
        // Counted by piece of triangles and brick slab (bx), then written straight to their
        // places (slab by slab, piece by piece: no second list of pairs), and each slab sorted
        // on its own (in cache, in parallel).
        let slab = u64::from(bd[1]) * u64::from(bd[2]);
        let slabs = bd[0] as usize;
        // Each piece's keys (4 bytes a pair: keys are below 2²⁷) and its triangles' key counts
        // are kept from the counting pass, so the bricks of a triangle are found once.
        type Piece = (Vec<usize>, Vec<u32>, Vec<u32>);
        let found: Vec<Piece> = tris
            .par_chunks(crate::PAR_PIECE)
            .map(|chunk| {
                let mut c = vec![0usize; slabs];
                let mut keys = Vec::with_capacity(chunk.len() * 6);
                let mut per = Vec::with_capacity(chunk.len());
                for t in chunk {
                    let before = keys.len();
                    each(t, &mut |k| {
                        debug_assert!(k < 1 << 27, "brick keys fit 27 bits");
                        c[(k / slab) as usize] += 1;
                        keys.push(k as u32);
                    });
                    per.push((keys.len() - before) as u32);
                }
                (c, keys, per)
            })
            .collect();
        let total = found.iter().flat_map(|f| &f.0).sum();
        let mut pairs = vec![0u64; total];
        let mut places: Vec<Vec<&mut [u64]>> = found.iter().map(|_| Vec::new()).collect();
        let mut slab_len = vec![0usize; slabs];
        {
            let mut rest = pairs.as_mut_slice();
            for s in 0..slabs {
                for (c, (count, _, _)) in found.iter().enumerate() {
                    let (part, tail) = std::mem::take(&mut rest).split_at_mut(count[s]);
                    places[c].push(part);
                    rest = tail;
                    slab_len[s] += count[s];
                }
            }
        }
        found
            .into_par_iter()
            .zip(places.into_par_iter())
            .enumerate()
            .for_each(|(c, ((_, keys, per), mut places))| {
                let mut at = vec![0usize; slabs];
                let mut next = keys.iter();
                for (j, &m) in per.iter().enumerate() {
                    let i = (c * crate::PAR_PIECE + j) as u64;
                    for &k in next.by_ref().take(m as usize) {
                        let k = u64::from(k);
                        let s = (k / slab) as usize;
                        places[s][at[s]] = k << 32 | i;
                        at[s] += 1;
                    }
                }
            });
        crate::split_lengths(&mut pairs, slab_len)
            .into_par_iter()
            .for_each(|p| p.sort_unstable());
        let mut groups = Vec::new();
        let mut list = Vec::with_capacity(pairs.len());
        let mut start = 0;
        for (i, &p) in pairs.iter().enumerate() {
            if i > 0 && pairs[i - 1] >> 32 != p >> 32 {
                groups.push((pairs[i - 1] >> 32, start, i));
                start = i;
            }
            list.push(p as u32);
        }
        if let Some(&p) = pairs.last() {
            groups.push((p >> 32, start, pairs.len()));
        }
        Bins { groups, tris: list }
    }

    pub fn groups(&self) -> &[(u64, usize, usize)] {
        &self.groups
    }
    pub fn tris(&self) -> &[u32] {
        &self.tris
    }
    /// Bricks with a triangle.
    pub fn len(&self) -> usize {
        self.groups.len()
    }
    pub fn contains(&self, key: u64) -> bool {
        self.groups.binary_search_by_key(&key, |g| g.0).is_ok()
    }
    /// The triangles of brick `key`.
    pub fn get(&self, key: u64) -> &[u32] {
        match self.groups.binary_search_by_key(&key, |g| g.0) {
            Ok(i) => &self.tris[self.groups[i].1..self.groups[i].2],
            Err(_) => &[],
        }
    }
}
