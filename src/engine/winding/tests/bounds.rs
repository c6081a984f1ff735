//! The bounds against exact sums: a triangle's solid-angle gradient and Hessian, the
//! boundary chain's field and its bound, the Taylor model of a ball, and the interval
//! (`spread`) over a ball.
//!
//! Not here: the same bounds from the eight-lane traversals (`traversal`).

use super::*;

#[test]
fn solid_angle_gradient_is_at_most_twice_the_area_over_the_cubed_distance() {
    let mut rng = Rng::new(0x9e37_79b9_7f4a_7c15);
    let mut tightest: f64 = 0.0;
    for i in 0..4000 {
        // Near and far, from all sides; every fourth along the normal, where the bound is
        // attained in the limit.
        let Some((t, area, _, q)) = triangle_and_query(&mut rng, i % 4 == 0, 0.05) else {
            continue;
        };
        let d = dist2_to_triangle(q, &t).sqrt();
        if d < 1e-2 {
            continue;
        }
        let g = norm(gradient(&t, q, 1e-5 * d));
        let bound = 2.0 * area / d.powi(3);
        let ratio = g / bound;
        assert!(ratio <= 1.0 + 1e-4, "{t:?} {q:?}: |∇Ω| {g} > bound {bound}");
        tightest = tightest.max(ratio);
    }
    // The bound is nearly attained: half of it would be wrong.
    assert!(tightest > 0.95, "{tightest}");
}

#[test]
fn solid_angle_gradient_is_the_boundary_field() {
    let mut rng = Rng::new(0x1234_5678);
    for _ in 0..500 {
        let t = [0; 3].map(|_| rng.point(-1.0, 1.0));
        let q = rng.point(-2.0, 2.0);
        let d = dist2_to_triangle(q, &t).sqrt();
        if d < 0.05 || norm(area_normal(&t)) < 1e-3 {
            continue;
        }
        let want = gradient(&t, q, 1e-6 * d);
        let got = solid_angle_gradient(&t, q);
        assert!(
            norm(sub(got, want)) <= 1e-5 * norm(want) + 1e-7,
            "{t:?} {q:?}: {got:?} vs {want:?}"
        );
    }
}

#[test]
fn boundary_field_expansion_error_is_bounded() {
    // The sheet's boundary: the tree's field (clusters by their first-order expansion) is
    // within its error bound of the exact sum of the segments' fields.
    let (p, t) = sheet(40);
    let segs: Vec<[[f64; 3]; 2]> = chain_boundary(&t)
        .iter()
        .map(|e| e.map(|i| p[i as usize]))
        .collect();
    let edges = EdgeTree::new(segs.clone());
    let mut rng = Rng::new(99);
    let (mut used, mut tightest): (u32, f64) = (0, 0.0);
    for _ in 0..400 {
        let q = add(
            [0.5, 0.5, 0.0],
            rng.direction(),
            10f64.powf(rng.range(-1.0, 1.0)),
        );
        let exact = segs
            .iter()
            .fold([0.0; 3], |f, s| add3(f, segment_field(s, q)));
        let Some((got, error)) = edges.field(q) else {
            continue;
        };
        let off = norm(sub(got, exact));
        assert!(
            off <= error * (1.0 + 1e-9) + 1e-12,
            "{q:?}: {off} > {error}"
        );
        if error > 0.0 {
            used += 1;
            tightest = tightest.max(off / error);
        }
    }
    eprintln!("tightest {tightest}");
    assert!(used > 100, "{used}");
}

#[test]
fn taylor_model_holds_the_exact_sum_over_the_ball() {
    // A bumpy sheet as the caps: near triangles exact, the rest by value, boundary-field
    // gradient and remainder bound, against the exact sum at points of the ball.
    let (tree, edges, tris) = sheet_trees();
    let exact = |q: [f64; 3]| tris.iter().map(|t| solid_angle(t, q)).sum::<f64>();
    let mut rng = Rng::new(2718);
    let (mut checked, mut tightest, mut with_near): (u32, f64, u32) = (0, 0.0, 0);
    for _ in 0..300 {
        let c = add(
            [0.5, 0.5, 0.0],
            rng.direction(),
            10f64.powf(rng.range(-1.5, 0.5)),
        );
        let rq = 10f64.powf(rng.range(-2.5, -1.0));
        let mut near = Vec::new();
        let Some(m) = tree.taylor(c, rq, 10.0 * rq, 1e-9, SMALL * 4.0 * PI, &mut near) else {
            continue;
        };
        let Some((field, error)) = edges.field(c) else {
            continue;
        };
        let mut grad = field.map(|v| GRADIENT_SIGN * v);
        for &(i, _) in &near {
            grad = sub(grad, solid_angle_gradient(&tree.tris[i as usize], c));
        }
        with_near += u32::from(!near.is_empty());
        // The rest at c exactly; the model's value is the hierarchy's (less small nodes).
        let Some(near_c) = tree.near_sum(&near, c, 1e-9) else {
            continue;
        };
        let rest_c = exact(c) - near_c;
        assert!((m.value - rest_c).abs() <= m.left_out + 2e-3 * 4.0 * PI);
        for _ in 0..8 {
            let x = add(c, rng.direction(), rq * rng.unit().sqrt());
            let Some(n) = tree.near_sum(&near, x, 1e-9) else {
                continue;
            };
            let d = sub(x, c);
            let dd = dot(d, d);
            let model = n + rest_c + dot(grad, d);
            let bound = 3.0 * dd * m.hessian + error * dd.sqrt();
            let off = (exact(x) - model).abs();
            assert!(
                off <= bound * (1.0 + 1e-6) + 1e-11,
                "{c:?} r {rq}: {off} > {bound}"
            );
            checked += 1;
            if bound > 0.0 {
                tightest = tightest.max(off / bound);
            }
        }
    }
    eprintln!("checked {checked}, with near {with_near}, tightest {tightest}");
    assert!(checked > 1000 && with_near > 50, "{checked} {with_near}");
}

#[test]
fn solid_angle_hessian_is_at_most_six_times_the_area_over_the_fourth_power() {
    // Along segments from q, the solid angle departs from its first-order model by at most
    // 3|δ|² area/g⁴ (g the distance from the segment to the triangle); nearly attained
    // somewhere, so a smaller constant would fail.
    let mut rng = Rng::new(0xfeed_beef);
    let mut tightest: f64 = 0.0;
    for i in 0..6000 {
        let Some((t, area, normal, q)) = triangle_and_query(&mut rng, i % 3 == 0, 0.1) else {
            continue;
        };
        let dist = dist2_to_triangle(q, &t).sqrt();
        let step = if i % 3 == 0 { normal } else { rng.direction() };
        let len = dist * rng.range(0.01, 0.5);
        let x = add(q, step, len);
        let g = dist - len;
        let model = solid_angle(&t, q) + dot(solid_angle_gradient(&t, q), sub(x, q));
        let off = (solid_angle(&t, x) - model).abs();
        let bound = 3.0 * len * len * area / g.powi(4);
        assert!(
            off <= bound * (1.0 + 1e-6) + 1e-13,
            "{t:?} {q:?} {x:?}: {off} > {bound}"
        );
        tightest = tightest.max(off / bound);
    }
    eprintln!("tightest {tightest}");
    assert!(tightest > 0.5, "{tightest}");
}

#[test]
fn spread_bounds_the_variation_over_the_ball() {
    let mut rng = Rng::new(12345);
    let (p, t) = sheet(12);
    let one = vec![[0.2, 0.1, 0.0], [0.9, 0.3, 0.05], [0.4, 0.8, -0.1]];
    let sets: [Soup; 3] = [(p.clone(), t.clone()), (one, vec![[0, 1, 2]]), sheet(3)];
    let (mut tightest, mut checked, mut worst_value): (f64, u32, f64) = (0.0, 0, 0.0);
    for (p, t) in &sets {
        let tree = WindingTree::new(p, t);
        let tris: Vec<_> = t.iter().map(|t| t.map(|i| p[i as usize])).collect();
        let exact = |q: [f64; 3]| tris.iter().map(|t| solid_angle(t, q)).sum::<f64>();
        for i in 0..600 {
            let q = add(
                [0.5, 0.5, 0.0],
                rng.direction(),
                10f64.powf(rng.range(-0.7, 1.3)),
            );
            let rq = if i % 5 == 0 {
                0.0
            } else {
                norm(sub(q, [0.5, 0.5, 0.0])) * 10f64.powf(rng.range(-3.0, -0.3))
            };
            let Some(s) = tree.spread(q, rq, 0.0, f64::INFINITY, 0.0, true) else {
                continue;
            };
            // With small nodes bounded instead of summed: the interval still holds the
            // exact sum (up to the expansions' error).
            let bounded = tree
                .spread(q, rq, 0.0, f64::INFINITY, SMALL * 4.0 * PI, true)
                .expect("the same nodes come near");
            checked += 1;
            let at_q = exact(q);
            // Where no node was left out, `value` is the hierarchy's value at q and `spread`
            // bounds the variation; otherwise `value ± spread` holds every exact sum.
            let whole = s.left_out == 0.0;
            if whole {
                worst_value = worst_value.max((s.value - at_q).abs() / (4.0 * PI));
            }
            // Points of the ball: random ones, and the two along the gradient at q.
            let grad = {
                let g: [f64; 3] = (0..3)
                    .map(|k| {
                        let h = 1e-6 * (1.0 + norm(q));
                        let mut e = [0.0; 3];
                        e[k] = h;
                        (exact(add(q, e, 1.0)) - exact(add(q, e, -1.0))) / (2.0 * h)
                    })
                    .collect::<Vec<_>>()
                    .try_into()
                    .unwrap();
                let l = norm(g);
                if l > 0.0 {
                    g.map(|v| v / l)
                } else {
                    [1.0, 0.0, 0.0]
                }
            };
            let mut points = vec![add(q, grad, rq), add(q, grad, -rq)];
            for _ in 0..6 {
                points.push(add(q, rng.direction(), rq * rng.unit().sqrt()));
            }
            for x in points {
                let change = (exact(x) - if whole { at_q } else { s.value }).abs();
                let allowed = if whole { 0.0 } else { 1e-3 * 4.0 * PI };
                assert!(
                    change <= s.spread * (1.0 + 1e-9) + 1e-12 + allowed,
                    "{q:?} r {rq}: change {change} > spread {}",
                    s.spread
                );
                let off = (exact(x) - bounded.value).abs();
                assert!(
                    off <= bounded.spread + 1e-3 * 4.0 * PI,
                    "{q:?} r {rq}: {off} off > {}",
                    bounded.spread
                );
                let magnitude: f64 = tris.iter().map(|t| solid_angle(t, x).abs()).sum();
                assert!(magnitude <= s.crude * (1.0 + 1e-9) + 1e-12);
                if whole && s.spread > 1e-9 {
                    tightest = tightest.max(change / s.spread);
                }
            }
        }
    }
    assert!(checked > 1000, "{checked}");
    // The variation bound is close to attained somewhere (half of it would be wrong), and the
    // hierarchy's value at the centre is well within the margin added for it.
    assert!(tightest > 0.8, "{tightest}");
    assert!(worst_value < MARGIN / 4.0, "{worst_value}");
}

#[test]
fn boundary_field_bounds_the_variation_off_the_surface() {
    // An open bumpy sheet: its solid angle varies over a ball that misses it by at most
    // rq × the Biot–Savart bound of its boundary.
    let (p, t) = sheet(10);
    let tris: Vec<_> = t.iter().map(|t| t.map(|i| p[i as usize])).collect();
    let segs: Vec<[[f64; 3]; 2]> = chain_boundary(&t)
        .iter()
        .map(|e| e.map(|i| p[i as usize]))
        .collect();
    assert_eq!(segs.len(), 40);
    let edges = EdgeTree::new(segs.clone());
    let exact = |q: [f64; 3]| tris.iter().map(|t| solid_angle(t, q)).sum::<f64>();
    let mut rng = Rng::new(4242);
    let (mut checked, mut tightest): (u32, f64) = (0, 0.0);
    for i in 0..400 {
        let q = add(
            [0.5, 0.5, 0.0],
            rng.direction(),
            10f64.powf(rng.range(-1.0, 1.0)),
        );
        // The segment's field against a quadrature of dl × (x − q)/|x − q|³.
        if i % 10 == 0 {
            let s = &segs[i % segs.len()];
            let n = 2000;
            let mut sum = [0.0; 3];
            for k in 0..n {
                let x = add(s[0], sub(s[1], s[0]), (k as f64 + 0.5) / n as f64);
                let r = sub(x, q);
                let f = cross(sub(s[1], s[0]), r).map(|v| v / (n as f64 * norm(r).powi(3)));
                sum = add3(sum, f);
            }
            let got = segment_field(s, q);
            assert!(
                norm(sub(got, sum)) <= 1e-4 * norm(sum) + 1e-9,
                "{got:?} {sum:?}"
            );
        }
        let gap = tris
            .iter()
            .map(|t| dist2_to_triangle(q, t).sqrt())
            .fold(f64::INFINITY, f64::min);
        let rq = gap * rng.range(0.05, 0.95);
        let b = edges.bound(q, rq, f64::INFINITY);
        if !b.is_finite() {
            continue;
        }
        checked += 1;
        let at_q = exact(q);
        for _ in 0..8 {
            let x = add(q, rng.direction(), rq * rng.unit().sqrt());
            let change = (exact(x) - at_q).abs();
            assert!(
                change <= rq * b * (1.0 + 1e-9),
                "{q:?} r {rq}: {change} > {}",
                rq * b
            );
            tightest = tightest.max(change / (rq * b));
        }
    }
    assert!(checked > 300, "{checked}");
    eprintln!("tightest {tightest}");
}
