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

/// Whether `p` is set in the dilation (or erosion) of the volume whose set voxels (or, for
/// erosion, whose empty voxels) are `features`, straight from the definition: some feature q
/// with q − p in the kernel. Erosion also fails where a kernel offset leaves the grid, which is
/// exactly where p is less than r from a face (the offsets ±r along each axis are in every
/// kernel, and no offset is longer than r along any axis).
fn by_definition(
    features: &[[i64; 3]],
    dims: [u32; 3],
    r: u32,
    k: Kernel,
    erode: bool,
    p: [i64; 3],
) -> bool {
    let r = r as i64;
    let hit = features
        .iter()
        .any(|q| in_kernel(k, r, [q[0] - p[0], q[1] - p[1], q[2] - p[2]]));
    if erode {
        let leaves = (0..3).any(|a| p[a] < r || p[a] + r >= dims[a] as i64);
        !hit && !leaves
    } else {
        hit
    }
}

/// Checks dilation and erosion with radius `r` on a grid of `dims` at every sampled voxel
/// (all voxels of a band through the middle plus random ones): dilation of a sparse volume
/// (random voxels and a small box), erosion of a full one with a few holes.
fn check_large_radius(dims: [u32; 3], r: u32, kernels: &[Kernel], seed: u64) {
    let mut rng = Rng::new(seed);
    let g = Grid {
        origin: [0.0; 3],
        voxel_size: 1.0,
        dims,
    };
    let pick = |rng: &mut Rng| [0, 1, 2].map(|a| rng.below(dims[a] as u64) as i64);
    let mut sparse = BitVolume::new(g);
    let mut set = vec![];
    for _ in 0..3 {
        set.push(pick(&mut rng));
    }
    for x in 10..14 {
        for y in 20..23 {
            for z in 5..9 {
                set.push([x, y, z]);
            }
        }
    }
    for p in &set {
        sparse.set(p[0] as u32, p[1] as u32, p[2] as u32, true);
    }
    // Holes that cut into the part of the grid erosion can keep (r from every face), and one
    // far away.
    let mid = dims.map(|d| d as i64 / 2);
    let n = dims.map(i64::from);
    let holes = vec![
        [mid[0], mid[1], n[2] - 6],
        [n[0] - 8, mid[1] - 5, mid[2] + 3],
        [3, 4, 5],
    ];
    let mut full = BitVolume::new(g);
    for x in 0..dims[0] {
        for y in 0..dims[1] {
            for z in 0..dims[2] {
                full.set(x, y, z, true);
            }
        }
    }
    for h in &holes {
        full.set(h[0] as u32, h[1] as u32, h[2] as u32, false);
    }
    let mut samples: Vec<[i64; 3]> = (0..6000).map(|_| pick(&mut rng)).collect();
    // A slab through the middle, where the erosion keeps voxels.
    for x in mid[0] - 3..=mid[0] + 3 {
        for y in 0..dims[1] as i64 {
            for z in 0..dims[2] as i64 {
                samples.push([x, y, z]);
            }
        }
    }
    for &k in kernels {
        let d = apply(&sparse, MorphOp::Dilate, r, k, false);
        let e = apply(&full, MorphOp::Erode, r, k, false);
        let (mut kept, mut grown) = (0, 0);
        for &p in &samples {
            let (x, y, z) = (p[0] as u32, p[1] as u32, p[2] as u32);
            let want = by_definition(&set, dims, r, k, false, p);
            assert_eq!(d.get(x, y, z), want, "dilate {k:?} r={r} at {p:?}");
            let want = by_definition(&holes, dims, r, k, true, p);
            assert_eq!(e.get(x, y, z), want, "erode {k:?} r={r} at {p:?}");
            grown += d.get(x, y, z) as usize;
            kept += e.get(x, y, z) as usize;
        }
        // Neither is trivial: some sampled voxels are in and some out (erosion keeps nothing
        // where no voxel is r from every face).
        assert!(grown > 0 && grown < samples.len(), "{k:?}: {grown}");
        if (0..3).all(|a| 2 * r < dims[a]) {
            assert!(kept > 0 && kept < samples.len(), "{k:?}: {kept}");
        } else {
            assert_eq!(kept, 0);
        }
    }
}

#[test]
fn large_radii_match_the_definition_on_samples() {
    check_large_radius(
        [96, 96, 96],
        40,
        &[Kernel::Sphere, Kernel::Cross, Kernel::Cube],
        4242,
    );
    // Odd sizes, not multiples of the word size, and a radius near the grid's half.
    check_large_radius([53, 71, 130], 24, &[Kernel::Sphere, Kernel::Cross], 4343);
}

/// Radius 64 at 128³ (an r³-per-voxel sphere took minutes here): one pass, on samples equal to
/// the definition; erosion at this radius leaves nothing on a 128³ grid.
#[test]
fn sphere_radius_64_on_128_cubed_is_one_pass() {
    let dims = [128, 128, 128];
    check_large_radius(dims, 64, &[Kernel::Sphere], 4444);
    let g = Grid {
        origin: [0.0; 3],
        voxel_size: 1.0,
        dims,
    };
    let mut v = BitVolume::new(g);
    v.set(5, 120, 64, true);
    let d = apply(&v, MorphOp::Dilate, 64, Kernel::Sphere, false);
    // The ball of radius 64 around one voxel, clipped by the grid: its count by definition.
    let mut want = 0u64;
    for x in 0..128i64 {
        for y in 0..128i64 {
            let rest = 64 * 64 - (x - 5).pow(2) - (y - 120).pow(2);
            if rest >= 0 {
                let h = (rest as u64).isqrt() as i64;
                want += ((64 + h).min(127) - (64 - h).max(0) + 1) as u64;
            }
        }
    }
    assert_eq!(d.count_ones(), want);
}

/// The control: a canceled or expired one stops morphology with `Canceled` and no result; a
/// live one hears every plane and ends at 1, with the same bits as without it.
#[test]
fn morphology_stops_when_canceled_and_reports_progress() {
    use std::time::{Duration, Instant};
    use voxd::cancel::{Canceled, Control};
    use voxd::volume::morph::apply_with;
    let mut rng = Rng::new(77);
    let v = random_fill(
        &mut rng,
        Grid {
            origin: [0.0; 3],
            voxel_size: 1.0,
            dims: [20, 17, 70],
        },
    );
    let canceled = Control::new();
    canceled.cancel();
    assert_eq!(
        apply_with(&v, MorphOp::Close, 3, Kernel::Sphere, true, &canceled),
        Err(Canceled::Canceled)
    );
    let expired = Control::new().with_deadline(Instant::now() - Duration::from_millis(1));
    assert_eq!(
        apply_with(&v, MorphOp::Dilate, 3, Kernel::Cube, false, &expired),
        Err(Canceled::DeadlinePassed)
    );
    for op in [
        MorphOp::Dilate,
        MorphOp::Erode,
        MorphOp::Open,
        MorphOp::Close,
    ] {
        let ctl = Control::new();
        let got = apply_with(&v, op, 2, Kernel::Cross, false, &ctl).unwrap();
        assert_eq!(got, apply(&v, op, 2, Kernel::Cross, false), "{op:?}");
        assert_eq!(ctl.progress(), 1.0, "{op:?}");
    }
}
