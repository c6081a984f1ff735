//! `voxd mesh` (issue 33: meshes back out), on files: a volume's boundary written as OBJ, STL
//! and PLY, each read back two ways — voxelized again by voxd itself (`method=solid`,
//! `fill=parity` on the same grid must give the same bits) and by trimesh, the reader users
//! use (watertight, winding consistent, enclosed volume = set voxels × s³). trimesh comes from
//! the venv scripts/provision.sh makes (`VOXD_MESH_VENV`); it is required where
//! `VOXD_REQUIRE_TRIMESH=1` (scripts/test.sh sets it once the venv imports).

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::common::run_voxd as voxd;
use crate::common::*;
use voxd::codec::VolumeFormat;
use voxd::volume::{BitVolume, Volume};

/// The grid: voxel corners at multiples of 1/8 (exact in f32, so STL's float32 positions are
/// the lattice's exactly).
const GRID: [&str; 6] = [
    "--origin",
    "-3.25,-0.25,-2.25",
    "--voxel-size",
    "0.125",
    "--dims",
    "56,30,38",
];

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn ok(args: &[&str]) -> String {
    let o = voxd(args);
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn bits(p: &Path) -> BitVolume {
    let b = std::fs::read(p).unwrap();
    match VolumeFormat::sniff(&b).unwrap().decode(&b).unwrap() {
        Volume::Bits(b) => b,
        v => panic!("{}: a bit volume, got {:?}", p.display(), v.kind()),
    }
}

/// The trimesh venv's python, or `None` with a notice where it is absent and not required.
pub(crate) fn trimesh_python() -> Option<PathBuf> {
    let venv = std::env::var_os("VOXD_MESH_VENV").map(PathBuf::from);
    let py = venv.map(|v| v.join("bin/python"));
    let works = py.as_ref().is_some_and(|py| {
        Command::new(py)
            .args(["-c", "import trimesh"])
            .output()
            .is_ok_and(|o| o.status.success())
    });
    if works {
        return py;
    }
    assert!(
        std::env::var("VOXD_REQUIRE_TRIMESH").as_deref() != Ok("1"),
        "trimesh is required here but VOXD_MESH_VENV's python cannot import it (scripts/provision.sh mesh)"
    );
    eprintln!("NOTICE: no trimesh venv (VOXD_MESH_VENV); skipping the trimesh checks");
    None
}

/// trimesh's reading of the mesh file `p`, its vertices as the file indexes them (not merged
/// by position: where two parts of a solid touch along an edge or at a point, the mesh has a
/// vertex for each): (watertight, winding consistent, volume, triangles).
pub(crate) fn trimesh_check(py: &Path, p: &Path) -> (bool, bool, f64, u64) {
    let script = "import sys, trimesh\n\
        m = trimesh.load(sys.argv[1], force='mesh', process=False)\n\
        print(m.is_watertight, m.is_winding_consistent, repr(float(m.volume)), len(m.faces))";
    let o = Command::new(py)
        .args(["-c", script, s(p)])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = String::from_utf8_lossy(&o.stdout);
    let w: Vec<&str> = out.split_whitespace().collect();
    (
        w[0] == "True",
        w[1] == "True",
        w[2].parse().unwrap(),
        w[3].parse().unwrap(),
    )
}

#[test]
fn cubes_of_the_teapot_read_back_as_the_same_voxels() {
    let dir = Scratch::new("mesh-cli");
    let vol = dir.join("teapot.vxl");
    let teapot = data("teapot.obj");
    let mut args = vec![
        "voxelize",
        s(&teapot),
        "-o",
        s(&vol),
        "--fill",
        "winding",
        "--engine",
        "cpu",
    ];
    args.extend(GRID);
    ok(&args);
    let want = bits(&vol);
    let n = want.count_ones();
    assert!(n > 1000, "{n} voxels");
    let py = trimesh_python();
    for ext in ["obj", "stl", "ply", "glb"] {
        let out = dir.join(format!("teapot.{ext}"));
        let said = ok(&["mesh", s(&vol), "-o", s(&out), "--algorithm", "cubes"]);
        assert!(said.contains("watertight"), "{said}");
        // voxd again, by the solid (even-odd) rule on the same grid.
        let again = dir.join(format!("again-{ext}.vxl"));
        let mut args = vec![
            "voxelize",
            s(&out),
            "-o",
            s(&again),
            "--method",
            "solid",
            "--fill",
            "parity",
            "--engine",
            "cpu",
        ];
        args.extend(GRID);
        ok(&args);
        assert!(bits(&again) == want, "{ext}: re-voxelized voxels differ");
        if let Some(py) = &py {
            let (watertight, consistent, volume, _) = trimesh_check(py, &out);
            // STL has no vertex indices: a reader joins its triangles by position, and sees
            // the edges where two parts touch as shared by four triangles. Its triangles are
            // still consistently wound and enclose the same volume.
            assert!(watertight || ext == "stl", "{ext}: trimesh: not watertight");
            assert!(consistent, "{ext}: trimesh: winding not consistent");
            let s3 = 0.125f64.powi(3);
            assert!(
                (volume - n as f64 * s3).abs() <= 1e-9 * n as f64 * s3,
                "{ext}: volume {volume} vs {}",
                n as f64 * s3
            );
        }
    }
}

#[test]
fn surface_nets_and_marching_cubes_of_the_teapot_and_its_sdf_are_watertight_for_trimesh() {
    let dir = Scratch::new("mesh-cli-nets");
    let teapot = data("teapot.obj");
    let vol = dir.join("teapot.vxl");
    let sdf = dir.join("teapot-sdf.vxl");
    for (out, extra) in [
        (&vol, &[][..]),
        (&sdf, &["--method", "sdf", "--band", "2"][..]),
    ] {
        let mut args = vec!["voxelize", s(&teapot), "-o", s(out), "--fill", "winding"];
        args.extend(extra);
        args.extend(GRID);
        ok(&args);
    }
    let want = bits(&vol).count_ones() as f64 * 0.125f64.powi(3);
    let py = trimesh_python();
    for input in [&vol, &sdf] {
        for (ext, algorithm) in [
            ("glb", "surface-nets"),
            ("ply", "surface-nets"),
            ("ply", "marching-cubes"),
        ] {
            let out = dir.join(format!("nets.{ext}"));
            let said = ok(&["mesh", s(input), "-o", s(&out), "--algorithm", algorithm]);
            assert!(said.contains("watertight"), "{said}");
            if let Some(py) = &py {
                let (watertight, consistent, volume, _) = trimesh_check(py, &out);
                assert!(
                    watertight && consistent,
                    "{}: {algorithm} {ext}",
                    input.display()
                );
                // Smoothed (bits) or at the zero crossings (sdf): close to the voxels' volume.
                assert!(
                    (volume / want - 1.0).abs() < 0.05,
                    "{}: {ext}: {volume} vs {want}",
                    input.display()
                );
            }
        }
    }
}

#[test]
fn mesh_refuses_unknown_formats_and_algorithms() {
    let dir = Scratch::new("mesh-cli-refusals");
    let vol = dir.join("box.vxl");
    ok(&[
        "voxelize",
        s(&data("Box.gltf")),
        "-o",
        s(&vol),
        "--resolution",
        "8",
        "--engine",
        "cpu",
    ]);
    let o = voxd(&["mesh", s(&vol), "-o", s(&dir.join("box.fbx"))]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains(".glb, .obj, .stl or .ply"), "{e}");
    let o = voxd(&[
        "mesh",
        s(&vol),
        "-o",
        s(&dir.join("box.obj")),
        "--algorithm",
        "bricks",
    ]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains("algorithm must be one of cubes, surface-nets, marching-cubes"),
        "{e}"
    );
    assert!(!dir.join("box.obj").exists());
}

/// Dual contouring from a mesh file, read by trimesh, and the Hermite data it is made from,
/// read by numpy: each point on its edge between two voxel centres, unit normals facing from
/// the inside end to the outside one, every edge crossed (spot is watertight).
#[test]
fn dual_contouring_of_spot_and_its_hermite_data_read_back() {
    let dir = Scratch::new("mesh-cli-dc");
    let spot = data("spot.obj");
    let out = dir.join("spot.glb");
    let said = ok(&[
        "mesh",
        s(&spot),
        "-o",
        s(&out),
        "--algorithm",
        "dual-contouring",
        "--resolution",
        "40",
    ]);
    assert!(
        said.contains("dual-contouring") && said.contains("watertight"),
        "{said}"
    );
    let npz = dir.join("spot.npz");
    let said = ok(&["hermite", s(&spot), "-o", s(&npz), "--resolution", "40"]);
    assert!(said.contains("(0 uncrossed)"), "{said}");
    // A volume has no Hermite data.
    let vol = dir.join("spot.vxl");
    ok(&["voxelize", s(&spot), "-o", s(&vol), "--resolution", "40"]);
    let o = voxd(&[
        "mesh",
        s(&vol),
        "-o",
        s(&out),
        "--algorithm",
        "dual-contouring",
    ]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("needs Hermite data"));
    let Some(py) = trimesh_python() else { return };
    let (watertight, consistent, volume, _) = trimesh_check(&py, &out);
    assert!(watertight && consistent);
    let script = "import sys, numpy as np\n\
        z = np.load(sys.argv[2])\n\
        e, t, p, n = z['edges'], z['t'], z['points'], z['normals']\n\
        s, o = z['voxel_size'][0], z['origin']\n\
        step = np.eye(3)[e[:, 3]]\n\
        want = o + (e[:, :3] + 0.5 + t[:, None] * step) * s\n\
        assert len(e) > 1000 and z['crossed'].all()\n\
        assert np.abs(p - want).max() < 1e-9 * s, 'points off their edges'\n\
        assert ((t >= 0) & (t <= 1)).all()\n\
        assert np.abs(np.linalg.norm(n, axis=1) - 1).max() < 1e-12\n\
        out = np.where(z['lower_inside'], 1.0, -1.0)\n\
        facing = (n * step).sum(axis=1) * out\n\
        assert (facing >= 0).mean() > 0.99, facing.min()\n";
    let o = std::process::Command::new(&py)
        .args(["-c", script, s(&spot), s(&npz)])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // spot's own volume (Σ p0 · (p1 × p2) / 6 over its triangles): dual contouring lands
    // within 1%.
    let m = voxd::mesh::load_file(&spot, usize::MAX).unwrap();
    let source: f64 = m
        .triangles()
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| m.positions()[i as usize]);
            let x = [
                b[1] * c[2] - b[2] * c[1],
                b[2] * c[0] - b[0] * c[2],
                b[0] * c[1] - b[1] * c[0],
            ];
            (a[0] * x[0] + a[1] * x[1] + a[2] * x[2]) / 6.0
        })
        .sum();
    assert!((volume / source - 1.0).abs() < 0.01, "{volume} vs {source}");
}
