//! Reading compressed files as they are decoded. Text in blocks gives what the file in memory
//! gives. Decompression bombs and header counts: each is refused after a bounded amount of
//! decoding, whatever the stream would expand to. The bombs are gzip streams of a gibibyte or more (about
//! a megabyte compressed), built once by streaming so the tests stay small in memory; an
//! implementation that inflated before checking would decode all of it (and hold it).

use std::io::Write;
use std::sync::OnceLock;

use super::stream::Stream;
use super::*;
use crate::limits::Limits;
use crate::testkit::gz;

const GIB: u64 = 1 << 30;
const MIB: u64 = 1 << 20;

/// `len` copies of `byte`, gzipped as one member, written a mebibyte at a time.
fn gz_run(len: u64, byte: u8) -> Vec<u8> {
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    let piece = vec![byte; MIB as usize];
    let mut left = len;
    while left > 0 {
        let n = left.min(MIB) as usize;
        e.write_all(&piece[..n]).unwrap();
        left -= n as u64;
    }
    e.finish().unwrap()
}

/// A gibibyte of zeros, gzipped (about 1 MB).
fn zeros() -> &'static [u8] {
    static B: OnceLock<Vec<u8>> = OnceLock::new();
    B.get_or_init(|| gz_run(GIB, 0))
}

/// `prefix` then a gibibyte of zeros: two gzip members, which decode as one file.
fn with_zeros(prefix: &[u8]) -> Vec<u8> {
    let mut b = gz(prefix);
    b.extend_from_slice(zeros());
    b
}

/// The service's decoded-size limit (4 GiB) and a triangle limit.
fn service(max_triangles: usize) -> LoadOptions {
    LoadOptions {
        max_triangles,
        max_decompressed_bytes: Limits::SERVICE.max_decompressed_bytes,
        ..Default::default()
    }
}

/// Loads a gzip stream; the result and how many bytes were decoded.
fn load_gz(z: &[u8], format: Option<Format>, opts: &LoadOptions) -> (Result<Mesh, MeshError>, u64) {
    let mut s = Stream::gzip(z, opts.max_decompressed_bytes);
    let r = load_stream(&mut s, format, opts).map(|(m, _)| m);
    (r, s.decoded())
}

#[test]
fn a_gzip_bomb_is_refused_after_a_bounded_decode() {
    let opts = service(20_000_000);
    let cases: [(Option<Format>, u64); 6] = [
        (None, 2 * MIB),
        (Some(Format::Stl), 2 * MIB),
        (Some(Format::Ply), 3 * MIB),
        (Some(Format::Gltf), 2 * MIB),
        (Some(Format::Glb), 2 * MIB),
        // A line of zeros: OBJ reads up to its longest line (16 MiB).
        (Some(Format::Obj), 18 * MIB),
    ];
    for (format, bound) in cases {
        let (r, decoded) = load_gz(zeros(), format, &opts);
        assert!(r.is_err(), "{format:?}");
        assert!(
            decoded <= bound,
            "{format:?}: decoded {decoded} bytes of the bomb before refusing it ({r:?})"
        );
    }
    assert_eq!(
        load_gz(zeros(), None, &opts).0,
        Err(MeshError::UnknownFormat)
    );
}

#[test]
fn text_is_parsed_as_decoded_and_decoding_stops_at_the_limit() {
    // 96 MiB of line breaks as OBJ under a 64 MiB limit: parsed in blocks as decoded, refused
    // one byte past the limit.
    let z = gz_run(96 * MIB, b'\n');
    let opts = LoadOptions {
        max_decompressed_bytes: 64 * MIB,
        ..service(1000)
    };
    let (r, decoded) = load_gz(&z, Some(Format::Obj), &opts);
    assert_eq!(r, Err(MeshError::TooLarge(64 * MIB)));
    assert_eq!(decoded, 64 * MIB + 1);
    // Within the limit it is read through (and has no triangles).
    let (r, _) = load_gz(&z, Some(Format::Obj), &service(1000));
    assert!(matches!(r, Err(MeshError::NoTriangles(_))), "{r:?}");
}

fn stl_header(text: &[u8], n: u32) -> Vec<u8> {
    let mut h = text.to_vec();
    h.resize(80, b' ');
    h.extend_from_slice(&n.to_le_bytes());
    h
}

#[test]
fn a_binary_stl_header_over_the_limit_is_refused_before_inflating() {
    let opts = service(1000);
    let want = MeshError::CountOverLimit {
        format: "STL",
        what: "triangles declared in the binary header",
        count: 25_000_000,
        limit: 1000,
    };
    // 25 M triangles would be 1.25 GB; a header starting with "solid" does not make it text.
    for text in [&b"binary"[..], b"solid but binary"] {
        let z = with_zeros(&stl_header(text, 25_000_000));
        for format in [Some(Format::Stl), None] {
            let (r, decoded) = load_gz(&z, format, &opts);
            assert_eq!(r.as_ref().unwrap_err(), &want, "{format:?}");
            assert!(decoded <= 2 * MIB, "{format:?}: decoded {decoded}");
        }
    }
    // Within the limit, a binary STL is read whole: exactly its size, no more.
    let mut ok = stl_header(b"binary", 1);
    ok.extend_from_slice(&[0; 12]);
    for c in [[0f32, 0., 0.], [1., 0., 0.], [0., 1., 0.]] {
        ok.extend(c.iter().flat_map(|v| v.to_le_bytes()));
    }
    ok.extend_from_slice(&[0, 0]);
    let (r, _) = load_gz(&gz(&ok), None, &opts);
    assert_eq!(r.unwrap().triangles().len(), 1);
    let (r, _) = load_gz(&with_zeros(&ok), Some(Format::Stl), &opts);
    assert!(r.unwrap_err().to_string().contains("the file is longer"));
    // In memory, a consistent file of too many triangles is what it always was.
    let mut big = stl_header(b"binary", 1001);
    big.resize(84 + 50 * 1001, 0);
    assert_eq!(
        load_bytes(&big, None, &opts),
        Err(MeshError::TooManyTriangles {
            count: 1001,
            limit: 1000
        })
    );
}

#[test]
fn ply_element_counts_are_checked_before_the_body() {
    let opts = service(1000);
    let header = |enc: &str, vertices: u64, faces: u64| {
        format!(
            "ply\nformat {enc} 1.0\nelement vertex {vertices}\nproperty float x\nproperty float y\nproperty float z\nelement face {faces}\nproperty list uchar int vertex_indices\nend_header\n"
        )
    };
    for enc in ["binary_little_endian", "ascii"] {
        let z = with_zeros(header(enc, 100_000_000, 1).as_bytes());
        let (r, decoded) = load_gz(&z, None, &opts);
        assert_eq!(
            r.unwrap_err(),
            MeshError::CountOverLimit {
                format: "PLY",
                what: "vertices declared by `element vertex`",
                count: 100_000_000,
                limit: 3 * 1000 + 65536,
            }
        );
        assert!(decoded <= 2 * MIB);
        let z = with_zeros(header(enc, 3, 50_000_000).as_bytes());
        let (r, decoded) = load_gz(&z, Some(Format::Ply), &opts);
        assert!(
            matches!(r, Err(MeshError::CountOverLimit { count: 50_000_000, what, .. }) if what.contains("faces")),
            "{r:?}"
        );
        assert!(decoded <= 2 * MIB);
    }
    // Counts within the limits whose records cannot fit under the decoded-size limit.
    let tight = LoadOptions {
        max_decompressed_bytes: 100_000,
        ..opts.clone()
    };
    let z = with_zeros(header("binary_little_endian", 60_000, 1).as_bytes());
    let (r, decoded) = load_gz(&z, None, &tight);
    assert_eq!(r.unwrap_err(), MeshError::TooLarge(100_000));
    assert!(decoded <= 100_001);
    // One face of more triangles than allowed is refused before its indices are read.
    let mut b = header("binary_little_endian", 3, 1).into_bytes();
    b.extend_from_slice(&[0; 36]);
    let small = LoadOptions {
        max_triangles: 100,
        ..opts.clone()
    };
    b.push(200);
    let (r, _) = load_gz(&with_zeros(&b), None, &small);
    assert!(
        matches!(r, Err(MeshError::CountOverLimit { count: 198, .. })),
        "{r:?}"
    );
}

/// A GLB whose JSON chunk declares `indices` u32 indices, its BIN chunk left to the caller.
fn glb_head(indices: u64) -> Vec<u8> {
    let bin = indices * 4 + 36;
    let mut json = format!(
        r#"{{"asset":{{"version":"2.0"}},"buffers":[{{"byteLength":{bin}}}],"bufferViews":[{{"buffer":0,"byteLength":{}}},{{"buffer":0,"byteOffset":{},"byteLength":36}}],"accessors":[{{"bufferView":0,"componentType":5125,"count":{indices},"type":"SCALAR"}},{{"bufferView":1,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}}],"meshes":[{{"primitives":[{{"attributes":{{"POSITION":1}},"indices":0}}]}}],"nodes":[{{"mesh":0}}],"scenes":[{{"nodes":[0]}}],"scene":0}}"#,
        indices * 4,
        indices * 4
    )
    .into_bytes();
    while json.len() % 4 != 0 {
        json.push(b' ');
    }
    let length = 12 + 8 + json.len() as u64 + 8 + bin;
    let mut b = b"glTF".to_vec();
    b.extend_from_slice(&2u32.to_le_bytes());
    b.extend_from_slice(&(length as u32).to_le_bytes());
    b.extend_from_slice(&(json.len() as u32).to_le_bytes());
    b.extend_from_slice(b"JSON");
    b.extend_from_slice(&json);
    b.extend_from_slice(&(bin as u32).to_le_bytes());
    b.extend_from_slice(b"BIN\0");
    b
}

#[test]
fn glb_accessor_counts_are_checked_before_the_bin_chunk() {
    let opts = service(1000);
    // 30 M triangles: a 360 MB BIN chunk (zeros here) that is never decoded.
    let z = with_zeros(&glb_head(90_000_000));
    let (r, decoded) = load_gz(&z, None, &opts);
    assert!(
        matches!(
            r,
            Err(MeshError::CountOverLimit {
                format: "glTF",
                count: 30_000_000,
                limit: 1000,
                ..
            })
        ),
        "{r:?}"
    );
    assert!(decoded <= 2 * MIB, "decoded {decoded}");
    // A GLB header longer than the decoded-size limit is refused as it is read.
    let tight = LoadOptions {
        max_decompressed_bytes: 1_000_000,
        ..opts.clone()
    };
    let (r, decoded) = load_gz(&z, None, &tight);
    assert_eq!(r.unwrap_err(), MeshError::TooLarge(1_000_000));
    assert!(decoded <= 2 * MIB);
    // Within the limits the same file loads.
    let mut ok = glb_head(3);
    ok.extend((0u32..3).flat_map(|i| i.to_le_bytes()));
    for c in [[0f32, 0., 0.], [1., 0., 0.], [0., 1., 0.]] {
        ok.extend(c.iter().flat_map(|v| v.to_le_bytes()));
    }
    let (r, _) = load_gz(&gz(&ok), None, &opts);
    assert_eq!(r.unwrap().triangles().len(), 1);
    assert_eq!(load_bytes(&ok, None, &opts).unwrap().triangles().len(), 1);
}

#[test]
fn gltf_json_is_deserialized_as_decoded() {
    // `{` and then a gibibyte of spaces: whitespace is not kept, and the document is cut short.
    let mut z = gz(b"{");
    z.extend_from_slice(&gz_run(GIB / 4, b' '));
    let opts = LoadOptions {
        max_decompressed_bytes: 64 * MIB,
        ..service(1000)
    };
    let (r, decoded) = load_gz(&z, Some(Format::Gltf), &opts);
    assert_eq!(r.unwrap_err(), MeshError::TooLarge(64 * MIB));
    assert_eq!(decoded, 64 * MIB + 1);
}

fn spot_obj() -> Vec<u8> {
    std::fs::read(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/spot.obj")).unwrap()
}

/// `load_bytes` of `text` in memory, and as a gzip stream read in blocks of `block` bytes.
fn whole_and_blocks(text: &[u8], format: Format, block: usize) -> [Result<Mesh, MeshError>; 2] {
    let opts = LoadOptions::default();
    let z = gz(text);
    let mut s = Stream::gzip(&z, u64::MAX).with_blocks(block);
    [
        load_bytes(text, Some(format), &opts),
        load_stream(&mut s, Some(format), &opts).map(|(m, _)| m),
    ]
}

#[test]
fn obj_in_blocks_reads_what_obj_in_memory_reads() {
    let text = String::from_utf8(spot_obj()).unwrap();
    // Relative (negative) indices; every face before every vertex (forward references); and
    // vertex lines continued with a backslash.
    let (mut relative, mut faces, mut verts, mut continued) = (vec![], vec![], vec![], vec![]);
    let mut defined = 0i64;
    for (i, line) in text.lines().enumerate() {
        if line.starts_with("v ") {
            defined += 1;
            verts.push(line.to_string());
            let cut = line.rfind(' ').unwrap();
            let sep = if i % 2 == 0 { " \\\n" } else { " \\\r\n" };
            continued.push(if i % 5 == 0 {
                format!("{}{sep}{}", &line[..cut], &line[cut + 1..])
            } else {
                line.to_string()
            });
        } else {
            continued.push(line.to_string());
        }
        if let Some(rest) = line.strip_prefix("f ") {
            faces.push(line.to_string());
            let rel: Vec<String> = rest
                .split_whitespace()
                .map(|t| {
                    let (v, tail) = t
                        .split_once('/')
                        .map_or((t, ""), |(v, _)| (v, &t[v.len()..]));
                    format!("{}{tail}", v.parse::<i64>().unwrap() - 1 - defined)
                })
                .collect();
            relative.push(format!("f {}", rel.join(" ")));
        } else {
            relative.push(line.to_string());
        }
    }
    let join = |v: &[String]| (v.join("\n") + "\n").into_bytes();
    let forward = [faces.clone(), verts.clone()].concat();
    let bad_forward = [vec![format!("f 1 2 {}", verts.len() + 1)], forward.clone()].concat();
    let mut bad_negative = relative.clone();
    bad_negative.insert(10, "f -1 -2 -99999".into());
    let want = load_bytes(text.as_bytes(), Some(Format::Obj), &LoadOptions::default()).unwrap();
    for (name, file, ok) in [
        ("plain", text.clone().into_bytes(), true),
        ("relative", join(&relative), true),
        ("forward", join(&forward), true),
        ("continued", join(&continued), true),
        ("bad forward", join(&bad_forward), false),
        ("bad negative", join(&bad_negative), false),
    ] {
        for block in [1, 97, 4096, 1 << 16] {
            let [whole, blocks] = whole_and_blocks(&file, Format::Obj, block);
            assert_eq!(whole.is_ok(), ok, "{name}: {whole:?}");
            if ok {
                let (w, b) = (whole.unwrap(), blocks.unwrap());
                assert_eq!(w.triangles().len(), want.triangles().len(), "{name}");
                assert_eq!(w, b, "{name}, blocks of {block}");
            } else {
                let (w, b) = (
                    whole.unwrap_err().to_string(),
                    blocks.unwrap_err().to_string(),
                );
                let line = |e: &str| e.split(':').take(2).collect::<String>();
                assert_eq!(line(&w), line(&b), "{name}, blocks of {block}: {w} / {b}");
            }
        }
    }
}

#[test]
fn ascii_stl_in_blocks_reads_what_ascii_stl_in_memory_reads() {
    let m = load_bytes(&spot_obj(), Some(Format::Obj), &LoadOptions::default()).unwrap();
    let mut s = String::from("solid spot\n");
    for t in 0..m.triangles().len() {
        s += "facet normal 0 0 1\n outer loop\n";
        for p in m.triangle(t) {
            s += &format!("  vertex {:e} {:e} {:e}\n", p[0], p[1], p[2]);
        }
        s += " endloop\nendfacet\n";
    }
    s += "endsolid spot\n";
    for block in [1, 333, 1 << 16] {
        let [whole, blocks] = whole_and_blocks(s.as_bytes(), Format::Stl, block);
        let (w, b) = (whole.unwrap(), blocks.unwrap());
        assert_eq!(w.triangles().len(), m.triangles().len());
        assert_eq!(w, b, "blocks of {block}");
    }
    // Cut short, in memory or in blocks: the same error.
    let cut = &s.as_bytes()[..s.len() - 100];
    let [whole, blocks] = whole_and_blocks(cut, Format::Stl, 333);
    assert_eq!(whole.unwrap_err(), blocks.unwrap_err());
}

/// A bad vertex (non-finite or huge) is refused as `Mesh::new` refuses it, whichever block or
/// chunk it is in, and only once the rest of the file has been read without error.
#[test]
fn obj_bad_vertices_are_refused_as_mesh_new_refuses_them() {
    let n = 60_000;
    let position = |i: usize| [i as f64, (i % 7) as f64, 0.5];
    for (bad, value) in [
        (0, "nan"),
        (1, "inf"),
        (n / 2, "-inf"),
        (n / 2 + 1, "1e300"),
        (n - 1, "-2e15"),
    ] {
        let mut positions: Vec<[f64; 3]> = (0..n).map(position).collect();
        let mut text = String::new();
        for (i, p) in positions.iter_mut().enumerate() {
            if i == bad {
                p[1] = value.parse().unwrap();
                text += &format!("v {} {value} {}\n", p[0], p[2]);
            } else if i == bad + 7 && i < n {
                // A second bad one later: the first is named.
                p[0] = f64::NAN;
                text += &format!("v nan {} {}\n", p[1], p[2]);
            } else {
                text += &format!("v {} {} {}\n", p[0], p[1], p[2]);
            }
        }
        let triangles: Vec<[u32; 3]> = (0..n as u32 - 2).map(|i| [i, i + 1, i + 2]).collect();
        for t in &triangles {
            text += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
        }
        let want = Mesh::new(positions, triangles).unwrap_err();
        for block in [1 << 10, 1 << 16, usize::MAX] {
            for got in whole_and_blocks(text.as_bytes(), Format::Obj, block) {
                // By their Debug text: NaN is not equal to itself.
                let got = format!("{:?}", got.unwrap_err());
                assert_eq!(got, format!("{want:?}"), "vertex {bad}, block {block}");
            }
        }
        // A malformed line after the bad vertex is what is reported.
        let broken = text.clone() + "f 1 2 x\n";
        for got in whole_and_blocks(broken.as_bytes(), Format::Obj, 1 << 16) {
            assert!(
                got.unwrap_err()
                    .to_string()
                    .contains("is not a vertex index")
            );
        }
    }
}
