//! `mesh::load_bytes` with no format: sniffing, then whichever loader it picks (or gzip).
#![no_main]

#[path = "common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let opts = common::mesh_options();
    let _ = voxd::mesh::load_bytes(data, None, &opts);
});
