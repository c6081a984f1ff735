//! CSG between volumes: every op against a naive per-voxel implementation by world position,
//! the identities, and exact booleans of boxes.

use crate::common::*;
use voxd::engine::cpu::CpuEngine;
use voxd::engine::{Engine, GridMesh, Method};
use voxd::grid::Grid;
use voxd::volume::BitVolume;
use voxd::volume::csg::{CsgError, CsgOp, apply, overlap_count, result_grid};

fn random_volume(rng: &mut Rng, origin: [i64; 3]) -> BitVolume {
    let dims = [
        1 + rng.below(9) as u32,
        1 + rng.below(9) as u32,
        [1, 7, 63, 64, 65, 129][rng.below(6) as usize],
    ];
    let g = Grid {
        origin: origin.map(|o| o as f64 * 0.5),
        voxel_size: 0.5,
        dims,
    };
    random_fill(rng, g)
}

/// Is the voxel of `v` at world-lattice index `p` (in voxels from the world origin) set?
fn at(v: &BitVolume, p: [i64; 3]) -> bool {
    let g = v.grid();
    let i = [0, 1, 2].map(|a| p[a] - (g.origin[a] / g.voxel_size).round() as i64);
    (0..3).all(|a| i[a] >= 0 && i[a] < g.dims[a] as i64)
        && v.get(i[0] as u32, i[1] as u32, i[2] as u32)
}

#[test]
fn every_op_matches_a_naive_per_voxel_implementation() {
    for seed in 0..80u64 {
        let mut rng = Rng::new(seed);
        let n = 2 + rng.below(3) as usize;
        let vols: Vec<BitVolume> = (0..n)
            .map(|_| {
                let o = [
                    rng.below(9) as i64 - 4,
                    rng.below(9) as i64 - 4,
                    rng.below(140) as i64 - 70,
                ];
                random_volume(&mut rng, o)
            })
            .collect();
        let refs: Vec<&BitVolume> = vols.iter().collect();
        for op in [
            CsgOp::Union,
            CsgOp::Intersection,
            CsgOp::Difference,
            CsgOp::Xor,
        ] {
            let r = match apply(op, &refs) {
                Ok(r) => r,
                Err(CsgError::NoOverlap) => {
                    assert_eq!(op, CsgOp::Intersection);
                    continue;
                }
                Err(e) => panic!("{e}"),
            };
            let g = r.grid();
            let base = g.origin.map(|o| (o / g.voxel_size).round() as i64);
            for x in 0..g.dims[0] {
                for y in 0..g.dims[1] {
                    for z in 0..g.dims[2] {
                        let p = [base[0] + x as i64, base[1] + y as i64, base[2] + z as i64];
                        let ins: Vec<bool> = vols.iter().map(|v| at(v, p)).collect();
                        let want = match op {
                            CsgOp::Union => ins.iter().any(|&b| b),
                            CsgOp::Intersection => ins.iter().all(|&b| b),
                            CsgOp::Difference => ins[0] && !ins[1..].iter().any(|&b| b),
                            CsgOp::Xor => ins.iter().filter(|&&b| b).count() % 2 == 1,
                        };
                        assert_eq!(r.get(x, y, z), want, "seed {seed} {op:?} at {p:?}");
                    }
                }
            }
            // Grid rules.
            match op {
                CsgOp::Difference => assert_eq!(g, vols[0].grid()),
                CsgOp::Union | CsgOp::Xor => {
                    for v in &vols {
                        for a in 0..3 {
                            assert!(
                                v.grid().origin[a] >= g.origin[a]
                                    && v.grid().max_corner()[a] <= g.max_corner()[a] + 1e-9
                            );
                        }
                    }
                }
                CsgOp::Intersection => {}
            }
        }
        if n == 2 {
            let inter = apply(CsgOp::Intersection, &refs)
                .map(|v| v.count_ones())
                .unwrap_or(0);
            assert_eq!(overlap_count(&vols[0], &vols[1]).unwrap(), inter);
        }
    }
}

#[test]
fn identities() {
    let mut rng = Rng::new(7);
    let a = random_volume(&mut rng, [0, 0, 0]);
    let b = random_volume(&mut rng, [1, -2, 3]);
    let aa = apply(CsgOp::Union, &[&a, &a]).unwrap();
    assert_eq!(aa, a);
    assert_eq!(apply(CsgOp::Difference, &[&a, &a]).unwrap().count_ones(), 0);
    let xor = apply(CsgOp::Xor, &[&a, &b]).unwrap();
    let union = apply(CsgOp::Union, &[&a, &b]).unwrap();
    let inter = apply(CsgOp::Intersection, &[&a, &b]);
    let expected = match inter {
        Ok(i) => apply(CsgOp::Difference, &[&union, &i]).unwrap(),
        Err(_) => union.clone(),
    };
    assert_eq!(xor, expected);
    // Misaligned grids are refused with the reason.
    let mut c = a.clone();
    let shifted = Grid {
        origin: [0.25, 0.0, 0.0],
        ..*a.grid()
    };
    c = BitVolume::from_words(shifted, c.into_words()).unwrap();
    let e = apply(CsgOp::Union, &[&a, &c]).unwrap_err();
    assert!(e.to_string().contains("not aligned"), "{e}");
    assert!(matches!(
        result_grid(CsgOp::Union, &[]),
        Err(CsgError::NoOperands)
    ));
    // Aligned operands 2^33 voxels apart: the union's grid would be longer than u32 voxels
    // along x (its dims were cut to 32 bits), so it is refused.
    let far = Grid {
        origin: [
            a.grid().origin[0] + (1u64 << 33) as f64 * a.grid().voxel_size,
            a.grid().origin[1],
            a.grid().origin[2],
        ],
        ..*a.grid()
    };
    assert!(matches!(
        result_grid(CsgOp::Union, &[*a.grid(), far]),
        Err(CsgError::TooFarApart { .. })
    ));
    assert_eq!(
        voxd::app::Error::from(CsgError::TooFarApart { voxels: 1 << 33 }).kind,
        voxd::app::ErrorKind::GridTooLarge
    );
}

#[test]
fn booleans_of_boxes_equal_voxelizing_the_boolean() {
    // A shared explicit grid, as the API's CSG workflow uses.
    let g = Grid {
        origin: [0.0; 3],
        voxel_size: 0.5,
        dims: [30, 28, 26],
    };
    let vox = |lo, hi| {
        CpuEngine
            .voxelize(
                &GridMesh::new(&box_mesh(lo, hi), &g).unwrap(),
                Method::Solid,
            )
            .unwrap()
    };
    let a = vox([1.2, 1.1, 1.3], [9.3, 8.7, 9.1]);
    let b = vox([5.4, 0.3, 0.2], [14.1, 13.2, 12.4]);
    // A ∩ B is the box of the overlap; A − B, with B covering A beyond x = 5.4, is the rest of A.
    assert_eq!(
        apply(CsgOp::Intersection, &[&a, &b]).unwrap().words(),
        vox([5.4, 1.1, 1.3], [9.3, 8.7, 9.1]).words()
    );
    assert_eq!(
        apply(CsgOp::Difference, &[&a, &b]).unwrap(),
        vox([1.2, 1.1, 1.3], [5.4, 8.7, 9.1])
    );
    let u = apply(CsgOp::Union, &[&a, &b]).unwrap();
    let i = apply(CsgOp::Intersection, &[&a, &b]).unwrap();
    assert_eq!(
        u.count_ones(),
        a.count_ones() + b.count_ones() - i.count_ones()
    );
}

/// CSG under a control: a canceled one stops before the first operand; a live one gives the
/// same volume as without it and hears every operand; grid errors still come first as
/// `CsgError`s.
#[test]
fn csg_stops_when_canceled_and_reports_progress() {
    use voxd::cancel::{Canceled, Control};
    use voxd::volume::csg::apply_with;
    #[derive(Debug, PartialEq)]
    enum E {
        Csg(CsgError),
        Canceled(Canceled),
    }
    impl From<CsgError> for E {
        fn from(e: CsgError) -> E {
            E::Csg(e)
        }
    }
    impl From<Canceled> for E {
        fn from(c: Canceled) -> E {
            E::Canceled(c)
        }
    }
    let mut rng = Rng::new(64);
    let vs: Vec<BitVolume> = (0..4)
        .map(|_| {
            let x = rng.below(3) as i64;
            random_volume(&mut rng, [x, 0, 1])
        })
        .collect();
    let refs: Vec<&BitVolume> = vs.iter().collect();
    let canceled = Control::new();
    canceled.cancel();
    assert_eq!(
        apply_with::<E>(CsgOp::Union, &refs, &canceled),
        Err(E::Canceled(Canceled::Canceled))
    );
    for op in [
        CsgOp::Union,
        CsgOp::Intersection,
        CsgOp::Difference,
        CsgOp::Xor,
    ] {
        let ctl = Control::new();
        let got = apply_with::<E>(op, &refs, &ctl);
        assert_eq!(got, apply(op, &refs).map_err(E::Csg), "{op:?}");
        if got.is_ok() {
            assert_eq!(ctl.progress(), 1.0, "{op:?}");
        }
    }
}
