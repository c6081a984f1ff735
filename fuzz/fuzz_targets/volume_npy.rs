//! `VolumeFormat::Npy` decoding (within a voxel budget); what decodes must encode and
//! decode again to the same volume.
#![no_main]

use voxd::codec::VolumeFormat;

#[path = "common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    common::init();
    let f = VolumeFormat::Npy;
    let Ok(v) = f.decode_limited(data, common::MAX_VOXELS) else {
        return;
    };
    let bytes = f.encode(&v).expect("a decoded volume encodes");
    assert_eq!(f.decode(&bytes).expect("and decodes again"), v);
});
