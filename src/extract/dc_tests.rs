//! Dual contouring's sharp features, measured (issue 33): on boxes, a prism, a rotated cube, an
//! L-shaped bracket (the union of two boxes: a concave edge) and `rocker-arm` (from
//! `../shared/meshes`, skipped with a notice when absent), the two-sided Hausdorff distance to
//! the source is at most a voxel, the dihedral angle across each feature edge is within 5° of
//! the source's (on rocker-arm, at 384 voxels, where the edge lies clear of the other creases:
//! `measure::isolated`), the mesh is valid (`check`) and no two triangles cross. Surface nets'
//! and marching cubes' errors on the same edges are printed beside them for contrast.

use std::borrow::Cow;

use super::measure::{
    Feature, dihedral_errors, feature_distances, features, hausdorff, isolated, probes,
    self_intersections,
};
use super::surface_nets::{Field, surface_nets};
use super::{TriMesh, check, dual_contouring, marching_cubes};
use crate::cancel::Control;
use crate::engine::cpu::CpuEngine;
use crate::engine::fill::{self, Fill};
use crate::engine::{FIXED_ONE, Method, hermite};
use crate::grid::Grid;
use crate::mesh::Mesh;

/// An extrusion along z of a polygon star-shaped about its first vertex (counter-clockwise),
/// from `z0` to `z1`, then turned by `angles` (about x, then y, then z) about `centre`.
fn prism(poly: &[[f64; 2]], z0: f64, z1: f64, angles: [f64; 3], centre: [f64; 3]) -> Mesh {
    let n = poly.len() as u32;
    let mut pos: Vec<[f64; 3]> = vec![];
    for &z in &[z0, z1] {
        for p in poly {
            pos.push([p[0], p[1], z]);
        }
    }
    let mut tris = vec![];
    for i in 1..n - 1 {
        tris.push([0, i + 1, i]); // bottom, facing −z
        tris.push([n, n + i, n + i + 1]); // top
    }
    for i in 0..n {
        let j = (i + 1) % n;
        tris.push([i, j, n + j]);
        tris.push([i, n + j, n + i]);
    }
    let rot = |p: [f64; 3]| {
        let mut p = [0, 1, 2].map(|a| p[a] - centre[a]);
        for (a, &t) in angles.iter().enumerate() {
            let (c, s) = (t.cos(), t.sin());
            let (u, v) = ((a + 1) % 3, (a + 2) % 3);
            let (pu, pv) = (p[u], p[v]);
            p[u] = c * pu - s * pv;
            p[v] = s * pu + c * pv;
        }
        [0, 1, 2].map(|a| p[a] + centre[a])
    };
    Mesh::new(pos.into_iter().map(rot).collect(), tris).unwrap()
}

/// The source mesh in lattice units of `g`.
fn lattice(m: &Mesh, g: &Grid) -> TriMesh {
    TriMesh {
        positions: m
            .positions()
            .iter()
            .map(|p| [0, 1, 2].map(|a| (p[a] - g.origin[a]) / g.voxel_size))
            .collect(),
        triangles: m.triangles().to_vec(),
        colors: vec![],
    }
}

/// How far from a feature edge its faces' normals are probed, in voxels: the faces of an acute
/// edge are closer than a voxel to each other up to 1/(2·sin(θ/2)) voxels from it (1.05 for
/// the prism's 56° edge), where no voxel centre lies between them and no grid can show them.
const PROBE: f64 = 1.5;

/// How far a probe keeps from corners, and where measured alone from other creases, in voxels
/// (`measure::probes`, `measure::isolated`).
const CLEAR: f64 = 2.0;

struct Measured {
    hausdorff: f64,
    /// Per feature edge its mean dihedral error, degrees (`None`: no probe on it).
    dihedral: Vec<Option<f64>>,
    /// The same over its probes clear of other creases (`measure::isolated`).
    alone: Vec<Option<f64>>,
    /// Per feature edge, the mean distance from it to the mesh, voxels.
    cut: Vec<Option<f64>>,
    intersections: usize,
}

/// The largest of the values there are.
fn worst(v: &[Option<f64>]) -> f64 {
    v.iter().flatten().cloned().fold(0.0, f64::max)
}

/// How many of the values there are exceed `bound`.
fn over(v: &[Option<f64>], bound: f64) -> usize {
    v.iter().flatten().filter(|&&e| e > bound).count()
}

/// The mean of the values there are.
fn mean(v: &[Option<f64>]) -> f64 {
    let n = v.iter().flatten().count();
    v.iter().flatten().sum::<f64>() / n.max(1) as f64
}

/// Dual contouring, surface nets and marching cubes of `m`'s solid on `g`, each checked and
/// measured against `m` (feature edges: dihedral over `min_angle`).
fn measure(name: &str, m: &Mesh, g: &Grid, min_angle: f64) -> [Measured; 3] {
    let diag = m.diagnostics();
    let ctl = Control::none();
    let (bits, _) =
        fill::voxelize_with(&CpuEngine, m, g, Method::Solid, Fill::Parity, &diag, &ctl).unwrap();
    let tris = crate::engine::sdf::lattice_triangles(m, g, Some(FIXED_ONE)).unwrap();
    let h = hermite::hermite(&tris, &bits, &ctl).unwrap();
    assert_eq!(h.uncrossed(), 0, "{name}");
    let field = Field::bits(Cow::Borrowed(&bits));
    let meshes = [
        dual_contouring::dual_contouring(&bits, &h, &ctl).unwrap(),
        surface_nets(&field, &ctl).unwrap(),
        marching_cubes::marching_cubes(&field, &ctl).unwrap(),
    ];
    let src = lattice(m, g);
    let feats = features(&src, min_angle);
    assert!(!feats.is_empty(), "{name}: no feature edges");
    let all = probes(&feats, CLEAR);
    let alone = isolated(&src, &feats, &all, CLEAR);
    let out = meshes.map(|out| {
        let r = check::check(&out);
        assert!(r.is_valid(), "{name}: {r:?}");
        Measured {
            hausdorff: hausdorff(&src, &out, 0.25),
            dihedral: dihedral_errors(&src, &out, &feats, &all, PROBE),
            alone: dihedral_errors(&src, &out, &feats, &alone, PROBE),
            cut: feature_distances(&out, &all),
            intersections: self_intersections(&out),
        }
    });
    for (alg, o) in ["dual-contouring", "surface-nets", "marching-cubes"]
        .iter()
        .zip(&out)
    {
        eprintln!(
            "{name} {alg}: Hausdorff {:.3} voxels; over {} feature edges: dihedral error mean {:.2}°, max {:.2}°, {} over 5°; over the {} with probes clear of other creases: mean {:.2}°, max {:.2}°, {} over 5°; edge to mesh mean {:.3}, max {:.3} voxels; {} crossing triangle pairs",
            o.hausdorff,
            o.dihedral.iter().flatten().count(),
            mean(&o.dihedral),
            worst(&o.dihedral),
            over(&o.dihedral, 5.0),
            o.alone.iter().flatten().count(),
            mean(&o.alone),
            worst(&o.alone),
            over(&o.alone, 5.0),
            mean(&o.cut),
            worst(&o.cut),
            o.intersections
        );
    }
    out
}

fn grid(dims: [u32; 3]) -> Grid {
    Grid {
        origin: [0.0; 3],
        voxel_size: 1.0,
        dims,
    }
}

/// The feature edges of `m` on `g` (over `min_angle`) whose error in `errors` (theirs, in
/// order) is over 5°, with it.
fn over_5(m: &Mesh, g: &Grid, min_angle: f64, errors: &[Option<f64>]) -> Vec<(Feature, f64)> {
    features(&lattice(m, g), min_angle)
        .into_iter()
        .zip(errors)
        .filter_map(|(f, e)| e.filter(|&e| e > 5.0).map(|e| (f, e)))
        .collect()
}

/// Dual contouring keeps every feature of `m` sharp (module doc's bounds).
fn assert_sharp(name: &str, m: &Mesh, g: &Grid, contrast: bool) {
    let [dc, sn, _] = measure(name, m, g, 30.0);
    assert!(dc.hausdorff <= 1.0, "{name}: Hausdorff {}", dc.hausdorff);
    let bad = over_5(m, g, 30.0, &dc.dihedral);
    assert!(bad.is_empty(), "{name}: {bad:?}");
    assert_eq!(dc.intersections, 0, "{name}");
    // On the edges, up to the prism's 56° edge, thinner than a voxel near its apex (PROBE).
    assert!(worst(&dc.cut) <= 0.35, "{name}: {:?}", dc.cut);
    // The contrast the measures must be able to see: surface nets cut the edges off (not a
    // box whose faces lie on the voxels' faces: surface nets' vertices land on them too).
    if contrast {
        assert!(mean(&sn.cut) > 4.0 * mean(&dc.cut), "{name}: {:?}", sn.cut);
    }
}

#[test]
fn boxes_stay_sharp() {
    let sq = |x0: f64, y0: f64, x1: f64, y1: f64| vec![[x0, y0], [x1, y0], [x1, y1], [x0, y1]];
    let m = prism(&sq(2.3, 3.1, 13.7, 11.4), 2.6, 15.2, [0.0; 3], [0.0; 3]);
    assert_sharp("box", &m, &grid([17, 15, 18]), true);
    let m = prism(&sq(3.0, 3.0, 10.0, 10.0), 3.0, 10.0, [0.0; 3], [0.0; 3]);
    assert_sharp("box on the lattice", &m, &grid([14, 14, 14]), false);
}

#[test]
fn a_prism_and_a_rotated_cube_stay_sharp() {
    let tri = [[2.2, 2.7], [17.3, 3.9], [6.1, 16.8]];
    let m = prism(&tri, 2.4, 14.3, [0.0; 3], [0.0; 3]);
    assert_sharp("prism", &m, &grid([20, 20, 17]), true);
    let sq = [[5.0, 5.0], [15.0, 5.0], [15.0, 15.0], [5.0, 15.0]];
    let m = prism(&sq, 5.0, 15.0, [0.3, 0.5, 0.7], [10.0, 10.0, 10.0]);
    assert_sharp("rotated cube", &m, &grid([21, 21, 21]), true);
}

#[test]
fn an_l_bracket_keeps_its_concave_edge() {
    let l = [
        [2.3, 2.2],
        [18.6, 2.2],
        [18.6, 7.4],
        [7.5, 7.4],
        [7.5, 17.7],
        [2.3, 17.7],
    ];
    let m = prism(&l, 2.5, 11.3, [0.05, -0.08, 0.11], [10.0, 10.0, 7.0]);
    assert_sharp("L-bracket", &m, &grid([22, 21, 16]), true);
}

/// `measure::isolated` keeps a probe unless a crease of another chain passes within `CLEAR`:
/// a 10-voxel cube keeps all, a slab 1.5 voxels thick none on its long edges (each has its twin
/// 1.5 voxels away), and an edge cut into two collinear mesh edges is one chain, whose halves
/// do not count against each other.
#[test]
fn isolated_probes_keep_clear_of_other_creases() {
    let sq = vec![[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]];
    let g = grid([12, 12, 12]);
    let alone = |m: &Mesh| {
        let src = lattice(m, &g);
        let feats = features(&src, 30.0);
        let all = probes(&feats, CLEAR);
        let alone = isolated(&src, &feats, &all, CLEAR);
        (feats, all, alone)
    };
    let (feats, all, kept) = alone(&prism(&sq, 0.0, 10.0, [0.0; 3], [0.0; 3]));
    assert_eq!(feats.len(), 12);
    assert_eq!(all, kept);
    assert_eq!(kept.iter().flatten().count(), 36);
    let (feats, all, kept) = alone(&prism(&sq, 0.0, 1.5, [0.0; 3], [0.0; 3]));
    assert_eq!(feats.len(), 12);
    assert_eq!(all.iter().flatten().count(), 24, "the long edges' probes");
    assert_eq!(kept.iter().flatten().count(), 0);
    // The bottom edge y = 0, z = 0 in two pieces (a vertex at x = 5; fanned from (10, 10)).
    let five = vec![
        [10.0, 10.0],
        [0.0, 10.0],
        [0.0, 0.0],
        [5.0, 0.0],
        [10.0, 0.0],
    ];
    let (feats, all, kept) = alone(&prism(&five, 0.0, 10.0, [0.0; 3], [0.0; 3]));
    let half = feats
        .iter()
        .position(|f| {
            let ends = [f.a, f.b];
            ends.contains(&[0.0; 3]) && ends.contains(&[5.0, 0.0, 0.0])
        })
        .expect("the half edge");
    // At ½ and ¾ (¼ is 1.25 from the corner); ¾ is 1.25 from the other half.
    assert_eq!(all[half], vec![[2.5, 0.0, 0.0], [3.75, 0.0, 0.0]]);
    assert_eq!(kept[half], all[half]);
}

/// `rocker-arm` from `../shared/meshes` (`None` with a notice for `test` when absent).
fn rocker_arm(test: &str) -> Option<Mesh> {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../shared/meshes/rocker-arm.obj"
    );
    let m = crate::mesh::load_file(std::path::Path::new(path), usize::MAX).ok();
    if m.is_none() {
        eprintln!("SKIP {test}: {path} is absent");
    }
    m
}

/// A grid of voxel size `s` over `m` with two voxels to spare on every side.
fn padded_grid(m: &Mesh, s: f64) -> Grid {
    let d = m.diagnostics();
    let origin = d.bbox_min.map(|c| c - 2.0 * s);
    let dims = [0, 1, 2].map(|a| ((d.bbox_max[a] - origin[a]) / s).ceil() as u32 + 2);
    Grid {
        origin,
        voxel_size: s,
        dims,
    }
}

#[test]
fn rocker_arm_stays_sharp() {
    let Some(m) = rocker_arm("rocker_arm_stays_sharp") else {
        return;
    };
    let s = std::env::var("VOXD_ROCKER_S").map_or(1.0 / 384.0, |v| v.parse().unwrap());
    let g = padded_grid(&m, s);
    let [dc, sn, mc] = measure("rocker-arm", &m, &g, 60.0);
    assert!(dc.hausdorff <= 1.0, "Hausdorff {}", dc.hausdorff);
    assert_eq!(dc.intersections, 0);
    assert!(mean(&dc.dihedral) < mean(&sn.dihedral) && mean(&dc.dihedral) < mean(&mc.dihedral));
    // Every edge the grid shows apart from the other creases is within 5°, and there are enough
    // of them to say so (16 of the 47 at 384 voxels); their mean is 0.74° (1.67° with the rank
    // rule at 2%, as before 2026-12-07).
    let alone = dc.alone.iter().flatten().count();
    assert!(alone >= 10, "{alone} edges clear of other creases");
    assert!(mean(&dc.alone) <= 1.0, "mean {}", mean(&dc.alone));
    let bad = over_5(&m, &g, 60.0, &dc.alone);
    assert!(bad.is_empty(), "{bad:?}");
    // All 47 edges at the default 384 voxels, crowded ones too (docs/methods.md): mean 1.9°,
    // the worst 11.7°, the four over 5° those where a probe reaches past the edge's faces or
    // within a voxel of another crease. Held so that a change which loses them shows.
    if s == 1.0 / 384.0 {
        let all = over_5(&m, &g, 60.0, &dc.dihedral);
        assert!(mean(&dc.dihedral) <= 2.0, "mean {}", mean(&dc.dihedral));
        assert!(all.len() <= 4 && worst(&dc.dihedral) < 12.5, "{all:?}");
    }
}

/// A solid the grid cuts (a box reaching past the grid on every side of x and y): the faces on
/// the grid's sides have no edge in the Hermite data (their outside voxel is off the grid) and
/// take their midpoints; the mesh is still valid, and closed where the box is inside the grid.
#[test]
fn a_solid_cut_by_the_grid_contours_to_a_valid_mesh() {
    let sq = |x0: f64, y0: f64, x1: f64, y1: f64| vec![[x0, y0], [x1, y0], [x1, y1], [x0, y1]];
    let m = prism(&sq(-2.3, -1.7, 14.6, 13.2), 2.6, 9.2, [0.0; 3], [0.0; 3]);
    let g = grid([12, 11, 12]);
    let ctl = Control::none();
    let diag = m.diagnostics();
    let (bits, _) =
        fill::voxelize_with(&CpuEngine, &m, &g, Method::Solid, Fill::Parity, &diag, &ctl).unwrap();
    assert!(bits.get(0, 0, 5));
    assert!(bits.get(11, 10, 5));
    let tris = crate::engine::sdf::lattice_triangles(&m, &g, Some(FIXED_ONE)).unwrap();
    let h = hermite::hermite(&tris, &bits, &ctl).unwrap();
    let out = dual_contouring::dual_contouring(&bits, &h, &ctl).unwrap();
    let r = check::check(&out);
    assert!(r.is_valid(), "{r:?}");
    // The top and bottom stay at the box's planes, as the lattice holds them (1/256 voxel).
    let zs: Vec<f64> = out.positions.iter().map(|p| p[2]).collect();
    let lo = zs.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = zs.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let step = 1.0 / FIXED_ONE as f64;
    assert!(
        (lo - 2.6).abs() <= step && (hi - 9.2).abs() <= step,
        "{lo} {hi}"
    );
}

/// No two dual-contouring triangles of rocker-arm cross at 128, 192, 256 and 576 voxels along
/// its longest side (at 192 six pairs did before `untangle`: vertices on sharp edges folded
/// their triangles through their neighbours'; at 576 plain f64 orientation signs saw four
/// pairs that do not meet), counted by the independent all-pairs check.
#[test]
fn rocker_arm_has_no_crossing_triangles() {
    let Some(m) = rocker_arm("rocker_arm_has_no_crossing_triangles") else {
        return;
    };
    let d = m.diagnostics();
    let long = (0..3)
        .map(|a| d.bbox_max[a] - d.bbox_min[a])
        .fold(0.0, f64::max);
    for n in [128.0, 192.0, 256.0, 576.0] {
        let g = padded_grid(&m, long / n);
        let ctl = Control::none();
        let (bits, _) =
            fill::voxelize_with(&CpuEngine, &m, &g, Method::Solid, Fill::Parity, &d, &ctl).unwrap();
        let tris = crate::engine::sdf::lattice_triangles(&m, &g, Some(FIXED_ONE)).unwrap();
        let h = hermite::hermite(&tris, &bits, &ctl).unwrap();
        let out = dual_contouring::dual_contouring(&bits, &h, &ctl).unwrap();
        assert!(check::check(&out).is_valid(), "{n}");
        assert_eq!(self_intersections(&out), 0, "rocker-arm at {n} voxels");
    }
}
