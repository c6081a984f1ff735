//! Meshes and volumes made for the tests: boxes, octahedra, spheres, random closed meshes and
//! triangle soups, random volumes, and what the library gives for a mesh file (the reference a
//! front's output is compared with). Not the oracles (`oracles`), which say what a method should
//! give without the library.

use voxd::engine::cpu::CpuEngine;
use voxd::engine::{Engine, GridMesh, Method};
use voxd::grid::{Grid, GridSpec};
use voxd::mesh::Mesh;
use voxd::volume::BitVolume;

use super::Rng;

/// The closed, outward-oriented box [lo, hi] as a mesh.
pub fn box_mesh(lo: [f64; 3], hi: [f64; 3]) -> Mesh {
    let (mut p, mut t) = (vec![], vec![]);
    push_box(&mut p, &mut t, lo, hi);
    Mesh::new(p, t).unwrap()
}

/// Appends a closed, outward-oriented box [lo, hi] to a triangle list.
pub fn push_box(p: &mut Vec<[f64; 3]>, t: &mut Vec<[u32; 3]>, lo: [f64; 3], hi: [f64; 3]) {
    let b = p.len() as u32;
    for i in 0..8 {
        p.push([
            if i & 1 == 0 { lo[0] } else { hi[0] },
            if i & 2 == 0 { lo[1] } else { hi[1] },
            if i & 4 == 0 { lo[2] } else { hi[2] },
        ]);
    }
    for f in [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ] {
        t.push([b + f[0], b + f[1], b + f[2]]);
        t.push([b + f[0], b + f[2], b + f[3]]);
    }
}

/// Appends a closed, outward-oriented octahedron.
pub fn push_octahedron(p: &mut Vec<[f64; 3]>, t: &mut Vec<[u32; 3]>, c: [f64; 3], r: [f64; 3]) {
    let b = p.len() as u32;
    for (a, s) in [
        (0, 1.0),
        (0, -1.0),
        (1, 1.0),
        (1, -1.0),
        (2, 1.0),
        (2, -1.0),
    ] {
        let mut q = c;
        q[a] += s * r[a];
        p.push(q);
    }
    // +x 0, -x 1, +y 2, -y 3, +z 4, -z 5
    for f in [
        [0, 2, 4],
        [2, 1, 4],
        [1, 3, 4],
        [3, 0, 4],
        [2, 0, 5],
        [1, 2, 5],
        [3, 1, 5],
        [0, 3, 5],
    ] {
        t.push([b + f[0], b + f[1], b + f[2]]);
    }
}

/// Appends a closed, outward-oriented tetrahedron with the given corners.
pub fn push_tetrahedron(p: &mut Vec<[f64; 3]>, t: &mut Vec<[u32; 3]>, v: [[f64; 3]; 4]) {
    let b = p.len() as u32;
    let s = |u: [f64; 3], w: [f64; 3]| [u[0] - w[0], u[1] - w[1], u[2] - w[2]];
    let (e1, e2, e3) = (s(v[1], v[0]), s(v[2], v[0]), s(v[3], v[0]));
    let vol = e1[0] * (e2[1] * e3[2] - e2[2] * e3[1]) - e1[1] * (e2[0] * e3[2] - e2[2] * e3[0])
        + e1[2] * (e2[0] * e3[1] - e2[1] * e3[0]);
    let v = if vol < 0.0 {
        [v[0], v[2], v[1], v[3]]
    } else {
        v
    };
    p.extend_from_slice(&v);
    for f in [[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]] {
        t.push([b + f[0], b + f[1], b + f[2]]);
    }
}

/// Random closed solids (boxes, octahedra, tetrahedra; overlapping) with vertices on the
/// half-voxel lattice of a unit grid at the origin, so many vertices sit on column centres and
/// faces on voxel faces. Some reach outside the grid and below it.
pub fn random_closed(rng: &mut Rng, dims: [u32; 3]) -> Mesh {
    let (mut p, mut t) = (vec![], vec![]);
    let d = dims.map(|d| d as f64);
    for _ in 0..1 + rng.below(4) {
        match rng.below(3) {
            0 => {
                let lo = [0, 1, 2].map(|a| rng.half(-1.5, d[a]));
                let hi =
                    [0, 1, 2].map(|a| lo[a] + rng.half(0.5, d[a] + 1.0 - lo[a].max(0.0)).max(0.5));
                push_box(&mut p, &mut t, lo, hi);
            }
            1 => {
                let c = [0, 1, 2].map(|a| rng.half(0.0, d[a]));
                let r = [0, 1, 2].map(|a| rng.half(0.5, (d[a] / 2.0).max(1.0)));
                push_octahedron(&mut p, &mut t, c, r);
            }
            _ => {
                let v = [0; 4].map(|_| [0, 1, 2].map(|a| rng.half(-1.0, d[a] + 1.0)));
                push_tetrahedron(&mut p, &mut t, v);
            }
        }
    }
    Mesh::new(p, t).unwrap()
}

/// A random triangle soup: lattice and off-lattice vertices, degenerate and vertical triangles,
/// triangles outside the grid, below it and above it.
pub fn random_soup(rng: &mut Rng, dims: [u32; 3]) -> Mesh {
    let d = dims.map(|d| d as f64);
    let mut p = vec![];
    let mut t = vec![];
    for _ in 0..1 + rng.below(12) {
        let b = p.len() as u32;
        let mut v = [0; 3].map(|_| {
            [0, 1, 2].map(|a| {
                if rng.below(2) == 0 {
                    rng.half(-2.0, d[a] + 2.0)
                } else {
                    rng.range(-2.0, d[a] + 2.0)
                }
            })
        });
        match rng.below(6) {
            0 => v[2] = v[1],                                         // two corners coincide
            1 => v[2] = [0, 1, 2].map(|a| (v[0][a] + v[1][a]) / 2.0), // collinear
            2 => v[2] = [v[0][0], v[0][1], v[1][2] + 1.5],            // vertical
            3 => v.iter_mut().for_each(|q| q[2] -= d[2] + 5.0),       // below the grid
            _ => {}
        }
        p.extend_from_slice(&v);
        t.push([b, b + 1, b + 2]);
    }
    Mesh::new(p, t).unwrap()
}

/// The unit lattice: origin 0, voxels of size 1, so a mesh's coordinates are voxel coordinates.
pub fn unit_grid(dims: [u32; 3]) -> Grid {
    Grid {
        origin: [0.0; 3],
        voxel_size: 1.0,
        dims,
    }
}

/// A grid that is not the unit lattice (odd origin, voxel size 0.93), so that snapping a mesh
/// made on the unit lattice rounds.
pub fn off_lattice_grid(dims: [u32; 3]) -> Grid {
    Grid {
        origin: [-0.37, 0.11, -0.5],
        voxel_size: 0.93,
        dims,
    }
}

/// Describes the first difference between two volumes, for assertion messages.
pub fn first_difference(a: &BitVolume, b: &BitVolume) -> Option<String> {
    let [nx, ny, nz] = a.dims();
    for x in 0..nx {
        for y in 0..ny {
            for z in 0..nz {
                if a.get(x, y, z) != b.get(x, y, z) {
                    let n = a
                        .words()
                        .iter()
                        .zip(b.words())
                        .map(|(p, q)| (p ^ q).count_ones() as u64)
                        .sum::<u64>();
                    return Some(format!(
                        "voxel ({x},{y},{z}): {} vs {}; {n} voxels differ",
                        a.get(x, y, z),
                        b.get(x, y, z)
                    ));
                }
            }
        }
    }
    None
}

/// A volume on `g` with each voxel set with a random probability chosen per volume.
pub fn random_fill(rng: &mut Rng, g: Grid) -> BitVolume {
    let mut v = BitVolume::new(g);
    let fill = rng.below(100);
    for x in 0..g.dims[0] {
        for y in 0..g.dims[1] {
            for z in 0..g.dims[2] {
                if rng.below(100) < fill {
                    v.set(x, y, z, true);
                }
            }
        }
    }
    v
}

/// "X Y Z count Σx Σy Σz" of a volume: what the Python checks print for it.
pub fn summary(v: &BitVolume) -> String {
    let s = v.iter_ones().fold([0u64; 3], |a, p| {
        [a[0] + p[0] as u64, a[1] + p[1] as u64, a[2] + p[2] as u64]
    });
    let d = v.dims();
    format!(
        "{} {} {} {} {} {} {}",
        d[0],
        d[1],
        d[2],
        v.count_ones(),
        s[0],
        s[1],
        s[2]
    )
}

/// A random closed mesh on even seeds, a random triangle soup on odd ones.
pub fn random_mesh(rng: &mut Rng, dims: [u32; 3], seed: u64) -> Mesh {
    if seed.is_multiple_of(2) {
        random_closed(rng, dims)
    } else {
        random_soup(rng, dims)
    }
}

/// An octahedron subdivided `levels` times onto the sphere of `radius` around `centre`.
pub fn sphere(centre: [f64; 3], radius: f64, levels: u32) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let (mut p, mut t) = (vec![], vec![]);
    push_octahedron(&mut p, &mut t, [0.0; 3], [1.0; 3]);
    for _ in 0..levels {
        let mut nt = vec![];
        for tri in &t {
            let [a, b, c]: [u32; 3] = *tri;
            let mut mid = |i: u32, j: u32| {
                let (u, v) = (p[i as usize], p[j as usize]);
                p.push([0, 1, 2].map(|k| (u[k] + v[k]) / 2.0));
                p.len() as u32 - 1
            };
            let (ab, bc, ca) = (mid(a, b), mid(b, c), mid(c, a));
            nt.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        t = nt;
    }
    let p = p
        .iter()
        .map(|q| {
            let l = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt();
            [0, 1, 2].map(|k| centre[k] + radius * q[k] / l)
        })
        .collect();
    (p, t)
}

/// A mesh file and the grid `spec` (plus `padding`) fits to it.
pub fn mesh_and_grid(path: &std::path::Path, spec: GridSpec, padding: u32) -> (Mesh, Grid) {
    let mesh = voxd::mesh::load_file(path, usize::MAX).unwrap();
    let (lo, hi) = mesh.bounds();
    let g = Grid::fit(lo, hi, spec, padding, Default::default()).unwrap();
    (mesh, g)
}

/// What the library (and so the CLI and the service) gives for a mesh file, grid and method.
pub fn voxelize_file(path: &std::path::Path, spec: GridSpec, padding: u32, m: Method) -> BitVolume {
    let (mesh, g) = mesh_and_grid(path, spec, padding);
    CpuEngine
        .voxelize(&GridMesh::new(&mesh, &g).unwrap(), m)
        .unwrap()
}

/// The mesh as OBJ text.
pub fn to_obj(mesh: &Mesh) -> Vec<u8> {
    let mut s = String::new();
    for p in mesh.positions() {
        s += &format!("v {} {} {}\n", p[0], p[1], p[2]);
    }
    for t in mesh.triangles() {
        s += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    s.into_bytes()
}

/// An OBJ of closed, outward boxes [lo, hi], each with its `usemtl` name, reading the material
/// library `mtllib`: the colour tests' models.
pub fn material_boxes_obj(mtllib: &str, boxes: &[(&str, [f64; 3], [f64; 3])]) -> String {
    let (mut p, mut t) = (vec![], vec![]);
    let mut s = format!("mtllib {mtllib}\n");
    for &(name, lo, hi) in boxes {
        let first = t.len();
        push_box(&mut p, &mut t, lo, hi);
        s += &format!("usemtl {name}\n");
        for f in &t[first..] {
            s += &format!("f {} {} {}\n", f[0] + 1, f[1] + 1, f[2] + 1);
        }
    }
    let vertices: String = p
        .iter()
        .map(|q| format!("v {} {} {}\n", q[0], q[1], q[2]))
        .collect();
    vertices + &s
}

/// A sphere with its top cut off (an open bowl) and one more triangle missing: not watertight,
/// and parity streaks on it.
pub fn open_bowl() -> Mesh {
    let (p, mut t) = sphere([0.1, -0.2, 0.05], 1.0, 3);
    t.retain(|tri| tri.iter().map(|&v| p[v as usize][2]).sum::<f64>() / 3.0 < 0.6);
    t.remove(7);
    Mesh::new(p, t).unwrap()
}
