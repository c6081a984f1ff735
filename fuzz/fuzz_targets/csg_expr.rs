//! A CSG expression body (`POST /v1/volumes/csg`) through `CsgExpr::from_json` with the
//! service's limits; what parses must come back from its own JSON the same.
#![no_main]

use voxd::app::CsgExpr;
use voxd::limits::Limits;

#[path = "common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    common::init();
    let Ok(json) = serde_json::from_slice::<serde_json::Value>(data) else {
        return;
    };
    let Ok(e) = CsgExpr::from_json(&json, &Limits::SERVICE) else {
        return;
    };
    let again = CsgExpr::from_json(&e.to_json(), &Limits::SERVICE).expect("its own JSON parses");
    assert_eq!(again, e);
    let _ = e.volume_ids();
});
