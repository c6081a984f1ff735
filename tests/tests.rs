//! The integration tests, gathered into one binary (`cargo test --test integration`) so that
//! `common` and the library are compiled and linked once rather than once per file. Each file of
//! tests/ is one module; run one of them with a filter, e.g.
//! `cargo test --test integration service::`.

mod common;

mod auth;
mod cli;
mod codecs;
mod connections;
mod crash;
mod csg;
mod density;
mod fill;
mod gpu;
mod loaders;
mod morph;
mod openapi_enums;
mod oracles;
mod props;
mod query;
mod real_meshes;
mod redis_queue;
mod replicas;
mod s3;
mod service;
mod stats;

/// With `autotests = false` (Cargo.toml) a file of tests/ that is not declared a module here
/// would never be compiled nor run: every one is.
#[test]
fn every_file_of_tests_is_a_module() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests");
    let this = std::fs::read_to_string(dir.join("tests.rs")).unwrap();
    for entry in std::fs::read_dir(&dir).unwrap() {
        let name = entry.unwrap().file_name().into_string().unwrap();
        if let Some(module) = name.strip_suffix(".rs").filter(|m| *m != "tests") {
            assert!(
                this.contains(&format!("\nmod {module};\n")),
                "tests/{name} is not declared in tests/tests.rs, so it never runs"
            );
        }
    }
}
