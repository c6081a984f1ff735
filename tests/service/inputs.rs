//! Input that integrating clients send, on both fronts (the service and `voxd voxelize`): glTF
//! with application-specific attributes, booleans as Python's requests writes them, 400s that
//! name the parameter, the cross-parameter rules, `fill=auto` as the default, and what a gzip'd
//! upload records as its format.

use super::*;

/// A glTF written by trimesh with the attributes `_s` and `_t` (legal per the glTF spec) loads:
/// the attributes are ignored, on both fronts.
#[test]
fn gltf_with_application_specific_attributes_loads() {
    let dir = tmpdir("inputs-gltf");
    let glb = std::fs::read(data("trimesh-attrs.glb")).unwrap();
    assert!(glb.windows(4).any(|w| w == b"\"_s\""), "the fixture has _s");
    let srv = Server::start(&dir, &[]);
    let meta = srv.created(
        "/v1/voxelize?resolution=8&wait=60",
        &[("Content-Type", "model/gltf-binary")],
        &glb,
    );
    assert_eq!(meta["source"]["triangles"], 12);
    assert_eq!(meta["diagnostics"]["watertight"], true);
    // A unit box at 8³: every voxel centre is inside.
    assert_eq!(meta["solid_voxels"], 512);
    drop(srv);
    let out = dir.join("attrs.npy");
    let o = run_voxd(&[
        "voxelize",
        data("trimesh-attrs.glb").to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--resolution",
        "8",
        "--engine",
        "cpu",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stdout).contains("512 voxels set"));
}

/// Booleans: true/false/1/0 in any case; anything else is a 400 naming the parameter and the
/// values accepted. Every malformed parameter's 400 names it and the value given.
#[test]
fn booleans_and_parse_errors_name_the_parameter() {
    let dir = tmpdir("inputs-params");
    let srv = Server::start(&dir, &[]);
    let obj = [("Content-Type", "model/obj")];
    let cube = box_obj([0.0, 0.0, 0.0], [2.0, 1.0, 1.0]);
    for (v, dims) in [
        ("True", [4, 4, 4]),
        ("TRUE", [4, 4, 4]),
        ("1", [4, 4, 4]),
        ("false", [4, 2, 2]),
        ("False", [4, 2, 2]),
        ("0", [4, 2, 2]),
    ] {
        let meta = srv.created(
            &format!("/v1/voxelize?resolution=4&wait=60&cubic={v}"),
            &obj,
            &cube,
        );
        assert_eq!(meta["grid"]["dims"], serde_json::json!(dims), "cubic={v}");
    }
    for (q, names) in [
        (
            "cubic=yes",
            &["cubic", "\"yes\"", "true, false, 1 or 0"][..],
        ),
        ("cubic=", &["cubic", "true, false, 1 or 0"]),
        ("resolution=abc", &["resolution", "\"abc\"", "whole number"]),
        ("resolution=-3", &["resolution", "\"-3\"", "whole number"]),
        ("padding=1.5", &["padding", "\"1.5\"", "whole number"]),
        (
            "density_factor=two&method=density",
            &["density_factor", "whole number"],
        ),
        ("max_voxels=lots", &["max_voxels", "whole number"]),
        ("voxel_size=big", &["voxel_size", "\"big\"", "a number"]),
        ("wait=soon", &["wait", "\"soon\"", "a number"]),
        (
            "fill=blob",
            &["fill", "\"blob\"", "parity, vote, winding, flood or auto"],
        ),
        (
            "method=sculpt",
            &[
                "method",
                "solid, surface, conservative, interior, density, distance or sdf",
            ],
        ),
        ("origin=1,2&dims=2,2,2&voxel_size=1", &["origin", "X,Y,Z"]),
        ("grid=x", &["unknown field `grid`", "resolution"]),
    ] {
        let r = srv.req("POST", &format!("/v1/voxelize?{q}"), &obj, &cube);
        let p = assert_problem(&r, 400, "invalid-parameter");
        let d = p["detail"].as_str().unwrap();
        for n in names {
            assert!(d.contains(n), "{q}: {d:?} does not say {n}");
        }
    }
    let r = srv.req("GET", "/v1/volumes?limit=many", &[], &[]);
    let d = assert_problem(&r, 400, "invalid-parameter")["detail"].to_string();
    assert!(d.contains("limit") && d.contains("many"), "{d}");
    // JSON bodies say where in the document the error is.
    let r = srv.req(
        "POST",
        "/v1/volumes/intersect",
        &[("Content-Type", "application/json")],
        br#"{"a": "x", "b": 7}"#,
    );
    let d = assert_problem(&r, 400, "invalid-parameter")["detail"].to_string();
    assert!(d.contains("(at b)"), "{d}");
}

/// The spec's cross-parameter rules, on both fronts: density_factor only with method=density
/// (and only 2 or 4), fill not with method=surface; the grid options' combinations.
#[test]
fn cross_parameter_rules_are_enforced() {
    let dir = tmpdir("inputs-rules");
    let srv = Server::start(&dir, &[]);
    let obj = [("Content-Type", "model/obj")];
    let cube = box_obj([0.0, 0.0, 0.0], [1.0, 1.0, 1.0]);
    for (q, names) in [
        (
            "density_factor=3",
            &["density_factor", "method=solid", "method=density"][..],
        ),
        (
            "density_factor=2&method=solid",
            &["density_factor", "method=solid"],
        ),
        (
            "density_factor=4&method=surface",
            &["density_factor", "method=surface"],
        ),
        (
            "density_factor=3&method=density",
            &["density_factor", "2 or 4"],
        ),
        (
            "fill=winding&method=surface",
            &["fill=winding", "method=surface"],
        ),
        ("fill=auto&method=surface", &["fill=auto", "method=surface"]),
        ("resolution=8&voxel_size=0.1", &["resolution", "voxel_size"]),
        ("origin=0,0,0&dims=2,2,2", &["origin", "dims", "voxel_size"]),
        ("dims=2,2,2&voxel_size=1", &["origin", "dims", "voxel_size"]),
    ] {
        let r = srv.req("POST", &format!("/v1/voxelize?{q}"), &obj, &cube);
        let p = assert_problem(&r, 400, "invalid-parameter");
        let d = p["detail"].as_str().unwrap();
        for n in names {
            assert!(d.contains(n), "{q}: {d:?} does not say {n}");
        }
    }
    // What the rules allow.
    for q in [
        "method=density&density_factor=4",
        "method=density&fill=winding",
        "method=surface",
        "method=interior&fill=vote",
    ] {
        srv.created(
            &format!("/v1/voxelize?resolution=6&wait=60&{q}"),
            &obj,
            &cube,
        );
    }
    drop(srv);
    let mesh = dir.join("cube.obj");
    std::fs::write(&mesh, &cube).unwrap();
    let out = dir.join("cube.vxl");
    let run = |extra: &[&str]| {
        let mut args = vec![
            "voxelize",
            mesh.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(&["--resolution", "6", "--engine", "cpu"]);
        args.extend_from_slice(extra);
        run_voxd(&args)
    };
    for (extra, names) in [
        (
            &["--density-factor", "2"][..],
            &["density_factor", "method=solid"][..],
        ),
        (
            &["--method", "surface", "--fill", "winding"],
            &["fill=winding", "method=surface"],
        ),
        (
            &["--method", "density", "--density-factor", "3"],
            &["2 or 4"],
        ),
    ] {
        let o = run(extra);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{extra:?} was accepted");
        for n in names {
            assert!(err.contains(n), "{extra:?}: {err:?} does not say {n}");
        }
    }
    for extra in [
        &["--method", "density", "--density-factor", "4"][..],
        &["--method", "surface"],
    ] {
        let o = run(extra);
        assert!(
            o.status.success(),
            "{extra:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
}

/// Without `fill`, solid-based methods use `auto`: parity on a watertight mesh, winding on an
/// open one (no streaks), and the volume says which and why; `fill=parity` is still there.
#[test]
fn fill_auto_is_the_default_and_says_why() {
    let dir = tmpdir("inputs-fill");
    let srv = Server::start(&dir, &[]);
    let obj = [("Content-Type", "model/obj")];
    let bowl = to_obj(&open_bowl());
    let meta = srv.created("/v1/voxelize?resolution=20&wait=60", &obj, &bowl);
    let f = &meta["fill"];
    assert_eq!(
        (&f["requested"], &f["used"]),
        (&"auto".into(), &"winding".into()),
        "{f}"
    );
    let why = f["reason"].as_str().unwrap();
    assert!(
        why.contains("not watertight") && why.contains("winding"),
        "{why}"
    );
    assert!(f["warning"].is_null(), "{f}");
    let default_id = meta["id"].as_str().unwrap().to_string();
    let winding = srv.created(
        "/v1/voxelize?resolution=20&wait=60&fill=winding",
        &obj,
        &bowl,
    );
    let parity = srv.created(
        "/v1/voxelize?resolution=20&wait=60&fill=parity",
        &obj,
        &bowl,
    );
    assert_eq!(parity["fill"]["used"], "parity");
    assert!(parity["fill"]["warning"].is_string());
    let bits = |id: &str| {
        decode_bits(
            &srv.req("GET", &format!("/v1/volumes/{id}/data"), &[], &[])
                .ok(200)
                .body,
        )
    };
    let d = bits(&default_id);
    assert!(d == bits(winding["id"].as_str().unwrap()));
    assert!(
        d != bits(parity["id"].as_str().unwrap()),
        "parity should streak"
    );
    // Watertight: parity, and the reason says so; density too.
    let cube = box_obj([0.0, 0.0, 0.0], [1.0, 1.0, 1.0]);
    for m in ["solid", "density"] {
        let meta = srv.created(
            &format!("/v1/voxelize?resolution=6&wait=60&method={m}"),
            &obj,
            &cube,
        );
        let f = &meta["fill"];
        assert_eq!(
            (&f["requested"], &f["used"]),
            (&"auto".into(), &"parity".into()),
            "{f}"
        );
        assert!(
            f["reason"]
                .as_str()
                .unwrap()
                .contains("watertight, so parity"),
            "{f}"
        );
    }
    drop(srv);
    // The command line: the same default, and the summary says why.
    let mesh = dir.join("bowl.obj");
    std::fs::write(&mesh, &bowl).unwrap();
    let out = dir.join("bowl.vxl");
    let o = run_voxd(&[
        "voxelize",
        mesh.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--resolution",
        "20",
        "--engine",
        "cpu",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("fill winding (auto: the mesh is not watertight"),
        "{err}"
    );
    assert!(!err.contains("WARNING"), "{err}");
}

/// A gzip'd upload of undeclared format records the mesh's format (sniffed inside) and the
/// compression, in the metadata and in the .vxl header.
#[test]
fn a_gzipped_upload_records_the_format_inside() {
    let dir = tmpdir("inputs-gzip");
    let srv = Server::start(&dir, &[]);
    let cube = box_obj([0.0, 0.0, 0.0], [1.0, 1.0, 1.0]);
    let meta = srv.created("/v1/voxelize?resolution=4&wait=60", &[], &gz(&cube));
    assert_eq!(meta["source"]["format"], "obj", "{meta}");
    assert_eq!(meta["source"]["compression"], "gzip", "{meta}");
    let id = meta["id"].as_str().unwrap();
    let vxl = srv
        .req("GET", &format!("/v1/volumes/{id}/data"), &[], &[])
        .ok(200)
        .body;
    let (_, header) = voxd::codec::vxl::decode(&vxl).unwrap();
    assert_eq!(header["source_format"], "obj");
    assert_eq!(header["source_compression"], "gzip");
    // Not gzip'd: no compression recorded.
    let meta = srv.created(
        "/v1/voxelize?resolution=4&wait=60",
        &[("Content-Type", "model/obj")],
        &cube,
    );
    assert_eq!(meta["source"]["format"], "obj");
    assert!(meta["source"].get("compression").is_none(), "{meta}");
}
