//! `mesh::load_bytes` with the format given as Glb (a gzip'd input goes through gzip too).
#![no_main]

#[path = "common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let opts = common::mesh_options();
    let _ = voxd::mesh::load_bytes(data, Some(voxd::mesh::Format::Glb), &opts);
});
