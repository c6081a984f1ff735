//! `GET /v1/volumes/{id}/mesh` (issue 33: meshes back out) over HTTP: every format of a stored
//! volume's mesh, uploaded again on the same grid (the same voxels must come back), read by
//! trimesh where its venv is (tests/mesh_cli.rs), with its headers (type, exact length, ETag and
//! 304, attachment name) and refusals (unknown algorithm or format, too many triangles, an
//! unknown volume).

use super::*;

#[test]
fn meshes_of_stored_volumes() {
    let dir = tmpdir("mesh-route");
    let srv = Server::start(&dir, &[]);
    let grid = "origin=-1,-1,-1&voxel_size=0.25&dims=24,20,18";
    // Two boxes meeting along an edge only: the mesh must keep them apart there.
    let mut obj = box_obj([0.0, 0.0, 0.0], [2.0, 1.5, 1.0]);
    let second = box_obj([2.0, 1.5, 0.0], [3.5, 2.5, 2.0]);
    let text = String::from_utf8(second).unwrap();
    let mut out = String::new();
    for l in text.lines() {
        // The second box's faces index after the first's 8 vertices.
        if let Some(f) = l.strip_prefix("f ") {
            let idx: Vec<String> = f
                .split_whitespace()
                .map(|i| (i.parse::<u32>().unwrap() + 8).to_string())
                .collect();
            out.push_str(&format!("f {}\n", idx.join(" ")));
        } else {
            out.push_str(l);
            out.push('\n');
        }
    }
    obj.extend_from_slice(out.as_bytes());
    let v = srv.created(
        &format!("/v1/voxelize?{grid}&name=two%20boxes&wait=60"),
        &[("Content-Type", "model/obj")],
        &obj,
    );
    let id = v["id"].as_str().unwrap().to_string();
    let data = |id: &str| {
        decode_bits(
            &srv.req("GET", &format!("/v1/volumes/{id}/data"), &[], &[])
                .body,
        )
    };
    let want = data(&id);
    assert_eq!(want.count_ones(), 8 * 6 * 4 + 6 * 4 * 8);
    let py = crate::mesh_cli::trimesh_python();
    for (format, media) in [
        ("obj", "model/obj"),
        ("stl", "model/stl"),
        ("ply", "model/ply"),
        ("glb", "model/gltf-binary"),
    ] {
        let path = format!("/v1/volumes/{id}/mesh?algorithm=cubes&format={format}");
        let r = srv.req("GET", &path, &[], &[]);
        assert_eq!(r.status, 200, "{}", String::from_utf8_lossy(&r.body));
        assert_eq!(r.header("content-type"), Some(media));
        if format != "obj" {
            assert_eq!(
                r.header("content-length"),
                Some(r.body.len().to_string().as_str())
            );
        }
        let disposition = r.header("content-disposition").unwrap();
        assert!(
            disposition.contains(&format!("two_boxes.{format}")),
            "{disposition}"
        );
        // The mesh, uploaded again on the same grid with the even-odd rule: the same voxels.
        let again = srv.created(
            &format!("/v1/voxelize?{grid}&method=solid&fill=parity&wait=60"),
            &[("Content-Type", media)],
            &r.body,
        );
        assert!(
            data(again["id"].as_str().unwrap()) == want,
            "{format}: re-voxelized voxels differ"
        );
        if let Some(py) = &py {
            let f = dir.join(format!("m.{format}"));
            std::fs::write(&f, &r.body).unwrap();
            let (watertight, consistent, volume, _) = crate::mesh_cli::trimesh_check(py, &f);
            assert!(watertight || format == "stl", "{format}: not watertight");
            assert!(consistent, "{format}");
            let exact = want.count_ones() as f64 * 0.25f64.powi(3);
            assert!((volume - exact).abs() < 1e-9 * exact, "{format}: {volume}");
        }
        // Its ETag is known before the build: a revalidation is a 304 without a body.
        let etag = r.header("etag").unwrap().to_string();
        let again = srv.req("GET", &path, &[("If-None-Match", &etag)], &[]);
        assert_eq!(again.status, 304);
        assert!(again.body.is_empty());
    }
    // Surface nets of the bit volume and of its sdf (a stored distance volume): watertight for
    // trimesh, close to the voxels' volume.
    let sdf = srv.created(&format!("/v1/volumes/{id}/sdf?band=2"), &[], &[]);
    for (of, algorithm) in [
        (id.as_str(), "surface-nets"),
        (sdf["id"].as_str().unwrap(), "surface-nets"),
        (sdf["id"].as_str().unwrap(), "marching-cubes"),
    ] {
        let r = srv.req(
            "GET",
            &format!("/v1/volumes/{of}/mesh?algorithm={algorithm}&format=ply"),
            &[],
            &[],
        );
        assert_eq!(r.status, 200, "{}", String::from_utf8_lossy(&r.body));
        if let Some(py) = &py {
            let f = dir.join("nets.ply");
            std::fs::write(&f, &r.body).unwrap();
            let (watertight, consistent, volume, _) = crate::mesh_cli::trimesh_check(py, &f);
            assert!(watertight && consistent, "{algorithm} of {of}");
            let exact = want.count_ones() as f64 * 0.25f64.powi(3);
            assert!(
                (volume / exact - 1.0).abs() < 0.1,
                "{of}: {volume} vs {exact}"
            );
        }
    }
    // The defaults: cubes as OBJ.
    let r = srv.req("GET", &format!("/v1/volumes/{id}/mesh"), &[], &[]);
    assert_eq!(r.header("content-type"), Some("model/obj"));
    // Gzip'd on request (OBJ is text).
    let r = srv.req(
        "GET",
        &format!("/v1/volumes/{id}/mesh"),
        &[("Accept-Encoding", "gzip")],
        &[],
    );
    assert_eq!(r.header("content-encoding"), Some("gzip"));

    for (query, status, slug) in [
        ("algorithm=bricks", 400, "invalid-parameter"),
        ("format=fbx", 400, "invalid-parameter"),
        ("colour=red", 400, "invalid-parameter"),
    ] {
        let r = srv.req("GET", &format!("/v1/volumes/{id}/mesh?{query}"), &[], &[]);
        let p = assert_problem(&r, status, slug);
        assert!(p["detail"].as_str().unwrap().len() > 10, "{p}");
    }
    let r = srv.req("GET", "/v1/volumes/0123456789abcdef/mesh", &[], &[]);
    assert_problem(&r, 404, "not-found");
    drop(srv);

    // Over the triangle limit: refused with the numbers before anything is built.
    let srv = Server::start(&tmpdir("mesh-route-limit"), &["--max-triangles", "100"]);
    let v = srv.created(
        &format!("/v1/voxelize?{grid}&wait=60"),
        &[("Content-Type", "model/obj")],
        &box_obj([0.0, 0.0, 0.0], [2.0, 1.5, 1.0]),
    );
    let id = v["id"].as_str().unwrap();
    let r = srv.req(
        "GET",
        &format!("/v1/volumes/{id}/mesh?format=stl"),
        &[],
        &[],
    );
    let p = assert_problem(&r, 422, "too-many-triangles");
    let detail = p["detail"].as_str().unwrap();
    assert!(detail.contains("over the limit of 100"), "{detail}");
}
