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
    let mut b = vec![];
    for p in [[0f32, 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]] {
        for c in p {
            b.extend_from_slice(&c.to_le_bytes());
        }
    }
    for i in [0u16, 1, 2, 0, 2, 3] {
        b.extend_from_slice(&i.to_le_bytes());
    }
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
                base_color: [1.0, 0.0, 0.0, 1.0]
            },
            Material {
                name: "material 1".into(),
                base_color: [0.0, 0.5, 1.0, 0.25]
            },
            Material {
                name: "default".into(),
                base_color: [1.0; 4]
            },
        ]
    );
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
