//! Extraction checked by the project's own mesh checks, exact volumes, and re-voxelization
//! (the solid kernel on the extracted mesh gives back the volume).

use super::TriMesh;
use super::check::check;
use super::cubes::{cubes, triangle_bound};
use super::write::{MeshFormat, encoded_len, write};
use crate::cancel::Control;
use crate::engine::Method;
use crate::engine::cpu::CpuEngine;
use crate::engine::fill::{self, Fill};
use crate::grid::Grid;
use crate::mesh::Mesh;
use crate::testkit::Rng;
use crate::volume::BitVolume;

fn grid(dims: [u32; 3]) -> Grid {
    Grid {
        origin: [-1.25, 0.5, 2.0],
        voxel_size: 0.125,
        dims,
    }
}

/// Cubes of `bits`: valid, volume = count exactly, face count as estimated, and the solid of
/// the mesh on the same grid is `bits` again.
fn round_trip(bits: &BitVolume) -> TriMesh {
    let m = cubes(bits, &Control::none()).unwrap();
    let r = check(&m);
    assert!(r.is_valid(), "{r:?}");
    assert_eq!(r.volume, bits.count_ones() as f64, "{r:?}");
    assert!(r.triangles as u64 <= triangle_bound(bits), "{r:?}");
    let g = *bits.grid();
    let world = m.clone().to_world(&g);
    if world.triangles.is_empty() {
        assert_eq!(bits.count_ones(), 0);
        return m;
    }
    let mesh = Mesh::new(world.positions, world.triangles).unwrap();
    let diag = mesh.diagnostics();
    let (again, _) = fill::voxelize_with(
        &CpuEngine,
        &mesh,
        &g,
        Method::Solid,
        Fill::Parity,
        &diag,
        &Control::none(),
    )
    .unwrap();
    assert_eq!(again.words(), bits.words(), "re-voxelized");
    m
}

#[test]
fn one_voxel_is_a_cube_of_twelve_triangles() {
    let mut b = BitVolume::new(grid([3, 3, 3]));
    b.set(1, 1, 1, true);
    let m = round_trip(&b);
    assert_eq!((m.positions.len(), m.triangles.len()), (8, 12));
}

#[test]
fn a_box_merges_to_twelve_triangles_and_a_notch_adds_no_t_junction() {
    let mut b = BitVolume::new(grid([9, 7, 5]));
    for x in 1..8 {
        for y in 1..6 {
            for z in 1..4 {
                b.set(x, y, z, true);
            }
        }
    }
    let m = round_trip(&b);
    assert_eq!(m.triangles.len(), 12);
    // A notch: the faces around it split, and the big faces' sides carry its corners.
    b.set(4, 5, 3, false);
    round_trip(&b);
}

/// Voxels meeting only along an edge or at a point: each gets its own copies of the shared
/// vertices, so every edge is used by exactly two triangles.
#[test]
fn edge_and_point_contacts_stay_manifold() {
    let mut b = BitVolume::new(grid([4, 4, 4]));
    b.set(1, 1, 1, true);
    b.set(2, 2, 1, true); // along an edge
    b.set(2, 1, 2, true); // along another edge of the first... and a point of the second
    round_trip(&b);
    let mut c = BitVolume::new(grid([4, 4, 4]));
    c.set(1, 1, 1, true);
    c.set(2, 2, 2, true); // a point
    let m = round_trip(&c);
    assert_eq!(m.positions.len(), 16);
    // Six voxels of a 2×2×2 block, the two missing ones opposite: the empty ones meet at a point.
    let mut d = BitVolume::new(grid([4, 4, 4]));
    for o in 1..7u32 {
        d.set(1 + (o & 1), 1 + (o >> 1 & 1), 1 + (o >> 2 & 1), true);
    }
    round_trip(&d);
}

/// A volume on `grid(dims)` with dims drawn from 1..=max_dim, each voxel set with
/// probability `p` (voxels on the grid's faces too).
pub(super) fn random_bits(
    rng: &mut Rng,
    grid: impl Fn([u32; 3]) -> Grid,
    max_dim: usize,
    p: f64,
) -> BitVolume {
    let dims = [0; 3].map(|_| 1 + rng.below(max_dim) as u32);
    crate::testkit::random_bit_volume(rng, grid(dims), p)
}

#[test]
fn random_volumes_round_trip() {
    let mut rng = Rng::new(33);
    for case in 0..60 {
        // Sparse, dense and blocky volumes.
        let b = random_bits(&mut rng, grid, 9, [0.1, 0.5, 0.85][case % 3]);
        let dims = b.dims();
        assert_eq!(triangle_bound(&b), brute_bound(&b), "{dims:?}");
        round_trip(&b);
    }
}

/// The triangle bound, counted voxel by voxel: 3 per boundary face, 12 per pinched edge.
fn brute_bound(b: &BitVolume) -> u64 {
    let d = b.dims().map(i64::from);
    let at = |p: [i64; 3]| {
        (0..3).all(|a| p[a] >= 0 && p[a] < d[a]) && b.get(p[0] as u32, p[1] as u32, p[2] as u32)
    };
    let mut n = 0;
    for x in -1..=d[0] {
        for y in -1..=d[1] {
            for z in -1..=d[2] {
                let p = [x, y, z];
                for a in 0..3 {
                    let mut q = p;
                    q[a] += 1;
                    n += 3 * u64::from(at(p) != at(q));
                    // The edge along a through the corner p + 1 (in the other two axes): the
                    // four voxels p, p + e_b, p + e_c, p + e_b + e_c.
                    let (bb, cc) = ((a + 1) % 3, (a + 2) % 3);
                    let (mut pb, mut pc, mut pbc) = (p, p, p);
                    pb[bb] += 1;
                    pc[cc] += 1;
                    pbc[bb] += 1;
                    pbc[cc] += 1;
                    let (v0, v1, v2, v3) = (at(p), at(pb), at(pc), at(pbc));
                    n += 12 * u64::from(v0 == v3 && v1 == v2 && v0 != v1);
                }
            }
        }
    }
    n
}

#[test]
fn columns_longer_than_a_word_round_trip_and_bound() {
    let mut rng = Rng::new(34);
    for (case, dims) in [
        [2, 3, 64],
        [3, 2, 65],
        [2, 2, 128],
        [3, 3, 130],
        [1, 4, 200],
    ]
    .into_iter()
    .enumerate()
    {
        for p in [0.1, 0.5, 0.9] {
            let mut b = BitVolume::new(grid(dims));
            for x in 0..dims[0] {
                for y in 0..dims[1] {
                    for z in 0..dims[2] {
                        // Runs across the word boundaries as well as single voxels.
                        if rng.unit() < p || (case % 2 == 0 && (60..70).contains(&z)) {
                            b.set(x, y, z, true);
                        }
                    }
                }
            }
            assert_eq!(triangle_bound(&b), brute_bound(&b), "{dims:?} {p}");
            round_trip(&b);
        }
    }
}

#[test]
fn files_hold_the_mesh() {
    let mut b = BitVolume::new(grid([5, 4, 3]));
    b.set(1, 1, 1, true);
    b.set(2, 1, 1, true);
    let m = cubes(&b, &Control::none()).unwrap().to_world(b.grid());
    for f in MeshFormat::ALL {
        let mut out = Vec::new();
        write(&m, f, &mut out).unwrap();
        let out_len = out.len() as u64;
        assert!(
            out.len() as u64
                <= f.size_bound(m.positions.len() as u64, m.triangles.len() as u64, false)
        );
        match f {
            MeshFormat::Stl => assert_eq!(out.len(), 84 + 50 * m.triangles.len()),
            MeshFormat::Obj => {
                let text = String::from_utf8(out).unwrap();
                assert_eq!(
                    text.lines().filter(|l| l.starts_with("v ")).count(),
                    m.positions.len()
                );
                assert_eq!(
                    text.lines().filter(|l| l.starts_with("f ")).count(),
                    m.triangles.len()
                );
            }
            MeshFormat::Ply => {
                let end = out.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
                assert_eq!(
                    out.len() - end,
                    24 * m.positions.len() + 13 * m.triangles.len()
                );
            }
            MeshFormat::Glb => {
                // Read back by the gltf crate: the same positions (float32) and triangles.
                let g = gltf::Gltf::from_slice(&out).unwrap();
                let blob = g.blob.as_deref().unwrap();
                let mesh = g.meshes().next().unwrap();
                let prim = mesh.primitives().next().unwrap();
                assert_eq!(prim.mode(), gltf::mesh::Mode::Triangles);
                let reader = prim.reader(|_| Some(blob));
                let pos: Vec<[f32; 3]> = reader.read_positions().unwrap().collect();
                let want: Vec<[f32; 3]> = m.positions.iter().map(|p| p.map(|c| c as f32)).collect();
                assert_eq!(pos, want);
                let idx: Vec<u32> = reader.read_indices().unwrap().into_u32().collect();
                let want: Vec<u32> = m.triangles.iter().flatten().copied().collect();
                assert_eq!(idx, want);
            }
        }
        if let Some(n) = encoded_len(&m, f) {
            assert_eq!(n, out_len, "{f:?}");
        }
    }
}

/// A two-voxel bar, one voxel red and one blue, as cubes: each vertex takes the mean (in linear
/// light) of the colours of the set voxels meeting at it, so the far ends are pure and the
/// shared face's corners the linear mix; the GLB's COLOR_0 (read by the gltf crate) is that in
/// linear f32, the PLY's and OBJ's the sRGB colours; every size within its bound.
#[test]
fn vertex_colours_come_from_the_voxels_meeting_there() {
    use crate::mesh::texture::{linear_to_srgb, srgb_to_linear};
    use crate::volume::{Attributed, ChannelValues};
    let mut b = BitVolume::new(grid([4, 3, 3]));
    b.set(1, 1, 1, true);
    b.set(2, 1, 1, true);
    let mut a = Attributed::new(b.clone());
    let (red, blue) = ([255u8, 0, 0, 255], [0u8, 0, 255, 255]);
    a.add("rgba", ChannelValues::Rgba8(vec![red, blue]))
        .unwrap();
    let mut m = cubes(&b, &Control::none()).unwrap();
    m.colors = super::colour::vertex_colours(&m, &a);
    let mix = (linear_to_srgb(srgb_to_linear(1.0) / 2.0) * 255.0).round() as u8;
    assert_eq!(m.colors.len(), m.positions.len());
    for (p, c) in m.positions.iter().zip(&m.colors) {
        let want = match p[0] as u32 {
            1 => red,
            3 => blue,
            2 => [mix, 0, mix, 255],
            x => panic!("a vertex at x = {x}"),
        };
        assert_eq!(*c, want, "vertex {p:?}");
    }
    let m = m.to_world(b.grid());
    for f in MeshFormat::ALL {
        let mut out = Vec::new();
        write(&m, f, &mut out).unwrap();
        assert!(
            out.len() as u64
                <= f.size_bound(m.positions.len() as u64, m.triangles.len() as u64, true),
            "{f:?}"
        );
        if let Some(n) = encoded_len(&m, f) {
            assert_eq!(n, out.len() as u64, "{f:?}");
        }
        match f {
            MeshFormat::Glb => {
                let g = gltf::Gltf::from_slice(&out).unwrap();
                let blob = g.blob.as_deref().unwrap();
                let prim = g.meshes().next().unwrap().primitives().next().unwrap();
                let reader = prim.reader(|_| Some(blob));
                let got: Vec<[f32; 4]> = reader.read_colors(0).unwrap().into_rgba_f32().collect();
                let lin = crate::mesh::texture::srgb_to_linear_table();
                let want: Vec<[f32; 4]> = m
                    .colors
                    .iter()
                    .map(|c| {
                        [
                            lin[c[0] as usize],
                            lin[c[1] as usize],
                            lin[c[2] as usize],
                            c[3] as f32 / 255.0,
                        ]
                    })
                    .collect();
                assert_eq!(got, want);
            }
            MeshFormat::Ply => {
                let text = String::from_utf8_lossy(&out);
                assert!(text.contains("property uchar red\nproperty uchar green\nproperty uchar blue\nproperty uchar alpha\n"));
                let end = out.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
                // The first vertex's colour follows its three doubles.
                assert_eq!(out[end + 24..end + 28], m.colors[0]);
            }
            MeshFormat::Obj => {
                let text = String::from_utf8(out).unwrap();
                let v = text.lines().find(|l| l.starts_with("v ")).unwrap();
                let n: Vec<f32> = v.split(' ').skip(1).map(|x| x.parse().unwrap()).collect();
                assert_eq!(n.len(), 6);
                assert_eq!(
                    n[3..],
                    m.colors[0][..3]
                        .iter()
                        .map(|&b| f32::from(b) / 255.0)
                        .collect::<Vec<_>>()[..]
                );
            }
            MeshFormat::Stl => {}
        }
    }
}

#[test]
fn a_canceled_extraction_stops() {
    let mut b = BitVolume::new(grid([4, 4, 4]));
    b.set(1, 1, 1, true);
    let ctl = Control::new();
    ctl.cancel();
    assert!(cubes(&b, &ctl).is_err());
}
