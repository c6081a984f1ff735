//! The input, gzip'd, through `mesh::load_bytes` (the streaming path: sniffing on the first
//! bytes, loaders reading as they decode), against the same input in memory: both must give the
//! same mesh, or the same kind of error (a fuzzer's inputs are shorter than what is decoded
//! first, so nothing else may differ; the text of an error may: a compressed .gltf is read by
//! serde_json's reader, whose positions are one column later than its slice parser's).
#![no_main]

use std::io::Write;

use voxd::mesh::MeshError::{CountOverLimit, Malformed};

#[path = "common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    if data.starts_with(&[0x1f, 0x8b]) {
        return;
    }
    let opts = common::mesh_options();
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    e.write_all(data).unwrap();
    let z = e.finish().unwrap();
    let format = data.first().and_then(|b| match b % 8 {
        0 => Some(voxd::mesh::Format::Obj),
        1 => Some(voxd::mesh::Format::Stl),
        2 => Some(voxd::mesh::Format::Ply),
        3 => Some(voxd::mesh::Format::Gltf),
        _ => None,
    });
    let plain = voxd::mesh::load_bytes(data, format, &opts);
    let gz = voxd::mesh::load_bytes(&z, format, &opts);
    match (&plain, &gz) {
        (Ok(a), Ok(b)) => assert_eq!(a, b, "in memory and gzip'd give different meshes"),
        (Err(a), Err(b)) => assert!(
            std::mem::discriminant(a) == std::mem::discriminant(b)
                && match (a, b) {
                    (Malformed { format: f, .. }, Malformed { format: g, .. }) => f == g,
                    (
                        CountOverLimit {
                            what: w, count: c, ..
                        },
                        CountOverLimit {
                            what: v, count: d, ..
                        },
                    ) => {
                        (w, c) == (v, d)
                    }
                    // As text: a NaN coordinate in both would not compare equal.
                    _ => format!("{a:?}") == format!("{b:?}"),
                },
            "in memory and gzip'd differ ({format:?}): {a:?} / {b:?}"
        ),
        _ => panic!("in memory and gzip'd differ ({format:?}): {plain:?} / {gz:?}"),
    }
});
