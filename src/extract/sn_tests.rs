//! Surface nets checked by the project's mesh checks on random bit volumes (every pinched
//! configuration occurs), on the configurations that make naive surface nets non-manifold, and
//! on distance and density volumes of a sphere against the sphere itself.

use super::check::check;
use super::surface_nets::{Field, surface_nets};
use super::tests::random_bits;
use crate::cancel::Control;
use crate::grid::Grid;
use crate::testkit::Rng;
use crate::volume::{BitVolume, Dense, DensityVolume, Volume};

fn grid(dims: [u32; 3]) -> Grid {
    Grid {
        origin: [0.0; 3],
        voxel_size: 1.0,
        dims,
    }
}

fn valid(v: &Volume) -> super::TriMesh {
    let m = surface_nets(&Field::of(v), &Control::none()).unwrap();
    let r = check(&m);
    assert!(r.is_valid(), "{r:?}");
    m
}

#[test]
fn random_bit_volumes_give_valid_manifold_meshes() {
    let mut rng = Rng::new(35);
    for case in 0..600 {
        let b = random_bits(&mut rng, grid, 8, [0.2, 0.35, 0.5, 0.65, 0.8][case % 5]);
        let n = b.count_ones();
        let m = valid(&Volume::Bits(b));
        assert_eq!(m.triangles.is_empty(), n == 0);
        // Every vertex manifold: its triangles form one fan (edges checked by `check`; here
        // the fan around each vertex is a single cycle).
        let mut around: std::collections::HashMap<u32, Vec<(u32, u32)>> = Default::default();
        for t in &m.triangles {
            for i in 0..3 {
                around
                    .entry(t[i])
                    .or_default()
                    .push((t[(i + 1) % 3], t[(i + 2) % 3]));
            }
        }
        for (v, fan) in around {
            let next: std::collections::HashMap<u32, u32> = fan.iter().copied().collect();
            let mut at = fan[0].0;
            let mut steps = 0;
            loop {
                at = next[&at];
                steps += 1;
                if at == fan[0].0 {
                    break;
                }
                assert!(steps <= fan.len(), "vertex {v}");
            }
            assert_eq!(steps, fan.len(), "vertex {v} is not a disk");
        }
    }
}

#[test]
fn pinched_edges_joined_through_a_block_stay_manifold() {
    // Two set voxels meeting along an edge, joined around it through the layer behind them
    // (six set voxels around two unset ones): naive surface nets joins two sheets there.
    for behind in [[true, true, true, true], [true, true, true, false]] {
        let mut b = BitVolume::new(grid([4, 4, 4]));
        b.set(1, 1, 1, true);
        b.set(2, 2, 1, true);
        let far = [(1, 1), (2, 2), (2, 1), (1, 2)];
        for (i, &(x, y)) in far.iter().enumerate() {
            if behind[i] {
                b.set(x, y, 2, true);
            }
        }
        valid(&Volume::Bits(b));
    }
}

fn sphere(dims: u32, r: f64) -> (Grid, impl Fn(u32, u32, u32) -> f64) {
    let c = f64::from(dims) / 2.0;
    let g = grid([dims; 3]);
    (g, move |x: u32, y: u32, z: u32| {
        let p = [x, y, z].map(|i| f64::from(i) + 0.5 - c);
        (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() - r
    })
}

#[test]
fn distance_and_density_spheres_lie_on_the_sphere() {
    let (r, n) = (9.3, 24);
    let (g, f) = sphere(n, r);
    let mut d = Dense::new(g, 0.0f32);
    let mut dens = DensityVolume::new(g, 64);
    for x in 0..n {
        for y in 0..n {
            for z in 0..n {
                d.set(x, y, z, f(x, y, z) as f32);
                // A coverage that falls linearly through the surface over one voxel.
                let cover = (0.5 - f(x, y, z)).clamp(0.0, 1.0);
                dens.set(x, y, z, (cover * 64.0).round() as u8);
            }
        }
    }
    let c = f64::from(n) / 2.0;
    for (v, tol) in [(Volume::Distance(d), 0.05), (Volume::Density(dens), 0.15)] {
        let m = valid(&v);
        let mut worst: f64 = 0.0;
        for p in &m.positions {
            let q = p.map(|k| k - c);
            let rr = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt();
            worst = worst.max((rr - r).abs());
        }
        assert!(
            worst < tol,
            "{:?}: vertex {worst} voxels off the sphere",
            v.kind()
        );
        let vol = check(&m).volume;
        let exact = 4.0 / 3.0 * std::f64::consts::PI * r * r * r;
        assert!(
            (vol / exact - 1.0).abs() < 0.02,
            "{:?}: {vol} vs {exact}",
            v.kind()
        );
    }
}

#[test]
fn bit_sphere_is_smoothed_within_its_cells() {
    let (r, n) = (9.3, 24);
    let (g, f) = sphere(n, r);
    let mut b = BitVolume::new(g);
    for x in 0..n {
        for y in 0..n {
            for z in 0..n {
                b.set(x, y, z, f(x, y, z) < 0.0);
            }
        }
    }
    let count = b.count_ones() as f64;
    let m = valid(&Volume::Bits(b));
    let c = f64::from(n) / 2.0;
    let mut worst: f64 = 0.0;
    for p in &m.positions {
        let q = p.map(|k| k - c);
        worst = worst.max(((q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt() - r).abs());
    }
    // Within a voxel of the sphere (vertices stay in their cells), and far smoother than the
    // voxels' steps: the volume within 2% of the voxel count's.
    assert!(worst < 1.0, "{worst}");
    let vol = check(&m).volume;
    assert!((vol / count - 1.0).abs() < 0.02, "{vol} vs {count}");
}

/// The largest distance (in voxels, on any axis) between the relaxed positions surface nets
/// gives for `b` (in f32, on offsets) and the relaxation by its definition in f64: each step
/// every vertex to p + f·(mean of its quad neighbours − p), clamped to its cell shrunk by 1/16.
fn relax_error(b: &BitVolume) -> f64 {
    let v = Volume::Bits(b.clone());
    let field = Field::of(&v);
    let got = surface_nets(&field, &Control::none()).unwrap();
    let net = super::surface_nets::net(&field, false, &Control::none()).unwrap();
    let nb = super::relax::quad_neighbours(&net.quads, net.cells.len());
    let cell = |v: usize| net.cells[v].map(f64::from);
    let mut p: Vec<[f64; 3]> = (0..nb.len())
        .map(|v| [0, 1, 2].map(|k| cell(v)[k] + f64::from(net.offsets[v][k])))
        .collect();
    let half = 0.5 - 1.0 / 16.0;
    for _ in 0..super::surface_nets::RELAX {
        for f in [0.5, -0.5263157894736842] {
            p = (0..nb.len())
                .map(|v| {
                    let c = cell(v);
                    [0, 1, 2].map(|k| {
                        let mean = nb[v].iter().map(|&w| p[w][k]).sum::<f64>() / nb[v].len() as f64;
                        (p[v][k] + f * (mean - p[v][k])).clamp(c[k] - half, c[k] + half)
                    })
                })
                .collect();
        }
    }
    assert_eq!(got.positions.len(), p.len());
    got.positions
        .iter()
        .zip(&p)
        .flat_map(|(a, b)| (0..3).map(move |k| (a[k] - b[k]).abs()))
        .fold(0.0, f64::max)
}

#[test]
fn relaxation_in_f32_is_within_its_bound_of_f64() {
    // The rounds work in f32 on offsets from the lattice points: a rounding of at most 2⁻²⁴
    // voxel a step on any grid, so after 24 steps (whose linear part amplifies an error at
    // most 2.06 times a round) well within 10⁻⁵ voxel of the f64 relaxation: checked on a
    // sphere far from the origin and on random blobs.
    let (g, f) = sphere(48, 19.7);
    let mut b = BitVolume::new(g);
    for x in 0..48 {
        for y in 0..48 {
            for z in 0..48 {
                b.set(x, y, z, f(x, y, z) < 0.0);
            }
        }
    }
    let e = relax_error(&b);
    assert!(e < 1e-5, "{e}");
    let mut rng = Rng::new(53);
    for case in 0..4 {
        let b = crate::testkit::random_bit_volume(&mut rng, grid([20, 17, 23]), 0.5);
        let e = relax_error(&b);
        assert!(e < 1e-5, "case {case}: {e}");
    }
}

/// The same on a `.vxl` bit volume named by `VOXD_RELAX_VXL` (igea-subdiv4 at 518³ for
/// `docs/methods.md`): `cargo test --release --lib relaxation_error_of -- --ignored
/// --nocapture`.
#[test]
#[ignore = "reads a volume named by VOXD_RELAX_VXL"]
fn relaxation_error_of_a_volume() {
    let path = std::env::var("VOXD_RELAX_VXL").expect("VOXD_RELAX_VXL");
    let (v, _) = crate::codec::vxl::decode(&std::fs::read(path).unwrap()).unwrap();
    let Volume::Bits(b) = v else {
        panic!("a bit volume")
    };
    println!("relaxation f32 vs f64: max {:e} voxel", relax_error(&b));
}

#[test]
fn a_canceled_surface_net_stops() {
    let mut b = BitVolume::new(grid([4, 4, 4]));
    b.set(1, 1, 1, true);
    let ctl = Control::new();
    ctl.cancel();
    assert!(surface_nets(&Field::of(&Volume::Bits(b)), &ctl).is_err());
}

mod marching {
    use super::*;
    use crate::extract::marching_cubes::marching_cubes;

    fn valid_mc(v: &Volume) -> crate::extract::TriMesh {
        let m = marching_cubes(&Field::of(v), &Control::none()).unwrap();
        let r = check(&m);
        assert!(r.is_valid(), "{r:?}");
        m
    }

    #[test]
    fn one_voxel_is_an_octahedron_facing_out() {
        let mut b = BitVolume::new(grid([3, 3, 3]));
        b.set(1, 1, 1, true);
        let m = valid_mc(&Volume::Bits(b));
        assert_eq!((m.positions.len(), m.triangles.len()), (6, 8));
        assert!((check(&m).volume - 1.0 / 6.0).abs() < 1e-12);
    }

    #[test]
    fn random_bit_volumes_give_valid_meshes() {
        let mut rng = Rng::new(36);
        for case in 0..400 {
            let b = random_bits(&mut rng, grid, 8, [0.2, 0.35, 0.5, 0.65, 0.8][case % 5]);
            valid_mc(&Volume::Bits(b));
        }
    }

    #[test]
    fn a_distance_sphere_lies_on_the_sphere() {
        let (r, n) = (9.3, 24);
        let (g, f) = sphere(n, r);
        let mut d = Dense::new(g, 0.0f32);
        for x in 0..n {
            for y in 0..n {
                for z in 0..n {
                    d.set(x, y, z, f(x, y, z) as f32);
                }
            }
        }
        let m = valid_mc(&Volume::Distance(d));
        let c = f64::from(n) / 2.0;
        // The crossings lie on the sphere to the linear interpolation's error (the added
        // centroids of larger polygons are not checked).
        let mut worst: f64 = 0.0;
        for p in &m.positions {
            let q = p.map(|k| k - c);
            let rr = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt();
            worst = worst.max((rr - r).abs());
        }
        assert!(worst < 0.1, "{worst}");
        let vol = check(&m).volume;
        let exact = 4.0 / 3.0 * std::f64::consts::PI * r * r * r;
        assert!((vol / exact - 1.0).abs() < 0.02, "{vol} vs {exact}");
    }
}

/// A sparse distance volume's inside, taken brick by brick, is the voxels with the sign bit set
/// (read one by one): bricks with random signs, negative and positive tiles, a grid that ends
/// inside its last bricks.
#[test]
fn a_sparse_volumes_inside_is_its_negative_voxels() {
    use crate::volume::Sparse;
    let g = crate::grid::Grid {
        origin: [0.0; 3],
        voxel_size: 1.0,
        dims: [21, 17, 70],
    };
    let mut s = 0x853c_49e6_748f_ea9bu64;
    let mut r = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        s
    };
    for tile in [-3.0f32, 3.0] {
        let mut v = Sparse::with_tile_value(g, 3.0, tile);
        let bd = v.brick_dims();
        for bx in 0..bd[0] {
            for by in 0..bd[1] {
                for bz in 0..bd[2] {
                    match r() % 4 {
                        0 => v.set_tile([bx, by, bz], true).unwrap(),
                        1 => {
                            // The background past the grid, as a brick must hold.
                            let vals = std::array::from_fn(|i| {
                                let (dx, dy, dz) = (i as u32 / 64, i as u32 / 8 % 8, i as u32 % 8);
                                let p = [bx * 8 + dx, by * 8 + dy, bz * 8 + dz];
                                if p[0] >= 21 || p[1] >= 17 || p[2] >= 70 {
                                    return 3.0;
                                }
                                match r() % 3 {
                                    0 => -0.0,
                                    1 => -1.5,
                                    _ => 0.5,
                                }
                            });
                            v.insert_brick([bx, by, bz], vals).unwrap();
                        }
                        _ => {}
                    }
                }
            }
        }
        let vol = Volume::SparseDistance(v.clone());
        let bits = super::surface_nets::inside(&vol);
        let mut n = 0;
        for x in 0..21 {
            for y in 0..17 {
                for z in 0..70 {
                    let want = v.get(x, y, z).is_sign_negative();
                    assert_eq!(bits.get(x, y, z), want, "{x} {y} {z} tile {tile}");
                    n += usize::from(want);
                }
            }
        }
        assert!(n > 1000, "{n}");
    }
}

#[test]
fn a_net_built_in_runs_is_the_net_built_in_one() {
    // Runs of a few faces join at shared slabs; built in one run nothing is joined. Same
    // vertices (numbered the same), quads, crossings and cells; sums equal up to the order of
    // their additions.
    use super::surface_nets::net_in_runs;
    let mut rng = Rng::new(36);
    let mut volumes: Vec<Volume> = (0..40)
        .map(|case| Volume::Bits(random_bits(&mut rng, grid, 9, [0.3, 0.5, 0.7][case % 3])))
        .collect();
    let (g, f) = sphere(20, 6.3);
    let mut d = Dense::<f32>::new(g, 0.0);
    for x in 0..20 {
        for y in 0..20 {
            for z in 0..20 {
                d.set(x, y, z, f(x, y, z) as f32);
            }
        }
    }
    volumes.push(Volume::Distance(d));
    for (case, v) in volumes.iter().enumerate() {
        let field = Field::of(v);
        let one = net_in_runs(&field, true, &Control::none(), usize::MAX).unwrap();
        // Without the crossings: the same net, the crossings left out.
        let bare = net_in_runs(&field, false, &Control::none(), 50).unwrap();
        assert!(bare.crossings.is_empty());
        assert_eq!(one.crossings.len(), one.faces.len());
        assert_eq!(bare.quads, one.quads, "case {case}");
        assert_eq!(bare.cells, one.cells, "case {case}");
        for run_faces in [1, 7, 50] {
            let runs = net_in_runs(&field, true, &Control::none(), run_faces).unwrap();
            assert_eq!(runs.vertices, one.vertices, "case {case}");
            assert_eq!(runs.quads, one.quads, "case {case}");
            assert_eq!(runs.cells, one.cells, "case {case}");
            assert_eq!(runs.crossings, one.crossings, "case {case}");
            assert_eq!(runs.offsets, one.offsets, "case {case}");
            for (a, b) in runs.sums.iter().zip(&one.sums) {
                for k in 0..4 {
                    assert!(
                        (a[k] - b[k]).abs() <= 1e-9 * b[k].abs().max(1.0),
                        "case {case}"
                    );
                }
                // Every vertex is in at least three quads (a closed 2-manifold).
                assert!(a[3] >= 3.0, "case {case}");
            }
        }
        // A valued field has sums, a bit volume offsets: each vertex's mean of the crossings
        // (for bits, the faces' centres) of the quads it is a corner of, less its lattice
        // point, summed here from the quads.
        assert_eq!(
            one.sums.len(),
            if matches!(v, Volume::Bits(_)) {
                0
            } else {
                one.vertices
            }
        );
        assert_eq!(
            one.offsets.len(),
            if matches!(v, Volume::Bits(_)) {
                one.vertices
            } else {
                0
            }
        );
        if matches!(v, Volume::Bits(_)) {
            let mut sum = vec![[0.0f64; 4]; one.vertices];
            for (q, c) in one.quads.iter().zip(&one.crossings) {
                for &i in q {
                    let s = &mut sum[i as usize];
                    for k in 0..3 {
                        s[k] += c[k];
                    }
                    s[3] += 1.0;
                }
            }
            for ((s, o), cell) in sum.iter().zip(&one.offsets).zip(&one.cells) {
                let want = [0, 1, 2].map(|k| (s[k] / s[3] - f64::from(cell[k])) as f32);
                assert_eq!(o[..3], want, "case {case}");
                assert_eq!(o[3], 0.0);
            }
        }
    }
}

#[test]
fn the_faces_counted_are_the_faces_found() {
    // `plane_counts_and_pinches` counts by words, layer by layer, what `faces_at` finds bit by
    // bit on each plane, on every plane, including grids whose z is a multiple of 64 (the top
    // face pushed separately) and thin ones; and its pinched edges are those found voxel by
    // voxel: two diagonal voxels of the four around a lattice edge set, the other two not.
    use super::faces::plane_counts_and_pinches;
    use super::surface_nets::faces_at;
    let mut rng = Rng::new(37);
    for case in 0..60 {
        let dims = [
            1 + rng.below(9) as u32,
            1 + rng.below(9) as u32,
            [1, 5, 63, 64, 65, 128, 130][case % 7],
        ];
        let b = crate::testkit::random_bit_volume(&mut rng, grid(dims), [0.1, 0.5, 0.9][case % 3]);
        let (counts, mut edges) = plane_counts_and_pinches(&b, &Control::none()).unwrap();
        assert_eq!(counts.len(), dims[0] as usize + 1, "case {case}");
        let mut faces = Vec::new();
        let mut total = 0;
        for x in 0..=dims[0] {
            faces.clear();
            faces_at(&b, x, &mut faces);
            assert_eq!(counts[x as usize], faces.len(), "case {case} plane {x}");
            total += faces.len();
        }
        let on = |p: [i64; 3]| {
            (0..3).all(|a| p[a] >= 0 && p[a] < i64::from(dims[a]))
                && b.get(p[0] as u32, p[1] as u32, p[2] as u32)
        };
        let mut want = Vec::new();
        for e in 0..3 {
            let (u, v) = ((e + 1) % 3, (e + 2) % 3);
            // Edge along e from lattice point p: the voxels p − 1 + (i, j) on axes u, v.
            for px in 0..=i64::from(dims[0]) {
                for py in 0..=i64::from(dims[1]) {
                    for pz in 0..=i64::from(dims[2]) {
                        let p = [px, py, pz];
                        if p[e] >= i64::from(dims[e]) {
                            continue;
                        }
                        let q = |i: i64, j: i64| {
                            let mut c = p;
                            c[u] += i - 1;
                            c[v] += j - 1;
                            on(c)
                        };
                        let (a, bb, c, d) = (q(0, 0), q(1, 1), q(1, 0), q(0, 1));
                        if a == bb && c == d && a != c {
                            want.push(([px as u32, py as u32, pz as u32], e as u8));
                        }
                    }
                }
            }
        }
        want.sort_unstable();
        edges.sort_unstable();
        assert_eq!(edges, want, "case {case}");
        // A volume with a set voxel has faces.
        assert_eq!(total > 0, b.count_ones() > 0, "case {case}");
    }
}
