//! Morphology of bit volumes (Eisemann & Décoret §7): dilate, erode, open, close with radius r and
//! a kernel — `cube` (Chebyshev ball, |d|∞ ≤ r), `cross` (Manhattan ball, |d|₁ ≤ r: r steps of the
//! 6-neighbourhood) or `sphere` (Euclidean ball, |d|₂ ≤ r).
//!
//! Definitions: voxels outside the grid are empty. dilate(v)(p) = ∃ d ∈ K: v(p + d);
//! erode(v)(p) = ∀ d ∈ K: v(p + d) (so voxels within r of the grid's border erode); open =
//! dilate(erode), close = erode(dilate). With `grow`, dilate and close work on the grid enlarged by
//! r voxels on every side, so nothing is clipped, and the result lives on that grid.
//!
//! Work is word-parallel along z (shifts inside and across the column words) and separable for
//! the cube; erosion is the complement of the dilation of the complement, on a grid padded by r.

use super::csg::regrid;
use super::{BitVolume, tail_mask};
use crate::grid::Grid;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kernel {
    Cube,
    Cross,
    Sphere,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MorphOp {
    Dilate,
    Erode,
    Open,
    Close,
}

impl crate::names::Named for Kernel {
    const WHAT: &'static str = "kernel";
    const ALL: &'static [Kernel] = &[Kernel::Cube, Kernel::Cross, Kernel::Sphere];
    fn name(self) -> &'static str {
        match self {
            Kernel::Cube => "cube",
            Kernel::Cross => "cross",
            Kernel::Sphere => "sphere",
        }
    }
}

impl crate::names::Named for MorphOp {
    const WHAT: &'static str = "operation";
    const ALL: &'static [MorphOp] = &[
        MorphOp::Dilate,
        MorphOp::Erode,
        MorphOp::Open,
        MorphOp::Close,
    ];
    fn name(self) -> &'static str {
        match self {
            MorphOp::Dilate => "dilate",
            MorphOp::Erode => "erode",
            MorphOp::Open => "open",
            MorphOp::Close => "close",
        }
    }
}

crate::impl_named!(Kernel, MorphOp);

/// Largest radius accepted: keeps the sphere kernel's r² column offsets cheap.
pub const MAX_RADIUS: u32 = crate::limits::Limits::LOCAL.max_morph_radius;

pub fn apply(v: &BitVolume, op: MorphOp, r: u32, k: Kernel, grow: bool) -> BitVolume {
    assert!(r <= MAX_RADIUS);
    match op {
        MorphOp::Dilate => dilate(&maybe_grow(v, r, grow), r, k),
        MorphOp::Erode => erode(v, r, k),
        MorphOp::Open => dilate(&erode(v, r, k), r, k),
        MorphOp::Close => erode(&dilate(&maybe_grow(v, r, grow), r, k), r, k),
    }
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

/// dst |= src shifted by `k` along z (dst bit z = src bit z − k), clipped to the column.
fn or_shifted(src: &[u64], k: i64, dst: &mut [u64]) {
    for (w, d) in dst.iter_mut().enumerate() {
        *d |= super::shifted_word(src, w, k);
    }
}

/// out(x, y) |= v(x − dx, y − dy) dilated along z by ±zr, for every offset in `offsets`.
fn dilate_by_offsets(v: &BitVolume, offsets: &[(i64, i64, i64)]) -> BitVolume {
    let mut out = BitVolume::new(*v.grid());
    let [nx, ny, nz] = v.dims();
    let tail = tail_mask(nz);
    for x in 0..nx as i64 {
        for y in 0..ny as i64 {
            let mut acc = vec![0u64; v.words_per_column()];
            for &(dx, dy, zr) in offsets {
                let (sx, sy) = (x - dx, y - dy);
                if sx < 0 || sy < 0 || sx >= nx as i64 || sy >= ny as i64 {
                    continue;
                }
                let src = v.column(sx as u32, sy as u32);
                for k in -zr..=zr {
                    or_shifted(src, k, &mut acc);
                }
            }
            if let Some(l) = acc.last_mut() {
                *l &= tail;
            }
            out.column_mut(x as u32, y as u32).copy_from_slice(&acc);
        }
    }
    out
}

pub fn dilate(v: &BitVolume, r: u32, k: Kernel) -> BitVolume {
    if r == 0 {
        return v.clone();
    }
    let r = r as i64;
    match k {
        // Separable: along x, then y, then z.
        Kernel::Cube => {
            let x: Vec<_> = (-r..=r).map(|d| (d, 0, 0)).collect();
            let y: Vec<_> = (-r..=r).map(|d| (0, d, 0)).collect();
            dilate_by_offsets(
                &dilate_by_offsets(&dilate_by_offsets(v, &x), &y),
                &[(0, 0, r)],
            )
        }
        Kernel::Cross => {
            let offsets: Vec<_> = (-r..=r)
                .flat_map(|dx| (-r..=r).map(move |dy| (dx, dy)))
                .filter(|(dx, dy)| dx.abs() + dy.abs() <= r)
                .map(|(dx, dy)| (dx, dy, r - dx.abs() - dy.abs()))
                .collect();
            dilate_by_offsets(v, &offsets)
        }
        Kernel::Sphere => {
            let offsets: Vec<_> = (-r..=r)
                .flat_map(|dx| (-r..=r).map(move |dy| (dx, dy)))
                .filter(|(dx, dy)| dx * dx + dy * dy <= r * r)
                .map(|(dx, dy)| (dx, dy, ((r * r - dx * dx - dy * dy) as u64).isqrt() as i64))
                .collect();
            dilate_by_offsets(v, &offsets)
        }
    }
}

pub fn erode(v: &BitVolume, r: u32, k: Kernel) -> BitVolume {
    if r == 0 {
        return v.clone();
    }
    // Outside the grid is empty: pad with empty voxels, complement (the pad becomes full), dilate,
    // complement back and crop.
    let big = padded(v.grid(), r);
    let mut c = regrid(v, &big).expect("aligned");
    complement(&mut c);
    let mut d = dilate(&c, r, k);
    complement(&mut d);
    regrid(&d, v.grid()).expect("aligned")
}

fn complement(v: &mut BitVolume) {
    let tail = v.tail_mask();
    let wpc = v.words_per_column();
    for col in v.words_mut().chunks_exact_mut(wpc) {
        for w in col.iter_mut() {
            *w = !*w;
        }
        if let Some(l) = col.last_mut() {
            *l &= tail;
        }
    }
}
