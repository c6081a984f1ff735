//! `method=sdf` and `method=distance` over HTTP: an open mesh's narrow band signed by the
//! winding fill (its inside voxels exactly `method=solid`'s with the same fill), distance's
//! shell, and the parameters' refusals.

use super::*;
use voxd::volume::Volume;

fn download(srv: &Server, id: &str) -> Volume {
    let r = srv
        .req(
            "GET",
            &format!("/v1/volumes/{id}/data?format=vxl"),
            &[],
            &[],
        )
        .ok(200);
    VolumeFormat::Vxl.decode(&r.body).unwrap()
}

#[test]
fn sdf_of_an_open_mesh_is_signed_like_its_solid() {
    let dir = tmpdir("distance-sdf");
    let srv = Server::start(&dir, &[]);
    let obj = [("Content-Type", "model/obj")];
    let bowl = to_obj(&open_bowl());
    let q = "resolution=40&padding=2&fill=winding&wait=120";
    let sdf = srv.created(&format!("/v1/voxelize?method=sdf&band=3&{q}"), &obj, &bowl);
    let solid = srv.created(&format!("/v1/voxelize?method=solid&{q}"), &obj, &bowl);
    assert_eq!(sdf["kind"], "sparse-distance", "{sdf}");
    assert_eq!(sdf["method"], "sdf");
    assert_eq!(sdf["fill"]["used"], "winding");
    let s = sdf["grid"]["voxel_size"].as_f64().unwrap();
    let d = &sdf["distance"];
    assert_eq!(d["band"], 3, "{sdf}");
    assert_eq!(
        d["background"].as_f64().unwrap(),
        f64::from((3.0 * s) as f32)
    );
    assert!(d["bricks"].as_u64().unwrap() > 0 && d["active_voxels"].as_u64().unwrap() > 0);
    assert_eq!(sdf["solid_voxels"], solid["solid_voxels"]);
    let Volume::SparseDistance(v) = download(&srv, sdf["id"].as_str().unwrap()) else {
        panic!("not a sparse distance volume")
    };
    let Volume::Bits(b) = download(&srv, solid["id"].as_str().unwrap()) else {
        panic!("not bits")
    };
    assert_eq!(v.grid(), b.grid());
    let [nx, ny, nz] = b.dims();
    let mut active = 0u64;
    for x in 0..nx {
        for y in 0..ny {
            for z in 0..nz {
                let val = v.get(x, y, z);
                assert_eq!(val.is_sign_negative(), b.get(x, y, z), "{x},{y},{z}: {val}");
                assert!(val.abs() <= v.background());
                active += u64::from(val.abs() < v.background());
            }
        }
    }
    assert_eq!(d["active_voxels"].as_u64(), Some(active));
    // band=all: every voxel has its distance.
    let all = srv.created(
        &format!("/v1/voxelize?method=sdf&band=all&{q}"),
        &obj,
        &bowl,
    );
    assert_eq!(all["distance"]["band"], "all");
    assert_eq!(all["distance"]["background"], "inf");
    srv.stop();
}

#[test]
fn distance_is_a_shell_of_the_thickness() {
    let dir = tmpdir("distance-shell");
    let srv = Server::start(&dir, &[]);
    let obj = [("Content-Type", "model/obj")];
    let cube = box_obj([0.0, 0.0, 0.0], [1.0, 1.0, 1.0]);
    // Voxels of 0.1 with the box's faces on voxel boundaries: centres 0.05 from a face.
    let g = "origin=-0.5,-0.5,-0.5&dims=20,20,20&voxel_size=0.1&wait=60";
    let thin = srv.created(
        &format!("/v1/voxelize?method=distance&thickness=0.04&{g}"),
        &obj,
        &cube,
    );
    assert_eq!(thin["kind"], "bits");
    assert_eq!(thin["solid_voxels"], 0, "{thin}");
    let shell = srv.created(
        &format!("/v1/voxelize?method=distance&thickness=0.05&{g}"),
        &obj,
        &cube,
    );
    // The layer of voxels on either side of each face (ties set), not the edges' and
    // corners' outside (√2·0.05 and √3·0.05 away): the inner shell 10³ − 8³ and 6 faces of 10².
    assert_eq!(
        shell["solid_voxels"],
        10 * 10 * 10 - 8 * 8 * 8 + 6 * 10 * 10,
        "{shell}"
    );
    let t = shell["distance"]["thickness"].as_f64().unwrap();
    assert!((t - 0.05).abs() < 1e-12, "{shell}");
    // Half the diagonal (222/256 voxel ≥ √3/2): the corners' outside voxels too.
    let default = srv.created(&format!("/v1/voxelize?method=distance&{g}"), &obj, &cube);
    assert_eq!(
        default["solid_voxels"],
        12 * 12 * 12 - 8 * 8 * 8,
        "{default}"
    );
    srv.stop();
}

#[test]
fn distance_and_sdf_parameters_are_refused_where_they_do_not_apply() {
    let dir = tmpdir("distance-refusals");
    let srv = Server::start(&dir, &[]);
    let obj = [("Content-Type", "model/obj")];
    let cube = box_obj([0.0, 0.0, 0.0], [1.0, 1.0, 1.0]);
    for (q, says) in [
        ("method=sdf&band=0", &["band", "1 to 64"][..]),
        ("method=sdf&band=65", &["band"]),
        ("method=sdf&band=wide", &["band", "all"]),
        (
            "method=solid&band=3",
            &["band=3", "method=solid", "method=sdf"],
        ),
        ("band=all", &["band=all", "method=solid"]),
        ("method=distance&thickness=-1", &["thickness", "≥ 0"]),
        ("method=distance&thickness=5", &["thickness", "at most 32"]),
        (
            "method=sdf&thickness=0.1",
            &["thickness", "method=distance"],
        ),
        ("method=distance&band=3", &["band", "method=sdf"]),
        (
            "method=distance&fill=winding",
            &["fill=winding", "method=distance"],
        ),
        (
            "method=sdf&density_factor=2",
            &["density_factor", "method=sdf"],
        ),
    ] {
        let r = srv.req(
            "POST",
            &format!("/v1/voxelize?resolution=16&{q}"),
            &obj,
            &cube,
        );
        let p = assert_problem(&r, 400, "invalid-parameter");
        let d = p["detail"].as_str().unwrap();
        for s in says {
            assert!(d.contains(s), "{q}: {d:?} does not say {s}");
        }
    }
    // The voxel limit counts an sdf's candidate voxels, not its grid: a 512³ grid of a box
    // passes where solid is refused, and a limit below the band's bricks refuses it.
    let big = "resolution=512&max_voxels=16777216&wait=120";
    let r = srv.req(
        "POST",
        &format!("/v1/voxelize?method=solid&{big}"),
        &obj,
        &cube,
    );
    assert_problem(&r, 422, "grid-too-large");
    let v = srv.created(
        &format!("/v1/voxelize?method=sdf&band=1&{big}"),
        &obj,
        &cube,
    );
    assert_eq!(v["grid"]["dims"], serde_json::json!([512, 512, 512]));
    let r = srv.req(
        "POST",
        "/v1/voxelize?method=sdf&resolution=512&max_voxels=4194304",
        &obj,
        &cube,
    );
    let p = assert_problem(&r, 422, "grid-too-large");
    assert!(p["detail"].as_str().unwrap().contains("bricks"), "{p}");
    srv.stop();
}

/// The command line: `voxd voxelize --method sdf --band 2` of an open mesh with the winding
/// fill writes a sparse distance volume signed like `--method solid`, and `voxd info` describes
/// it; `--band` and `--thickness` only with their methods.
#[test]
fn the_cli_writes_and_describes_an_sdf() {
    let dir = tmpdir("distance-cli");
    let mesh = dir.join("bowl.obj");
    std::fs::write(&mesh, to_obj(&open_bowl())).unwrap();
    let (sdf, solid) = (dir.join("bowl-sdf.vxl"), dir.join("bowl-solid.vxl"));
    let run = |args: &[&str]| {
        let o = run_voxd(args);
        assert!(
            o.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        String::from_utf8(o.stdout).unwrap()
    };
    let m = mesh.to_str().unwrap();
    let common = [
        "--resolution",
        "30",
        "--padding",
        "1",
        "--fill",
        "winding",
        "--engine",
        "cpu",
    ];
    let mut a = vec![
        "voxelize",
        m,
        "-o",
        sdf.to_str().unwrap(),
        "--method",
        "sdf",
        "--band",
        "2",
    ];
    a.extend(common);
    run(&a);
    let mut a = vec![
        "voxelize",
        m,
        "-o",
        solid.to_str().unwrap(),
        "--method",
        "solid",
    ];
    a.extend(common);
    run(&a);
    let read = |p: &Path| {
        VolumeFormat::Vxl
            .decode(&std::fs::read(p).unwrap())
            .unwrap()
    };
    let (Volume::SparseDistance(v), Volume::Bits(b)) = (read(&sdf), read(&solid)) else {
        panic!("kinds")
    };
    let [nx, ny, nz] = b.dims();
    let mut active = 0;
    for x in 0..nx {
        for y in 0..ny {
            for z in 0..nz {
                assert_eq!(
                    v.get(x, y, z).is_sign_negative(),
                    b.get(x, y, z),
                    "{x},{y},{z}"
                );
                active += u64::from(v.get(x, y, z).abs() < v.background());
            }
        }
    }
    let info = run(&["info", sdf.to_str().unwrap()]);
    assert!(info.contains("kind:       sparse-distance"), "{info}");
    assert!(info.contains("band 2 voxels"), "{info}");
    assert!(
        info.contains(&format!("stored ({active} voxels in band)")),
        "{info}"
    );
    for bad in [
        &["--method", "solid", "--band", "2"][..],
        &["--method", "sdf", "--band", "0"],
        &["--method", "sdf", "--thickness", "0.1"],
    ] {
        let out = dir.join("bad.vxl");
        let mut a = vec!["voxelize", m, "-o", out.to_str().unwrap()];
        a.extend(bad);
        let o = run_voxd(&a);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            !o.status.success() && (err.contains("band") || err.contains("thickness")),
            "{bad:?}: {err}"
        );
        assert!(!out.exists());
    }
}
