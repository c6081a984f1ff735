//! The real third-party meshes in `../shared/meshes`: every loader, every method against the
//! oracles, and the watertight ones against the winding number. Skips with a notice when the
//! folder is absent.

use crate::common::*;
use voxd::engine::cpu::CpuEngine;
use voxd::engine::{Engine, GridMesh, Method};
use voxd::grid::{Grid, GridSpec};
use voxd::mesh::{self, Mesh};

/// (file, triangles, watertight, bbox min, bbox max) from ../shared/meshes/README.md.
type Facts = (&'static str, usize, bool, [f64; 3], [f64; 3]);

const MESHES: &[Facts] = &[
    (
        "spot.obj",
        5856,
        true,
        [-0.471552, -0.736784, -0.668909],
        [0.471552, 0.953646, 1.049],
    ),
    (
        "stanford-bunny.obj",
        69451,
        false,
        [-0.09469, 0.032987, -0.061874],
        [0.061009, 0.187321, 0.0588],
    ),
    (
        "teapot.obj",
        6320,
        false,
        [-3.0, 0.0, -2.0],
        [3.434, 3.15, 2.0],
    ),
    (
        "suzanne.obj",
        968,
        false,
        [-3.86125, 0.267311, 3.25233],
        [-1.12688, 2.23606, 4.95545],
    ),
    (
        "rocker-arm.obj",
        20088,
        true,
        [-0.151733, -0.257456, -0.5],
        [0.151733, 0.257456, 0.5],
    ),
    (
        "ogre.obj",
        124008,
        false,
        [-15.61, -0.008192, -5.456],
        [15.61, 32.03, 4.267],
    ),
    (
        "igea.obj",
        268686,
        true,
        [-0.034556, -0.049669, -0.049538],
        [0.034556, 0.049669, 0.049538],
    ),
    (
        "igea-subdiv4.obj.gz",
        1074744,
        true,
        [-0.034556, -0.049669, -0.049538],
        [0.034556, 0.049669, 0.049538],
    ),
    ("Box.gltf", 12, true, [-0.5, -0.5, -0.5], [0.5, 0.5, 0.5]),
    (
        "2CylinderEngine.gltf",
        121496,
        false,
        [-371.692, -180.972, -140.0],
        [371.692, 92.0416, 128.0],
    ),
    (
        "Fox.glb",
        576,
        true,
        [-12.5927, -0.121745, -88.095],
        [12.5927, 78.9072, 66.6249],
    ),
];

fn load(dir: &std::path::Path, name: &str) -> Mesh {
    mesh::load_file(&dir.join(name), usize::MAX).unwrap_or_else(|e| panic!("{name}: {e}"))
}

fn fit(m: &Mesh, n: u32, cubic: bool) -> Grid {
    let (lo, hi) = m.bounds();
    Grid::fit(
        lo,
        hi,
        GridSpec::Resolution { n, cubic },
        0,
        Default::default(),
    )
    .unwrap()
}

#[test]
fn every_real_mesh_loads_with_the_documented_facts() {
    let Some(dir) = shared_meshes() else { return };
    for &(name, tris, watertight, lo, hi) in MESHES {
        let m = load(&dir, name);
        let d = m.diagnostics();
        assert_eq!(d.triangles, tris, "{name}");
        assert_eq!(d.watertight, watertight, "{name}");
        for a in 0..3 {
            let tol = 1e-4 * (hi[a] - lo[a]).abs().max(1.0);
            assert!(
                (d.bbox_min[a] - lo[a]).abs() < tol && (d.bbox_max[a] - hi[a]).abs() < tol,
                "{name} bbox {:?} {:?}",
                d.bbox_min,
                d.bbox_max
            );
        }
    }
    // Facts the README states beyond the table.
    assert_eq!(
        load(&dir, "2CylinderEngine.gltf")
            .diagnostics()
            .degenerate_triangles,
        11160
    );
    assert_eq!(load(&dir, "teapot.obj").diagnostics().boundary_edges, 160);
    assert_eq!(
        load(&dir, "stanford-bunny.obj")
            .diagnostics()
            .boundary_edges,
        223
    );
}

#[test]
fn every_real_mesh_matches_the_oracles_at_two_resolutions() {
    let Some(dir) = shared_meshes() else { return };
    for &(name, ..) in MESHES {
        let m = load(&dir, name);
        for (n, cubic) in [(37, false), (64, true)] {
            let g = fit(&m, n, cubic);
            let gm = GridMesh::new(&m, &g).unwrap();
            let solid = CpuEngine.voxelize(&gm, Method::Solid).unwrap();
            if let Some(d) = first_difference(&solid, &solid_binned(&m, &g)) {
                panic!("{name} at {n}: solid differs from the oracle: {d}");
            }
            let surface = CpuEngine.voxelize(&gm, Method::Surface).unwrap();
            if let Some(d) = first_difference(&surface, &surface_bbox(&m, &g)) {
                panic!("{name} at {n}: surface differs from the oracle: {d}");
            }
            assert!(solid.count_ones() > 0 && surface.count_ones() > 0, "{name}");
        }
    }
}

/// The acceptance case: igea at 256³ is the exact solid, compared with the per-voxel
/// oracle everywhere and with the winding number on sampled centres away from the surface.
#[test]
fn igea_at_256_is_the_exact_solid() {
    let Some(dir) = shared_meshes() else { return };
    let m = load(&dir, "igea.obj");
    let g = fit(&m, 256, true);
    let solid = CpuEngine
        .voxelize(&GridMesh::new(&m, &g).unwrap(), Method::Solid)
        .unwrap();
    if let Some(d) = first_difference(&solid, &solid_binned(&m, &g)) {
        panic!("igea at 256: {d}");
    }
    check_winding_samples(&m, &g, &solid, 60, "igea.obj");
}

#[test]
fn watertight_meshes_are_solid_where_the_winding_number_says() {
    let Some(dir) = shared_meshes() else { return };
    for name in ["spot.obj", "rocker-arm.obj", "Box.gltf", "Fox.glb"] {
        let m = load(&dir, name);
        let (lo, hi) = m.bounds();
        let g = Grid::fit(
            lo,
            hi,
            GridSpec::Resolution {
                n: 96,
                cubic: false,
            },
            3,
            Default::default(),
        )
        .unwrap();
        let solid = CpuEngine
            .voxelize(&GridMesh::new(&m, &g).unwrap(), Method::Solid)
            .unwrap();
        check_winding_samples(&m, &g, &solid, 400, name);
    }
}

/// Samples voxels (half of them solid, when there are enough) and checks each centre farther
/// than 1/100 voxel from the surface: solid iff |winding number| > ½.
fn check_winding_samples(m: &Mesh, g: &Grid, solid: &voxd::BitVolume, n: usize, name: &str) {
    let mut rng = Rng::new(7);
    let ones: Vec<[u32; 3]> = solid.iter_ones().collect();
    let (mut inside, mut outside) = (0, 0);
    for i in 0..n {
        let v = if i % 2 == 0 && !ones.is_empty() {
            ones[rng.below(ones.len() as u64) as usize]
        } else {
            g.dims.map(|d| rng.below(d as u64) as u32)
        };
        let (w, dist) = winding_and_distance(m, g.voxel_center(v[0], v[1], v[2]));
        if dist < 0.01 * g.voxel_size {
            continue;
        }
        let want = w.abs() > 0.5;
        assert_eq!(
            solid.get(v[0], v[1], v[2]),
            want,
            "{name}: voxel {v:?} winding {w}"
        );
        if want { inside += 1 } else { outside += 1 }
    }
    assert!(
        inside > n / 4 && outside > n / 20,
        "{name}: too few samples ({inside} in, {outside} out)"
    );
}
