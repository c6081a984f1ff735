//! The exact winding number, the hierarchy's values against the exact sums, and the error of
//! its expansion.
//!
//! Not here: the bounds built on those values (`bounds`).

use super::*;

#[test]
fn exact_winding_of_a_closed_mesh() {
    let m = octahedron();
    let tris = || (0..m.triangles().len()).map(|t| m.triangle(t));
    assert!((exact_winding_number(tris(), [0.1, 0.2, 0.1]) - 1.0).abs() < 1e-12);
    assert!(exact_winding_number(tris(), [1.1, 0.2, 0.1]).abs() < 1e-12);
    assert!(
        (exact_winding_number(
            m.flipped()
                .triangles()
                .iter()
                .enumerate()
                .map(|(t, _)| m.flipped().triangle(t)),
            [0.0; 3]
        ) + 1.0)
            .abs()
            < 1e-12
    );
}

#[test]
fn hierarchy_matches_the_exact_sum() {
    let (p, t) = sheet(40);
    let tree = WindingTree::new(&p, &t);
    let tris: Vec<_> = t.iter().map(|t| t.map(|i| p[i as usize])).collect();
    let mut worst: f64 = 0.0;
    let mut far_used = false;
    for i in 0..300 {
        let f = i as f64;
        let q = [
            (f * 0.618).fract() * 3.0 - 1.0,
            (f * 0.414).fract() * 3.0 - 1.0,
            (f * 0.732).fract() * 2.0 - 1.0,
        ];
        let exact = exact_winding_number(tris.iter().copied(), q);
        let fast = tree.winding_number(q);
        worst = worst.max((exact - fast).abs());
        far_used |= exact != fast;
    }
    assert!(far_used, "no query used an expansion");
    eprintln!("worst {worst}");
    assert!(worst < 2e-3, "largest error {worst}");
}

#[test]
fn expansion_error_falls_with_the_order() {
    // One node over a patch, evaluated from ever farther: the error of the second-order
    // expansion must fall faster than the distance cubed (a wrong moment would stall it).
    let (p, t) = sheet(6);
    let tris: Vec<_> = t.iter().map(|t| t.map(|i| p[i as usize])).collect();
    let mut all = tris.clone();
    let mut nodes = Vec::new();
    build::<Far>(&mut nodes, &mut Vec::new(), &mut all, 0);
    let root = &nodes[0];
    let mut errs = Vec::new();
    for d in [4.0, 8.0, 16.0] {
        let q = [0.5 + d * 0.6, 0.5 - d * 0.3, d * 0.74];
        let r = sub(root.centre, q);
        let approx = far_field(root, r, dot(r, r));
        let exact: f64 = tris.iter().map(|t| solid_angle(t, q)).sum();
        errs.push((approx - exact).abs() / exact.abs());
    }
    // Relative error of an order-2 expansion falls like (size / d)³: × 8 per doubling.
    eprintln!("{errs:?}");
    assert!(
        errs[0] / errs[1] > 6.0 && errs[1] / errs[2] > 6.0,
        "{errs:?}"
    );
}
