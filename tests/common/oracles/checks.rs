//! The oracles of `common` checked against brute force and closed forms, so that a test failing
//! against them points at the library.

use std::f64::consts::PI;

use super::*;
use crate::common::{Rng, box_mesh, push_octahedron};

/// A random triangle in [-2, 2]³, sometimes degenerate (two corners the same, collinear corners,
/// a single point) or tiny.
fn random_triangle(rng: &mut Rng) -> [[f64; 3]; 3] {
    let mut t = [0; 3].map(|_| [0; 3].map(|_| rng.range(-2.0, 2.0)));
    match rng.below(8) {
        0 => t[2] = t[1],
        1 => t[2] = [0, 1, 2].map(|i| 0.3 * t[0][i] + 0.7 * t[1][i]),
        2 => t = [t[0]; 3],
        3 => t[1] = [0, 1, 2].map(|i| t[0][i] + rng.range(-1e-3, 1e-3)),
        _ => {}
    }
    t
}

/// The triangle's points on a barycentric lattice with `n` steps per edge.
fn samples(t: &[[f64; 3]; 3], n: u32) -> impl Iterator<Item = [f64; 3]> + '_ {
    (0..=n).flat_map(move |i| {
        (0..=n - i).map(move |j| {
            let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
            [0, 1, 2].map(|k| t[0][k] + u * (t[1][k] - t[0][k]) + v * (t[2][k] - t[0][k]))
        })
    })
}

fn dist(p: [f64; 3], q: [f64; 3]) -> f64 {
    dotf(subf(p, q), subf(p, q)).sqrt()
}

/// Every sampled point of the triangle is at least the oracle's distance away, and the nearest
/// sample at most one lattice step farther than it (every point of the triangle is within the
/// longest lattice edge, longest edge / n, of a sample).
#[test]
fn dist2_to_triangle_matches_dense_sampling() {
    let n = 120;
    let mut rng = Rng::new(31);
    let mut above = 0;
    for case in 0..300 {
        let t = random_triangle(&mut rng);
        let step = (0..3)
            .map(|i| dist(t[i], t[(i + 1) % 3]))
            .fold(0.0, f64::max)
            / n as f64;
        let normal = crossf(subf(t[1], t[0]), subf(t[2], t[0]));
        let l = dotf(normal, normal).sqrt();
        for k in 0..6 {
            // Anywhere near, or above or below a point of the triangle's plane near it (so
            // that the plane case is exercised).
            let (u, v, h) = (
                rng.range(-0.2, 1.0),
                rng.range(-0.2, 1.0),
                rng.range(-1.0, 1.0),
            );
            let p = if k < 3 || l < 1e-3 {
                [0; 3].map(|_| rng.range(-3.0, 3.0))
            } else {
                [0, 1, 2].map(|i| {
                    t[0][i] + u * (t[1][i] - t[0][i]) + v * (t[2][i] - t[0][i]) + h * normal[i] / l
                })
            };
            let got = dist2_to_triangle(p, t[0], t[1], t[2]).sqrt();
            let nearest = samples(&t, n).map(|q| dist(p, q)).fold(f64::MAX, f64::min);
            assert!(
                got <= nearest + 1e-12 && nearest <= got + step + 1e-12,
                "case {case}: {got} vs sampled {nearest} (step {step}), p {p:?}, t {t:?}"
            );
            if k >= 3 && l >= 1e-3 && u >= 0.0 && v >= 0.0 && u + v <= 1.0 {
                // Over the triangle: the distance is the height.
                assert!((got - h.abs()).abs() < 1e-12, "case {case}: {got} vs {h}");
                above += 1;
            }
        }
    }
    assert!(above > 100, "{above}");
}

#[test]
fn dist2_to_segment_of_points_and_segments() {
    let (u, v) = ([0.0, 0.0, 0.0], [2.0, 0.0, 0.0]);
    assert_eq!(dist2_to_segment([1.0, 3.0, 4.0], u, v), 25.0);
    assert_eq!(dist2_to_segment([-3.0, 4.0, 0.0], u, v), 25.0);
    assert_eq!(dist2_to_segment([5.0, 0.0, 4.0], u, v), 25.0);
    assert_eq!(dist2_to_segment([1.0, 1.0, 1.0], u, u), 3.0);
}

/// Closed forms: the octant triangle seen from the corner is an eighth of the sphere, a cube's
/// face (two triangles) from the centre a sixth, the sign follows the orientation, and a point
/// in a triangle's plane outside it sees nothing.
#[test]
fn solid_angle_closed_forms() {
    let o = [0.0; 3];
    let (x, y, z) = ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]);
    assert!((solid_angle(o, x, y, z) - PI / 2.0).abs() < 1e-14);
    assert!((solid_angle(o, x, z, y) + PI / 2.0).abs() < 1e-14);
    // The face z = 1 of the cube [-1, 1]³, normal +z, from the centre: 4π / 6, each half π / 3.
    let (a, b, c, d) = (
        [-1.0, -1.0, 1.0],
        [1.0, -1.0, 1.0],
        [1.0, 1.0, 1.0],
        [-1.0, 1.0, 1.0],
    );
    assert!((solid_angle(o, a, b, c) - PI / 3.0).abs() < 1e-14);
    assert!((solid_angle(o, a, c, d) - PI / 3.0).abs() < 1e-14);
    assert_eq!(solid_angle([3.0, 0.0, 1.0], a, b, c), 0.0);
    assert_eq!(solid_angle(o, a, a, c), 0.0);
}

/// On random triangles seen from points not too close to them, the solid angle equals the
/// surface integral of n·(q − p) / |q − p|³ over the triangle, by the midpoint rule on a fine
/// subdivision.
#[test]
fn solid_angle_matches_numerical_integration() {
    let n = 80;
    let mut rng = Rng::new(77);
    let mut checked = 0;
    while checked < 300 {
        let t = [0; 3].map(|_| [0; 3].map(|_| rng.range(-2.0, 2.0)));
        let p = [0; 3].map(|_| rng.range(-3.0, 3.0));
        let size = (0..3)
            .map(|i| dist(t[i], t[(i + 1) % 3]))
            .fold(0.0, f64::max);
        if dist2_to_triangle(p, t[0], t[1], t[2]).sqrt() < 0.25 * size {
            continue;
        }
        // n² sub-triangles: (i, j) "up" and (i, j) "down", each a 1/n² share of the area.
        let at = |u: f64, v: f64| {
            [0, 1, 2].map(|k| t[0][k] + u * (t[1][k] - t[0][k]) + v * (t[2][k] - t[0][k]))
        };
        let area_normal = crossf(subf(t[1], t[0]), subf(t[2], t[0])).map(|c| c / 2.0);
        let mut sum = 0.0;
        for i in 0..n {
            for j in 0..n - i {
                let mut centroids = vec![(i as f64 + 1.0 / 3.0, j as f64 + 1.0 / 3.0)];
                if i + j + 1 < n {
                    centroids.push((i as f64 + 2.0 / 3.0, j as f64 + 2.0 / 3.0));
                }
                for (u, v) in centroids {
                    let r = subf(at(u / n as f64, v / n as f64), p);
                    sum += dotf(area_normal, r) / dotf(r, r).powf(1.5);
                }
            }
        }
        let want = sum / (n * n) as f64;
        let got = solid_angle(p, t[0], t[1], t[2]);
        assert!(
            (got - want).abs() < 1e-3 * (1.0 + want.abs()),
            "{got} vs integrated {want}: p {p:?}, t {t:?}"
        );
        checked += 1;
    }
}

/// The winding number of closed boxes and octahedra (either orientation) is ±1 inside and 0
/// outside, by their own inequalities.
#[test]
fn winding_number_of_closed_shapes() {
    let mut rng = Rng::new(5);
    for _ in 0..40 {
        let c = [0; 3].map(|_| rng.range(-1.0, 1.0));
        let r = [0; 3].map(|_| rng.range(0.3, 2.0));
        let (lo, hi) = (
            [0, 1, 2].map(|i| c[i] - r[i]),
            [0, 1, 2].map(|i| c[i] + r[i]),
        );
        let boxed = box_mesh(lo, hi);
        let (mut p, mut t) = (vec![], vec![]);
        push_octahedron(&mut p, &mut t, c, r);
        let octa = Mesh::new(p, t).unwrap();
        for _ in 0..20 {
            let q = [0, 1, 2].map(|i| c[i] + rng.range(-1.5, 1.5) * r[i]);
            let in_box = (0..3).all(|i| (q[i] - c[i]).abs() < r[i]);
            let l1: f64 = (0..3).map(|i| (q[i] - c[i]).abs() / r[i]).sum();
            for (mesh, inside) in [(&boxed, in_box), (&octa, l1 < 1.0)] {
                let (w, d) = winding_and_distance(mesh, q);
                if d < 1e-6 {
                    continue;
                }
                let want = if inside { 1.0 } else { 0.0 };
                assert!((w - want).abs() < 1e-9, "{w} at {q:?}, inside {inside}");
                let (wf, _) = winding_and_distance(&mesh.flipped(), q);
                assert!((wf + want).abs() < 1e-9, "flipped: {wf}");
            }
        }
    }
}
