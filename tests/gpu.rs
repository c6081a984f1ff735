//! The GPU engine against the CPU engine, bit for bit. Needs a Vulkan adapter (lavapipe in CI):
//! without one these tests skip with a notice, unless VOXD_REQUIRE_GPU=1 (set by scripts/test.sh
//! once it has installed a driver), where that is a failure. Built only with the `gpu` feature (on
//! by default), as is the engine they test.
#![cfg(feature = "gpu")]

use std::sync::OnceLock;

use crate::common::*;
use voxd::engine::cpu::CpuEngine;
use voxd::engine::gpu::{GpuEngine, GpuOptions, SolidStrategy};
use voxd::engine::{Engine, GridMesh, Method};
use voxd::grid::{Grid, GridSpec};
use voxd::mesh::{self, Mesh};

/// The shared GPU engine, or `None` (with a notice) where there is no adapter; with
/// VOXD_REQUIRE_GPU=1 no adapter is a failure.
pub(crate) fn gpu() -> Option<&'static GpuEngine> {
    static ENGINE: OnceLock<Option<GpuEngine>> = OnceLock::new();
    ENGINE
        .get_or_init(|| {
            match GpuEngine::new(GpuOptions {
                adapter: std::env::var("VOXD_ADAPTER").ok(),
                ..Default::default()
            }) {
                Ok(e) => {
                    eprintln!("GPU tests on {:?}", e.adapter());
                    Some(e)
                }
                Err(e) => {
                    assert!(
                        std::env::var("VOXD_REQUIRE_GPU").is_err(),
                        "VOXD_REQUIRE_GPU is set but: {e}"
                    );
                    eprintln!("NOTICE: {e}; skipping GPU tests");
                    None
                }
            }
        })
        .as_ref()
}

fn check(engine: &GpuEngine, mesh: &Mesh, g: &Grid, what: &str) {
    let gm = GridMesh::new(mesh, g).unwrap();
    for m in Method::ALL {
        let want = CpuEngine.voxelize(&gm, m).unwrap();
        let got = engine.voxelize(&gm, m).unwrap();
        if let Some(d) = first_difference(&got, &want) {
            panic!("{what}, {m}: GPU differs from CPU: {d}");
        }
    }
}

#[test]
fn random_meshes_equal_the_cpu() {
    let Some(e) = gpu() else { return };
    for seed in 0..60u64 {
        let mut rng = Rng::new(seed);
        let dims = [
            1 + rng.below(20) as u32,
            1 + rng.below(20) as u32,
            [1, 31, 32, 33, 64, 65, 100][rng.below(7) as usize],
        ];
        let mesh = random_mesh(&mut rng, dims, seed);
        let g = if seed % 3 == 0 {
            off_lattice_grid(dims)
        } else {
            unit_grid(dims)
        };
        check(e, &mesh, &g, &format!("seed {seed}"));
    }
}

#[test]
fn the_mask_strategy_equals_the_cpu_too() {
    let Some(_) = gpu() else { return };
    let masks = GpuEngine::new(GpuOptions {
        adapter: std::env::var("VOXD_ADAPTER").ok(),
        solid_strategy: SolidStrategy::Masks,
        ..Default::default()
    })
    .unwrap();
    for seed in 0..30u64 {
        let mut rng = Rng::new(500 + seed);
        let dims = [
            1 + rng.below(16) as u32,
            1 + rng.below(16) as u32,
            [1, 31, 32, 33, 64, 65, 200][rng.below(7) as usize],
        ];
        let mesh = random_mesh(&mut rng, dims, seed);
        check(
            &masks,
            &mesh,
            &unit_grid(dims),
            &format!("masks, seed {seed}"),
        );
    }
    let (mut p, mut t) = (vec![], vec![]);
    push_box(&mut p, &mut t, [0.5, 0.5, 0.5], [700.0, 500.0, 300.0]);
    check(
        &masks,
        &Mesh::new(p, t).unwrap(),
        &unit_grid([700, 500, 300]),
        "masks, big box",
    );
}

#[test]
fn several_slabs_and_triangle_chunks_equal_the_cpu() {
    let Some(_) = gpu() else { return };
    // Tiny slabs (a few x-rows) and tiny triangle chunks (10 triangles).
    let small = GpuEngine::new(GpuOptions {
        adapter: std::env::var("VOXD_ADAPTER").ok(),
        max_slab_bytes: Some(3 * 40 * 8),
        max_chunk_bytes: Some(36 * 10),
        ..Default::default()
    })
    .unwrap();
    let m = mesh::load_file(&data("spot.obj"), usize::MAX).unwrap();
    let (lo, hi) = m.bounds();
    let g = Grid::fit(
        lo,
        hi,
        GridSpec::Resolution {
            n: 40,
            cubic: false,
        },
        1,
        Default::default(),
    )
    .unwrap();
    let gm = GridMesh::new(&m, &g).unwrap();
    let (v, t) = small.voxelize_timed(&gm, Method::Conservative).unwrap();
    assert!(t.slabs > 5, "only {} slabs", t.slabs);
    assert_eq!(v, CpuEngine.voxelize(&gm, Method::Conservative).unwrap());
    check(&small, &m, &g, "spot in slabs");
}

#[test]
fn huge_triangles_do_not_hit_the_loop_cap() {
    let Some(e) = gpu() else { return };
    // A 12-triangle box spanning a 1024 × 1024 × 64 grid, plus a box inside it.
    let (mut p, mut t) = (vec![], vec![]);
    push_box(&mut p, &mut t, [0.0, 0.0, 0.0], [1024.0, 1024.0, 64.0]);
    push_box(&mut p, &mut t, [100.5, 200.25, 10.5], [900.0, 1000.0, 50.0]);
    // A box reaching out of the grid on every side (negative coordinates).
    push_box(&mut p, &mut t, [-20.5, -3.0, -7.25], [30.0, 40.0, 20.0]);
    let mesh = Mesh::new(p, t).unwrap();
    let g = unit_grid([1024, 1024, 64]);
    check(e, &mesh, &g, "box in a 1024² grid");
    let solid = e
        .voxelize(&GridMesh::new(&mesh, &g).unwrap(), Method::Solid)
        .unwrap();
    // Inner box: x centres 101..=899 (the one on the face x = 100.5 is excluded by the top-left
    // rule), y 200..=999, z 11..=49 (a centre on the bottom face is not above it).
    let cpu = CpuEngine
        .voxelize(&GridMesh::new(&mesh, &g).unwrap(), Method::Solid)
        .unwrap();
    assert_eq!(solid, cpu);
    // The third box flips its in-grid part (x 0..30, y 0..40, z 0..20) out of the outer one.
    assert_eq!(
        solid.count_ones(),
        1024 * 1024 * 64 - 799 * 800 * 39 - 30 * 40 * 20
    );
    // One triangle covering the whole xy plane (and more), tilted through the grid.
    let p = vec![
        [-3000.0, -3000.0, 5.0],
        [5000.0, -3000.0, 40.0],
        [-3000.0, 5000.0, 60.0],
    ];
    let mesh = Mesh::new(p, vec![[0, 1, 2]]).unwrap();
    check(
        e,
        &mesh,
        &unit_grid([700, 600, 64]),
        "one tilted triangle over the plane",
    );
}

#[test]
fn real_meshes_at_two_resolutions_equal_the_cpu() {
    let Some(e) = gpu() else { return };
    let Some(dir) = shared_meshes() else { return };
    for name in [
        "spot.obj",
        "stanford-bunny.obj",
        "teapot.obj",
        "suzanne.obj",
        "rocker-arm.obj",
        "ogre.obj",
        "igea.obj",
        "igea-subdiv4.obj.gz",
        "Box.gltf",
        "2CylinderEngine.gltf",
        "Fox.glb",
    ] {
        let m = mesh::load_file(&dir.join(name), usize::MAX).unwrap();
        let (lo, hi) = m.bounds();
        for (n, cubic) in [(48, false), (128, true)] {
            let g = Grid::fit(
                lo,
                hi,
                GridSpec::Resolution { n, cubic },
                0,
                Default::default(),
            )
            .unwrap();
            check(e, &m, &g, &format!("{name} at {n}"));
        }
    }
}

#[test]
fn density_equals_the_cpu() {
    let Some(e) = gpu() else { return };
    let m = mesh::load_file(&data("spot.obj"), usize::MAX).unwrap();
    let (lo, hi) = m.bounds();
    for (n, f) in [(33, 2), (64, 2), (40, 4)] {
        let g = Grid::fit(
            lo,
            hi,
            GridSpec::Resolution { n, cubic: false },
            1,
            Default::default(),
        )
        .unwrap();
        let (d, parity) = (m.diagnostics(), voxd::engine::fill::Fill::Parity);
        let dens = |e: &dyn Engine| {
            voxd::engine::density::density(e, &m, &g, f, Default::default(), parity, &d)
                .unwrap()
                .0
        };
        let (want, got) = (dens(&CpuEngine), dens(e));
        assert!(got == want, "density n={n} f={f}: GPU differs from CPU");
    }
}

/// The GPU engine under a control: a canceled one stops it before the first slab; a live one
/// hears every slab, ends at 1 and gives the CPU's bits.
#[test]
fn slabs_check_the_control_and_report_progress() {
    use voxd::cancel::{Canceled, Control};
    use voxd::engine::EngineError;
    let Some(_) = gpu() else { return };
    let small = GpuEngine::new(GpuOptions {
        adapter: std::env::var("VOXD_ADAPTER").ok(),
        max_slab_bytes: Some(3 * 40 * 8),
        ..Default::default()
    })
    .unwrap();
    let m = mesh::load_file(&data("spot.obj"), usize::MAX).unwrap();
    let (lo, hi) = m.bounds();
    let g = Grid::fit(
        lo,
        hi,
        GridSpec::Resolution {
            n: 40,
            cubic: false,
        },
        1,
        Default::default(),
    )
    .unwrap();
    let gm = GridMesh::new(&m, &g).unwrap();
    let canceled = Control::new();
    canceled.cancel();
    assert_eq!(
        small.voxelize_with(&gm, Method::Solid, &canceled),
        Err(EngineError::Canceled(Canceled::Canceled))
    );
    for method in Method::ALL {
        let ctl = Control::new();
        let (v, t) = small.voxelize_timed_with(&gm, method, &ctl).unwrap();
        assert!(t.slabs > 5, "only {} slabs", t.slabs);
        assert_eq!(ctl.progress(), 1.0, "{method}");
        assert_eq!(v, CpuEngine.voxelize(&gm, method).unwrap(), "{method}");
    }
}

/// Jobs from many threads at once on one engine, each in several slabs: every volume equals
/// the CPU's bits whichever batch its slabs went to the device in, and with buffers leased from
/// the pool that other jobs (other sizes, other methods) left their contents in. Rounds repeat
/// (at most 20) until some submission carried slabs of more than one job.
#[test]
fn jobs_from_many_threads_at_once_equal_the_cpu() {
    let Some(_) = gpu() else { return };
    let engine = GpuEngine::new(GpuOptions {
        adapter: std::env::var("VOXD_ADAPTER").ok(),
        max_slab_bytes: Some(8192),
        ..Default::default()
    })
    .unwrap();
    let spot = mesh::load_file(&data("spot.obj"), usize::MAX).unwrap();
    let (lo, hi) = spot.bounds();
    let mut meshes: Vec<GridMesh> = [20, 33, 48, 64]
        .into_iter()
        .map(|n| {
            let spec = GridSpec::Resolution { n, cubic: false };
            let g = Grid::fit(lo, hi, spec, 1, Default::default()).unwrap();
            GridMesh::new(&spot, &g).unwrap()
        })
        .collect();
    for seed in 0..4u64 {
        let mut rng = Rng::new(1000 + seed);
        let dims = [10 + rng.below(30) as u32, 10 + rng.below(30) as u32, 33];
        let m = random_mesh(&mut rng, dims, seed);
        meshes.push(GridMesh::new(&m, &unit_grid(dims)).unwrap());
    }
    let jobs: Vec<(&GridMesh, Method, voxd::volume::BitVolume)> = meshes
        .iter()
        .enumerate()
        .flat_map(|(i, gm)| [Method::ALL[i % Method::ALL.len()], Method::Solid].map(|m| (gm, m)))
        .map(|(gm, m)| (gm, m, CpuEngine.voxelize(gm, m).unwrap()))
        .collect();
    let threads = 6;
    let mut slabs = 0u64;
    for _round in 0..20 {
        slabs += std::thread::scope(|s| {
            let runs: Vec<_> = (0..threads)
                .map(|k| {
                    let jobs = &jobs;
                    let engine = &engine;
                    s.spawn(move || {
                        let mut slabs = 0u64;
                        for (i, (gm, m, want)) in jobs.iter().enumerate() {
                            if i % threads != k && (i + 1) % threads != k {
                                continue;
                            }
                            let (got, t) = engine.voxelize_timed(gm, *m).unwrap();
                            if let Some(d) = first_difference(&got, want) {
                                panic!("job {i} ({m}) on thread {k}: GPU differs from CPU: {d}");
                            }
                            slabs += u64::from(t.slabs);
                        }
                        slabs
                    })
                })
                .collect();
            runs.into_iter().map(|r| r.join().unwrap()).sum::<u64>()
        });
        if engine.stats().submissions.largest >= 2 {
            break;
        }
    }
    let stats = engine.stats();
    assert!(stats.submissions.largest >= 2, "{stats:?}");
    // One command buffer per slab, in fewer submissions; most buffers came from the pool.
    assert_eq!(stats.submissions.items, slabs, "{stats:?}");
    assert!(stats.submissions.batches < slabs, "{stats:?}");
    assert!(stats.buffers.reused > stats.buffers.created, "{stats:?}");
}

/// A job run again takes every buffer from the pool (none created), and gets the same bits; a
/// pool whose budget is smaller than a job's buffers keeps no more than its budget idle.
#[test]
fn a_job_run_again_reuses_its_buffers_within_the_pool_budget() {
    let Some(_) = gpu() else { return };
    let m = mesh::load_file(&data("spot.obj"), usize::MAX).unwrap();
    let (lo, hi) = m.bounds();
    let spec = GridSpec::Resolution {
        n: 64,
        cubic: false,
    };
    let gm = GridMesh::new(&m, &Grid::fit(lo, hi, spec, 1, Default::default()).unwrap()).unwrap();
    let want = CpuEngine.voxelize(&gm, Method::Conservative).unwrap();
    for budget in [None, Some(4096)] {
        let engine = GpuEngine::new(GpuOptions {
            adapter: std::env::var("VOXD_ADAPTER").ok(),
            pool_bytes: budget,
            ..Default::default()
        })
        .unwrap();
        assert_eq!(engine.stats().buffers, Default::default());
        let mut seen = vec![];
        for _ in 0..3 {
            assert!(engine.voxelize(&gm, Method::Conservative).unwrap() == want);
            let s = engine.stats().buffers;
            assert!(s.idle_bytes <= budget.unwrap_or(voxd::engine::gpu::POOL_BYTES));
            seen.push(s);
        }
        let first = seen[0];
        // Slabs a and b, the readback, the triangles, the items and their parameters.
        assert!(first.created >= 6, "{first:?}");
        match budget {
            None => {
                assert_eq!(first.idle, first.created, "{first:?}");
                assert!(seen.iter().all(|s| s.created == first.created), "{seen:?}");
                assert_eq!(seen[2].reused, 2 * first.created, "{seen:?}");
            }
            // The slabs (over 4 KiB each) are freed after each job and created again.
            Some(_) => assert!(seen[2].created >= first.created + 2 * 3, "{seen:?}"),
        }
    }
}

// ---- distance: the GPU against the CPU (which is tested against an exact oracle). ----

/// Thicknesses (lattice units) with several integer vectors of their length, for ties.
const THICKNESSES: [i64; 8] = [0, 1, 21, 222, 231, 256, 693, 8085];

/// Triangles exactly `t` from voxel centre `c` through a vertex, an edge and a face: f = c + o
/// with |o| = t, the rest of each triangle in the half-space (q − f)·o ≥ 0.
fn tie_triangles(rng: &mut Rng, c: [i64; 3], t: i64) -> Vec<[[i32; 3]; 3]> {
    let mut dirs = vec![[1, 0, 0], [0, 1, 0], [0, 0, 1]];
    for (d, l) in [
        ([1, 2, 2], 3),
        ([2, 3, 6], 7),
        ([2, 6, 9], 11),
        ([-2, 1, 2], 3),
    ] {
        if t % l == 0 {
            dirs.push(d.map(|x| x * t / l));
        }
    }
    let mut o = dirs[rng.below(dirs.len() as u64) as usize];
    if o.iter().all(|&x| x.abs() <= 1) {
        o = o.map(|x| x * t);
    }
    let f = [0, 1, 2].map(|a| c[a] + o[a]);
    let dot = |a: [i64; 3], b: [i64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let perp: Vec<[i64; 3]> = [[o[1], -o[0], 0], [o[2], 0, -o[0]], [0, o[2], -o[1]]]
        .into_iter()
        .filter(|&u| u != [0; 3])
        .collect();
    let (u1, u2) = if o == [0; 3] {
        ([1, 0, 0], [0, 1, 0])
    } else {
        let u1 = perp[0];
        let cross = |a: [i64; 3], b: [i64; 3]| {
            [
                a[1] * b[2] - a[2] * b[1],
                a[2] * b[0] - a[0] * b[2],
                a[0] * b[1] - a[1] * b[0],
            ]
        };
        let u2 = perp[1..]
            .iter()
            .copied()
            .find(|&u| cross(u1, u) != [0; 3])
            .unwrap_or_else(|| cross(o, u1));
        (u1, u2)
    };
    let at = |p: [i64; 3], k: i64, d: [i64; 3]| [0, 1, 2].map(|a| p[a] + k * d[a]);
    let mut away = || {
        let d = [0, 1, 2].map(|_| rng.below(601) as i64 - 300);
        if dot(d, o) < 0 { d.map(|x| -x) } else { d }
    };
    let (a, b) = (away(), away());
    [
        [
            at(at(f, -1, u1), -1, u2),
            at(at(f, 2, u1), -1, u2),
            at(at(f, -1, u1), 2, u2),
        ],
        [at(f, -1, u1), at(f, 1, u1), at(f, 1, a)],
        [f, at(f, 1, a), at(f, 1, b)],
    ]
    .into_iter()
    .map(|v| v.map(|p| p.map(|x| i32::try_from(x).unwrap())))
    .collect()
}

fn check_distance(e: &GpuEngine, gm: &GridMesh, t: i64, what: &str) {
    let want = CpuEngine.distance_with(gm, t, &Default::default()).unwrap();
    let got = e.distance_with(gm, t, &Default::default()).unwrap();
    if let Some(d) = first_difference(&got, &want) {
        panic!("{what}, distance t = {t}: GPU differs from CPU: {d}");
    }
}

/// Random meshes with degenerate (segments, points), tiny and huge triangles and triangles
/// exactly at the threshold from voxel centres.
#[test]
fn distance_equals_the_cpu_on_random_meshes() {
    let Some(e) = gpu() else { return };
    let mut set = 0;
    for seed in 0..48u64 {
        let mut rng = Rng::new(seed);
        let dims = [
            1 + rng.below(16) as u32,
            1 + rng.below(16) as u32,
            [1, 31, 32, 33, 40][rng.below(5) as usize],
        ];
        let g = unit_grid(dims);
        let mut gm = GridMesh::new(&random_mesh(&mut rng, dims, seed), &g).unwrap();
        let t = THICKNESSES[seed as usize % THICKNESSES.len()];
        let centre = |rng: &mut Rng, a: usize| rng.below(dims[a] as u64) as i64 * 256 + 128;
        for _ in 0..4 {
            let c = [0, 1, 2].map(|a| centre(&mut rng, a));
            gm.triangles.extend(tie_triangles(&mut rng, c, t));
            let p = [0, 1, 2].map(|a| centre(&mut rng, a) as i32 + 37);
            let q = [p[0] + 900, p[1] - 300, p[2] + 5];
            // A point, a segment (repeated vertex), three collinear points, a sliver, a speck.
            gm.triangles.extend([
                [p, p, p],
                [p, q, q],
                [p, q, [2 * q[0] - p[0], 2 * q[1] - p[1], 2 * q[2] - p[2]]],
                [
                    p,
                    q,
                    [2 * q[0] - p[0] + 1, 2 * q[1] - p[1], 2 * q[2] - p[2]],
                ],
                [p, [p[0] + 3, p[1], p[2]], [p[0], p[1] + 2, p[2] - 1]],
            ]);
        }
        let want = CpuEngine
            .distance_with(&gm, t, &Default::default())
            .unwrap();
        set += want.count_ones();
        check_distance(e, &gm, t, &format!("seed {seed}"));
    }
    assert!(set > 0);
}

/// Triangles far larger than the grid (the host leaves out tiles far from their planes), in
/// several slabs.
#[test]
fn distance_of_huge_triangles_in_slabs_equals_the_cpu() {
    let Some(e) = gpu() else { return };
    let p = vec![
        [-3000.0, -3000.0, 5.0],
        [5000.0, -3000.0, 40.0],
        [-3000.0, 5000.0, 60.0],
        [-50.0, 10.0, -40.0],
        [400.0, 20.0, 90.0],
        [100.0, 300.0, 20.5],
    ];
    let mesh = Mesh::new(p, vec![[0, 1, 2], [3, 4, 5]]).unwrap();
    let g = unit_grid([300, 200, 64]);
    let gm = GridMesh::new(&mesh, &g).unwrap();
    for t in [0, 222, 1000] {
        check_distance(e, &gm, t, "huge triangles");
    }
    let small = GpuEngine::new(GpuOptions {
        adapter: std::env::var("VOXD_ADAPTER").ok(),
        max_slab_bytes: Some(3 * 200 * 8),
        max_chunk_bytes: Some(36),
        ..Default::default()
    })
    .unwrap();
    let (v, timings) = small
        .distance_timed_with(&gm, 600, &Default::default())
        .unwrap();
    assert!(timings.slabs > 50, "only {} slabs", timings.slabs);
    assert_eq!(
        v,
        CpuEngine
            .distance_with(&gm, 600, &Default::default())
            .unwrap()
    );
}

/// Real meshes: spot (tests/data) and the shared meshes where present.
#[test]
fn distance_of_real_meshes_equals_the_cpu() {
    let Some(e) = gpu() else { return };
    let mut meshes = vec![(
        "spot.obj",
        mesh::load_file(&data("spot.obj"), usize::MAX).unwrap(),
    )];
    if let Some(dir) = shared_meshes() {
        for name in ["teapot.obj", "stanford-bunny.obj", "2CylinderEngine.gltf"] {
            meshes.push((name, mesh::load_file(&dir.join(name), usize::MAX).unwrap()));
        }
    }
    for (name, m) in &meshes {
        let (lo, hi) = m.bounds();
        for n in [48, 128] {
            let g = Grid::fit(
                lo,
                hi,
                GridSpec::Resolution { n, cubic: false },
                1,
                Default::default(),
            )
            .unwrap();
            let gm = GridMesh::new(m, &g).unwrap();
            for t in [222, 700] {
                check_distance(e, &gm, t, &format!("{name} at {n}"));
            }
        }
    }
}
