//! Morphology against the per-voxel definitions on random volumes: every op, every kernel,
//! radius 0..3, odd sizes that are not multiples of the word size.

use crate::common::*;
use voxd::grid::Grid;
use voxd::volume::BitVolume;
use voxd::volume::morph::{Kernel, MorphOp, apply, padded};

fn in_kernel(k: Kernel, r: i64, d: [i64; 3]) -> bool {
    match k {
        Kernel::Cube => d.iter().all(|c| c.abs() <= r),
        Kernel::Cross => d.iter().map(|c| c.abs()).sum::<i64>() <= r,
        Kernel::Sphere => d.iter().map(|c| c * c).sum::<i64>() <= r * r,
    }
}

fn get(v: &BitVolume, p: [i64; 3]) -> bool {
    let d = v.dims();
    (0..3).all(|a| p[a] >= 0 && p[a] < d[a] as i64) && v.get(p[0] as u32, p[1] as u32, p[2] as u32)
}

fn naive(v: &BitVolume, r: u32, k: Kernel, erode: bool) -> BitVolume {
    let mut out = BitVolume::new(*v.grid());
    let r = r as i64;
    let d = v.dims();
    for x in 0..d[0] as i64 {
        for y in 0..d[1] as i64 {
            for z in 0..d[2] as i64 {
                let mut hits = (-r..=r)
                    .flat_map(|a| (-r..=r).flat_map(move |b| (-r..=r).map(move |c| [a, b, c])))
                    .filter(|o| in_kernel(k, r, *o));
                let val = if erode {
                    hits.all(|o| get(v, [x + o[0], y + o[1], z + o[2]]))
                } else {
                    hits.any(|o| get(v, [x + o[0], y + o[1], z + o[2]]))
                };
                out.set(x as u32, y as u32, z as u32, val);
            }
        }
    }
    out
}

#[test]
fn every_op_and_kernel_matches_the_definition() {
    for seed in 0..24u64 {
        let mut rng = Rng::new(900 + seed);
        let dims = [
            1 + rng.below(8) as u32,
            1 + rng.below(8) as u32,
            [1, 5, 63, 64, 66, 130][rng.below(6) as usize],
        ];
        let v = random_fill(
            &mut rng,
            Grid {
                origin: [0.0; 3],
                voxel_size: 1.0,
                dims,
            },
        );
        for k in [Kernel::Cube, Kernel::Cross, Kernel::Sphere] {
            for r in 0..=3 {
                let (d, e) = (naive(&v, r, k, false), naive(&v, r, k, true));
                let ctx = format!("seed {seed} {k:?} r={r} dims {dims:?}");
                assert_eq!(apply(&v, MorphOp::Dilate, r, k, false), d, "dilate {ctx}");
                assert_eq!(apply(&v, MorphOp::Erode, r, k, false), e, "erode {ctx}");
                assert_eq!(
                    apply(&v, MorphOp::Open, r, k, false),
                    naive(&e, r, k, false),
                    "open {ctx}"
                );
                assert_eq!(
                    apply(&v, MorphOp::Close, r, k, false),
                    naive(&d, r, k, true),
                    "close {ctx}"
                );
            }
        }
    }
}

#[test]
fn grow_keeps_what_dilation_would_clip() {
    let mut rng = Rng::new(5);
    let v = random_fill(
        &mut rng,
        Grid {
            origin: [1.0, 2.0, 3.0],
            voxel_size: 0.5,
            dims: [5, 6, 70],
        },
    );
    let g = apply(&v, MorphOp::Dilate, 2, Kernel::Sphere, true);
    assert_eq!(g.grid(), &padded(v.grid(), 2));
    // On the grown grid it is the dilation of the volume moved there, and it contains every
    // voxel of the clipped dilation.
    let moved = voxd::volume::csg::regrid(&v, g.grid()).unwrap();
    assert_eq!(g, naive(&moved, 2, Kernel::Sphere, false));
    let clipped = apply(&v, MorphOp::Dilate, 2, Kernel::Sphere, false);
    assert_eq!(voxd::volume::csg::regrid(&g, v.grid()).unwrap(), clipped);
}
