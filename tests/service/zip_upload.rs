//! Zip uploads over HTTP (issue 34): an OBJ with its `.mtl` in a folder of a `.zip`, coloured by
//! the library's `Kd` colours; and the archives refused, each with a problem naming the entry:
//! a path out of the archive, a symbolic link, a bomb, too many entries, no mesh, two meshes.

use std::io::Write;

use super::*;

/// A zip of `entries` (name, bytes), deflated.
pub(super) fn zip_of(entries: &[(&str, &[u8])]) -> Vec<u8> {
    let mut w = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
    let opts = zip::write::SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Deflated);
    for (name, bytes) in entries {
        w.start_file(*name, opts).unwrap();
        w.write_all(bytes).unwrap();
    }
    w.finish().unwrap().into_inner()
}

/// Two unit cubes side by side, `usemtl red` and `usemtl blue`, their library `m.mtl`.
fn two_cubes() -> (String, String) {
    let obj = material_boxes_obj(
        "m.mtl",
        &[
            ("red", [0.0; 3], [1.0; 3]),
            ("blue", [2.0, 0.0, 0.0], [3.0, 1.0, 1.0]),
        ],
    );
    let mtl = "newmtl red\nKd 1 0 0\nnewmtl blue\nKd 0 0 1\n".to_string();
    (obj, mtl)
}

#[test]
fn a_zipped_obj_brings_its_materials() {
    let dir = tmpdir("zip-upload");
    let srv = Server::start(&dir, &[]);
    let (obj, mtl) = two_cubes();
    let body = zip_of(&[
        ("model/", b""),
        ("model/cubes.obj", obj.as_bytes()),
        ("model/m.mtl", mtl.as_bytes()),
        ("readme.txt", b"two cubes"),
    ]);
    let v = srv.created(
        "/v1/voxelize?origin=-0.5,-0.5,-0.5&voxel_size=0.25&dims=16,8,8&color=true&material=true&wait=60",
        &[("Content-Type", "application/zip")],
        &body,
    );
    assert_eq!(v["source"]["format"], "obj", "{v}");
    assert_eq!(v["source"]["compression"], "zip", "{v}");
    let names: Vec<&str> = v["attributes"]["materials"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["red", "blue"]);
    let id = v["id"].as_str().unwrap().to_string();
    let c = rgba_of(&srv, &id);
    // Voxel x = 2..6 is the red cube ([0, 1]), x = 10..14 the blue one ([2, 3]).
    let at = |x: usize, y: usize, z: usize| c[(x * 8 + y) * 8 + z];
    assert_eq!(at(3, 3, 3), [255, 0, 0, 255]);
    assert_eq!(at(11, 3, 3), [0, 0, 255, 255]);
}

/// The textured cube of the colour tests as an OBJ: `vt` lines (OBJ's v up: 1 − the glTF
/// coordinate), faces `a/a/a` and, for the last face, relative indices `-k/-k`.
fn textured_cube_obj() -> String {
    let (p, uv, tris) = super::colour::cube();
    let mut obj = String::from("mtllib model.mtl\n");
    for q in &p {
        obj += &format!("v {} {} {}\n", q[0], q[1], q[2]);
    }
    for t in &uv {
        obj += &format!("vt {} {}\n", t[0], 1.0 - t[1]);
    }
    obj += "usemtl atlas\n";
    let n = p.len() as i64;
    for (face, idx) in tris.iter().enumerate() {
        for t in idx.chunks(3) {
            let corners: Vec<String> = t
                .iter()
                .map(|&i| {
                    let i = i64::from(i) + 1;
                    if face == 5 {
                        // Relative to the 24 vertices and 24 coordinates defined before.
                        format!("{}/{}", i - n - 1, i - n - 1)
                    } else {
                        format!("{i}/{i}/{i}")
                    }
                })
                .collect();
            obj += &format!("f {}\n", corners.join(" "));
        }
    }
    obj
}

/// A zipped OBJ whose `.mtl` names a `map_Kd` texture (a PNG in a subfolder, its path relative
/// to the library) is coloured from it: each face of the atlas cube its region's colour, exactly
/// as the glTF form of the same cube (tests/service/colour.rs).
#[test]
fn a_zipped_obj_brings_its_texture() {
    let dir = tmpdir("zip-texture");
    let srv = Server::start(&dir, &[]);
    let obj = textured_cube_obj();
    let mtl = b"newmtl atlas\nKd 1 1 1\nmap_Kd textures/atlas.png\n";
    let png = super::colour::atlas();
    let body = zip_of(&[
        ("cube/model.obj", obj.as_bytes()),
        ("cube/model.mtl", mtl),
        ("cube/textures/atlas.png", &png),
    ]);
    let v = srv.created(
        "/v1/voxelize?origin=0,0,0&voxel_size=1&dims=10,10,10&method=surface&color=true&wait=60",
        &[("Content-Type", "application/zip")],
        &body,
    );
    assert_eq!(v["source"]["compression"], "zip", "{v}");
    super::colour::assert_atlas_colours(&srv, v["id"].as_str().unwrap());
    // Without the texture in the archive, the material's Kd (white): every set voxel white.
    let body = zip_of(&[("cube/model.obj", obj.as_bytes()), ("cube/model.mtl", mtl)]);
    let v = srv.created(
        "/v1/voxelize?origin=0,0,0&voxel_size=1&dims=10,10,10&method=surface&color=true&wait=60",
        &[("Content-Type", "application/zip")],
        &body,
    );
    let id = v["id"].as_str().unwrap();
    let colours: std::collections::BTreeSet<[u8; 4]> = rgba_of(&srv, id).into_iter().collect();
    assert_eq!(
        colours.into_iter().collect::<Vec<_>>(),
        [[0u8, 0, 0, 0], [255, 255, 255, 255]]
    );
}

#[test]
fn unsafe_archives_are_refused_naming_the_entry() {
    let dir = tmpdir("zip-refusals");
    let srv = Server::start(&dir, &[]);
    let (obj, _) = two_cubes();
    let post = |body: &[u8]| {
        srv.req(
            "POST",
            "/v1/voxelize?resolution=8&wait=30",
            &[("Content-Type", "application/zip")],
            body,
        )
    };
    let detail = |body: &[u8]| {
        let r = post(body);
        assert_problem(&r, 422, "invalid-mesh")["detail"]
            .as_str()
            .unwrap()
            .to_string()
    };
    let d = detail(&zip_of(&[("../evil.obj", obj.as_bytes())]));
    assert!(d.contains("../evil.obj") && d.contains("outside"), "{d}");
    let d = detail(&zip_of(&[("/abs.obj", obj.as_bytes())]));
    assert!(d.contains("abs.obj"), "{d}");
    // A symbolic link, even to a file inside.
    let mut w = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
    let opts = zip::write::SimpleFileOptions::default();
    w.start_file("a.obj", opts).unwrap();
    w.write_all(obj.as_bytes()).unwrap();
    w.add_symlink("m.mtl", "/etc/passwd", opts).unwrap();
    let d = detail(&w.finish().unwrap().into_inner());
    assert!(d.contains("m.mtl") && d.contains("symbolic link"), "{d}");
    // A bomb: 64 MiB of zeros deflate about a thousand times.
    let zeros = vec![0u8; 64 << 20];
    let d = detail(&zip_of(&[("a.obj", obj.as_bytes()), ("pad.bin", &zeros)]));
    assert!(d.contains("pad.bin") && d.contains("bomb"), "{d}");
    // Too many entries, no mesh, two meshes.
    let many: Vec<(String, Vec<u8>)> = (0..1025).map(|i| (format!("f{i}.txt"), vec![])).collect();
    let many: Vec<(&str, &[u8])> = many
        .iter()
        .map(|(n, b)| (n.as_str(), b.as_slice()))
        .collect();
    let d = detail(&zip_of(&many));
    assert!(d.contains("1025 entries"), "{d}");
    let d = detail(&zip_of(&[("a.txt", b"x")]));
    assert!(d.contains("no mesh"), "{d}");
    let d = detail(&zip_of(&[
        ("a.obj", obj.as_bytes()),
        ("b.stl", b"solid x\nendsolid x\n"),
    ]));
    assert!(d.contains("a.obj") && d.contains("b.stl"), "{d}");
}
