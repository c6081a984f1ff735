#![allow(dead_code)]

//! What the targets share: small limits (so a fuzzer's input cannot ask for much memory), and
//! a panic hook that keeps the service's own `catch_unwind` (the glTF reader) working as it
//! does in production. libfuzzer-sys aborts on every panic, caught or not; with this hook a
//! panic that escapes to libFuzzer still aborts (it catches and aborts), one the code catches
//! does not.

use voxd::mesh::{ExternalResources, LoadOptions};

pub fn mesh_options() -> LoadOptions {
    init();
    LoadOptions {
        external: ExternalResources::Deny,
        max_triangles: 100_000,
        max_decompressed_bytes: 16 << 20,
        max_texture_bytes: 16 << 20,
        // The texture decoders are fuzzed too (what a request with colour reads).
        textures: true,
    }
}

/// Voxels a decoded volume may have (a few bytes of .vxl or .binvox can name a huge grid).
pub const MAX_VOXELS: u64 = 1 << 24;

pub fn init() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        std::panic::set_hook(Box::new(|info| {
            if std::env::var_os("VOXD_FUZZ_QUIET_PANICS").is_none() {
                eprintln!("{info}");
            }
        }))
    });
}
