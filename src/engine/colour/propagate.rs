//! The nearest surface voxel of every set voxel: the feature transform of the exact Euclidean
//! distance transform (Felzenszwalb and Huttenlocher's lower envelope of parabolas, one axis at
//! a time: z, then y, then x), carrying each voxel's nearest source rather than its distance.
//! Every voxel of the grid gets the source whose centre is nearest to its own (straight-line
//! distance, as a distance transform measures it); among equally near sources, the one of
//! lowest key (x, then y, then z). Each pass keeps, among equally near candidates, the one it
//! met first along its axis (the lowest coordinate): the x pass so picks the lowest x among
//! the nearest sources, the y pass before it the lowest y within that slab, the z pass the
//! lowest z within that column (deterministic, whatever the thread count). Three passes over
//! the grid, each linear in its voxels and parallel over lines; one `u32` a voxel.
//!
//! When nearly every set voxel is a source (`surface`: only voxels that a triangle touches
//! with zero area are not), the few others are looked up directly instead
//! ([`local`]): the sources in growing cubes around each, by the same rule. That answer is
//! the transform's exactly (tested against it and against brute force).

use rayon::prelude::*;

use crate::cancel::{Canceled, Control};
use crate::volume::BitVolume;

const NONE: u32 = u32::MAX;

/// Voxel (x, y, z) of key `k` ([`super::key`]'s inverse).
pub(super) fn coords(k: u64, dims: [u32; 3]) -> [u32; 3] {
    let z = (k % u64::from(dims[2])) as u32;
    let c = k / u64::from(dims[2]);
    [
        (c / u64::from(dims[1])) as u32,
        (c % u64::from(dims[1])) as u32,
        z,
    ]
}

/// A shared view of the feature array for the passes whose lines are not contiguous.
struct Lines(*mut u32);
// SAFETY: the passes write each voxel from exactly one line, and lines are handed to one
// thread each, so no two threads touch the same element.
unsafe impl Sync for Lines {}
unsafe impl Send for Lines {}

impl Lines {
    /// Element `i`.
    ///
    /// # Safety
    /// `i` is within the array, and no other thread writes it meanwhile.
    unsafe fn get(&self, i: usize) -> u32 {
        // SAFETY: as the caller promises.
        unsafe { *self.0.add(i) }
    }
    /// Sets element `i`.
    ///
    /// # Safety
    /// `i` is within the array, and no other thread reads or writes it meanwhile.
    unsafe fn set(&self, i: usize, v: u32) {
        // SAFETY: as the caller promises.
        unsafe { *self.0.add(i) = v }
    }
}

/// No source on the line yet: [`envelope`]'s `f` value.
const FAR: u64 = u64::MAX;

/// One line's lower envelope: `f[q]` ([`FAR`]: no source) are the squared distances along the
/// axes done so far; on return `feat[i]` is the feature of the q minimising f[q] + (i − q)²
/// (the lowest q among equal ones). `v`, `z` and `orig` are scratch: `z[k]` is where parabola
/// `v[k]` starts to be the lowest, the fraction num / den (den > 0), compared in exact integers
/// (no division: it was a tenth of the pass).
fn envelope(
    f: &[u64],
    feat: &mut [u32],
    v: &mut Vec<usize>,
    z: &mut Vec<(i64, i64)>,
    orig: &mut Vec<u32>,
) {
    v.clear();
    z.clear();
    let parab = |q: usize| f[q] as i64 + (q * q) as i64;
    for (q, &fq) in f.iter().enumerate() {
        if fq == FAR {
            continue;
        }
        let pq = parab(q);
        // Pop the parabolas that q's hides from where they start; the first is never popped
        // (it starts at −∞, and its z is never read).
        while v.len() >= 2 {
            let last = *v.last().expect("two");
            let (num, den) = (pq - parab(last), 2 * (q - last) as i64);
            let (zn, zd) = *z.last().expect("one per parabola");
            // num / den <= zn / zd, both denominators positive.
            if i128::from(num) * i128::from(zd) <= i128::from(zn) * i128::from(den) {
                v.pop();
                z.pop();
            } else {
                break;
            }
        }
        match v.last() {
            None => z.push((-1, 0)),
            Some(&last) => z.push((pq - parab(last), 2 * (q - last) as i64)),
        }
        v.push(q);
    }
    if v.is_empty() {
        return;
    }
    orig.clear();
    orig.extend(v.iter().map(|&q| feat[q]));
    let mut k = 0;
    for (i, out) in feat.iter_mut().enumerate() {
        // z[k + 1] < i.
        while k + 1 < v.len() && z[k + 1].0 < i as i64 * z[k + 1].1 {
            k += 1;
        }
        *out = orig[k];
    }
}

/// Scratch of one thread's lines: f, v, z and orig.
type Scratch = (Vec<u64>, Vec<usize>, Vec<(i64, i64)>, Vec<u32>);

/// One pass over one line of features (`NONE`: none yet): each voxel takes the nearest of the
/// line's features, `dist(feature)` being its squared distance over the axes done so far; a
/// line without any stays as it is.
fn pass_line(
    line: &mut [u32],
    dist: impl Fn(u32) -> u64,
    f: &mut Vec<u64>,
    v: &mut Vec<usize>,
    z: &mut Vec<(i64, i64)>,
    orig: &mut Vec<u32>,
) {
    if line.iter().all(|&s| s == NONE) {
        return;
    }
    f.clear();
    f.extend(line.iter().map(|&s| if s == NONE { FAR } else { dist(s) }));
    envelope(f, line, v, z, orig);
}

/// z lines a task of the y and x passes handles at once: 16 `u32` share a cache line.
const TILE: usize = 16;

/// Reads `width` (at most [`TILE`]) lines of `len` cells into `block`, line after line (cell
/// i of line j at `block[j·len + i]`): the lines lie across rows, row i holding cell i of each,
/// and `row(i, out)` copies row i into `out`.
fn gather(block: &mut [u32], len: usize, width: usize, mut row: impl FnMut(usize, &mut [u32])) {
    let mut r = [NONE; TILE];
    for i in 0..len {
        row(i, &mut r[..width]);
        for (j, &s) in r[..width].iter().enumerate() {
            block[j * len + i] = s;
        }
    }
}

/// Writes the lines [`gather`] read back, `row(i, values)` storing row i.
fn scatter(block: &[u32], len: usize, width: usize, mut row: impl FnMut(usize, &[u32])) {
    let mut r = [NONE; TILE];
    for i in 0..len {
        for (j, s) in r[..width].iter_mut().enumerate() {
            *s = block[j * len + i];
        }
        row(i, &r[..width]);
    }
}

/// For each set voxel of `bits` (by rank: the order of [`BitVolume::iter_ones`]), the index in
/// `sources` (sorted keys of [`super::key`]) of its nearest source (module docs); 0 for every
/// voxel when there are no sources.
pub fn nearest(bits: &BitVolume, sources: &[u64], ctl: &Control) -> Result<Vec<u32>, Canceled> {
    if let Some(v) = local(bits, sources, LOCAL_RADIUS, ctl)? {
        return Ok(v);
    }
    transform(bits, sources, ctl)
}

/// Non-source set voxels [`local`] looks up at most: a set fraction and a floor.
const LOCAL_SHARE: u64 = 64;
const LOCAL_FLOOR: u64 = 4096;
/// The largest cube (half side, voxels) [`local`] searches around a voxel.
pub(super) const LOCAL_RADIUS: u32 = 6;

/// [`nearest`] by direct lookup when few set voxels are not sources: each of those searches the
/// cube of half side r = 1, 2, … about it; the nearest source in the cube is the nearest of all
/// once its distance is at most r (any source outside is farther than r), and every source as
/// near is in the cube, so the lowest key among them is the rule's choice. `None` (the caller
/// runs the transform) when more than one set voxel in [`LOCAL_SHARE`] (and over
/// [`LOCAL_FLOOR`]) is not a source, some voxel has no source within `radius`, or the lookups
/// pass the grid's voxel count (one pass of the transform).
pub(super) fn local(
    bits: &BitVolume,
    sources: &[u64],
    radius: u32,
    ctl: &Control,
) -> Result<Option<Vec<u32>>, Canceled> {
    let dims = bits.dims();
    if sources.is_empty() {
        return Ok(None);
    }
    let limit = (bits.count_ones() / LOCAL_SHARE).max(LOCAL_FLOOR);
    // Each set voxel's source rank, or NONE; sources and set voxels are both in key order.
    let mut out = Vec::with_capacity(bits.count_ones() as usize);
    let mut others = Vec::new();
    let mut j = 0;
    for v in bits.iter_ones() {
        let k = super::key(v, dims);
        while j < sources.len() && sources[j] < k {
            j += 1;
        }
        if j < sources.len() && sources[j] == k {
            out.push(j as u32);
        } else {
            if others.len() as u64 >= limit {
                return Ok(None);
            }
            others.push((out.len(), v));
            out.push(NONE);
        }
    }
    if others.is_empty() {
        return Ok(Some(out));
    }
    let mut is_source = BitVolume::new(*bits.grid());
    for &k in sources {
        let [x, y, z] = coords(k, dims);
        is_source.set(x, y, z, true);
    }
    let mut budget = dims.iter().map(|&d| u64::from(d)).product::<u64>();
    for (i, (rank, v)) in others.into_iter().enumerate() {
        if i % 1024 == 0 {
            ctl.check()?;
        }
        let mut found = None;
        for r in 1..=radius {
            let lo = v.map(|c| c.saturating_sub(r));
            let hi: [u32; 3] = std::array::from_fn(|a| (v[a] + r).min(dims[a] - 1));
            let cube = (0..3)
                .map(|a| u64::from(hi[a] - lo[a] + 1))
                .product::<u64>();
            let Some(left) = budget.checked_sub(cube) else {
                return Ok(None);
            };
            budget = left;
            // (squared distance, key): the rule's order.
            let mut best: Option<(u64, u64)> = None;
            for x in lo[0]..=hi[0] {
                for y in lo[1]..=hi[1] {
                    for z in lo[2]..=hi[2] {
                        if is_source.get(x, y, z) {
                            let d2 = [x, y, z]
                                .iter()
                                .zip(&v)
                                .map(|(&a, &b)| (i64::from(a) - i64::from(b)).unsigned_abs().pow(2))
                                .sum::<u64>();
                            let c = (d2, super::key([x, y, z], dims));
                            best = Some(best.map_or(c, |b: (u64, u64)| b.min(c)));
                        }
                    }
                }
            }
            if let Some((d2, k)) = best
                && d2 <= u64::from(r) * u64::from(r)
            {
                found = Some(k);
                break;
            }
        }
        let Some(k) = found else {
            return Ok(None);
        };
        out[rank] = sources.binary_search(&k).expect("a source") as u32;
    }
    Ok(Some(out))
}

/// [`nearest`] by the feature transform (the module docs).
pub(super) fn transform(
    bits: &BitVolume,
    sources: &[u64],
    ctl: &Control,
) -> Result<Vec<u32>, Canceled> {
    let start = std::time::Instant::now();
    let dims = bits.dims();
    let [nx, ny, nz] = dims.map(|d| d as usize);
    let n = nx * ny * nz;
    // The sources' y and z side by side (the x pass reads both; x is never read).
    let at: Vec<[u32; 2]> = sources
        .par_iter()
        .map(|&k| {
            let [_, y, z] = coords(k, dims);
            [y, z]
        })
        .collect();
    let mut feat = Vec::with_capacity(n);
    // Filled by every thread: the first touch of its pages costs as much as the filling.
    (0..n)
        .into_par_iter()
        .map(|_| NONE)
        .collect_into_vec(&mut feat);
    for (i, &k) in sources.iter().enumerate() {
        feat[k as usize] = i as u32;
    }
    let d = |a: u32, b: u32| (i64::from(a) - i64::from(b)).unsigned_abs().pow(2);
    let t0 = std::time::Instant::now();
    // z: contiguous columns (one with no source stays as it is).
    feat.par_chunks_mut(nz)
        .for_each_init(Scratch::default, |(f, v, zs, orig), col| {
            pass_line(col, |_| 0, f, v, zs, orig);
        });
    ctl.check()?;
    let t1 = std::time::Instant::now();
    ctl.set(1.0 / 3.0);
    // y: within each x slab, lines of stride Z, TILE of them (consecutive z) at a time: read
    // and written a row of TILE at once.
    feat.par_chunks_mut(ny * nz).for_each_init(
        || (Scratch::default(), vec![NONE; ny * TILE]),
        |((f, v, zs, orig), block), slab| {
            for z0 in (0..nz).step_by(TILE) {
                let width = TILE.min(nz - z0);
                let at_y = |y: usize| y * nz + z0..y * nz + z0 + width;
                gather(block, ny, width, |y, out| {
                    out.copy_from_slice(&slab[at_y(y)])
                });
                for j in 0..width {
                    let z = (z0 + j) as u32;
                    let line = &mut block[j * ny..(j + 1) * ny];
                    pass_line(line, |s| d(z, at[s as usize][1]), f, v, zs, orig);
                }
                scatter(block, ny, width, |y, row| {
                    slab[at_y(y)].copy_from_slice(row)
                });
            }
        },
    );
    ctl.check()?;
    let t2 = std::time::Instant::now();
    ctl.set(2.0 / 3.0);
    // x: lines of stride Y·Z, one (y, z) each, TILE of them (consecutive z) a task; only the
    // lines with a set voxel (the answer is read there only).
    let wanted: Vec<Vec<u64>> = (0..ny)
        .into_par_iter()
        .map(|y| {
            let mut any = vec![0u64; bits.words_per_column()];
            for x in 0..nx {
                for (a, w) in any.iter_mut().zip(bits.column(x as u32, y as u32)) {
                    *a |= w;
                }
            }
            any
        })
        .collect();
    let shared = Lines(feat.as_mut_ptr());
    let shared = &shared;
    let tiles = nz.div_ceil(TILE);
    (0..ny * tiles).into_par_iter().for_each_init(
        || (Scratch::default(), vec![NONE; nx * TILE]),
        |((f, v, zs, orig), block), t| {
            let (y, z0) = (t / tiles, (t % tiles) * TILE);
            let width = TILE.min(nz - z0);
            let wanted = &wanted[y];
            let want = |z: usize| wanted[z / 64] >> (z % 64) & 1 == 1;
            if !(z0..z0 + width).any(want) {
                return;
            }
            let base = y * nz + z0;
            gather(block, nx, width, |x, out| {
                for (j, s) in out.iter_mut().enumerate() {
                    // SAFETY: the lines (y, z0..z0 + width) are read and written by this task
                    // only (module-level note on `Lines`); every index is below X·Y·Z.
                    *s = unsafe { shared.get(x * ny * nz + base + j) };
                }
            });
            for j in (0..width).filter(|&j| want(z0 + j)) {
                let z = (z0 + j) as u32;
                let col = &mut block[j * nx..(j + 1) * nx];
                let dist = |s: u32| {
                    let [ay, az] = at[s as usize];
                    d(y as u32, ay) + d(z, az)
                };
                pass_line(col, dist, f, v, zs, orig);
            }
            scatter(block, nx, width, |x, row| {
                for (j, &s) in row.iter().enumerate() {
                    // SAFETY: as above.
                    unsafe { shared.set(x * ny * nz + base + j, s) };
                }
            });
        },
    );
    ctl.check()?;
    let t3 = std::time::Instant::now();
    // Each set voxel's feature, by rank: the x slabs on every thread, each into its own part
    // of the answer (no copy of it: the memory estimate counts one).
    let words_per_slab = ny * bits.words_per_column();
    let slab_words = |x: usize| &bits.words()[x * words_per_slab..(x + 1) * words_per_slab];
    let counts: Vec<usize> = (0..nx)
        .into_par_iter()
        .map(|x| slab_words(x).iter().map(|w| w.count_ones() as usize).sum())
        .collect();
    let mut out = vec![0u32; counts.iter().sum()];
    crate::split_lengths(&mut out, counts)
        .into_par_iter()
        .enumerate()
        .for_each(|(x, part)| {
            let mut r = 0;
            for y in 0..ny {
                let base = (x * ny + y) * nz;
                for (i, &w) in bits.column(x as u32, y as u32).iter().enumerate() {
                    let mut w = w;
                    while w != 0 {
                        let s = feat[base + i * 64 + w.trailing_zeros() as usize];
                        part[r] = if s == NONE { 0 } else { s };
                        r += 1;
                        w &= w - 1;
                    }
                }
            }
        });
    tracing::debug!(
        setup_s = (t0 - start).as_secs_f64(),
        z_s = (t1 - t0).as_secs_f64(),
        y_s = (t2 - t1).as_secs_f64(),
        x_s = (t3 - t2).as_secs_f64(),
        gather_s = t3.elapsed().as_secs_f64(),
        "feature transform"
    );
    Ok(out)
}
