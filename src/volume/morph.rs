//! Morphology of bit volumes (Eisemann & Décoret §7): dilate, erode, open, close with radius r and
//! a kernel — `cube` (Chebyshev ball, |d|∞ ≤ r), `cross` (Manhattan ball, |d|₁ ≤ r: r steps of the
//! 6-neighbourhood) or `sphere` (Euclidean ball, |d|₂ ≤ r).
//!
//! Definitions: voxels outside the grid are empty. dilate(v)(p) = ∃ d ∈ K: v(p + d);
//! erode(v)(p) = ∀ d ∈ K: v(p + d) (so voxels within r of the grid's border erode); open =
//! dilate(erode), close = erode(dilate). With `grow`, dilate and close work on the grid enlarged by
//! r voxels on every side, so nothing is clipped, and the result lives on that grid.
//!
//! How: a distance transform of the kernel's metric, thresholded at r, in one pass of three
//! separable steps whatever the radius (integer arithmetic throughout, so the results are the
//! definitions' bits). dilate(v)(p) ⇔ dist(p, v) ≤ r over the voxels of the grid; erode(v)(p) ⇔
//! no empty voxel of the grid within r and p at least r voxels inside every face (the nearest
//! voxel outside the grid is straight across the nearest face, at the same distance in every
//! metric). Each x-plane of the result is computed on its own (in parallel):
//!
//! 1. along x, word-parallel over the columns x − r ..= x + r: the distance |dx| ≤ r to the
//!    nearest set (for erosion: empty) voxel of each (y, z) line, as the metric's cost (dx² for
//!    the sphere, |dx| for the cross, 0 for the cube);
//! 2. along z: the sphere's lower envelope of parabolas (Meijster et al. 2000, exact in integers)
//!    min (dz² + cost); the cross's and cube's two sweeps of min (|dz| + cost), an exact L1
//!    transform;
//! 3. along y: every (y', z) whose partial distance h still leaves room covers the interval
//!    y' ± s (s = ⌊√(r² − h)⌋ for the sphere, r − h for the cross, r for the cube), two
//!    sweeps of running reach.
//!
//! Costs above the threshold are dropped at every step, so every value fits 16 bits. The
//! control ([`apply_with`]) is checked per x-plane and hears each one done.

use rayon::prelude::*;

use super::csg::regrid;
use super::{BitVolume, VolumeKind, tail_mask};

/// The kinds morphology works on.
pub const ACCEPTS: &[VolumeKind] = super::BITS_AND_CHANNELS;
use crate::cancel::{Canceled, Control};
use crate::grid::Grid;

crate::named_enum! {
    /// The kernel's shape: which offsets d lie within radius r.
    pub enum Kernel: "kernel" {
        /// Chebyshev ball, |d|∞ ≤ r.
        Cube = "cube",
        /// Manhattan ball, |d|₁ ≤ r: r steps of the 6-neighbourhood.
        Cross = "cross",
        /// Euclidean ball, |d|₂ ≤ r.
        Sphere = "sphere",
    }
}

crate::named_enum! {
    /// The morphology operations (definitions in the module doc).
    pub enum MorphOp: "operation" {
        Dilate = "dilate",
        Erode = "erode",
        /// dilate(erode).
        Open = "open",
        /// erode(dilate).
        Close = "close",
    }
}

/// Largest radius accepted (the limits' `max_morph_radius`); keeps every squared distance that
/// matters within 16 bits.
pub const MAX_RADIUS: u32 = crate::limits::Limits::LOCAL.max_morph_radius;
const _: () = assert!(MAX_RADIUS <= 255, "r² must stay below the 16-bit FAR");

pub fn apply(v: &BitVolume, op: MorphOp, r: u32, k: Kernel, grow: bool) -> BitVolume {
    apply_with(v, op, r, k, grow, &Control::none()).expect("Control::none never stops")
}

/// [`apply`], checking `ctl` per x-plane of each pass and reporting progress there.
pub fn apply_with(
    v: &BitVolume,
    op: MorphOp,
    r: u32,
    k: Kernel,
    grow: bool,
    ctl: &Control,
) -> Result<BitVolume, Canceled> {
    assert!(r <= MAX_RADIUS);
    ctl.check()?;
    let out = match op {
        MorphOp::Dilate => dilate_with(&maybe_grow(v, r, grow), r, k, ctl)?,
        MorphOp::Erode => erode_with(v, r, k, ctl)?,
        MorphOp::Open => {
            let e = erode_with(v, r, k, &ctl.stage(0.0, 0.5))?;
            dilate_with(&e, r, k, &ctl.stage(0.5, 1.0))?
        }
        MorphOp::Close => {
            let d = dilate_with(&maybe_grow(v, r, grow), r, k, &ctl.stage(0.0, 0.5))?;
            erode_with(&d, r, k, &ctl.stage(0.5, 1.0))?
        }
    };
    ctl.complete();
    Ok(out)
}

/// `g` with `r` more voxels on every side.
pub fn padded(g: &Grid, r: u32) -> Grid {
    g.padded(r)
}

fn maybe_grow(v: &BitVolume, r: u32, grow: bool) -> BitVolume {
    if grow && r > 0 {
        regrid(v, &padded(v.grid(), r)).expect("a padded grid is aligned")
    } else {
        v.clone()
    }
}

pub fn dilate(v: &BitVolume, r: u32, k: Kernel) -> BitVolume {
    dilate_with(v, r, k, &Control::none()).expect("Control::none never stops")
}

pub fn erode(v: &BitVolume, r: u32, k: Kernel) -> BitVolume {
    erode_with(v, r, k, &Control::none()).expect("Control::none never stops")
}

/// [`dilate`], checking `ctl` per x-plane.
pub fn dilate_with(v: &BitVolume, r: u32, k: Kernel, ctl: &Control) -> Result<BitVolume, Canceled> {
    transform(v, r, k, false, ctl)
}

/// [`erode`], checking `ctl` per x-plane.
pub fn erode_with(v: &BitVolume, r: u32, k: Kernel, ctl: &Control) -> Result<BitVolume, Canceled> {
    transform(v, r, k, true, ctl)
}

/// A cost or partial distance beyond the threshold: it can no longer reach a voxel.
const FAR: u16 = u16::MAX;

/// Per-thread buffers of one x-plane.
struct Scratch {
    /// Step 1's costs, then step 2's partial distances, `[y * Z + z]`.
    cost: Vec<u16>,
    /// Whether row y has any cost below `FAR`.
    row_any: Vec<bool>,
    /// One column's features found so far (step 1).
    acc: Vec<u64>,
    /// Step 2's envelope: sites, their starts, and the output line.
    sites: Vec<usize>,
    starts: Vec<usize>,
    line: Vec<u16>,
    /// Step 3's running reach per z, forwards and backwards.
    reach: Vec<i32>,
}

impl Scratch {
    fn new(ny: usize, nz: usize, wpc: usize) -> Scratch {
        Scratch {
            cost: vec![FAR; ny * nz],
            row_any: vec![false; ny],
            acc: vec![0; wpc],
            sites: vec![0; nz],
            starts: vec![0; nz],
            line: vec![FAR; nz],
            reach: vec![0; nz],
        }
    }
}

/// What stays constant over the planes of one transform.
struct Plan<'a> {
    v: &'a BitVolume,
    r: u32,
    kernel: Kernel,
    erode: bool,
    /// The valid bits of each word of a column.
    valid: Vec<u64>,
    /// For erosion: the bits of the voxels at least r from the column's ends.
    inner: Vec<u64>,
    /// `reach[h]`: how far along y a partial distance h still reaches (h ≤ the threshold).
    reach: Vec<i32>,
    /// The largest partial distance kept.
    limit: u16,
}

fn transform(
    v: &BitVolume,
    r: u32,
    kernel: Kernel,
    erode: bool,
    ctl: &Control,
) -> Result<BitVolume, Canceled> {
    ctl.check()?;
    if r == 0 {
        ctl.complete();
        return Ok(v.clone());
    }
    let [nx, ny, nz] = v.dims();
    let wpc = v.words_per_column();
    let mut out = BitVolume::new(*v.grid());
    let plane_words = ny as usize * wpc;
    if plane_words == 0 || nx == 0 {
        ctl.complete();
        return Ok(out);
    }
    let mut valid = vec![u64::MAX; wpc];
    valid[wpc - 1] = tail_mask(nz);
    let inner = (0..wpc)
        .map(|w| {
            (0..64u32)
                .filter(|b| {
                    let z = w as u64 * 64 + *b as u64;
                    z >= r as u64 && z + (r as u64) < nz as u64
                })
                .fold(0u64, |m, b| m | 1 << b)
        })
        .collect();
    let ri = r as i32;
    let (limit, reach) = match kernel {
        Kernel::Sphere => (
            ri * ri,
            (0..=ri * ri)
                .map(|h| ((ri * ri - h) as u32).isqrt() as i32)
                .collect(),
        ),
        Kernel::Cross => (ri, (0..=ri).map(|h| ri - h).collect()),
        Kernel::Cube => (ri, vec![ri; r as usize + 1]),
    };
    let plan = Plan {
        v,
        r,
        kernel,
        erode,
        valid,
        inner,
        reach,
        limit: limit as u16,
    };
    let planes = ctl.counter(nx as u64);
    out.words_mut()
        .par_chunks_mut(plane_words)
        .enumerate()
        .try_for_each_init(
            || Scratch::new(ny as usize, nz as usize, wpc),
            |scratch, (x, words)| {
                planes.check()?;
                plane(&plan, x as u32, scratch, words);
                planes.add(1);
                Ok(())
            },
        )?;
    Ok(out)
}

/// The x-plane `x` of the transform into `out` (its Y columns, zero on entry).
fn plane(p: &Plan, x: u32, s: &mut Scratch, out: &mut [u64]) {
    let v = p.v;
    let [nx, ny, nz] = v.dims();
    let (r, wpc) = (p.r, v.words_per_column());
    let (ny, nz) = (ny as usize, nz as usize);
    if p.erode && (x < r || x + r >= nx) {
        return; // within r of a face along x: eroded
    }
    // 1. Along x: the cost of the nearest feature of each (y, z) line within r.
    let feature = |x: u32, y: usize, w: usize| {
        let c = v.column(x, y as u32)[w];
        if p.erode { !c & p.valid[w] } else { c }
    };
    let mut any = false;
    for y in 0..ny {
        let cost = &mut s.cost[y * nz..(y + 1) * nz];
        cost.fill(FAR);
        s.acc.fill(0);
        let mut found = false;
        for d in 0..=r {
            let c = match p.kernel {
                Kernel::Sphere => (d * d) as u16,
                Kernel::Cross => d as u16,
                Kernel::Cube => 0,
            };
            let below = x.checked_sub(d);
            let above = (d > 0 && x + d < nx).then_some(x + d);
            for xs in [below, above].into_iter().flatten() {
                for w in 0..wpc {
                    let mut new = feature(xs, y, w) & !s.acc[w];
                    if new == 0 {
                        continue;
                    }
                    s.acc[w] |= new;
                    found = true;
                    while new != 0 {
                        let b = new.trailing_zeros() as usize;
                        cost[w * 64 + b] = c;
                        new &= new - 1;
                    }
                }
            }
            if s.acc.iter().zip(&p.valid).all(|(a, m)| a == m) {
                break;
            }
        }
        s.row_any[y] = found;
        any |= found;
    }
    if any {
        // 2. Along z, row by row.
        for y in 0..ny {
            if !s.row_any[y] {
                continue;
            }
            let row = &mut s.cost[y * nz..(y + 1) * nz];
            match p.kernel {
                Kernel::Sphere => {
                    parabolas(row, &mut s.line, &mut s.sites, &mut s.starts, p.limit);
                    row.copy_from_slice(&s.line);
                }
                Kernel::Cross | Kernel::Cube => l1_sweeps(row, p.limit),
            }
        }
        // 3. Along y: the intervals y' ± reach(h), forwards then backwards.
        let r_at = |h: u16| p.reach[h as usize];
        s.reach.fill(-1);
        for y in 0..ny {
            let col = &mut out[y * wpc..(y + 1) * wpc];
            if s.row_any[y] {
                for (z, &h) in s.cost[y * nz..(y + 1) * nz].iter().enumerate() {
                    if h != FAR {
                        s.reach[z] = s.reach[z].max(y as i32 + r_at(h));
                    }
                }
            }
            for (z, &e) in s.reach.iter().enumerate() {
                if e >= y as i32 {
                    col[z / 64] |= 1 << (z % 64);
                }
            }
        }
        s.reach.fill(i32::MAX);
        for y in (0..ny).rev() {
            let col = &mut out[y * wpc..(y + 1) * wpc];
            if s.row_any[y] {
                for (z, &h) in s.cost[y * nz..(y + 1) * nz].iter().enumerate() {
                    if h != FAR {
                        s.reach[z] = s.reach[z].min(y as i32 - r_at(h));
                    }
                }
            }
            for (z, &b) in s.reach.iter().enumerate() {
                if b <= y as i32 {
                    col[z / 64] |= 1 << (z % 64);
                }
            }
        }
    }
    if p.erode {
        // Kept: voxels no empty voxel reaches, at least r inside the faces along y and z.
        for y in 0..ny {
            let col = &mut out[y * wpc..(y + 1) * wpc];
            let inside = y >= r as usize && y + (r as usize) < ny;
            for (w, word) in col.iter_mut().enumerate() {
                *word = if inside { !*word & p.inner[w] } else { 0 };
            }
        }
    }
}

/// `out[u] = min_i (u − i)² + f[i]` (`FAR` entries are no sites), `FAR` where above `limit`: the
/// lower envelope of parabolas of Meijster, Roerdink & Hesselink (2000), in integers.
fn parabolas(f: &[u16], out: &mut [u16], s: &mut [usize], t: &mut [usize], limit: u16) {
    // Larger than any finite value: (u − i)² < 2⁴⁰ on a grid axis.
    const INF: i64 = 1 << 42;
    let n = f.len();
    let g = |i: usize| if f[i] == FAR { INF } else { f[i] as i64 };
    let at = |x: usize, i: usize| {
        let d = x as i64 - i as i64;
        d * d + g(i)
    };
    // The first x at which site u is strictly below site i (i < u).
    let sep = |i: usize, u: usize| {
        let (a, b) = (i as i64, u as i64);
        (b * b - a * a + g(u) - g(i)).div_euclid(2 * (b - a)) + 1
    };
    let mut q = 0usize;
    let mut empty = false;
    s[0] = 0;
    t[0] = 0;
    for u in 1..n {
        loop {
            if at(t[q], s[q]) <= at(t[q], u) {
                break;
            }
            if q == 0 {
                empty = true;
                break;
            }
            q -= 1;
        }
        if empty {
            empty = false;
            q = 0;
            s[0] = u;
            t[0] = 0;
        } else {
            let w = sep(s[q], u);
            if w < n as i64 {
                q += 1;
                s[q] = u;
                t[q] = w as usize;
            }
        }
    }
    for u in (0..n).rev() {
        let d = at(u, s[q]);
        out[u] = if d <= limit as i64 { d as u16 } else { FAR };
        if u == t[q] && q > 0 {
            q -= 1;
        }
    }
}

/// `row[z] = min_z' |z − z'| + row[z']`, `FAR` where above `limit`: the exact L1 transform by a
/// forward and a backward sweep.
fn l1_sweeps(row: &mut [u16], limit: u16) {
    for z in 1..row.len() {
        row[z] = row[z].min(row[z - 1].saturating_add(1));
    }
    for z in (0..row.len().saturating_sub(1)).rev() {
        row[z] = row[z].min(row[z + 1].saturating_add(1));
    }
    for c in row.iter_mut() {
        if *c > limit {
            *c = FAR;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parabolas_match_brute_force() {
        let mut seed = 12345u64;
        let mut next = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 33) as u32
        };
        for n in [1usize, 2, 3, 7, 64, 130] {
            for _ in 0..50 {
                let f: Vec<u16> = (0..n)
                    .map(|_| match next() % 4 {
                        0 => FAR,
                        _ => (next() % 200) as u16,
                    })
                    .collect();
                let limit = 150u16;
                let (mut out, mut s, mut t) = (vec![0; n], vec![0; n], vec![0; n]);
                parabolas(&f, &mut out, &mut s, &mut t, limit);
                for (u, &got) in out.iter().enumerate() {
                    let best = (0..n)
                        .filter(|&i| f[i] != FAR)
                        .map(|i| (u as i64 - i as i64).pow(2) + f[i] as i64)
                        .min()
                        .filter(|&d| d <= limit as i64)
                        .map_or(FAR, |d| d as u16);
                    assert_eq!(got, best, "n {n} u {u} f {f:?}");
                }
            }
        }
    }
}
