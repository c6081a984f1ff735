//! The eight-lane kernels against the scalar geometry they stand for, and the same bits from
//! every instruction set.
//!
//! Not here: the traversals that inline them (`traversal`).

// Loops run over lane indices, as in the kernels.
#![allow(clippy::needless_range_loop)]

use std::f64::consts::PI;

use crate::engine::geom::{
    cross, dist2_to_segment, dist2_to_triangle, dot, norm, solid_angle, sub,
};
use crate::engine::winding::lanes::*;
use crate::testkit::Rng;

/// Random triangles, with degenerate ones among them: collinear, a repeated vertex, a
/// point, slivers, and ones far larger or smaller than their distance to the query.
fn triangle(rng: &mut Rng, i: usize) -> [[f64; 3]; 3] {
    let [a, b, c] = [
        rng.point(-1.0, 1.0),
        rng.point(-1.0, 1.0),
        rng.point(-1.0, 1.0),
    ];
    match i % 7 {
        0 => [a, b, [0, 1, 2].map(|k| a[k] + 0.37 * (b[k] - a[k]))],
        1 => [a, a, c],
        2 => [a, a, a],
        3 => [
            a,
            b,
            [0, 1, 2].map(|k| a[k] + 0.5 * (b[k] - a[k]) + 1e-9 * c[k]),
        ],
        4 => [a, b, c].map(|p| p.map(|v| v * 1e-3)),
        5 => [a, b, c].map(|p| p.map(|v| v * 1e3)),
        _ => [a, b, c],
    }
}

#[test]
fn atan2_matches_the_c_library() {
    let mut rng = Rng::plain(7);
    let mut worst: f64 = 0.0;
    let specials = [
        0.0,
        -0.0,
        1e-300,
        -1e-300,
        1.0,
        -1.0,
        0.66,
        2.414_213_562_373_095,
    ];
    for &y in &specials {
        for &x in &specials {
            if y == 0.0 && x == 0.0 {
                continue;
            }
            let (ours, libm) = (atan2(y, x), y.atan2(x));
            if y == 0.0 || x == 0.0 {
                // The axes, signs of zero included: exactly.
                assert_eq!(ours.to_bits(), libm.to_bits(), "atan2({y}, {x})");
            } else {
                assert!((ours - libm).abs() <= 4e-16 * libm.abs(), "atan2({y}, {x})");
            }
        }
    }
    for _ in 0..200_000 {
        let (y, x) = (rng.unit() * 2.0 - 1.0, rng.unit() * 2.0 - 1.0);
        let scale = 10f64.powi((rng.unit() * 12.0) as i32 - 6);
        let (ours, libm) = (atan2(y * scale, x), (y * scale).atan2(x));
        worst = worst.max((ours - libm).abs() / libm.abs().max(1e-300));
    }
    assert!(worst < 4e-16, "relative error {worst:e}");
}

#[test]
fn leaves_match_the_scalar_solid_angle_and_distance() {
    let mut rng = Rng::plain(11);
    let mut checked = 0;
    for case in 0..4000 {
        let count = 1 + case % LANES;
        let tris: Vec<_> = (0..count).map(|i| triangle(&mut rng, case + i)).collect();
        let areas: Vec<f64> = (0..count).map(|_| rng.unit()).collect();
        let leaf_ = Leaf::new(&tris, &areas);
        let s = if case % 3 == 0 { 0.3 } else { 3.0 };
        let q = rng.point(-s, s);
        let (angles, dist2) = leaf(&leaf_, q);
        let rq = rng.unit() * 0.5;
        let (sp, ta) = (leaf_spread(&leaf_, q, rq), leaf_taylor(&leaf_, q, rq));
        for (j, t) in tris.iter().enumerate() {
            // The bounds, from the distance and each triangle's own area, as `spread` and
            // `taylor` define them.
            let g = dist2[j].sqrt() - rq;
            let by_distance = areas[j] / (g * g);
            let want = [
                (sp.angle[j], angles[j]),
                (sp.g[j], g),
                (sp.magnitude[j], by_distance.min(2.0 * PI)),
                (sp.variation[j], 2.0 * rq * areas[j] / (g * g * g)),
                (ta.angle[j], angles[j]),
                (ta.dist[j], dist2[j].sqrt()),
                (ta.hessian[j], areas[j] / g.powi(4)),
            ];
            for (k, (got, want)) in want.into_iter().enumerate() {
                assert!(
                    (got - want).abs() <= 1e-12 * want.abs().max(1e-300),
                    "case {case} lane {j} bound {k}: {got} against {want}"
                );
            }
            // Ericson's distance, but never more than the edges' (which it can exceed, or
            // be NaN, for a triangle whose area is lost to rounding or zero).
            let edges = (0..3)
                .map(|e| dist2_to_segment(q, &[t[e], t[(e + 1) % 3]]))
                .fold(f64::INFINITY, f64::min);
            let d = dist2_to_triangle(q, t).min(edges);
            let a = solid_angle(t, q);
            assert!(
                (angles[j] - a).abs() <= 1e-12,
                "case {case} lane {j}: solid angle {} against {a}",
                angles[j]
            );
            assert!(
                (dist2[j] - d).abs() <= 1e-12 * d.max(1e-12),
                "case {case} lane {j}: squared distance {} against {d}",
                dist2[j]
            );
            checked += 1;
        }
    }
    assert!(checked > 10_000);
}

#[test]
fn nodes_match_the_scalar_bounds() {
    let mut rng = Rng::plain(19);
    for case in 0..500 {
        let far = Far {
            n1: rng.point(-1.0, 1.0),
            tr: rng.unit(),
            m: std::array::from_fn(|_| rng.unit() - 0.5),
            w: rng.point(-1.0, 1.0),
            c: std::array::from_fn(|_| std::array::from_fn(|_| rng.unit() - 0.5)),
        };
        let centre = rng.point(-1.0, 1.0);
        let (radius, area, rq) = (rng.unit() * 0.5, rng.unit(), rng.unit() * 0.2);
        let qs = [0, 1, 2].map(|_| std::array::from_fn(|_| rng.unit() * 6.0 - 3.0));
        // The expansion is computed where some point lies beyond `reach2` (and 0 elsewhere):
        // from some cases' points, from all, from none.
        let reach2 = [0.0, 4.0, 9.0, 1e9][case % 4];
        let (sp, ta) = (
            node_body::<true>(&far, centre, radius, area, rq, reach2, &qs),
            node_body::<false>(&far, centre, radius, area, rq, reach2, &qs),
        );
        let any = (0..LANES).any(|i| {
            let r = [0, 1, 2].map(|a| centre[a] - qs[a][i]);
            dot(r, r) > reach2
        });
        for i in 0..LANES {
            let r = [0, 1, 2].map(|a| centre[a] - qs[a][i]);
            let d2 = dot(r, r);
            let g = d2.sqrt() - radius - rq;
            let expansion = if any { far_one(&far, r, d2) } else { 0.0 };
            let want = [
                (sp.d2[i], d2),
                (sp.far[i], expansion),
                (sp.g[i], g),
                (sp.magnitude[i], area / (g * g)),
                (sp.extra[i], 2.0 * rq * area / (g * g * g)),
                (ta.d2[i], d2),
                (ta.far[i], expansion),
                (ta.g[i], g),
                (ta.magnitude[i], area / (g * g)),
                (ta.extra[i], area / g.powi(4)),
            ];
            for (k, (got, want)) in want.into_iter().enumerate() {
                assert!(
                    (got - want).abs() <= 1e-12 * want.abs().max(1e-300),
                    "case {case} lane {i} output {k}: {got} against {want}"
                );
            }
        }
    }
}

#[test]
fn point_sums_match_the_scalar_sum() {
    let mut rng = Rng::plain(13);
    let tris: Vec<_> = (0..40).map(|i| triangle(&mut rng, i)).collect();
    let twice_area = |t: &[[f64; 3]; 3]| norm(cross(sub(t[1], t[0]), sub(t[2], t[0])));
    let near: Vec<(u32, f64)> = (0..tris.len() as u32)
        .map(|i| (i, twice_area(&tris[i as usize])))
        .filter(|&(_, a)| a > 0.0)
        .collect();
    let mut saw_close = false;
    for case in 0..500 {
        let points: [[f64; 3]; LANES] = std::array::from_fn(|_| rng.point(-2.0, 2.0));
        // Some queries on a triangle's plane.
        let mut points = points;
        if case % 5 == 0 {
            let t = tris[case % tris.len()];
            points[1] = [0, 1, 2].map(|k| 0.25 * t[0][k] + 0.25 * t[1][k] + 0.5 * t[2][k]);
        }
        let q = [0, 1, 2].map(|a| points.map(|p| p[a]));
        let gap = 1e-6;
        let (sums, close) = point_sums(&tris, &near, &q, gap);
        for (i, p) in points.iter().enumerate() {
            let exact: f64 = near
                .iter()
                .map(|&(t, _)| solid_angle(&tris[t as usize], *p))
                .sum();
            let any_close = near.iter().any(|&(t, ta)| {
                let [a, b, c] = tris[t as usize].map(|v| sub(v, *p));
                let det = dot(a, cross(b, c));
                det.abs() <= 2.0 * gap * ta || det.is_nan()
            });
            assert_eq!(close[i], any_close, "case {case} point {i}");
            saw_close |= any_close;
            if !any_close {
                assert!(
                    (sums[i] - exact).abs() < 1e-10,
                    "case {case}: {} against {exact}",
                    sums[i]
                );
            }
        }
    }
    assert!(saw_close, "no query came close to a plane");
}

// The node and cluster kernels run inlined into the winding fill's traversals; compiled
// here on their own, per instruction set, for the comparison below.
dispatch! {
    #[allow(dead_code)]
    fn nodes(
        f: &Far,
        centre: [f64; 3],
        radius: f64,
        area: f64,
        rq: f64,
        reach2: f64,
        q: &[[f64; LANES]; 3],
    ) -> (NodeLanes, NodeLanes)
        = nodes_body, nodes_avx512, nodes_avx2;
}

/// The node kernel for `spread` and for `taylor`.
#[inline(always)]
fn nodes_body(
    f: &Far,
    centre: [f64; 3],
    radius: f64,
    area: f64,
    rq: f64,
    reach2: f64,
    q: &[[f64; LANES]; 3],
) -> (NodeLanes, NodeLanes) {
    (
        node_body::<true>(f, centre, radius, area, rq, reach2, q),
        node_body::<false>(f, centre, radius, area, rq, reach2, q),
    )
}

dispatch! {
    #[allow(dead_code)]
    fn edge_node(
        centre: [f64; 3],
        net: [f64; 3],
        moment: &[[f64; 3]; 3],
        anti: [f64; 3],
        q: &[[f64; LANES]; 3],
    ) -> EdgeLanes
        = edge_node_body, edge_node_avx512, edge_node_avx2;
}

dispatch! {
    #[allow(dead_code)]
    fn edge_leaf(
        segs: &[[[f64; 3]; 2]],
        q: &[[f64; LANES]; 3],
        acc: [[f64; LANES]; 3],
    ) -> ([[f64; LANES]; 3], [bool; LANES])
        = edge_leaf_body, edge_leaf_avx512, edge_leaf_avx2;
}

#[test]
fn every_instruction_set_gives_the_same_bits() {
    let mut rng = Rng::plain(17);
    let tris: Vec<_> = (0..LANES).map(|i| triangle(&mut rng, i)).collect();
    let areas: Vec<f64> = (0..LANES).map(|_| rng.unit()).collect();
    let leaf_ = Leaf::new(&tris, &areas);
    let near: Vec<(u32, f64)> = (0..LANES as u32).map(|i| (i, 1.0)).collect();
    let far = Far {
        n1: rng.point(-1.0, 1.0),
        tr: rng.unit(),
        m: std::array::from_fn(|_| rng.unit() - 0.5),
        w: rng.point(-1.0, 1.0),
        c: std::array::from_fn(|_| std::array::from_fn(|_| rng.unit() - 0.5)),
    };
    let moment = [
        rng.point(-1.0, 1.0),
        rng.point(-1.0, 1.0),
        rng.point(-1.0, 1.0),
    ];
    let (net, anti, centre) = (
        rng.point(-1.0, 1.0),
        rng.point(-1.0, 1.0),
        rng.point(-3.0, 3.0),
    );
    let (radius, area, rq) = (0.3, 0.7, 0.05);
    let segs: Vec<[[f64; 3]; 2]> = (0..LANES)
        .map(|_| [rng.point(-1.0, 1.0), rng.point(-1.0, 1.0)])
        .collect();
    let acc = [0, 1, 2].map(|_| std::array::from_fn(|_| rng.unit()));
    // Every kernel's outputs by one instruction set (0 the baseline, 1 AVX2, 2 AVX-512), as
    // bits.
    let outputs = |path: u32, q: [f64; 3], qs: &[[f64; LANES]; 3]| -> Vec<u64> {
        // SAFETY: each path is run only where the processor has its instructions (below).
        let (l, ls, lt, p, (ns, nt), e, el) = unsafe {
            match path {
                #[cfg(target_arch = "x86_64")]
                1 => (
                    leaf_avx2(&leaf_, q),
                    leaf_spread_avx2(&leaf_, q, rq),
                    leaf_taylor_avx2(&leaf_, q, rq),
                    point_sums_avx2(&tris, &near, qs, 1e-9),
                    nodes_avx2(&far, centre, radius, area, rq, 0.0, qs),
                    edge_node_avx2(centre, net, &moment, anti, qs),
                    edge_leaf_avx2(&segs, qs, acc),
                ),
                #[cfg(target_arch = "x86_64")]
                2 => (
                    leaf_avx512(&leaf_, q),
                    leaf_spread_avx512(&leaf_, q, rq),
                    leaf_taylor_avx512(&leaf_, q, rq),
                    point_sums_avx512(&tris, &near, qs, 1e-9),
                    nodes_avx512(&far, centre, radius, area, rq, 0.0, qs),
                    edge_node_avx512(centre, net, &moment, anti, qs),
                    edge_leaf_avx512(&segs, qs, acc),
                ),
                _ => (
                    leaf_body(&leaf_, q),
                    leaf_spread_body(&leaf_, q, rq),
                    leaf_taylor_body(&leaf_, q, rq),
                    point_sums_body(&tris, &near, qs, 1e-9),
                    nodes_body(&far, centre, radius, area, rq, 0.0, qs),
                    edge_node_body(centre, net, &moment, anti, qs),
                    edge_leaf_body(&segs, qs, acc),
                ),
            }
        };
        let nodes = [ns, nt]
            .into_iter()
            .flat_map(|n| [n.d2, n.far, n.g, n.magnitude, n.extra]);
        let values = [l.0, l.1, p.0]
            .into_iter()
            .chain([ls.angle, ls.g, ls.magnitude, ls.variation])
            .chain([lt.angle, lt.dist, lt.hessian])
            .chain(nodes)
            .chain([e.d, e.field[0], e.field[1], e.field[2]])
            .chain(el.0);
        let mut bits: Vec<u64> = values.flat_map(|v| v.map(f64::to_bits)).collect();
        bits.extend(p.1.map(u64::from));
        bits.extend(el.1.map(u64::from));
        bits
    };
    let mut paths = Vec::new();
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") {
            paths.push((1, "AVX2"));
        }
        if std::arch::is_x86_feature_detected!("avx512f") {
            paths.push((2, "AVX-512"));
        }
    }
    if paths.is_empty() {
        eprintln!("NOTICE: no AVX2 or AVX-512 here; only the baseline path ran");
    }
    for _ in 0..200 {
        let q = rng.point(-2.0, 2.0);
        let qs = [0, 1, 2].map(|_| std::array::from_fn(|_| rng.unit() * 2.0 - 1.0));
        let plain = outputs(0, q, &qs);
        for &(path, name) in &paths {
            assert_eq!(plain, outputs(path, q, &qs), "{name}");
        }
    }
}
