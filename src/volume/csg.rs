//! Boolean operations between bit volumes on aligned grids (equal voxel size, origins a whole
//! number of voxels apart), combined by world position. The result's grid: union and xor, the
//! bounding grid of the operands; intersection, their overlap; difference, the first operand's.
//! Volumes are moved onto the result grid by whole columns and word-wise shifts along z.

use super::{BitVolume, VolumeKind, tail_mask};

/// The kinds CSG combines.
pub const ACCEPTS: &[VolumeKind] = super::BITS_ONLY;
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
