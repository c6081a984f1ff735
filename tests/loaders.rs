//! Every loader on every format, and every malformed-input error path.

use crate::common::*;
use base64::Engine as _;
use voxd::mesh::{self, ExternalResources, Format, LoadOptions, Mesh, MeshError};

fn opts() -> LoadOptions {
    LoadOptions::default()
}

fn load(bytes: &[u8], f: Option<Format>) -> Result<Mesh, MeshError> {
    mesh::load_bytes(bytes, f, &opts())
}

/// Triangles as position triples: what every format must agree on.
fn soup(m: &Mesh) -> Vec<[[f64; 3]; 3]> {
    (0..m.triangles().len()).map(|t| m.triangle(t)).collect()
}

/// spot.obj with every coordinate rounded to f32, so binary STL (f32) can hold it exactly.
fn spot() -> Mesh {
    let m = mesh::load_file(&data("spot.obj"), usize::MAX).unwrap();
    Mesh::new(f32_positions(&m), m.triangles().to_vec()).unwrap()
}

fn obj_text(m: &Mesh) -> Vec<u8> {
    let mut s = String::from("o spot\n");
    for p in m.positions() {
        s += &format!("v {} {} {}\n", p[0], p[1], p[2]);
    }
    for t in m.triangles() {
        s += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    s.into_bytes()
}

fn stl_binary(m: &Mesh) -> Vec<u8> {
    let mut b = b"solid but actually binary".to_vec();
    b.resize(80, b' ');
    b.extend_from_slice(&(m.triangles().len() as u32).to_le_bytes());
    for t in soup(m) {
        b.extend_from_slice(&[0u8; 12]);
        for p in t {
            for c in p {
                b.extend_from_slice(&(c as f32).to_le_bytes());
            }
        }
        b.extend_from_slice(&[0, 0]);
    }
    b
}

fn stl_ascii(m: &Mesh) -> Vec<u8> {
    let mut s = String::from("solid spot\n");
    for t in soup(m) {
        s += "  facet normal 0 0 1\n    outer loop\n";
        for p in t {
            s += &format!("      vertex {:e} {:e} {:e}\n", p[0], p[1], p[2]);
        }
        s += "    endloop\n  endfacet\n";
    }
    s += "endsolid spot\n";
    s.into_bytes()
}

/// PLY with every face written as given; `enc` is ascii, binary_little_endian or binary_big_endian.
fn ply(positions: &[[f64; 3]], faces: &[Vec<u32>], strips: Option<&[i32]>, enc: &str) -> Vec<u8> {
    let mut h = format!(
        "ply\nformat {enc} 1.0\ncomment made by voxd tests\nelement vertex {}\nproperty double x\nproperty float y\nproperty double z\nproperty uchar red\nelement face {}\nproperty list uchar int vertex_indices\n",
        positions.len(),
        faces.len()
    );
    if strips.is_some() {
        h += "element tristrips 1\nproperty list int int vertex_indices\n";
    }
    h += "end_header\n";
    let mut b = h.into_bytes();
    let be = enc == "binary_big_endian";
    let put = |b: &mut Vec<u8>, le: &[u8]| {
        if be {
            b.extend(le.iter().rev())
        } else {
            b.extend_from_slice(le)
        }
    };
    if enc == "ascii" {
        let mut s = String::new();
        for p in positions {
            s += &format!("{} {} {} 7\n", p[0], p[1], p[2]);
        }
        for f in faces {
            s += &format!(
                "{} {}\n",
                f.len(),
                f.iter()
                    .map(|i| i.to_string())
                    .collect::<Vec<_>>()
                    .join(" ")
            );
        }
        if let Some(st) = strips {
            s += &format!(
                "{} {}\n",
                st.len(),
                st.iter()
                    .map(|i| i.to_string())
                    .collect::<Vec<_>>()
                    .join(" ")
            );
        }
        b.extend_from_slice(s.as_bytes());
        return b;
    }
    for p in positions {
        put(&mut b, &p[0].to_le_bytes());
        put(&mut b, &(p[1] as f32).to_le_bytes());
        put(&mut b, &p[2].to_le_bytes());
        b.push(7);
    }
    for f in faces {
        b.push(f.len() as u8);
        for &i in f {
            put(&mut b, &(i as i32).to_le_bytes());
        }
    }
    if let Some(st) = strips {
        put(&mut b, &(st.len() as i32).to_le_bytes());
        for &i in st {
            put(&mut b, &i.to_le_bytes());
        }
    }
    b
}

fn f32_positions(m: &Mesh) -> Vec<[f64; 3]> {
    m.positions()
        .iter()
        .map(|p| p.map(|c| c as f32 as f64))
        .collect()
}

#[test]
fn every_format_gives_the_same_triangles() {
    let m = spot();
    let want = soup(&m);
    let faces: Vec<Vec<u32>> = m.triangles().iter().map(|t| t.to_vec()).collect();
    let positions = m.positions().to_vec();
    let mut cases: Vec<(&str, Vec<u8>, Option<Format>)> = vec![
        ("stl binary", stl_binary(&m), None),
        ("stl ascii", stl_ascii(&m), None),
        ("ply ascii", ply(&positions, &faces, None, "ascii"), None),
        (
            "ply le",
            ply(&positions, &faces, None, "binary_little_endian"),
            None,
        ),
        (
            "ply be",
            ply(&positions, &faces, None, "binary_big_endian"),
            None,
        ),
        ("obj", obj_text(&m), Some(Format::Obj)),
    ];
    let gzipped: Vec<_> = cases.iter().map(|(n, b, f)| (*n, gz(b), *f)).collect();
    cases.extend(gzipped);
    for (name, bytes, f) in cases {
        let got = load(&bytes, f).unwrap_or_else(|e| panic!("{name}: {e}"));
        let (g, w) = (soup(&got), &want);
        let first = g.iter().zip(w).position(|(a, b)| a != b);
        assert!(
            g.len() == w.len() && first.is_none(),
            "{name}: triangles differ from spot.obj ({} vs {}, first at {first:?}: {:?} vs {:?})",
            g.len(),
            w.len(),
            g[0],
            w[0]
        );
    }
}

#[test]
fn polygons_and_strips_are_triangulated() {
    // A unit square as a quad, a pentagon, and a strip with a restart.
    let p = vec![
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.5, 1.5, 0.0],
    ];
    let obj = b"o a\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0.5 1.5 0\ng g1\nf 1 2 3 4\ng g2\nf 1/1 2/1 3/1 5/1 4/1\nl 1 2\n";
    let m = load(obj, None).unwrap();
    let want: Vec<[[f64; 3]; 3]> = [[0, 1, 2], [0, 2, 3], [0, 1, 2], [0, 2, 4], [0, 4, 3]]
        .iter()
        .map(|t| t.map(|i| p[i]))
        .collect();
    assert_eq!(soup(&m), want);
    for enc in ["ascii", "binary_little_endian", "binary_big_endian"] {
        let faces = vec![vec![0, 1, 2, 3], vec![0, 1, 2, 4, 3]];
        let b = ply(&p, &faces, Some(&[0, 1, 3, 2, -1, 2, 3, 4]), enc);
        let m = load(&b, None).unwrap();
        assert_eq!(
            m.triangles(),
            &[
                [0, 1, 2],
                [0, 2, 3],
                [0, 1, 2],
                [0, 2, 4],
                [0, 4, 3],
                [0, 1, 3],
                [3, 1, 2],
                [2, 3, 4]
            ],
            "{enc}"
        );
    }
}

fn b64(b: &[u8]) -> String {
    base64::engine::general_purpose::STANDARD.encode(b)
}

/// A glTF with one buffer: 4 positions (f32) and 6 u16 indices, and the given primitives/nodes.
fn gltf_json(uri: &str, prims: &str, nodes: &str) -> String {
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":{nodes},
        "meshes":[{{"primitives":{prims}}}],
        "buffers":[{{"uri":"{uri}","byteLength":60}}],
        "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":48}},{{"buffer":0,"byteOffset":48,"byteLength":12}}],
        "accessors":[{{"bufferView":0,"componentType":5126,"count":4,"type":"VEC3"}},
                     {{"bufferView":1,"componentType":5123,"count":6,"type":"SCALAR"}},
                     {{"bufferView":1,"componentType":5123,"count":4,"type":"SCALAR"}}]}}"#
    )
}

/// Four f32 positions of a unit quad, then six u16 indices (its two triangles).
pub(crate) fn quad_buffer() -> Vec<u8> {
    let mut b = vec![];
    for p in [[0f32, 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]] {
        for c in p {
            b.extend_from_slice(&c.to_le_bytes());
        }
    }
    for i in [0u16, 1, 2, 0, 2, 3] {
        b.extend_from_slice(&i.to_le_bytes());
    }
    b
}

fn data_uri() -> String {
    format!(
        "data:application/octet-stream;base64,{}",
        b64(&quad_buffer())
    )
}

fn glb(json: &str, bin: &[u8]) -> Vec<u8> {
    let mut j = json.as_bytes().to_vec();
    while !j.len().is_multiple_of(4) {
        j.push(b' ');
    }
    let mut bin = bin.to_vec();
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let mut out = b"glTF".to_vec();
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&((12 + 8 + j.len() + 8 + bin.len()) as u32).to_le_bytes());
    out.extend_from_slice(&(j.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&j);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out
}

#[test]
fn gltf_modes_transforms_and_glb() {
    let tri = r#"[{"attributes":{"POSITION":0},"indices":1}]"#;
    // Node 0 translates by (10,0,0); its child scales by 2: the child's mesh lands at 10 + 2p.
    let nodes = r#"[{"translation":[10,0,0],"children":[1]},{"scale":[2,2,2],"mesh":0}]"#;
    let m = load(gltf_json(&data_uri(), tri, nodes).as_bytes(), None).unwrap();
    assert_eq!(m.triangles().len(), 2);
    assert_eq!(m.bounds(), ([10.0, 0.0, 0.0], [12.0, 2.0, 0.0]));
    // Strip (mode 5) and fan (mode 6) over indices 0 1 2 0 via accessor 2 (first 4 indices).
    let modes = r#"[{"attributes":{"POSITION":0},"indices":2,"mode":5},{"attributes":{"POSITION":0},"indices":2,"mode":6},{"attributes":{"POSITION":0},"mode":1}]"#;
    let plain = r#"[{"mesh":0}]"#;
    let m = load(gltf_json(&data_uri(), modes, plain).as_bytes(), None).unwrap();
    // Indices 0 1 2 0: the strip gives (0,1,2) and the odd, reversed (2,1,0); the fan (0,1,2) and
    // (0,2,0), offset by the strip primitive's 4 vertices; the line primitive is skipped.
    assert_eq!(m.triangles(), &[[0, 1, 2], [2, 1, 0], [4, 5, 6], [4, 6, 4]]);
    // The same as GLB, with the buffer in the BIN chunk.
    let json = gltf_json("", tri, plain).replace(r#""uri":"","#, "");
    let m = load(&glb(&json, &quad_buffer()), None).unwrap();
    assert_eq!(m.bounds(), ([0.0; 3], [1.0, 1.0, 0.0]));
    assert_eq!(load(&gz(&glb(&json, &quad_buffer())), None).unwrap(), m);
    // Attributes of semantics that are not read: application-specific (`_s`, legal per the
    // spec) and unknown ones (`FOO`, `TEXCOORD_x`) are ignored, gzip'd or not.
    let extra = r#"[{"attributes":{"POSITION":0,"_s":2,"FOO":2,"TEXCOORD_x":2},"indices":1}]"#;
    let json = gltf_json("", extra, plain).replace(r#""uri":"","#, "");
    assert_eq!(load(&glb(&json, &quad_buffer()), None).unwrap(), m);
    assert_eq!(load(&gz(&glb(&json, &quad_buffer())), None).unwrap(), m);
    // Real files: Box.gltf (embedded, rotated node) and Fox.glb (skinned; bind pose).
    let b = mesh::load_file(&data("Box.gltf"), usize::MAX).unwrap();
    assert_eq!(
        (b.triangles().len(), b.bounds()),
        (12, ([-0.5; 3], [0.5; 3]))
    );
    assert_eq!(
        mesh::load_file(&data("Fox.glb"), usize::MAX)
            .unwrap()
            .triangles()
            .len(),
        576
    );
}

#[test]
fn gltf_external_buffers_are_read_only_beside_the_file_and_only_when_allowed() {
    let dir = tmpdir("gltf");
    std::fs::create_dir_all(dir.join("sub")).unwrap();
    std::fs::write(dir.join("sub/quad data.bin"), quad_buffer()).unwrap();
    let tri = r#"[{"attributes":{"POSITION":0},"indices":1}]"#;
    let plain = r#"[{"mesh":0}]"#;
    let ok = gltf_json("sub/quad%20data.bin", tri, plain);
    // Denied (the service's setting): never read, whatever the path.
    for uri in [
        "sub/quad%20data.bin",
        "/etc/passwd",
        "../x.bin",
        "file:///etc/passwd",
    ] {
        let e = load(gltf_json(uri, tri, plain).as_bytes(), None).unwrap_err();
        assert!(matches!(e, MeshError::ExternalRefused { .. }), "{uri}: {e}");
    }
    let beside = LoadOptions {
        external: ExternalResources::BesideFile(dir.clone()),
        ..opts()
    };
    assert_eq!(
        mesh::load_bytes(ok.as_bytes(), None, &beside)
            .unwrap()
            .triangles()
            .len(),
        2
    );
    for uri in [
        "/etc/passwd",
        "../x.bin",
        "sub/../../x.bin",
        "file:///etc/passwd",
        "http://example.com/a.bin",
    ] {
        let e = mesh::load_bytes(gltf_json(uri, tri, plain).as_bytes(), None, &beside).unwrap_err();
        assert!(matches!(e, MeshError::ExternalRefused { .. }), "{uri}: {e}");
    }
    std::fs::remove_dir_all(dir).unwrap();
}

/// voxd's parallel OBJ reader against tobj, on real files and on the syntax corners.
#[test]
fn fast_obj_reader_agrees_with_tobj() {
    let mut files: Vec<(String, Vec<u8>)> =
        vec![("spot.obj".into(), std::fs::read(data("spot.obj")).unwrap())];
    if let Some(dir) = shared_meshes() {
        for f in [
            "stanford-bunny.obj",
            "teapot.obj",
            "suzanne.obj",
            "rocker-arm.obj",
            "ogre.obj",
            "igea.obj",
        ] {
            files.push((f.into(), std::fs::read(dir.join(f)).unwrap()));
        }
    }
    let corners = "# corners\nmtllib x.mtl\no a\nv 0 0 0\nv 1 0 0 1.0\nvt 0 0\nvn 0 0 1\nv 1 1 0\n\tv  0 1 0\ng g\nusemtl m\nf 1/1/1 2/1/1 3/1/1 4/1/1\nf -4//1 -3//1 -2//1\nl 1 2\np 3\nv 2 2 2\nf -1 1 2\r\nf 3 4 5 1 2 \n";
    files.push(("corners".into(), corners.as_bytes().to_vec()));
    // Big enough to be cut into several chunks, with relative indices across chunk borders.
    let mut big = String::new();
    for i in 0..120_000 {
        big += &format!(
            "v {i} {} 0.5\nv {i} 1 {}\nv 0 {i} 1e-3\nf -3 -2 -1\n",
            i % 7,
            i % 3
        );
    }
    files.push(("big".into(), big.into_bytes()));
    for (name, bytes) in files {
        let fast = load(&bytes, Some(Format::Obj)).unwrap_or_else(|e| panic!("{name}: {e}"));
        let reference = obj_with_tobj(&bytes);
        assert!(
            soup(&fast) == soup(&reference),
            "{name}: the fast reader and tobj disagree"
        );
    }
    // tobj 4.0.5 fails this valid file once a smoothing-group line is added; the fast reader does not.
    let with_s = corners.replace("usemtl m\n", "usemtl m\ns 1\n");
    assert_eq!(
        load(with_s.as_bytes(), Some(Format::Obj))
            .unwrap()
            .triangles()
            .len(),
        7
    );
    // A backslash at the end of a line continues it.
    let cont = b"v 0 0 0\nv 1 0 \\\r\n 0\nv 0 1 0\nf 1 \\\n 2 3\n";
    assert_eq!(
        load(cont, Some(Format::Obj)).unwrap().bounds(),
        ([0.0; 3], [1.0, 1.0, 0.0])
    );
}

/// tobj's reading (all objects and groups, fan-triangulated) as a Mesh.
fn obj_with_tobj(bytes: &[u8]) -> Mesh {
    let opts = tobj::LoadOptions {
        single_index: false,
        triangulate: true,
        ignore_points: true,
        ignore_lines: true,
    };
    let (models, _) = tobj::load_obj_buf(&mut std::io::BufReader::new(bytes), &opts, |_| {
        Ok(Default::default())
    })
    .unwrap();
    let (mut positions, mut triangles) = (vec![], vec![]);
    for m in &models {
        let base = positions.len() as u32;
        positions.extend(m.mesh.positions.chunks_exact(3).map(|c| [c[0], c[1], c[2]]));
        triangles.extend(
            m.mesh
                .indices
                .chunks_exact(3)
                .map(|t| [base + t[0], base + t[1], base + t[2]]),
        );
    }
    Mesh::new(positions, triangles).unwrap()
}

fn err(bytes: &[u8], f: Option<Format>) -> String {
    load(bytes, f).unwrap_err().to_string()
}

#[test]
fn malformed_inputs_get_clear_errors() {
    let m = spot();
    let has = |e: String, s: &str| assert!(e.contains(s), "{e:?} should mention {s:?}");
    has(err(b"", None), "cannot tell the mesh format");
    has(err(b"hello world", None), "cannot tell the mesh format");
    has(err(b"", Some(Format::Obj)), "no triangles");
    has(
        err(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", None),
        "OBJ: line 4: vertex index 4 is out of range (the file has 3 vertices)",
    );
    has(
        err(b"v 0 0 0\nv 1 0 0\nf -1 -2 -3\nv 0 1 0\n", None),
        "OBJ: line 3: vertex index -3 is out of range",
    );
    has(
        err(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", None),
        "index 0",
    );
    has(
        err(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n", None),
        "not a vertex index",
    );
    has(
        err(b"v 0 0 0\nv 1 0\nv 0 1 0\nf 1 2 3\n", None),
        "line 2: a vertex needs x, y and z",
    );
    has(
        err(b"v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n", None),
        "non-finite",
    );
    has(
        err(b"v 0 0 0\nv 1 0 0\nv 0 1 0\n", Some(Format::Obj)),
        "no triangles",
    );
    has(err(b"v 0 0 0\nv 1 0 zz\nv 0 1 0\nf 1 2 3\n", None), "OBJ:");
    let bin = stl_binary(&m);
    has(err(&bin[..bin.len() - 10], Some(Format::Stl)), "truncated");
    has(err(&bin[..50], Some(Format::Stl)), "truncated");
    let ascii = stl_ascii(&m);
    has(
        err(&ascii[..ascii.len() - 200], None),
        "truncated ASCII STL",
    );
    has(err(b"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nendloop\nendfacet\nendsolid\n", None), "exactly 3 vertices");
    let p = [[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let good = ply(&p, &[vec![0, 1, 2]], None, "binary_little_endian");
    has(err(&good[..good.len() - 3], None), "truncated");
    has(
        err(&ply(&p, &[vec![0, 1, 7]], None, "ascii"), None),
        "uses vertex index 7",
    );
    has(
        err(
            &ply(
                &[[0.0, 0.0, 1e300], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
                &[vec![0, 1, 2]],
                None,
                "ascii",
            ),
            None,
        ),
        "beyond the limit",
    );
    has(
        err(
            b"ply\nformat ascii 1.0\nelement vertex 1\nproperty quux x\nend_header\n1\n",
            None,
        ),
        "unknown type",
    );
    has(err(b"ply\nformat ascii 1.0\nelement vertex 99999999\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n", None), "more than the file holds");
    has(
        err(b"ply\nformat ascii 1.0\nelement vertex 1\n", None),
        "no end_header",
    );
    has(err(b"{ not json", Some(Format::Gltf)), "glTF:");
    let lines = r#"[{"attributes":{"POSITION":0},"mode":1}]"#;
    has(
        err(
            gltf_json(&data_uri(), lines, r#"[{"mesh":0}]"#).as_bytes(),
            None,
        ),
        "unsupported primitive modes only: Lines",
    );
    let big = gltf_json(
        &data_uri(),
        r#"[{"attributes":{"POSITION":0}}]"#,
        r#"[{"mesh":0}]"#,
    )
    .replace(r#""count":4,"type":"VEC3""#, r#""count":40,"type":"VEC3""#);
    has(err(big.as_bytes(), None), "does not fit its bufferView");
    let tri = r#"[{"attributes":{"POSITION":0},"indices":1}]"#;
    let short = gltf_json(
        &format!(
            "data:application/octet-stream;base64,{}",
            b64(&quad_buffer()[..30])
        ),
        tri,
        r#"[{"mesh":0}]"#,
    );
    has(err(short.as_bytes(), None), "less than its byteLength");
    let json = gltf_json("", tri, r#"[{"mesh":0}]"#).replace(r#""uri":"","#, "");
    let g = glb(&json, &quad_buffer());
    has(err(&g[..g.len() - 20], None), "glTF:");
    has(
        err(&[0x1f, 0x8b, 8, 0, 0, 0, 0, 0, 0, 3, 1, 2, 3], None),
        "gzip",
    );
    let lim = LoadOptions {
        max_triangles: 100,
        ..opts()
    };
    let e = mesh::load_bytes(&stl_binary(&m), None, &lim).unwrap_err();
    assert_eq!(
        e,
        MeshError::TooManyTriangles {
            count: 5856,
            limit: 100
        }
    );
}

/// Counts a file declares, or reaches by instancing, are checked against the limits before the
/// data is read or the triangles made (tests of the gzip'd cases, with the bytes decoded, are in
/// src/mesh/streaming_tests.rs).
#[test]
fn declared_counts_are_checked_before_the_work() {
    let tri = r#"[{"attributes":{"POSITION":0},"indices":1}]"#;
    let small = LoadOptions {
        max_triangles: 1000,
        ..opts()
    };
    // One 2-triangle mesh instanced by 600 nodes: 1200 triangles, refused before any is made.
    let nodes: Vec<String> = (0..600).map(|_| r#"{"mesh":0}"#.to_string()).collect();
    let many = gltf_json(&data_uri(), tri, &format!("[{}]", nodes.join(","))).replace(
        r#""scenes":[{"nodes":[0]}]"#,
        &format!(
            r#""scenes":[{{"nodes":[{}]}}]"#,
            (0..600)
                .map(|i| i.to_string())
                .collect::<Vec<_>>()
                .join(",")
        ),
    );
    let e = mesh::load_bytes(many.as_bytes(), None, &small).unwrap_err();
    assert!(
        matches!(
            e,
            MeshError::CountOverLimit {
                format: "glTF",
                limit: 1000,
                ..
            }
        ),
        "{e:?}"
    );
    assert_eq!(
        mesh::load_bytes(many.as_bytes(), None, &opts())
            .unwrap()
            .triangles()
            .len(),
        1200
    );
    // Nodes sharing children (not a tree): 2 per level, each the parent of both below it, so
    // 40 levels would be 2^40 visits. Refused after a bounded walk.
    let mut dag = vec![];
    for level in 0..40 {
        let kids = if level < 39 {
            format!(r#","children":[{},{}]"#, 2 * level + 2, 2 * level + 3)
        } else {
            r#","mesh":0"#.to_string()
        };
        for _ in 0..2 {
            dag.push(format!("{{{}}}", &kids[1..]));
        }
    }
    let dag = gltf_json(&data_uri(), tri, &format!("[{}]", dag.join(",")));
    let e = mesh::load_bytes(dag.as_bytes(), None, &opts()).unwrap_err();
    assert!(e.to_string().contains("not a tree"), "{e}");
    // PLY: a face count over the triangle limit, and a vertex count over the vertex limit.
    let p = [[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let faces: Vec<Vec<u32>> = (0..1001).map(|_| vec![0, 1, 2]).collect();
    let e = mesh::load_bytes(&ply(&p, &faces, None, "ascii"), None, &small).unwrap_err();
    assert!(
        matches!(
            e,
            MeshError::CountOverLimit {
                format: "PLY",
                count: 1001,
                limit: 1000,
                ..
            }
        ),
        "{e:?}"
    );
    let e = mesh::load_bytes(
        b"ply\nformat ascii 1.0\nelement vertex 70000\nproperty float x\nproperty float y\nproperty float z\nend_header\n",
        None,
        &small,
    )
    .unwrap_err();
    assert_eq!(
        e.to_string(),
        "PLY: 70000 vertices declared by `element vertex`, over the limit of 68536"
    );
    // An element without properties takes no bytes, whatever its count: nothing to loop over.
    let mut b = ply(&p, &[vec![0, 1, 2]], None, "binary_little_endian");
    let at = b.windows(10).position(|w| w == b"end_header").unwrap();
    b.splice(
        at..at,
        b"element nothing 18446744073709551615\n".iter().copied(),
    );
    assert_eq!(
        mesh::load_bytes(&b, None, &opts())
            .unwrap()
            .triangles()
            .len(),
        1
    );
    // A face of more vertices than triangles allowed is refused before its indices are read.
    let e = mesh::load_bytes(
        &ply(&p, &[vec![0; 250]], None, "binary_little_endian"),
        None,
        &LoadOptions {
            max_triangles: 100,
            ..opts()
        },
    )
    .unwrap_err();
    assert!(
        matches!(e, MeshError::CountOverLimit { count: 248, .. }),
        "{e:?}"
    );
    // Binary STL: the header's count against the limit, gzip'd and longer than the 64 KiB read
    // first (not inflated further: see the unit tests). Shorter, it is all at hand: truncated.
    let mut stl = b"binary".to_vec();
    stl.resize(80, b' ');
    stl.extend_from_slice(&25_000_000u32.to_le_bytes());
    stl.resize(84 + 50 * 1000, 0);
    let e = mesh::load_bytes(&gz(&stl), Some(Format::Stl), &small).unwrap_err();
    assert!(e.to_string().contains("truncated"), "{e}");
    stl.resize(84 + 50 * 2000, 0);
    let e = mesh::load_bytes(&gz(&stl), Some(Format::Stl), &small).unwrap_err();
    assert_eq!(
        e.to_string(),
        "STL: 25000000 triangles declared in the binary header, over the limit of 1000"
    );
}

/// Inputs the fuzzers found (fuzz/, scripts/fuzz.sh), in tests/data/fuzz-regressions, each with
/// what it must give, in memory and gzip'd.
#[test]
fn fuzz_regressions() {
    let cases = [
        // POSITION naming an accessor that does not exist: gltf-json's validation indexed the
        // accessors with it and panicked (caught, it became a vague error; uncaught, a crash).
        (
            "gltf-position-accessor-out-of-range-1.gltf",
            "accessor 2 does not exist",
        ),
        (
            "gltf-position-accessor-out-of-range-2.gltf",
            "does not exist",
        ),
        ("glb-position-accessor-out-of-range.glb", "does not exist"),
    ];
    for (file, want) in cases {
        let bytes = std::fs::read(data(&format!("fuzz-regressions/{file}"))).unwrap();
        for b in [bytes.clone(), gz(&bytes)] {
            let e = load(&b, None).unwrap_err().to_string();
            assert!(e.contains(want), "{file}: {e}");
        }
    }
}
