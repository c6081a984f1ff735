//! The `voxd` binary: voxelize, info, convert, and its errors.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

use crate::common::*;
use voxd::codec::VolumeFormat;
use voxd::engine::cpu::CpuEngine;
use voxd::engine::{Engine, GridMesh, Method};
use voxd::grid::{Grid, GridSpec};
use voxd::volume::Volume;

use crate::common::run_voxd as voxd;

/// A file in the scratch directory all the CLI tests share (emptied once, on first use).
fn tmp(name: &str) -> PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| tmpdir("cli")).join(name)
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn read(p: &Path) -> Volume {
    let b = std::fs::read(p).unwrap();
    VolumeFormat::sniff(&b).unwrap().decode(&b).unwrap()
}

#[test]
fn voxelize_writes_every_format_with_the_engine_bits() {
    let fox = data("Fox.glb");
    let want = voxelize_file(
        &fox,
        GridSpec::Resolution { n: 40, cubic: true },
        0,
        Method::Solid,
    );
    for ext in ["vxl", "npy", "binvox"] {
        let out = tmp(&format!("fox.{ext}"));
        let o = voxd(&[
            "voxelize",
            s(&fox),
            "-o",
            s(&out),
            "--resolution",
            "40",
            "--cubic",
            "--fill",
            "parity",
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let line = String::from_utf8(o.stdout).unwrap();
        assert!(
            line.contains("40x40x40 solid")
                && (line.contains("engine cpu") || line.contains("engine gpu (")),
            "{line}"
        );
        assert!(
            line.contains(&format!("{} voxels set", want.count_ones())),
            "{line}"
        );
        assert!(String::from_utf8_lossy(&o.stderr).contains("576 triangles"));
        let Volume::Bits(got) = read(&out) else {
            panic!("kind")
        };
        assert_eq!(got.words(), want.words(), "{ext}");
        if ext == "vxl" {
            assert_eq!(got.grid(), want.grid());
        }
    }
}

/// `--engine gpu` writes the same file as `--engine cpu` (needs a Vulkan adapter, as tests/gpu.rs).
#[test]
fn gpu_and_cpu_engines_write_the_same_file() {
    let mesh = data("Fox.glb");
    let (g, c) = (tmp("fox-gpu.vxl"), tmp("fox-cpu.vxl"));
    let og = voxd(&[
        "voxelize",
        s(&mesh),
        "-o",
        s(&g),
        "--resolution",
        "100",
        "--method",
        "conservative",
        "--fill",
        "parity",
        "--engine",
        "gpu",
    ]);
    if !og.status.success() {
        let err = String::from_utf8_lossy(&og.stderr);
        assert!(
            std::env::var("VOXD_REQUIRE_GPU").is_err() && err.contains("no GPU"),
            "{err}"
        );
        eprintln!("NOTICE: {err}; skipping");
        return;
    }
    assert!(String::from_utf8_lossy(&og.stdout).contains("engine gpu ("));
    let oc = voxd(&[
        "voxelize",
        s(&mesh),
        "-o",
        s(&c),
        "--resolution",
        "100",
        "--method",
        "conservative",
        "--fill",
        "parity",
        "--engine",
        "cpu",
    ]);
    assert!(oc.status.success());
    assert_eq!(std::fs::read(&g).unwrap(), std::fs::read(&c).unwrap());
    // A named adapter that does not exist is an error for --engine gpu, a fallback for auto.
    let o = voxd(&[
        "voxelize",
        s(&mesh),
        "-o",
        s(&g),
        "--engine",
        "gpu",
        "--adapter",
        "no-such-adapter",
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("no adapter named like \"no-such-adapter\"")
    );
    let o = voxd(&[
        "voxelize",
        s(&mesh),
        "-o",
        s(&g),
        "--engine",
        "auto",
        "--adapter",
        "no-such-adapter",
    ]);
    assert!(o.status.success() && String::from_utf8_lossy(&o.stdout).contains("engine cpu"));
    // On a machine whose only adapters are software ones (lavapipe: CI and this project's
    // machines), auto runs the CPU engine, and lavapipe only when asked for by name; a hardware
    // adapter, where one exists, is auto's choice.
    let gpu_line = String::from_utf8_lossy(&og.stdout).to_string();
    let software = gpu_line.contains("llvmpipe") || gpu_line.contains("lavapipe");
    let o = voxd(&["voxelize", s(&mesh), "-o", s(&g), "--engine", "auto"]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{o:?}");
    if software {
        assert!(
            out.contains("engine cpu"),
            "auto picked a software adapter: {out}"
        );
        let o = voxd(&[
            "voxelize",
            s(&mesh),
            "-o",
            s(&g),
            "--engine",
            "auto",
            "--adapter",
            "llvmpipe",
        ]);
        assert!(
            String::from_utf8_lossy(&o.stdout).contains("engine gpu (llvmpipe"),
            "{o:?}"
        );
    } else {
        assert!(
            out.contains("engine gpu ("),
            "auto passed over a hardware adapter: {out}"
        );
    }
}

#[test]
fn grid_options_and_methods() {
    let spot = data("spot.obj");
    let out = tmp("spot.vxl");
    let o = voxd(&[
        "voxelize",
        s(&spot),
        "-o",
        s(&out),
        "--voxel-size",
        "0.05",
        "--padding",
        "2",
        "--method",
        "interior",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let want = voxelize_file(
        &spot,
        GridSpec::VoxelSize {
            size: 0.05,
            cubic: false,
        },
        2,
        Method::Interior,
    );
    assert_eq!(read(&out), Volume::Bits(want));
    let o = voxd(&[
        "voxelize",
        s(&spot),
        "-o",
        s(&out),
        "--origin",
        "-1,-1,-1",
        "--voxel-size",
        "0.1",
        "--dims",
        "20,30,25",
        "--method",
        "surface",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v = read(&out);
    assert_eq!(
        v.grid(),
        &Grid {
            origin: [-1.0; 3],
            voxel_size: 0.1,
            dims: [20, 30, 25]
        }
    );
    let want = voxelize_file(
        &spot,
        GridSpec::Explicit {
            origin: [-1.0; 3],
            voxel_size: 0.1,
            dims: [20, 30, 25],
        },
        0,
        Method::Surface,
    );
    assert_eq!(v, Volume::Bits(want));
}

#[test]
fn info_and_convert() {
    let b = data("Box.gltf");
    let out = tmp("box.vxl");
    assert!(
        voxd(&[
            "voxelize",
            s(&b),
            "-o",
            s(&out),
            "--resolution",
            "10",
            "--padding",
            "1"
        ])
        .status
        .success()
    );
    let o = voxd(&["info", s(&out)]);
    let text = String::from_utf8(o.stdout).unwrap();
    assert!(
        text.contains("dims:       12 x 12 x 12") && text.contains("set voxels: 1000 "),
        "{text}"
    );
    assert!(
        text.contains("set bounds: index [1, 1, 1] ..= [10, 10, 10]"),
        "{text}"
    );
    let npy = tmp("box.npy");
    let bv = tmp("box.binvox");
    let back = tmp("box2.vxl");
    for (from, to) in [(&out, &npy), (&out, &bv), (&bv, &back)] {
        let o = voxd(&["convert", s(from), s(to)]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let (Volume::Bits(a), Volume::Bits(c)) = (read(&out), read(&back)) else {
        panic!()
    };
    assert_eq!(a.words(), c.words());
    let mesh_info = String::from_utf8(voxd(&["info", s(&b)]).stdout).unwrap();
    assert!(
        mesh_info.contains("12 triangles") && mesh_info.contains("watertight"),
        "{mesh_info}"
    );
}

#[test]
fn bad_input_exits_non_zero_with_one_line_naming_the_file() {
    // A .vxl of a few tens of KB whose zstd payload inflates to the 1.16 GB of a 2100³ grid:
    // over the command line's voxel limit (2048³), refused before it is inflated.
    let bomb = tmp("bomb.vxl");
    {
        use std::io::Write;
        let header = br#"{"kind":"bits","dims":[2100,2100,2100],"origin":[0.0,0.0,0.0],"voxel_size":1.0,"layout":"x-y-zcolumns-u64le","meta":{}}"#;
        let payload = 2100u64 * 2100 * 2100u64.div_ceil(64) * 8;
        let mut out = b"\x89VXL\r\n\x1a\n".to_vec();
        out.extend_from_slice(&1u32.to_le_bytes());
        out.extend_from_slice(&(header.len() as u32).to_le_bytes());
        out.extend_from_slice(header);
        let mut enc = zstd::Encoder::new(out, 1).unwrap();
        enc.include_checksum(true).unwrap();
        enc.set_pledged_src_size(Some(payload)).unwrap();
        let zeros = vec![0u8; 1 << 20];
        for _ in 0..payload / zeros.len() as u64 {
            enc.write_all(&zeros).unwrap();
        }
        enc.write_all(&zeros[..(payload % zeros.len() as u64) as usize])
            .unwrap();
        std::fs::write(&bomb, enc.finish().unwrap()).unwrap();
    }
    let junk = tmp("junk.obj");
    std::fs::write(&junk, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n").unwrap();
    let out = tmp("x.vxl");
    let cases: Vec<(Vec<String>, &str)> = vec![
        (
            vec![
                "voxelize".into(),
                "/nonexistent/m.obj".into(),
                "-o".into(),
                s(&out).into(),
            ],
            "/nonexistent/m.obj",
        ),
        (
            vec![
                "voxelize".into(),
                s(&junk).into(),
                "-o".into(),
                s(&out).into(),
            ],
            "line 4: vertex index 9 is out of range",
        ),
        (
            vec![
                "voxelize".into(),
                s(&data("spot.obj")).into(),
                "-o".into(),
                s(&tmp("x.txt")).into(),
            ],
            "unknown volume format",
        ),
        (
            vec![
                "voxelize".into(),
                s(&data("spot.obj")).into(),
                "-o".into(),
                s(&out).into(),
                "--resolution".into(),
                "3000".into(),
                "--cubic".into(),
            ],
            "over the limit",
        ),
        (
            vec![
                "voxelize".into(),
                s(&data("spot.obj")).into(),
                "-o".into(),
                s(&out).into(),
                "--resolution".into(),
                "100".into(),
                "--max-voxels".into(),
                "1000".into(),
            ],
            "over the limit of 1000",
        ),
        (vec!["info".into(), s(&junk).into()], "junk.obj"),
        (vec!["info".into(), s(&bomb).into()], "over the limit"),
        (
            vec!["convert".into(), s(&junk).into(), s(&out).into()],
            "not a volume file",
        ),
    ];
    for (args, want) in cases {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = voxd(&args);
        assert_eq!(o.status.code(), Some(1), "{args:?}");
        // The mesh's diagnostics line may come first; the error is one line, and the last.
        let err = String::from_utf8(o.stderr).unwrap();
        let errors: Vec<&str> = err
            .lines()
            .filter(|l| l.starts_with("voxd: error: "))
            .collect();
        assert_eq!(errors.len(), 1, "{err}");
        assert_eq!(err.lines().last(), Some(errors[0]));
        assert!(errors[0].contains(want), "{args:?}: {err}");
    }
    assert!(!out.exists(), "a failed run must not leave an output file");
    // Usage errors come from clap with its own exit code.
    assert_eq!(
        voxd(&["voxelize", "--origin", "1,2"]).status.code(),
        Some(2)
    );
}

/// A Python interpreter that can import `modules`: `python3` from PATH, else the system one.
/// Skips (None, with a notice) when there is none, unless VOXD_REQUIRE_PYTHON=1 (set by
/// scripts/test.sh once it has made them available), where that is a failure.
pub(crate) fn python_with(modules: &str) -> Option<&'static str> {
    let found = ["python3", "/usr/bin/python3"].into_iter().find(|py| {
        Command::new(py)
            .args(["-c", &format!("import {modules}")])
            .output()
            .is_ok_and(|o| o.status.success())
    });
    if found.is_none() {
        assert!(
            std::env::var("VOXD_REQUIRE_PYTHON").is_err(),
            "VOXD_REQUIRE_PYTHON is set but no python3 imports {modules}"
        );
        eprintln!("NOTICE: no python3 with {modules}; skipping the Python check");
    }
    found
}

#[test]
fn numpy_loads_the_npy() {
    let Some(python) = python_with("numpy") else {
        return;
    };
    let out = tmp("spot.npy");
    assert!(
        voxd(&[
            "voxelize",
            s(&data("spot.obj")),
            "-o",
            s(&out),
            "--resolution",
            "33"
        ])
        .status
        .success()
    );
    let Volume::Bits(v) = read(&out) else {
        panic!()
    };
    let script = "import numpy as np, sys; a = np.load(sys.argv[1]); assert a.dtype == np.uint8; print(*a.shape, int(a.sum()), *np.argwhere(a).sum(axis=0).tolist())";
    let o = Command::new(python)
        .args(["-c", script, s(&out)])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let want = summary(&v);
    assert_eq!(String::from_utf8(o.stdout).unwrap().trim(), want);
}

/// Runs the Python reader exactly as docs/format.md prints it.
#[test]
fn the_documented_python_reader_reads_vxl() {
    let Some(python) = python_with("numpy, zstandard") else {
        return;
    };
    let doc = std::fs::read_to_string(repo_file("docs/format.md")).unwrap();
    let code = doc
        .split("```python\n")
        .nth(1)
        .and_then(|r| r.split("```").next())
        .expect("a python block in docs/format.md");
    let script = tmp("read_vxl.py");
    std::fs::write(&script, code).unwrap();
    let out = tmp("python-reader-fox.vxl");
    assert!(
        voxd(&[
            "voxelize",
            s(&data("Fox.glb")),
            "-o",
            s(&out),
            "--resolution",
            "70"
        ])
        .status
        .success()
    );
    let Volume::Bits(v) = read(&out) else {
        panic!()
    };
    let o = Command::new(python)
        .args([s(&script), s(&out)])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let want = format!("bits {}", summary(&v));
    assert_eq!(String::from_utf8(o.stdout).unwrap().trim(), want);
    assert!(
        v.dims()[2] > 64,
        "the check should span several words per column"
    );
}

#[test]
fn csg_on_the_command_line() {
    let spot = data("spot.obj");
    let (a, b, out) = (tmp("csg-a.vxl"), tmp("csg-b.npy"), tmp("csg-out.vxl"));
    let grid = [
        "--origin",
        "-0.5,-0.8,-0.7",
        "--voxel-size",
        "0.05",
        "--dims",
        "20,34,36",
    ];
    for (m, o) in [("solid", &a), ("surface", &b)] {
        let mut args = vec![
            "voxelize",
            s(&spot),
            "-o",
            s(o),
            "--method",
            m,
            "--engine",
            "cpu",
        ];
        args.extend(grid);
        assert!(voxd(&args).status.success());
    }
    // npy drops the grid, so the npy operand is refused as misaligned unless its grid happens to
    // be the unit grid: use the vxl one twice and the difference with itself.
    let o = voxd(&["csg", "difference", s(&a), s(&a), "-o", s(&out)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let Volume::Bits(v) = read(&out) else {
        panic!()
    };
    assert_eq!(v.count_ones(), 0);
    let o = voxd(&["csg", "union", s(&a), s(&b), "-o", s(&out)]);
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("not aligned"));
    assert_eq!(
        voxd(&["csg", "sum", s(&a), "-o", s(&out)]).status.code(),
        Some(2),
        "clap refuses an unknown operation"
    );
}

#[test]
fn morph_on_the_command_line() {
    let (a, out) = (tmp("morph-a.vxl"), tmp("morph-out.vxl"));
    assert!(
        voxd(&[
            "voxelize",
            s(&data("Box.gltf")),
            "-o",
            s(&a),
            "--resolution",
            "10",
            "--padding",
            "3",
            "--engine",
            "cpu"
        ])
        .status
        .success()
    );
    let o = voxd(&[
        "morph",
        "erode",
        s(&a),
        "-o",
        s(&out),
        "--radius",
        "2",
        "--kernel",
        "cross",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (Volume::Bits(v), Volume::Bits(e)) = (read(&a), read(&out)) else {
        panic!()
    };
    let want = voxd::volume::morph::apply(
        &v,
        voxd::volume::morph::MorphOp::Erode,
        2,
        voxd::volume::morph::Kernel::Cross,
        false,
    );
    assert_eq!(e, want);
    assert!(e.count_ones() < v.count_ones() && e.count_ones() > 0);
    assert_eq!(
        voxd(&["morph", "melt", s(&a), "-o", s(&out)]).status.code(),
        Some(2),
        "clap refuses an unknown operation"
    );
}

fn read_normals(path: &Path) -> (String, Vec<[i8; 3]>) {
    let b = std::fs::read(path).unwrap();
    let hlen = u16::from_le_bytes([b[8], b[9]]) as usize;
    let header = String::from_utf8(b[10..10 + hlen].to_vec()).unwrap();
    (
        header,
        b[10 + hlen..]
            .chunks(3)
            .map(|c| [c[0] as i8, c[1] as i8, c[2] as i8])
            .collect(),
    )
}

#[test]
fn normals_export() {
    let (v, out) = (tmp("normals-v.vxl"), tmp("normals.npy"));
    // A bit volume: the unit box fills voxels 1..=6 of an 8³ grid.
    assert!(
        voxd(&[
            "voxelize",
            s(&data("Box.gltf")),
            "-o",
            s(&v),
            "--resolution",
            "6",
            "--padding",
            "1",
            "--engine",
            "cpu"
        ])
        .status
        .success()
    );
    let o = voxd(&["normals", s(&v), "-o", s(&out)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (header, n) = read_normals(&out);
    assert!(
        header.contains("'descr': '|i1'") && header.contains("'shape': (8, 8, 8, 3)"),
        "{header}"
    );
    let at = |x: usize, y: usize, z: usize| n[(x * 8 + y) * 8 + z];
    assert_eq!(at(1, 4, 4), [-127, 0, 0], "the -x face");
    assert_eq!(at(6, 4, 4), [127, 0, 0], "the +x face");
    assert_eq!(
        (at(4, 4, 4), at(0, 4, 4)),
        ([0; 3], [0; 3]),
        "inside and outside have none"
    );
    // A density volume: every partial voxel gets a unit normal (×127).
    assert!(
        voxd(&[
            "voxelize",
            s(&data("spot.obj")),
            "-o",
            s(&v),
            "--resolution",
            "20",
            "--method",
            "density",
            "--engine",
            "cpu"
        ])
        .status
        .success()
    );
    assert!(voxd(&["normals", s(&v), "-o", s(&out)]).status.success());
    let (_, n) = read_normals(&out);
    let set: Vec<_> = n.iter().filter(|c| **c != [0; 3]).collect();
    assert!(set.len() > 100);
    assert!(set.iter().all(|c| {
        ((c.iter().map(|&x| (x as f64).powi(2)).sum::<f64>()).sqrt() - 127.0).abs() < 2.0
    }));
    assert_eq!(
        voxd(&["normals", s(&v), "-o", s(&tmp("n.vxl"))])
            .status
            .code(),
        Some(1)
    );
}

#[test]
fn fill_options() {
    let out = tmp("fill.vxl");
    for fill in ["parity", "vote", "flood"] {
        let o = voxd(&[
            "voxelize",
            s(&data("spot.obj")),
            "-o",
            s(&out),
            "--resolution",
            "30",
            "--fill",
            fill,
            "--engine",
            "cpu",
        ]);
        assert!(
            o.status.success(),
            "{fill}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
    // spot is watertight: vote agrees with parity; flood is solid ∪ surface.
    let (mesh, g) = mesh_and_grid(
        &data("spot.obj"),
        GridSpec::Resolution {
            n: 30,
            cubic: false,
        },
        0,
    );
    let Volume::Bits(flood) = read(&out) else {
        panic!()
    };
    assert_eq!(
        flood,
        CpuEngine
            .voxelize(&GridMesh::new(&mesh, &g).unwrap(), Method::Conservative)
            .unwrap()
    );
    let o = voxd(&[
        "voxelize",
        s(&data("spot.obj")),
        "-o",
        s(&out),
        "--fill",
        "blob",
    ]);
    assert_eq!(o.status.code(), Some(2), "clap refuses an unknown fill");
    assert!(String::from_utf8_lossy(&o.stderr).contains("winding"));

    // A mesh with holes: auto picks winding and says so, parity warns; the bits are the
    // library's.
    let bowl = open_bowl();
    let obj = tmp("bowl.obj");
    std::fs::write(&obj, to_obj(&bowl)).unwrap();
    let (lo, hi) = bowl.bounds();
    let g = voxd::grid::Grid::fit(
        lo,
        hi,
        GridSpec::Resolution {
            n: 20,
            cubic: false,
        },
        0,
        Default::default(),
    )
    .unwrap();
    for (fill, used) in [
        ("auto", "winding"),
        ("parity", "parity"),
        ("winding", "winding"),
    ] {
        let o = voxd(&[
            "voxelize",
            s(&obj),
            "-o",
            s(&out),
            "--resolution",
            "20",
            "--fill",
            fill,
            "--engine",
            "cpu",
        ]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{err}");
        assert!(err.contains(&format!("fill {used}")), "{err}");
        assert!(err.contains("odd-parity columns"), "{err}");
        assert_eq!(err.contains("WARNING"), used == "parity", "{err}");
        // Once, not also as a log line (` WARN voxd::app::voxelize: fill …`).
        assert!(!err.contains(" WARN "), "{err}");
        assert_eq!(
            fill == "auto",
            err.contains("(auto: the mesh is not watertight (") && err.contains("so winding)"),
            "{err}"
        );
        let Volume::Bits(got) = read(&out) else {
            panic!()
        };
        let (want, _) = voxd::engine::fill::voxelize(
            &CpuEngine,
            &bowl,
            &g,
            Method::Solid,
            fill.parse().unwrap(),
            &bowl.diagnostics(),
        )
        .unwrap();
        assert_eq!(got, want, "{fill}");
    }
}
