//! Between bit volumes and distance volumes: [`threshold`] (a distance volume's voxels below a
//! level, as bits) and [`sdf_of_bits`] (the signed distance of a bit volume's voxels to its
//! boundary, by an exact Euclidean distance transform), as `docs/methods.md` defines them.
//!
//! The transform: for a voxel that is not set, D² is the squared distance (in voxels, an
//! integer) from its centre to the nearest set voxel's centre; for a set voxel, to the nearest
//! centre of a voxel that is not set, counting every voxel outside the grid as not set. The
//! value is `±(√D² − ½)·s` (negative at the set voxels; so never zero, and the two voxels on
//! either side of a face are ∓s/2), in f64 rounded once to f32. A voxel is in the band of `k`
//! voxels iff `√D² − ½ < k`, i.e. `D² ≤ k² + k` (decided in integers); the rest hold `±k·s`.
//! The squared distances come from Felzenszwalb & Huttenlocher's lower envelope of parabolas,
//! one axis at a time, in exact integer arithmetic (the envelope's breakpoints are compared as
//! fractions), with every squared distance capped at `k² + k + 1`: the capped transform equals
//! the exact one wherever that is below the cap, so it fits in a `u16`.

use super::sparse::{BRICK, BRICK_VOXELS, Sparse};
use super::{BitVolume, Volume, VolumeKind, WrongKind};
use crate::cancel::{Canceled, Control};

/// The kinds `threshold` (and distance statistics, queries and CSG) take.
pub const DISTANCE_KINDS: &[VolumeKind] = &[VolumeKind::Distance, VolumeKind::SparseDistance];
/// The kinds the distance transform takes.
pub const SDF_ACCEPTS: &[VolumeKind] = super::BITS_AND_CHANNELS;
/// The widest band the transform makes, in voxels (as `method=sdf`).
pub const MAX_BAND: u32 = 64;
/// The band when none is asked for, in voxels (OpenVDB's default half width).
pub const DEFAULT_BAND: u32 = 3;

/// A distance volume as sparse bricks (a dense one: every brick, background +∞, tiles −∞), or
/// the refusal of `what`.
pub fn into_distance(v: Volume, what: &str) -> Result<Sparse<f32>, WrongKind> {
    match v {
        Volume::SparseDistance(s) => Ok(s),
        Volume::Distance(d) => {
            let mut s = Sparse::with_tile_value(*d.grid(), f32::INFINITY, f32::NEG_INFINITY);
            let full = Sparse::from_dense(&d, f32::NAN);
            for (at, b) in full.bricks() {
                let mut brick = *b;
                // Past the grid: the background.
                for v in brick.iter_mut().filter(|v| v.is_nan()) {
                    *v = f32::INFINITY;
                }
                s.insert_brick(at, brick).expect("inside the brick grid");
            }
            Ok(s)
        }
        other => Err(WrongKind {
            given: other.kind(),
            accepts: DISTANCE_KINDS,
            what: what.into(),
        }),
    }
}

/// The (x, y, z) of each of a brick's voxels, with its offset in the brick, that lie in `dims`.
fn brick_voxels(at: [u32; 3], dims: [u32; 3]) -> impl Iterator<Item = (usize, [u32; 3])> {
    (0..BRICK_VOXELS).filter_map(move |i| {
        let i32_ = i as u32;
        let p = [
            at[0] * BRICK + i32_ / 64,
            at[1] * BRICK + i32_ / 8 % 8,
            at[2] * BRICK + i32_ % 8,
        ];
        (p[0] < dims[0] && p[1] < dims[1] && p[2] < dims[2]).then_some((i, p))
    })
}

/// The voxels of `s` below `level` under IEEE totalOrder (`f32::total_cmp`: −0.0 < +0.0, so
/// `level` 0 gives exactly the voxels whose sign bit is set).
pub fn threshold(s: &Sparse<f32>, level: f32) -> BitVolume {
    threshold_with(s, level, &Control::none()).expect("Control::none never stops")
}

/// [`threshold`], checking `ctl` every 1024 bricks and reporting progress there.
pub fn threshold_with(s: &Sparse<f32>, level: f32, ctl: &Control) -> Result<BitVolume, Canceled> {
    ctl.check()?;
    let below = |v: f32| v.total_cmp(&level).is_lt();
    let g = *s.grid();
    let dims = g.dims;
    let mut out = BitVolume::new(g);
    let background = below(s.background());
    if background {
        let tail = out.tail_mask();
        let wpc = out.words_per_column();
        for col in out.words_mut().chunks_exact_mut(wpc) {
            col.fill(u64::MAX);
            col[wpc - 1] &= tail;
        }
    }
    let tile = below(s.tile_value());
    if tile != background {
        for at in s.tiles() {
            for (_, [x, y, z]) in brick_voxels(at, dims) {
                out.set(x, y, z, tile);
            }
        }
    }
    let done = ctl.counter(s.brick_count() as u64);
    for (n, (at, b)) in s.bricks().enumerate() {
        if n % 1024 == 1023 {
            done.add(1024);
            done.check()?;
        }
        for (i, [x, y, z]) in brick_voxels(at, dims) {
            out.set(x, y, z, below(b[i]));
        }
    }
    ctl.complete();
    Ok(out)
}

/// The signed distance volume of `b` in a band of `band` voxels (1..=[`MAX_BAND`], checked by
/// the caller), as the module doc defines it.
pub fn sdf_of_bits(b: &BitVolume, band: u32) -> Sparse<f32> {
    sdf_of_bits_with(b, band, &Control::none()).expect("Control::none never stops")
}

/// Squared distances along one line: `out[q] = min_p (q − p)² + f[p]` (the lower envelope of
/// the parabolas rooted at every `p`, Felzenszwalb & Huttenlocher), exactly, capped at
/// `u16::MAX`. `v` and `z` are scratch of at least `f.len()`.
fn envelope(f: &[u16], v: &mut [usize], z: &mut [(i128, i128)], out: &mut [u16]) {
    let n = f.len();
    if n == 0 {
        return;
    }
    // z[k]: where parabola v[k] starts being the lowest, as a fraction (num, den > 0); z[0] is
    // −∞ (never compared).
    let h = |p: usize| f[p] as i128 + (p * p) as i128;
    let mut k = 0usize;
    v[0] = 0;
    z[0] = (0, 1);
    for q in 1..n {
        loop {
            let p = v[k];
            let s = (h(q) - h(p), 2 * (q - p) as i128);
            // The new parabola is lower from s on; it hides v[k] when s ≤ z[k].
            if k > 0 && s.0 * z[k].1 <= z[k].0 * s.1 {
                k -= 1;
                continue;
            }
            k += 1;
            v[k] = q;
            z[k] = s;
            break;
        }
    }
    let m = k + 1;
    let mut k = 0usize;
    for (q, o) in out.iter_mut().enumerate().take(n) {
        while k + 1 < m && z[k + 1].0 < q as i128 * z[k + 1].1 {
            k += 1;
        }
        let p = v[k];
        let d = (q as i64 - p as i64).pow(2) as u64 + f[p] as u64;
        *o = d.min(u64::from(u16::MAX)) as u16;
    }
}

/// One pass of the transform along `axis` over a padded array of `dims` (z fastest).
fn pass(f: &mut [u16], dims: [usize; 3], axis: usize, ctl: &Control) -> Result<(), Canceled> {
    let stride = [dims[1] * dims[2], dims[2], 1];
    let n = dims[axis];
    let (mut line, mut out) = (vec![0u16; n], vec![0u16; n]);
    let (mut v, mut z) = (vec![0usize; n], vec![(0i128, 1i128); n]);
    let others: Vec<usize> = (0..3).filter(|&a| a != axis).collect();
    let (a, b) = (others[0], others[1]);
    for i in 0..dims[a] {
        ctl.check()?;
        for j in 0..dims[b] {
            let base = i * stride[a] + j * stride[b];
            let st = stride[axis];
            for (q, l) in line.iter_mut().enumerate() {
                *l = f[base + q * st];
            }
            envelope(&line, &mut v, &mut z, &mut out);
            for (q, o) in out.iter().enumerate() {
                f[base + q * st] = *o;
            }
        }
    }
    Ok(())
}

/// Squared distances (capped at `cap`) from each voxel of the grid padded by one voxel on every
/// side to the nearest voxel where `feature` holds (its argument: padded coordinates).
fn squared_edt(
    dims: [u32; 3],
    cap: u16,
    feature: impl Fn(i64, i64, i64) -> bool,
    ctl: &Control,
) -> Result<Vec<u16>, Canceled> {
    let p = dims.map(|d| d as usize + 2);
    let mut f = vec![cap; p[0] * p[1] * p[2]];
    for x in 0..p[0] {
        for y in 0..p[1] {
            let row = (x * p[1] + y) * p[2];
            for z in 0..p[2] {
                if feature(x as i64 - 1, y as i64 - 1, z as i64 - 1) {
                    f[row + z] = 0;
                }
            }
        }
    }
    for (i, axis) in [2, 1, 0].into_iter().enumerate() {
        pass(
            &mut f,
            p,
            axis,
            &ctl.stage(i as f64 / 3.0, (i + 1) as f64 / 3.0),
        )?;
    }
    Ok(f)
}

/// [`sdf_of_bits`], checking `ctl` per plane of each pass and reporting progress.
pub fn sdf_of_bits_with(b: &BitVolume, band: u32, ctl: &Control) -> Result<Sparse<f32>, Canceled> {
    assert!((1..=MAX_BAND).contains(&band), "band {band} out of range");
    ctl.check()?;
    let g = *b.grid();
    let dims = g.dims;
    let s = g.voxel_size;
    let k = u64::from(band);
    let in_band = k * k + k; // D² ≤ k² + k  ⇔  √D² − ½ < k
    let cap = (in_band + 1) as u16;
    let inside = |x: i64, y: i64, z: i64| {
        (0..3).all(|a| [x, y, z][a] >= 0 && [x, y, z][a] < i64::from(dims[a]))
            && b.get(x as u32, y as u32, z as u32)
    };
    // To the nearest set voxel (for the voxels not set), and to the nearest voxel not set
    // (for the set ones; the padding is not set).
    let to_set = squared_edt(dims, cap, inside, &ctl.stage(0.0, 0.45))?;
    let to_unset = squared_edt(dims, cap, |x, y, z| !inside(x, y, z), &ctl.stage(0.45, 0.9))?;
    let width = (band as f64 * s) as f32;
    let mut out = Sparse::with_tile_value(g, width, -width);
    let p = dims.map(|d| d as usize + 2);
    let bd = out.brick_dims();
    let planes = ctl.stage(0.9, 1.0).counter(u64::from(bd[0]));
    for bx in 0..bd[0] {
        planes.add(1);
        planes.check()?;
        for by in 0..bd[1] {
            for bz in 0..bd[2] {
                let at = [bx, by, bz];
                let mut brick = [width; BRICK_VOXELS];
                let (mut active, mut set, mut unset) = (false, false, false);
                for (i, [x, y, z]) in brick_voxels(at, dims) {
                    let idx = ((x as usize + 1) * p[1] + y as usize + 1) * p[2] + z as usize + 1;
                    let here = b.get(x, y, z);
                    let d2 = u64::from(if here { to_unset[idx] } else { to_set[idx] });
                    let m = if d2 <= in_band {
                        active = true;
                        ((d2 as f64).sqrt() - 0.5) * s
                    } else {
                        band as f64 * s
                    };
                    if here {
                        set = true;
                        brick[i] = -(m as f32);
                    } else {
                        unset = true;
                        brick[i] = m as f32;
                    }
                }
                if active || (set && unset) {
                    out.insert_brick(at, brick).expect("inside the brick grid");
                } else if set {
                    out.set_tile(at, true).expect("inside the brick grid");
                }
            }
        }
    }
    ctl.complete();
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::Grid;

    fn grid(d: [u32; 3], s: f64) -> Grid {
        Grid {
            origin: [0.5, -1.0, 2.0],
            voxel_size: s,
            dims: d,
        }
    }

    /// A small deterministic generator (xorshift), for test volumes.
    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> u64 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            self.0
        }
        fn below(&mut self, n: u64) -> u64 {
            self.next() % n
        }
    }

    /// Random balls and boxes.
    fn blobs(d: [u32; 3], rng: &mut Rng) -> BitVolume {
        let mut b = BitVolume::new(grid(d, 0.25));
        for _ in 0..1 + rng.below(4) {
            let c: Vec<i64> = d.iter().map(|&n| rng.below(u64::from(n)) as i64).collect();
            let r = 1 + rng.below(5) as i64;
            let ball = rng.below(2) == 0;
            for x in 0..d[0] {
                for y in 0..d[1] {
                    for z in 0..d[2] {
                        let e = [x as i64 - c[0], y as i64 - c[1], z as i64 - c[2]];
                        let hit = if ball {
                            e.iter().map(|v| v * v).sum::<i64>() <= r * r
                        } else {
                            e.iter().all(|v| v.abs() <= r)
                        };
                        if hit {
                            b.set(x, y, z, true);
                        }
                    }
                }
            }
        }
        b
    }

    /// The squared distance (voxels) from voxel p to the nearest voxel of the other state,
    /// by looking at every voxel, and at the nearest voxel outside the grid for a set one.
    fn brute_d2(b: &BitVolume, p: [u32; 3]) -> u64 {
        let d = b.dims();
        let here = b.get(p[0], p[1], p[2]);
        let mut best = u64::MAX;
        for x in 0..d[0] {
            for y in 0..d[1] {
                for z in 0..d[2] {
                    if b.get(x, y, z) != here {
                        let e = [x, y, z]
                            .iter()
                            .zip(p)
                            .map(|(&a, b)| (a as i64 - b as i64).pow(2) as u64)
                            .sum();
                        best = best.min(e);
                    }
                }
            }
        }
        if here {
            for a in 0..3 {
                best = best.min(u64::from(p[a] + 1).pow(2));
                best = best.min(u64::from(d[a] - p[a]).pow(2));
            }
        }
        best
    }

    #[test]
    fn the_transform_is_the_brute_force_distance_and_thresholds_back() {
        let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
        for case in 0..24 {
            let d = [
                3 + rng.below(14) as u32,
                3 + rng.below(14) as u32,
                3 + rng.below(14) as u32,
            ];
            let b = blobs(d, &mut rng);
            let band = 1 + (case % 4) as u32;
            let sdf = sdf_of_bits(&b, band);
            let s = b.grid().voxel_size;
            let width = (f64::from(band) * s) as f32;
            assert_eq!((sdf.background(), sdf.tile_value()), (width, -width));
            for x in 0..d[0] {
                for y in 0..d[1] {
                    for z in 0..d[2] {
                        let d2 = brute_d2(&b, [x, y, z]);
                        let here = b.get(x, y, z);
                        // In band iff the distance less half a voxel is under the band.
                        let m = (d2 as f64).sqrt() - 0.5;
                        let want = if m < f64::from(band) {
                            (m * s) as f32
                        } else {
                            width
                        };
                        let want = if here { -want } else { want };
                        let got = sdf.get(x, y, z);
                        assert_eq!(got.to_bits(), want.to_bits(), "{d:?} {x} {y} {z} d²={d2}");
                    }
                }
            }
            assert_eq!(threshold(&sdf, 0.0), b, "case {case}");
            // Stored bricks hold an in-band voxel; tiles are whole bricks of inside.
            for (_, brick) in sdf.bricks() {
                assert!(brick.iter().any(|v| v.abs() < width));
            }
        }
    }

    #[test]
    fn a_solid_far_from_its_faces_gets_tiles() {
        let d = [40, 24, 24];
        let mut b = BitVolume::new(grid(d, 1.0));
        for x in 1..39 {
            for y in 1..23 {
                for z in 1..23 {
                    b.set(x, y, z, true);
                }
            }
        }
        let sdf = sdf_of_bits(&b, 3);
        // Bricks x 1..=3, y 1, z 1 are 8..=31, 8..=15: 5 or more voxels from every face.
        assert!(sdf.is_tile([2, 1, 1]));
        assert_eq!(sdf.get(20, 12, 12), -3.0);
        assert_eq!(sdf.get(0, 5, 5), 0.5);
        assert_eq!(sdf.get(0, 0, 0), (3f64.sqrt() - 0.5) as f32);
        assert_eq!(sdf.get(1, 1, 1), -0.5);
        assert_eq!(sdf.get(2, 5, 5), -1.5);
        assert_eq!(threshold(&sdf, 0.0), b);
        // An offset surface one voxel in: the voxels at least 1.5 voxels deep.
        let inner = threshold(&sdf, -1.0);
        assert!(inner.get(2, 2, 2) && !inner.get(1, 5, 5));
        assert_eq!(inner.count_ones(), 36 * 20 * 20);
        assert_eq!(
            sdf_of_bits(&BitVolume::new(grid(d, 1.0)), 2).brick_count(),
            0
        );
    }

    #[test]
    fn threshold_reads_background_tiles_and_bricks_in_total_order() {
        let g = grid([12, 9, 8], 1.0);
        let mut s = Sparse::with_tile_value(g, 2.0f32, -2.0);
        s.set_tile([1, 0, 0], true).unwrap();
        s.set(0, 0, 0, -0.0);
        s.set(0, 0, 1, 0.0);
        s.set(3, 8, 7, -0.5);
        s.set(2, 2, 2, 1.0);
        for level in [0.0f32, -0.0, 1.0, 1.5, -2.0, 2.5, -3.0] {
            let t = threshold(&s, level);
            for x in 0..12 {
                for y in 0..9 {
                    for z in 0..8 {
                        let v = s.get(x, y, z);
                        // totalOrder: −0.0 sorts below +0.0.
                        let key = |f: f32| (f as f64, f.is_sign_negative());
                        let below = key(v).0 < key(level).0
                            || (key(v).0 == key(level).0 && key(v).1 && !key(level).1);
                        assert_eq!(t.get(x, y, z), below, "{x} {y} {z} {v} < {level}");
                    }
                }
            }
        }
        assert_eq!(threshold(&s, 0.0).count_ones(), 4 * 8 * 8 + 2);
        assert_eq!(threshold(&s, 3.0).count_ones(), 12 * 9 * 8);
    }
}
