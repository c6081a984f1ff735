//! Volume statistics against naive per-voxel computations and an analytic box.

use std::collections::VecDeque;

use crate::common::*;
use voxd::grid::Grid;
use voxd::volume::BitVolume;
use voxd::volume::stats::stats;

fn naive_components(v: &BitVolume, diag: bool) -> u64 {
    let d = v.dims();
    let mut seen = std::collections::HashSet::new();
    let mut n = 0;
    for p in v.iter_ones() {
        if !seen.insert(p) {
            continue;
        }
        n += 1;
        let mut q = VecDeque::from([p]);
        while let Some(c) = q.pop_front() {
            for dx in -1i64..=1 {
                for dy in -1i64..=1 {
                    for dz in -1i64..=1 {
                        let k = dx.abs() + dy.abs() + dz.abs();
                        if k == 0 || (!diag && k != 1) {
                            continue;
                        }
                        let t = [c[0] as i64 + dx, c[1] as i64 + dy, c[2] as i64 + dz];
                        if (0..3).all(|a| t[a] >= 0 && t[a] < d[a] as i64) {
                            let t = t.map(|x| x as u32);
                            if v.get(t[0], t[1], t[2]) && seen.insert(t) {
                                q.push_back(t);
                            }
                        }
                    }
                }
            }
        }
    }
    n
}

fn naive_surface(v: &BitVolume) -> u64 {
    let d = v.dims();
    v.iter_ones()
        .filter(|p| {
            [
                [-1i64, 0, 0],
                [1, 0, 0],
                [0, -1, 0],
                [0, 1, 0],
                [0, 0, -1],
                [0, 0, 1],
            ]
            .iter()
            .any(|o| {
                let t = [p[0] as i64 + o[0], p[1] as i64 + o[1], p[2] as i64 + o[2]];
                !(0..3).all(|a| t[a] >= 0 && t[a] < d[a] as i64)
                    || !v.get(t[0] as u32, t[1] as u32, t[2] as u32)
            })
        })
        .count() as u64
}

#[test]
fn stats_match_naive_computations() {
    for seed in 0..40u64 {
        let mut rng = Rng::new(70 + seed);
        let dims = [
            1 + rng.below(9) as u32,
            1 + rng.below(9) as u32,
            [1, 3, 63, 64, 65, 127, 128][rng.below(7) as usize],
        ];
        let g = Grid {
            origin: [rng.range(-3.0, 3.0), 0.5, -1.0],
            voxel_size: rng.range(0.1, 2.0),
            dims,
        };
        let v = random_fill(&mut rng, g);
        let st = stats(&v);
        let ctx = format!("seed {seed} dims {dims:?}");
        assert_eq!(st.solid_voxels, v.count_ones(), "{ctx}");
        assert_eq!(st.surface_voxels, naive_surface(&v), "surface {ctx}");
        assert_eq!(
            st.components_6,
            naive_components(&v, false),
            "6-components {ctx}"
        );
        assert_eq!(
            st.components_26,
            naive_components(&v, true),
            "26-components {ctx}"
        );
        if st.solid_voxels == 0 {
            assert!(st.centre_of_mass.is_none() && st.bounds_index.is_none());
            continue;
        }
        let s = g.voxel_size;
        let centres: Vec<[f64; 3]> = v
            .iter_ones()
            .map(|p| g.voxel_center(p[0], p[1], p[2]))
            .collect();
        let n = centres.len() as f64;
        let com = [0, 1, 2].map(|a| centres.iter().map(|c| c[a]).sum::<f64>() / n);
        let got = st.centre_of_mass.unwrap();
        assert!(
            (0..3).all(|a| (got[a] - com[a]).abs() < 1e-9 * (1.0 + com[a].abs())),
            "com {ctx}: {got:?} vs {com:?}"
        );
        let m = s.powi(3);
        let mut want = [[0.0; 3]; 3];
        for c in &centres {
            let r = [0, 1, 2].map(|a| c[a] - com[a]);
            let r2 = r.iter().map(|x| x * x).sum::<f64>();
            for a in 0..3 {
                for b in 0..3 {
                    want[a][b] += m * (if a == b { r2 + s * s / 6.0 } else { 0.0 } - r[a] * r[b]);
                }
            }
        }
        let i = st.inertia.unwrap();
        let scale = want[0][0].abs() + want[1][1].abs() + want[2][2].abs();
        for a in 0..3 {
            for b in 0..3 {
                assert!(
                    (i[a][b] - want[a][b]).abs() <= 1e-9 * scale,
                    "inertia {ctx} [{a}][{b}]: {} vs {}",
                    i[a][b],
                    want[a][b]
                );
            }
        }
    }
}

#[test]
fn a_solid_box_has_the_analytic_inertia() {
    // 4 × 6 × 10 voxels of size 0.5: a 2 × 3 × 5 box of mass 30.
    let g = Grid {
        origin: [1.0, 2.0, 3.0],
        voxel_size: 0.5,
        dims: [6, 8, 12],
    };
    let mut v = BitVolume::new(g);
    for x in 1..5 {
        for y in 1..7 {
            for z in 1..11 {
                v.set(x, y, z, true);
            }
        }
    }
    let st = stats(&v);
    let (a, b, c, m) = (2.0, 3.0, 5.0, 30.0);
    let i = st.inertia.unwrap();
    for (k, want) in [
        (0, m * (b * b + c * c) / 12.0),
        (1, m * (a * a + c * c) / 12.0),
        (2, m * (a * a + b * b) / 12.0),
    ] {
        assert!(
            (i[k][k] - want).abs() < 1e-9,
            "I[{k}][{k}] = {} vs {want}",
            i[k][k]
        );
    }
    assert!(i[0][1].abs() < 1e-9 && i[0][2].abs() < 1e-9 && i[1][2].abs() < 1e-9);
    assert_eq!(
        st.centre_of_mass.unwrap(),
        [1.0 + 1.5, 2.0 + 2.0, 3.0 + 3.0]
    );
    assert_eq!(st.volume, 30.0);
    assert_eq!(st.surface_voxels, 240 - 2 * 4 * 8);
    assert_eq!((st.components_6, st.components_26), (1, 1));
    assert_eq!(st.bounds_world, Some(([1.5, 2.5, 3.5], [3.5, 5.5, 8.5])));
}

/// Statistics under a control: canceled, they stop with `Canceled`; otherwise the same numbers
/// as without one, with the progress at 1.
#[test]
fn statistics_stop_when_canceled_and_report_progress() {
    use voxd::cancel::{Canceled, Control};
    use voxd::volume::stats::stats_with;
    let mut rng = Rng::new(31);
    let v = random_fill(
        &mut rng,
        Grid {
            origin: [0.0; 3],
            voxel_size: 1.0,
            dims: [9, 13, 70],
        },
    );
    let canceled = Control::new();
    canceled.cancel();
    assert_eq!(stats_with(&v, &canceled), Err(Canceled::Canceled));
    let ctl = Control::new();
    assert_eq!(stats_with(&v, &ctl).unwrap(), stats(&v));
    assert_eq!(ctl.progress(), 1.0);
}
