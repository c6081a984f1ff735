//! The traversals of eight balls at once: the same bits on every instruction set, and bounds
//! that hold as the one-ball traversals' do.
//!
//! Not here: the kernels they inline (`lanes`).

use super::*;
#[cfg(target_arch = "x86_64")]
use crate::engine::winding::edges::{field_lanes_avx2, field_lanes_avx512};
#[cfg(target_arch = "x86_64")]
use crate::engine::winding::traverse::{
    spread_lanes_avx2, spread_lanes_avx512, taylor_lanes_avx2, taylor_lanes_avx512,
};

#[test]
fn lane_traversals_give_the_same_bits_on_every_instruction_set() {
    // The traversals over eight points are compiled per instruction set with their kernels
    // inlined, bookkeeping and all: every path must give the baseline's bits, and
    // `winding_numbers` the one-point traversal's values.
    let (tree, edges, _) = sheet_trees();
    let mut rng = Rng::new(2718);
    let small = SMALL * 4.0 * PI;
    let (mut compared, mut open) = (0, 0);
    for case in 0..60 {
        let (qs, rq) = eight_balls(&mut rng);
        let by_area: [bool; LANES] = std::array::from_fn(|i| (i + case) % 3 != 0);
        let limit: [f64; LANES] =
            std::array::from_fn(|i| if i % 2 == 0 { f64::INFINITY } else { 2.0 });
        let lanes = if case % 4 == 0 { 0b1010_0110 } else { 0xff };
        // Each traversal's results as bits, by one path (0 the baseline, 1 AVX2, 2 AVX-512).
        let run = |path: u32| -> Vec<u64> {
            let mut near: [Vec<(u32, f64)>; LANES] = Default::default();
            // The three traversals by the functions given.
            macro_rules! traverse {
                ($spread:path, $taylor:path, $field:path) => {
                    (
                        $spread(&tree, &qs, rq, 1e-9, &limit, small, &by_area),
                        $taylor(&tree, &qs, lanes, rq, 10.0 * rq, 1e-9, small, &mut near),
                        $field(&edges, &qs, lanes),
                    )
                };
            }
            let (sp, ts, fs) = match path {
                // SAFETY: each path is run only where the processor has its instructions.
                #[cfg(target_arch = "x86_64")]
                1 => unsafe { traverse!(spread_lanes_avx2, taylor_lanes_avx2, field_lanes_avx2) },
                // SAFETY: as above.
                #[cfg(target_arch = "x86_64")]
                2 => unsafe {
                    traverse!(spread_lanes_avx512, taylor_lanes_avx512, field_lanes_avx512)
                },
                _ => traverse!(
                    WindingTree::spread_lanes_body,
                    WindingTree::taylor_lanes_body,
                    EdgeTree::field_lanes_body
                ),
            };
            let mut v = Vec::new();
            for i in 0..LANES {
                match sp[i] {
                    Some(s) => v.extend([s.value, s.spread, s.crude, s.left_out]),
                    None => v.push(f64::NAN),
                }
                match ts[i] {
                    Some(t) => v.extend([t.value, t.hessian, t.left_out]),
                    None => v.push(f64::NAN),
                }
                match fs[i] {
                    Some((f, e)) => v.extend(f.into_iter().chain([e])),
                    None => v.push(f64::NAN),
                }
                v.extend(near[i].iter().flat_map(|&(t, a)| [t as f64, a]));
            }
            v.into_iter().map(f64::to_bits).collect()
        };
        let base = run(0);
        open += nones(&base);
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx2") {
                assert_eq!(run(1), base, "case {case}: AVX2");
                compared += 1;
            }
            if std::arch::is_x86_feature_detected!("avx512f") {
                assert_eq!(run(2), base, "case {case}: AVX-512");
                compared += 1;
            }
        }
        // Points: the hierarchy's winding numbers, eight at a time as one at a time.
        let w = tree.winding_numbers(&qs);
        for i in 0..LANES {
            let one = tree.winding_number(qs[i]);
            assert!((w[i] - one).abs() < 1e-12, "case {case}: {} {one}", w[i]);
        }
    }
    eprintln!("instruction sets compared {compared}, lanes left open {open}");
    assert!(open > 0, "no lane was stopped by its limit or a gap");
}

#[test]
fn lane_traversals_bound_as_one_ball_at_a_time_does() {
    // Eight balls at the centres of a 4³ block's 2³ blocks, near a bumpy sheet (the caps):
    // each lane's interval (`spread_lanes`) must hold the exact sum over its ball, its model
    // (`taylor_lanes`, `field_lanes`) the exact sum at each point, as the one-ball versions.
    let (tree, edges, tris) = sheet_trees();
    let exact = |q: [f64; 3]| tris.iter().map(|t| solid_angle(t, q)).sum::<f64>();
    let mut rng = Rng::new(31415);
    let (mut intervals, mut models, mut near_lanes) = (0u32, 0u32, 0u32);
    for case in 0..120 {
        let (qs, rq) = eight_balls(&mut rng);
        let by_area: [bool; LANES] = std::array::from_fn(|i| (i + case) % 3 != 0);
        let small = SMALL * 4.0 * PI;
        let spreads = spread_lanes(
            &tree,
            &qs,
            rq,
            1e-9,
            &[f64::INFINITY; LANES],
            small,
            &by_area,
        );
        // Some lanes only: the others' traversal must not be disturbed by them.
        let lanes = if case % 4 == 0 { 0b1010_0110 } else { 0xff };
        let mut near: [Vec<(u32, f64)>; LANES] = Default::default();
        let ts = taylor_lanes(&tree, &qs, lanes, rq, 10.0 * rq, 1e-9, small, &mut near);
        let fields = field_lanes(&edges, &qs, lanes);
        for (i, &c) in qs.iter().enumerate() {
            let points: Vec<[f64; 3]> = (0..6)
                .map(|_| add(c, rng.direction(), rq * rng.unit().sqrt()))
                .collect();
            if let Some(sp) = spreads[i] {
                intervals += 1;
                for &x in &points {
                    let off = (exact(x) - sp.value).abs();
                    assert!(
                        off <= sp.spread + 1e-3 * 4.0 * PI,
                        "case {case} lane {i}: {off} > {}",
                        sp.spread
                    );
                    let magnitude: f64 = tris.iter().map(|t| solid_angle(t, x).abs()).sum();
                    assert!(magnitude <= sp.crude * (1.0 + 1e-9) + 1e-12);
                }
            }
            if lanes >> i & 1 == 0 {
                assert!(ts[i].is_none() && fields[i].is_none() && near[i].is_empty());
                continue;
            }
            let (Some(m), Some((field, error))) = (ts[i], fields[i]) else {
                continue;
            };
            // The field as the one-point traversal finds it, within both error bounds.
            let (one, one_error) = edges.field(c).expect("no segment at the centre");
            assert!(
                norm(sub(field, one)) <= error + one_error + 1e-9,
                "case {case} lane {i}"
            );
            let mut grad = field.map(|v| GRADIENT_SIGN * v);
            for &(t, _) in &near[i] {
                grad = sub(grad, solid_angle_gradient(&tree.tris[t as usize], c));
            }
            near_lanes += u32::from(!near[i].is_empty());
            let Some(near_c) = tree.near_sum(&near[i], c, 1e-9) else {
                continue;
            };
            let rest_c = exact(c) - near_c;
            assert!((m.value - rest_c).abs() <= m.left_out + 2e-3 * 4.0 * PI);
            for &x in &points {
                let Some(n) = tree.near_sum(&near[i], x, 1e-9) else {
                    continue;
                };
                let d = sub(x, c);
                let dd = dot(d, d);
                let bound = 3.0 * dd * m.hessian + error * dd.sqrt();
                let off = (exact(x) - (n + rest_c + dot(grad, d))).abs();
                assert!(
                    off <= bound * (1.0 + 1e-6) + 1e-11,
                    "case {case} lane {i}: {off} > {bound}"
                );
                models += 1;
            }
        }
    }
    eprintln!("intervals {intervals}, model points {models}, lanes with near caps {near_lanes}");
    assert!(
        intervals > 500 && models > 2000 && near_lanes > 100,
        "{intervals} {models} {near_lanes}"
    );
}
