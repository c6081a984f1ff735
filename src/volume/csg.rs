//! Boolean operations between bit volumes on aligned grids (equal voxel size, origins a whole
//! number of voxels apart), combined by world position. The result's grid: union and xor, the
//! bounding grid of the operands; intersection, their overlap; difference, the first operand's.
//! Volumes are moved onto the result grid by whole columns and word-wise shifts along z.
//!
//! Distance volumes ([`apply_distance_with`]) combine voxel by voxel on one grid (the same
//! origin, voxel size and dims): union is the minimum, intersection the maximum, difference
//! `max(a, −b)` (first minus the rest), each under IEEE totalOrder (−0.0 < +0.0), so that the
//! inside (sign bit set) of the result is exactly the bit operation on the operands' insides.
//! Every operand is first clamped to ±B, B the smallest of their backgrounds (band widths): a
//! value beyond an operand's band is only known to be beyond it. The result is sparse again,
//! with background B and tiles −B: bricks where an operand has one (dropped again where they
//! came out all B, made tiles where all −B), tiles where the operands' tiles make −B.

use super::sparse::{BRICK, BRICK_VOXELS, Sparse};
use super::{BitVolume, VolumeKind, tail_mask};

/// The kinds CSG combines (bits with bits, [`DISTANCE_ACCEPTS`] with each other).
pub const ACCEPTS: &[VolumeKind] = super::BITS_AND_CHANNELS;
/// The distance kinds CSG combines with each other.
pub const DISTANCE_ACCEPTS: &[VolumeKind] = super::levelset::DISTANCE_KINDS;
use crate::cancel::{Canceled, Control};
use crate::grid::Grid;

crate::named_enum! {
    /// How operands combine; the result's grid for each is in the module doc.
    pub enum CsgOp: "operation" {
        Union = "union",
        Intersection = "intersection",
        Difference = "difference",
        Xor = "xor",
    }
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum CsgError {
    #[error(
        "grids are not aligned: voxel sizes {a} and {b} with origins {oa:?} and {ob:?}; CSG needs equal voxel sizes and origins a whole number of voxels apart (voxelize with an explicit grid)"
    )]
    Misaligned {
        a: f64,
        b: f64,
        oa: [f64; 3],
        ob: [f64; 3],
    },
    #[error("the operands do not overlap, so their intersection has no grid")]
    NoOverlap,
    #[error("an operation needs at least one operand")]
    NoOperands,
    #[error(
        "distance volumes combine on one grid: {a:?} (origin {oa:?}, voxel size {sa}) and {b:?} (origin {ob:?}, voxel size {sb}) differ"
    )]
    DifferentGrids {
        a: [u32; 3],
        b: [u32; 3],
        oa: [f64; 3],
        ob: [f64; 3],
        sa: f64,
        sb: f64,
    },
    #[error("{0}")]
    NotForDistance(String),
    #[error(
        "the union of these operands would be {voxels} voxels long along one axis, longer than any grid can be"
    )]
    TooFarApart { voxels: i64 },
}

/// Offset of `b`'s origin from `a`'s in whole voxels, if aligned.
fn offset(a: &Grid, b: &Grid) -> Result<[i64; 3], CsgError> {
    a.offset_to(b).ok_or(CsgError::Misaligned {
        a: a.voxel_size,
        b: b.voxel_size,
        oa: a.origin,
        ob: b.origin,
    })
}

/// The grid of `op` over operands on `grids` (aligned with the first).
pub fn result_grid(op: CsgOp, grids: &[Grid]) -> Result<Grid, CsgError> {
    let first = *grids.first().ok_or(CsgError::NoOperands)?;
    if op == CsgOp::Difference {
        for g in &grids[1..] {
            offset(&first, g)?;
        }
        return Ok(first);
    }
    let (mut lo, mut hi) = ([0i64; 3], first.dims.map(i64::from));
    for g in &grids[1..] {
        let o = offset(&first, g)?;
        for a in 0..3 {
            let (glo, ghi) = (o[a], o[a] + g.dims[a] as i64);
            if op == CsgOp::Intersection {
                lo[a] = lo[a].max(glo);
                hi[a] = hi[a].min(ghi);
            } else {
                lo[a] = lo[a].min(glo);
                hi[a] = hi[a].max(ghi);
            }
        }
    }
    if (0..3).any(|a| hi[a] <= lo[a]) {
        return Err(CsgError::NoOverlap);
    }
    let mut dims = [0u32; 3];
    for a in 0..3 {
        dims[a] = u32::try_from(hi[a] - lo[a]).map_err(|_| CsgError::TooFarApart {
            voxels: hi[a] - lo[a],
        })?;
    }
    Ok(first.sub_grid(lo, dims))
}

/// `v` moved onto the aligned grid `target`: same voxels by world position, zero elsewhere.
pub fn regrid(v: &BitVolume, target: &Grid) -> Result<BitVolume, CsgError> {
    let o = offset(target, v.grid())?;
    let mut out = BitVolume::new(*target);
    let [sx, sy, _] = v.dims();
    let [tx, ty, tz] = target.dims;
    let tail = tail_mask(tz);
    for x in 0..tx {
        let vx = x as i64 - o[0];
        if vx < 0 || vx >= sx as i64 {
            continue;
        }
        for y in 0..ty {
            let vy = y as i64 - o[1];
            if vy < 0 || vy >= sy as i64 {
                continue;
            }
            let src = v.column(vx as u32, vy as u32);
            let dst = out.column_mut(x, y);
            shift_into(src, dst, o[2]);
            if let Some(last) = dst.last_mut() {
                *last &= tail;
            }
        }
    }
    Ok(out)
}

/// dst bit k = src bit (k − shift) (src bits beyond its length are zero by the volume invariant).
fn shift_into(src: &[u64], dst: &mut [u64], shift: i64) {
    for (w, d) in dst.iter_mut().enumerate() {
        *d = super::shifted_word(src, w, shift);
    }
}

/// `op` over the operands, n-ary: union/intersection/xor fold over all; difference removes every
/// later operand from the first.
pub fn apply(op: CsgOp, operands: &[&BitVolume]) -> Result<BitVolume, CsgError> {
    apply_with::<Uncanceled>(op, operands, &Control::none()).map_err(|e| e.0)
}

/// A [`CsgError`] from work that cannot be canceled.
struct Uncanceled(CsgError);

impl From<CsgError> for Uncanceled {
    fn from(e: CsgError) -> Self {
        Uncanceled(e)
    }
}

impl From<Canceled> for Uncanceled {
    fn from(_: Canceled) -> Self {
        unreachable!("Control::none never stops")
    }
}

/// [`apply`], checking `ctl` before each operand and reporting each one done; the error is
/// either a [`CsgError`] or [`Canceled`], as the caller's `E` holds them.
pub fn apply_with<E: From<CsgError> + From<Canceled>>(
    op: CsgOp,
    operands: &[&BitVolume],
    ctl: &Control,
) -> Result<BitVolume, E> {
    ctl.check()?;
    let grids: Vec<Grid> = operands.iter().map(|v| *v.grid()).collect();
    let grid = result_grid(op, &grids)?;
    let done = ctl.counter(operands.len() as u64);
    let mut acc = regrid(operands[0], &grid)?;
    done.add(1);
    for v in &operands[1..] {
        done.check()?;
        let b = regrid(v, &grid)?;
        match op {
            CsgOp::Union => acc.union_with(&b),
            CsgOp::Intersection => acc.intersect_with(&b),
            CsgOp::Difference => acc.subtract(&b),
            CsgOp::Xor => acc.xor_with(&b),
        }
        done.add(1);
    }
    Ok(acc)
}

/// Voxels set in both (aligned) volumes, without building the intersection.
pub fn overlap_count(a: &BitVolume, b: &BitVolume) -> Result<u64, CsgError> {
    let g = match result_grid(CsgOp::Intersection, &[*a.grid(), *b.grid()]) {
        Ok(g) => g,
        Err(CsgError::NoOverlap) => return Ok(0),
        Err(e) => return Err(e),
    };
    let (ra, rb) = (regrid(a, &g)?, regrid(b, &g)?);
    Ok(ra
        .words()
        .iter()
        .zip(rb.words())
        .map(|(x, y)| (x & y).count_ones() as u64)
        .sum())
}

/// `op` of two clamped distances, under totalOrder.
fn combine(op: CsgOp, a: f32, b: f32) -> f32 {
    let max = |x: f32, y: f32| if x.total_cmp(&y).is_ge() { x } else { y };
    match op {
        CsgOp::Union => {
            if a.total_cmp(&b).is_le() {
                a
            } else {
                b
            }
        }
        CsgOp::Intersection => max(a, b),
        CsgOp::Difference => max(a, -b),
        CsgOp::Xor => unreachable!("refused before"),
    }
}

/// `op` over distance volumes on one grid, as the module doc says: union and intersection
/// fold over all; difference removes every later operand from the first.
pub fn apply_distance(op: CsgOp, operands: &[&Sparse<f32>]) -> Result<Sparse<f32>, CsgError> {
    apply_distance_with::<Uncanceled>(op, operands, &Control::none()).map_err(|e| e.0)
}

/// [`apply_distance`], checking `ctl` every 256 brick positions and reporting them done.
pub fn apply_distance_with<E: From<CsgError> + From<Canceled>>(
    op: CsgOp,
    operands: &[&Sparse<f32>],
    ctl: &Control,
) -> Result<Sparse<f32>, E> {
    ctl.check()?;
    let first = *operands.first().ok_or(CsgError::NoOperands)?;
    if op == CsgOp::Xor {
        return Err(CsgError::NotForDistance(
            "xor has no distance form; distance volumes combine by union, intersection or difference".into(),
        )
        .into());
    }
    let grid = *first.grid();
    for v in &operands[1..] {
        let g = v.grid();
        if *g != grid {
            return Err(CsgError::DifferentGrids {
                a: grid.dims,
                b: g.dims,
                oa: grid.origin,
                ob: g.origin,
                sa: grid.voxel_size,
                sb: g.voxel_size,
            }
            .into());
        }
    }
    let width = operands
        .iter()
        .map(|v| v.background())
        .fold(f32::INFINITY, f32::min);
    if width.is_nan() || width <= 0.0 || operands.iter().any(|v| v.tile_value() > 0.0) {
        return Err(CsgError::NotForDistance(
            "a distance volume whose background is not positive or whose tiles are not negative is not a level set CSG can combine".into(),
        )
        .into());
    }
    let clamp = |v: f32| {
        if v > width {
            width
        } else if v < -width {
            -width
        } else {
            v
        }
    };
    let fold = |vals: &mut dyn Iterator<Item = f32>| {
        let mut acc = clamp(vals.next().expect("at least one operand"));
        for v in vals {
            acc = combine(op, acc, clamp(v));
        }
        acc
    };
    let mut out = Sparse::with_tile_value(grid, width, -width);
    let mut positions: std::collections::BTreeSet<[u32; 3]> = std::collections::BTreeSet::new();
    for v in operands {
        positions.extend(v.bricks().map(|(at, _)| at));
        positions.extend(v.tiles());
    }
    let dims = grid.dims;
    let done = ctl.counter(positions.len() as u64);
    for (n, at) in positions.into_iter().enumerate() {
        if n % 256 == 255 {
            done.add(256);
            done.check()?;
        }
        // Each operand's value at offset i of this brick position.
        let value = |v: &Sparse<f32>, i: usize| match v.brick(at) {
            Some(b) => b[i],
            None if v.is_tile(at) => v.tile_value(),
            None => v.background(),
        };
        let mut brick = [width; BRICK_VOXELS];
        let (mut all_bg, mut all_tile) = (true, true);
        for (i, b) in brick.iter_mut().enumerate() {
            let o = i as u32;
            let p = [
                at[0] * BRICK + o / 64,
                at[1] * BRICK + o / 8 % 8,
                at[2] * BRICK + o % 8,
            ];
            if (0..3).any(|a| p[a] >= dims[a]) {
                continue;
            }
            *b = fold(&mut operands.iter().map(|v| value(v, i)));
            all_bg &= b.to_bits() == width.to_bits();
            all_tile &= b.to_bits() == (-width).to_bits();
        }
        if all_tile {
            out.set_tile(at, true).expect("an operand's brick position");
        } else if !all_bg {
            out.insert_brick(at, brick)
                .expect("an operand's brick position, the background past the grid");
        }
    }
    ctl.complete();
    Ok(out)
}

#[cfg(test)]
mod distance_tests {
    use super::*;
    use crate::volume::levelset::{sdf_of_bits, threshold};

    fn grid(d: [u32; 3]) -> Grid {
        Grid {
            origin: [1.0, 2.0, -3.0],
            voxel_size: 0.5,
            dims: d,
        }
    }

    /// A box of set voxels from `lo` to `hi` (inclusive).
    fn cuboid(d: [u32; 3], lo: [u32; 3], hi: [u32; 3]) -> BitVolume {
        let mut b = BitVolume::new(grid(d));
        for x in lo[0]..=hi[0] {
            for y in lo[1]..=hi[1] {
                for z in lo[2]..=hi[2] {
                    b.set(x, y, z, true);
                }
            }
        }
        b
    }

    /// Sorts −0.0 before +0.0 and otherwise by value: the key totalOrder gives non-NaN floats.
    fn key(v: f32) -> (f64, u8) {
        (f64::from(v), if v.is_sign_negative() { 0 } else { 1 })
    }

    #[test]
    fn distance_csg_is_the_voxelwise_min_max_of_the_clamped_operands() {
        let d = [26, 24, 25];
        let a = cuboid(d, [2, 2, 2], [22, 21, 22]);
        let b = cuboid(d, [9, 0, 5], [25, 12, 21]);
        let c = cuboid(d, [4, 4, 4], [6, 6, 20]);
        let (sa, sb, sc) = (sdf_of_bits(&a, 3), sdf_of_bits(&b, 2), sdf_of_bits(&c, 5));
        assert!(sa.tile_count() > 0);
        let width = 2.0 * 0.5; // the narrowest band, 2 voxels of 0.5
        for op in [CsgOp::Union, CsgOp::Intersection, CsgOp::Difference] {
            let r = apply_distance(op, &[&sa, &sb, &sc]).unwrap();
            assert_eq!((r.background(), r.tile_value()), (width, -width));
            for x in 0..d[0] {
                for y in 0..d[1] {
                    for z in 0..d[2] {
                        let vals: Vec<f32> = [&sa, &sb, &sc]
                            .iter()
                            .map(|s| s.get(x, y, z).clamp(-width, width))
                            .collect();
                        let pick_min = |xs: &[f32]| {
                            *xs.iter()
                                .min_by(|p, q| key(**p).partial_cmp(&key(**q)).unwrap())
                                .unwrap()
                        };
                        let pick_max = |xs: &[f32]| {
                            *xs.iter()
                                .max_by(|p, q| key(**p).partial_cmp(&key(**q)).unwrap())
                                .unwrap()
                        };
                        let want = match op {
                            CsgOp::Union => pick_min(&vals),
                            CsgOp::Intersection => pick_max(&vals),
                            _ => pick_max(&[vals[0], -vals[1], -vals[2]]),
                        };
                        let got = r.get(x, y, z);
                        assert_eq!(got.to_bits(), want.to_bits(), "{op:?} {x} {y} {z}");
                    }
                }
            }
            // The inside of the result is the bit operation on the insides.
            let bits = apply(op, &[&a, &b, &c]).unwrap();
            assert_eq!(threshold(&r, 0.0), bits, "{op:?}");
            // No stored brick is all background or all tile value.
            for (_, brick) in r.bricks() {
                assert!(brick.iter().any(|v| v.abs() < width), "{op:?}");
            }
        }
    }

    #[test]
    fn distance_csg_refuses_other_grids_and_xor() {
        let a = sdf_of_bits(&cuboid([8, 8, 8], [1, 1, 1], [3, 3, 3]), 2);
        let b = sdf_of_bits(&cuboid([8, 8, 9], [1, 1, 1], [3, 3, 3]), 2);
        assert!(matches!(
            apply_distance(CsgOp::Union, &[&a, &b]),
            Err(CsgError::DifferentGrids { .. })
        ));
        assert!(matches!(
            apply_distance(CsgOp::Xor, &[&a, &a]),
            Err(CsgError::NotForDistance(_))
        ));
        assert_eq!(apply_distance(CsgOp::Union, &[&a]).unwrap(), a);
    }
}
