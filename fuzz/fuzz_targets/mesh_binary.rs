//! `mesh::binary::decode` (the stored form of a job's prepared mesh): never a panic, counts
//! held to the limits before anything is allocated, and what decodes encodes to the same bytes.
#![no_main]

#[path = "common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let opts = common::mesh_options();
    if let Ok(mesh) = voxd::mesh::binary::decode(data, &opts) {
        assert_eq!(voxd::mesh::binary::encode(&mesh), data);
    }
});
