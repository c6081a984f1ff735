//! A query body (`POST /v1/volumes/{id}/query`): deserialized, checked against the service's
//! limits, and answered on a small bit volume and a small density volume.
#![no_main]

use std::sync::OnceLock;

use voxd::app::QueryRequest;
use voxd::grid::Grid;
use voxd::limits::Limits;
use voxd::volume::{BitVolume, DensityVolume, Volume};

#[path = "common.rs"]
mod common;

fn volumes() -> &'static [Volume; 2] {
    static V: OnceLock<[Volume; 2]> = OnceLock::new();
    V.get_or_init(|| {
        let grid = Grid {
            origin: [-1.0, -0.5, 0.25],
            voxel_size: 0.25,
            dims: [7, 5, 9],
        };
        let mut b = BitVolume::new(grid);
        let mut d = DensityVolume::new(grid, 8);
        for x in 0..7 {
            for y in 0..5 {
                for z in 0..9 {
                    if (x * 3 + y * 5 + z * 7) % 4 != 0 {
                        b.set(x, y, z, true);
                        d.set(x, y, z, ((x + y + z) % 9) as u8);
                    }
                }
            }
        }
        [Volume::Bits(b), Volume::Density(d)]
    })
}

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    common::init();
    let Ok(q) = serde_json::from_slice::<QueryRequest>(data) else {
        return;
    };
    let limits = Limits::SERVICE;
    if q.check(&limits).is_err() {
        return;
    }
    for v in volumes() {
        let _ = voxd::app::ops::query(v, &q, &limits);
    }
});
