//! `VolumeFormat::Binvox` decoding (within a voxel budget); what decodes must encode and
//! decode again to the same volume.
#![no_main]

use voxd::codec::VolumeFormat;

#[path = "common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    common::init();
    let f = VolumeFormat::Binvox;
    let Ok(v) = f.decode_limited(data, common::MAX_VOXELS) else {
        return;
    };
    // binvox pads a non-cubic grid to a cube of its longest axis: compare the bits, which it
    // keeps, and only where that cube is small (the encoder's cost is the cube's: a grid
    // 8 M voxels long would take forever, which is not what this target is about).
    let n = *v.grid().dims.iter().max().unwrap() as u64;
    if n * n * n > 1 << 20 {
        return;
    }
    let bytes = f.encode(&v).expect("a decoded volume encodes");
    let back = f.decode(&bytes).expect("and decodes again");
    let (voxd::volume::Volume::Bits(a), voxd::volume::Volume::Bits(b)) = (&v, &back) else {
        panic!("binvox holds bits");
    };
    assert_eq!(a.count_ones(), b.count_ones());
    assert!(a.iter_ones().all(|p| b.get(p[0], p[1], p[2])));
});
