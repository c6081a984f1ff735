//! Colours and materials the loaders keep (issue 34): glTF `COLOR_0` (normalized bytes here)
//! and materials (the document's table, glTF's default material after it for a primitive
//! without one), PLY `red`/`green`/`blue`/`alpha` (bytes and floats), nothing invented for a
//! file without them, and `voxd info` naming them. The expected values are written out here
//! from the files' bytes, not computed by the loaders' code.

use crate::common::*;
use base64::Engine as _;
use voxd::mesh::{self, Format, LoadOptions, Material, Mesh};

fn load(bytes: &[u8], f: Option<Format>) -> Mesh {
    mesh::load_bytes_as(bytes, f, &LoadOptions::default())
        .unwrap()
        .0
}

/// A quad (4 positions, 6 indices) drawn twice: once with byte colours and material 1, once
/// with neither.
fn coloured_gltf() -> Vec<u8> {
    // The loaders' tests' quad (48 bytes of positions, 12 of indices), then the colours.
    let mut b = crate::loaders::quad_buffer();
    b.extend_from_slice(&[
        255, 0, 0, 255, 0, 255, 0, 128, 0, 0, 255, 0, 51, 102, 153, 255,
    ]);
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&b)
    );
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
        "materials":[{{"name":"red","pbrMetallicRoughness":{{"baseColorFactor":[1,0,0,1]}}}},
                     {{"pbrMetallicRoughness":{{"baseColorFactor":[0,0.5,1,0.25]}}}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0,"COLOR_0":2}},"indices":1,"material":1}},
                                  {{"attributes":{{"POSITION":0}},"indices":1}}]}}],
        "buffers":[{{"uri":"{uri}","byteLength":76}}],
        "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":48}},{{"buffer":0,"byteOffset":48,"byteLength":12}},
                       {{"buffer":0,"byteOffset":60,"byteLength":16}}],
        "accessors":[{{"bufferView":0,"componentType":5126,"count":4,"type":"VEC3"}},
                     {{"bufferView":1,"componentType":5123,"count":6,"type":"SCALAR"}},
                     {{"bufferView":2,"componentType":5121,"normalized":true,"count":4,"type":"VEC4"}}]}}"#
    )
    .into_bytes()
}

#[test]
fn gltf_keeps_vertex_colours_and_the_material_table() {
    let m = load(&coloured_gltf(), Some(Format::Gltf));
    let a = m.attributes();
    let c = a.colors.as_ref().expect("COLOR_0 kept");
    assert_eq!(c.len(), 8);
    let byte = |v: u8| f32::from(v) / 255.0;
    let want_first = [
        [1.0, 0.0, 0.0, 1.0],
        [0.0, 1.0, 0.0, byte(128)],
        [0.0, 0.0, 1.0, 0.0],
        [byte(51), byte(102), byte(153), 1.0],
    ];
    for (got, want) in c[..4].iter().zip(want_first) {
        for k in 0..4 {
            assert!((got[k] - want[k]).abs() < 1e-6, "{got:?} vs {want:?}");
        }
    }
    // The second primitive has no COLOR_0: white (glTF multiplies by the vertex colour).
    assert!(c[4..].iter().all(|&v| v == [1.0; 4]));
    // Material 1 for the first quad; the default material (after the table) for the second.
    assert_eq!(a.material.as_deref(), Some(&[1u16, 1, 2, 2][..]));
    assert_eq!(
        a.materials,
        vec![
            Material {
                name: "red".into(),
                base_color: [1.0, 0.0, 0.0, 1.0],
                texture: None,
            },
            Material {
                name: "material 1".into(),
                base_color: [0.0, 0.5, 1.0, 0.25],
                texture: None,
            },
            Material {
                name: "default".into(),
                base_color: [1.0; 4],
                texture: None,
            },
        ]
    );
}

/// A glTF's texture coordinates are kept one per position, through the material's
/// `KHR_texture_transform`: a quad drawn first with an untextured material (its positions get
/// zeros), then with a textured one whose transform scales by (2, 4) and offsets by
/// (0.5, 0.25). The expected values are computed here from the file's numbers.
#[test]
fn gltf_texture_coordinates_are_kept_per_vertex_through_the_transform() {
    let mut b = crate::loaders::quad_buffer();
    let uv = [[0.1f32, 0.2], [0.3, 0.4], [0.5, 0.6], [0.7, 0.8]];
    for c in uv.iter().flatten() {
        b.extend_from_slice(&c.to_le_bytes());
    }
    let mut png = vec![];
    image::RgbaImage::from_pixel(2, 2, image::Rgba([10, 20, 30, 255]))
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    let b64 = |d: &[u8]| base64::engine::general_purpose::STANDARD.encode(d);
    let gltf = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
        "extensionsUsed":["KHR_texture_transform"],
        "images":[{{"uri":"data:image/png;base64,{png}"}}],"textures":[{{"source":0}}],
        "materials":[{{"name":"wood","pbrMetallicRoughness":{{"baseColorTexture":{{"index":0,
                        "extensions":{{"KHR_texture_transform":{{"offset":[0.5,0.25],"scale":[2,4]}}}}}}}}}},
                     {{"name":"plain","pbrMetallicRoughness":{{"baseColorFactor":[1,1,1,1]}}}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"indices":1,"material":1}},
                                  {{"attributes":{{"POSITION":0,"TEXCOORD_0":2}},"indices":1,"material":0}}]}}],
        "buffers":[{{"uri":"data:application/octet-stream;base64,{buf}","byteLength":92}}],
        "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":48}},{{"buffer":0,"byteOffset":48,"byteLength":12}},
                       {{"buffer":0,"byteOffset":60,"byteLength":32}}],
        "accessors":[{{"bufferView":0,"componentType":5126,"count":4,"type":"VEC3"}},
                     {{"bufferView":1,"componentType":5123,"count":6,"type":"SCALAR"}},
                     {{"bufferView":2,"componentType":5126,"count":4,"type":"VEC2"}}]}}"#,
        png = b64(&png),
        buf = b64(&b),
    );
    let opts = LoadOptions {
        textures: true,
        ..LoadOptions::default()
    };
    let m = mesh::load_bytes_as(gltf.as_bytes(), Some(Format::Gltf), &opts)
        .unwrap()
        .0;
    let a = m.attributes();
    assert_eq!(a.images.len(), 1);
    let Some(mesh::Uv::Vertices(got)) = a.uv.as_ref() else {
        panic!("a glTF's texture coordinates are per vertex: {:?}", a.uv)
    };
    assert_eq!(got.len(), 8, "one per position");
    assert!(
        got[..4].iter().all(|&c| c == [0.0; 2]),
        "untextured: {got:?}"
    );
    for (g, w) in got[4..].iter().zip(uv) {
        let want = [2.0 * w[0] + 0.5, 4.0 * w[1] + 0.25];
        assert!(
            (g[0] - want[0]).abs() < 1e-6 && (g[1] - want[1]).abs() < 1e-6,
            "{g:?} vs {want:?}"
        );
    }
    // The second quad's triangles read them through their indices (0, 1, 2 and 0, 2, 3).
    let uvs = a.uv.as_ref().unwrap();
    let tris = m.triangles();
    assert_eq!(uvs.corners(2, tris[2]), [got[4], got[5], got[6]]);
    assert_eq!(uvs.corners(3, tris[3]), [got[4], got[6], got[7]]);
}

fn ply(props: &str, rows: &[&str]) -> Vec<u8> {
    format!(
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n{props}element face 1\nproperty list uchar int vertex_indices\nend_header\n{}\n3 0 1 2\n",
        rows.join("\n")
    )
    .into_bytes()
}

#[test]
fn ply_keeps_byte_and_float_colours_and_invents_none() {
    let bytes = ply(
        "property uchar red\nproperty uchar green\nproperty uchar blue\nproperty uchar alpha\n",
        &["0 0 0 255 0 0 255", "1 0 0 0 255 0 51", "0 1 0 0 0 255 0"],
    );
    let m = load(&bytes, Some(Format::Ply));
    let c = m.attributes().colors.clone().expect("colours kept");
    assert_eq!(
        c,
        vec![
            [1.0, 0.0, 0.0, 1.0],
            [0.0, 1.0, 0.0, 0.2],
            [0.0, 0.0, 1.0, 0.0]
        ]
    );
    // Floats as written (no alpha: 1), clamped to [0, 1].
    let floats = ply(
        "property float red\nproperty float green\nproperty float blue\n",
        &["0 0 0 0.25 0.5 1.5", "1 0 0 0 0 0", "0 1 0 1 1 1"],
    );
    let c = load(&floats, Some(Format::Ply))
        .attributes()
        .colors
        .clone()
        .unwrap();
    assert_eq!(c[0], [0.25, 0.5, 1.0, 1.0]);
    assert_eq!(c[1], [0.0, 0.0, 0.0, 1.0]);
    // Without colour properties (or with only some of them): none.
    let plain = ply("", &["0 0 0", "1 0 0", "0 1 0"]);
    assert!(load(&plain, Some(Format::Ply)).attributes().is_empty());
    let partial = ply("property uchar red\n", &["0 0 0 255", "1 0 0 0", "0 1 0 0"]);
    assert!(load(&partial, Some(Format::Ply)).attributes().is_empty());
}

#[test]
fn info_names_the_attributes() {
    let o = run_voxd(&["info", data("Box.gltf").to_str().unwrap()]);
    assert!(o.status.success());
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        out.contains("attributes: 1 material: material 0 [0.800 0.000 0.000 1.000]"),
        "{out}"
    );
    let o = run_voxd(&["info", data("spot.obj").to_str().unwrap()]);
    assert!(String::from_utf8_lossy(&o.stdout).contains("attributes: none"));
}

/// OBJ: `v x y z r g b` (six numbers; four is `w`, not a colour) and `usemtl` names, checked
/// against a plain line-by-line reading written here, on a file large enough to be read in
/// several parallel chunks (and, gzip'd, in several blocks), so that a material in force
/// across a chunk's start is inherited.
#[test]
fn obj_keeps_vertex_colours_and_usemtl_across_chunks_and_blocks() {
    let small = b"v 0 0 0 1 0 0\nv 1 0 0 0 0.5 0\nv 0 1 0 1\nv 1 1 0\nf 1 2 3\nusemtl b\nf 2 4 3\nusemtl a x\nf 1 2 4\nusemtl b\nf 1 4 3\n";
    let m = load(small, Some(Format::Obj));
    let a = m.attributes();
    assert_eq!(
        a.colors.as_deref(),
        Some(
            &[
                [1.0, 0.0, 0.0, 1.0],
                [0.0, 0.5, 0.0, 1.0],
                [1.0; 4],
                [1.0; 4]
            ][..]
        )
    );
    assert_eq!(a.material.as_deref(), Some(&[2u16, 0, 1, 0][..]));
    let names: Vec<&str> = a.materials.iter().map(|m| m.name.as_str()).collect();
    assert_eq!(names, ["b", "a x", "default"]);
    // A file without either: nothing.
    assert!(
        load(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", Some(Format::Obj))
            .attributes()
            .is_empty()
    );

    // Large: 300 × 300 vertices (every third coloured), two triangles a cell, a `usemtl`
    // (one of five names) every 7919 faces.
    let n = 300u32;
    let mut text = String::new();
    let mut want_colors = vec![];
    for y in 0..n {
        for x in 0..n {
            let i = y * n + x;
            if i.is_multiple_of(3) {
                let c = [(i % 256) as f32 / 255.0, 0.25, 1.0];
                text += &format!("v {x} {y} 0 {} {} {}\n", c[0], c[1], c[2]);
                want_colors.push([c[0], c[1], c[2], 1.0]);
            } else {
                text += &format!("v {x} {y} 0\n");
                want_colors.push([1.0; 4]);
            }
        }
    }
    let mut want_ids: Vec<Option<usize>> = vec![];
    let mut current: Option<usize> = None;
    let mut faces = 0usize;
    for y in 0..n - 1 {
        for x in 0..n - 1 {
            let v = |dx: u32, dy: u32| (y + dy) * n + x + dx + 1;
            for f in [[v(0, 0), v(1, 0), v(1, 1)], [v(0, 0), v(1, 1), v(0, 1)]] {
                if faces > 0 && faces.is_multiple_of(7919) {
                    let k = (faces / 7919) % 5;
                    text += &format!("usemtl mat{k}\n");
                    current = Some(k);
                }
                text += &format!("f {} {} {}\n", f[0], f[1], f[2]);
                want_ids.push(current);
                faces += 1;
            }
        }
    }
    assert!(text.len() > 3 << 20, "several chunks: {} bytes", text.len());
    for bytes in [text.as_bytes().to_vec(), gz(text.as_bytes())] {
        let m = load(&bytes, Some(Format::Obj));
        let a = m.attributes();
        let colors = a.colors.as_ref().unwrap();
        assert_eq!(colors.len(), want_colors.len());
        for (g, w) in colors.iter().zip(&want_colors) {
            assert!((0..4).all(|k| (g[k] - w[k]).abs() < 1e-6), "{g:?} vs {w:?}");
        }
        // Names in the order of first use: mat1, mat2, mat3, mat4, mat0; then the default.
        let names: Vec<&str> = a.materials.iter().map(|m| m.name.as_str()).collect();
        assert_eq!(names, ["mat1", "mat2", "mat3", "mat4", "mat0", "default"]);
        let id = |w: Option<usize>| match w {
            None => 5u16,
            Some(0) => 4,
            Some(k) => (k - 1) as u16,
        };
        let want: Vec<u16> = want_ids.iter().map(|&w| id(w)).collect();
        assert_eq!(a.material.as_deref(), Some(&want[..]));
    }
}

/// An OBJ read from a file takes its materials' base colours from the `mtllib` beside it
/// (`Kd`, `d`); a library that is missing leaves them white, one outside the directory is not
/// read, and over HTTP (no files) none is read.
#[test]
fn obj_materials_take_kd_from_the_mtllib_beside_the_file() {
    let top = tmpdir("attributes-mtl");
    let dir = top.join("model");
    std::fs::create_dir_all(&dir).unwrap();
    let obj = b"mtllib paints.mtl missing.mtl ../outside.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nusemtl red paint\nf 1 2 3\nusemtl ghost\nf 2 4 3\n";
    std::fs::write(dir.join("m.obj"), obj).unwrap();
    std::fs::write(
        dir.join("paints.mtl"),
        b"newmtl red paint\nKd 0.8 0.1 0.2\nd 0.5\nnewmtl unused\nKd 0 1 0\n",
    )
    .unwrap();
    std::fs::write(top.join("outside.mtl"), b"newmtl ghost\nKd 0 0 1\n").unwrap();
    let m = mesh::load_file(&dir.join("m.obj"), usize::MAX).unwrap();
    let a = m.attributes();
    assert_eq!(
        a.materials,
        vec![
            Material {
                name: "red paint".into(),
                base_color: [0.8, 0.1, 0.2, 0.5],
                texture: None,
            },
            Material {
                name: "ghost".into(),
                base_color: [1.0; 4],
                texture: None,
            },
        ]
    );
    assert_eq!(a.material.as_deref(), Some(&[0u16, 1][..]));
    // The same bytes without a file (as over HTTP): names only.
    let m = load(obj, Some(Format::Obj));
    assert!(
        m.attributes()
            .materials
            .iter()
            .all(|m| m.base_color == [1.0; 4])
    );
    let o = run_voxd(&["info", dir.join("m.obj").to_str().unwrap()]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        out.contains(
            "2 materials: red paint [0.800 0.100 0.200 0.500], ghost [1.000 1.000 1.000 1.000]"
        ),
        "{out}"
    );
}

/// An OBJ read from a file takes its `map_Kd` textures from beside it: the image decoded, each
/// triangle's corners' coordinates in glTF's convention (v down: 1 − OBJ's v) with the
/// library's `-s`/`-o` applied, zeros where a material has no texture or a corner none; `-clamp
/// on` clamps. A missing image leaves the material untextured; without `vt` lines no texture is
/// kept; over HTTP (no files) neither.
#[test]
fn obj_textures_come_from_map_kd_beside_the_file() {
    use voxd::mesh::texture::Wrap;
    let dir = tmpdir("attributes-map-kd");
    std::fs::create_dir_all(dir.join("tex")).unwrap();
    let mut png = vec![];
    image::RgbaImage::from_pixel(4, 2, image::Rgba([10, 20, 30, 255]))
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    std::fs::write(dir.join("tex/wood.png"), &png).unwrap();
    std::fs::write(
        dir.join("m.mtl"),
        "newmtl wood\nmap_Kd -s 2 4 -o 0.5 0.25 -clamp on tex/wood.png\nnewmtl plain\nKd 0.5 0.5 0.5\nnewmtl lost\nmap_Kd nowhere.png\n",
    )
    .unwrap();
    let obj = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\nvt 0.25 0.5\nvt 1 1\nusemtl wood\nf 1/1 2/2/2 3/-1\nf 2 4 3\nusemtl plain\nf 1/1 3/3 4/2\nusemtl lost\nf 1/1 2/2 4/3\n";
    std::fs::write(dir.join("m.obj"), obj).unwrap();
    let m = mesh::load_file(&dir.join("m.obj"), usize::MAX).unwrap();
    let a = m.attributes();
    assert_eq!(a.images.len(), 1);
    assert_eq!((a.images[0].width, a.images[0].height), (4, 2));
    assert_eq!(a.images[0].rgba_at(0), [10, 20, 30, 255]);
    let t = a.materials[0].texture.expect("wood has its texture");
    assert_eq!(t.wrap, [Wrap::ClampToEdge; 2]);
    assert_eq!(a.materials[1].texture, None);
    assert_eq!(a.materials[1].base_color, [0.5, 0.5, 0.5, 1.0]);
    assert_eq!(a.materials[2].texture, None, "nowhere.png is missing");
    // (u, v) → (2u + 0.5, 1 − (4v + 0.25)).
    let Some(mesh::Uv::Corners(uv)) = a.uv.as_ref() else {
        panic!("an OBJ's texture coordinates are per corner: {:?}", a.uv)
    };
    assert_eq!(uv[0], [[0.5, 0.75], [1.0, -1.25], [2.5, -3.25]]);
    assert_eq!(uv[1], [[0.0; 2]; 3], "corners without vt");
    assert_eq!(uv[2], [[0.0; 2]; 3], "plain has no texture");
    assert_eq!(uv[3], [[0.0; 2]; 3], "lost's texture was not read");
    // A vt index past the file's: refused with the line.
    std::fs::write(
        dir.join("bad.obj"),
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/2 3/1\n",
    )
    .unwrap();
    let e = mesh::load_file(&dir.join("bad.obj"), usize::MAX)
        .unwrap_err()
        .to_string();
    assert!(e.contains("line 5: texture coordinate index 2 is out of range (the file has 1 texture coordinates)"), "{e}");
    // The same bytes over HTTP: no files, so no texture (and no vt kept).
    let m = load(obj.as_bytes(), Some(Format::Obj));
    assert!(m.attributes().images.is_empty() && m.attributes().uv.is_none());
}

/// Texture coordinates resolve across the reader's chunks (a file of several MB is parsed in
/// parallel pieces): relative `vt` indices count back from the coordinates defined before
/// their line, absolute ones from the file's first, whichever chunk holds them; and a gzip'd
/// copy (read in blocks) gives the same.
#[test]
fn texture_coordinates_resolve_across_chunks_and_blocks() {
    let dir = tmpdir("attributes-vt-chunks");
    let mut png = vec![];
    image::RgbaImage::from_pixel(2, 2, image::Rgba([200, 100, 50, 255]))
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    std::fs::write(dir.join("t.png"), &png).unwrap();
    std::fs::write(dir.join("m.mtl"), "newmtl t\nmap_Kd t.png\n").unwrap();
    let quads = 60_000;
    let mut obj = String::from("mtllib m.mtl\nusemtl t\n");
    for q in 0..quads {
        let x = q as f64;
        obj += &format!("v {x} 0 0\nv {x} 1 0\nv {x} 1 1\nv {x} 0 1\n");
        for k in 0..4 {
            obj += &format!("vt {} {}\n", q % 1000, k);
        }
        if q % 2 == 0 {
            obj += "f -4/-4 -3/-3 -2/-2 -1/-1\n";
        } else {
            let b = 4 * q + 1;
            obj += &format!(
                "f {b}/{b} {}/{} {}/{} {}/{}\n",
                b + 1,
                b + 1,
                b + 2,
                b + 2,
                b + 3,
                b + 3
            );
        }
    }
    assert!(obj.len() > 4 << 20, "{} bytes: several chunks", obj.len());
    std::fs::write(dir.join("m.obj"), &obj).unwrap();
    std::fs::write(dir.join("m.obj.gz"), gz(obj.as_bytes())).unwrap();
    for f in ["m.obj", "m.obj.gz"] {
        let m = mesh::load_file(&dir.join(f), usize::MAX).unwrap();
        let Some(mesh::Uv::Corners(uv)) = m.attributes().uv.as_ref() else {
            panic!("{f}: an OBJ's texture coordinates are per corner")
        };
        assert_eq!(uv.len(), 2 * quads);
        for q in 0..quads {
            let u = (q % 1000) as f32;
            assert_eq!(uv[2 * q], [[u, 1.0], [u, 0.0], [u, -1.0]], "{f}: quad {q}");
            assert_eq!(
                uv[2 * q + 1],
                [[u, 1.0], [u, -1.0], [u, -2.0]],
                "{f}: quad {q}"
            );
        }
    }
}

/// The command line's CSG and morphology carry colour and material channels as the service does
/// (tests/service/colour_ops.rs): the union's material table in the `.vxl` header merges the
/// operands' tables, the first operand wins where both are set, and a dilation's added voxels
/// are coloured.
#[test]
fn cli_csg_and_morph_keep_colour_and_materials() {
    let dir = tmpdir("attributes-cli-carry");
    let cube = |name: &str, kd: &str, x0: f64| {
        let obj = material_boxes_obj(
            &format!("{name}.mtl"),
            &[(name, [x0 + 1.0, 1.0, 1.0], [x0 + 5.0, 5.0, 5.0])],
        );
        std::fs::write(dir.join(format!("{name}.obj")), obj).unwrap();
        std::fs::write(
            dir.join(format!("{name}.mtl")),
            format!("newmtl {name}\nKd {kd}\n"),
        )
        .unwrap();
        let out = dir.join(format!("{name}.vxl"));
        let o = run_voxd(&[
            "voxelize",
            dir.join(format!("{name}.obj")).to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--origin=0,0,0",
            "--voxel-size=1",
            "--dims=10,6,6",
            "--color",
            "--material",
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        out
    };
    let (red, blue) = (cube("red", "1 0 0", 0.0), cube("blue", "0 0 1", 2.0));
    let union = dir.join("union.vxl");
    let o = run_voxd(&[
        "csg",
        "union",
        red.to_str().unwrap(),
        blue.to_str().unwrap(),
        "-o",
        union.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (v, meta) = voxd::codec::vxl::decode(&std::fs::read(&union).unwrap()).unwrap();
    let names: Vec<&str> = meta["materials"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["red", "blue"]);
    let voxd::volume::Volume::Channels(a) = v else {
        panic!("channels")
    };
    use voxd::volume::kind::VoxelValue;
    // Red covers x 1..5, blue x 3..7: x = 3 is both (red first), x = 6 blue only.
    assert_eq!(
        a.value("rgba", 1, 2, 2),
        Some(VoxelValue::Rgba8([255, 0, 0, 255]))
    );
    assert_eq!(
        a.value("rgba", 3, 2, 2),
        Some(VoxelValue::Rgba8([255, 0, 0, 255]))
    );
    assert_eq!(
        a.value("rgba", 6, 2, 2),
        Some(VoxelValue::Rgba8([0, 0, 255, 255]))
    );
    assert_eq!(a.value("material", 6, 2, 2), Some(VoxelValue::U16(1)));
    let fat = dir.join("fat.vxl");
    let o = run_voxd(&[
        "morph",
        "dilate",
        blue.to_str().unwrap(),
        "-o",
        fat.to_str().unwrap(),
        "--radius",
        "1",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (v, meta) = voxd::codec::vxl::decode(&std::fs::read(&fat).unwrap()).unwrap();
    assert_eq!(meta["materials"][0]["name"], "blue");
    let voxd::volume::Volume::Channels(a) = v else {
        panic!("channels")
    };
    assert!(a.len() > 4 * 4 * 4);
    assert!(a.colours().unwrap().iter().all(|&c| c == [0, 0, 255, 255]));
    assert_eq!(
        a.value("rgba", 2, 2, 2),
        Some(VoxelValue::Rgba8([0, 0, 255, 255])),
        "an added voxel"
    );
}
