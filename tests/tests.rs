//! The integration tests, gathered into one binary (`cargo test --test integration`) so that
//! `common` and the library are compiled and linked once rather than once per file. Each file of
//! tests/ is one module; run one of them with a filter, e.g.
//! `cargo test --test integration service::`.

mod common;

mod attributes;
mod auth;
mod cli;
mod codecs;
mod connections;
mod crash;
mod csg;
mod density;
mod distance_cli;
mod durable_jobs;
mod fill;
mod flood;
mod gpu;
mod loaders;
mod memory;
mod mesh_cli;
mod morph;
mod observability;
mod openapi_enums;
mod oracles;
mod props;
mod query;
mod real_meshes;
#[cfg(feature = "redis")]
mod redis_queue;
#[cfg(all(feature = "redis", feature = "s3"))]
mod replicas;
#[cfg(feature = "s3")]
mod s3;
mod service;
mod stats;
mod tenants;
mod upload_memory;
mod vdb;

/// With `autotests = false` (Cargo.toml) a file of tests/ that is not declared a module here
/// would never be compiled nor run: every one is, and so is every file of a folder module
/// (`service/`, `common/`) in its `mod.rs` (or `<folder>.rs`). Folders of neither kind are data.
#[test]
fn every_file_of_tests_is_a_module() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests");
    let checked = declared_below(&dir, &dir.join("tests.rs"));
    assert!(checked > 20, "only {checked} modules found");
}

/// Checks that `parent` (the file that declares the modules of `dir`) declares every `.rs` file
/// and module folder of `dir`, recursively; the number of modules checked.
fn declared_below(dir: &std::path::Path, parent: &std::path::Path) -> usize {
    let text = std::fs::read_to_string(parent).unwrap();
    let declares = |module: &str| {
        text.lines().any(|l| {
            let l = l
                .trim_start_matches("pub(crate) ")
                .trim_start_matches("pub ");
            l == format!("mod {module};")
        })
    };
    let mut checked = 0;
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_str().unwrap().to_string();
        let (module, declaring) = if path.is_dir() {
            let (inner, beside) = (path.join("mod.rs"), dir.join(format!("{name}.rs")));
            match (inner.is_file(), beside.is_file()) {
                (true, _) => (name.clone(), inner),
                // Declared as the file beside the folder; that file is checked on its own.
                (false, true) => {
                    checked += declared_below(&path, &beside);
                    continue;
                }
                (false, false) => continue,
            }
        } else {
            match name.strip_suffix(".rs") {
                Some(m) if path != parent && m != "mod" => (m.to_string(), path.clone()),
                _ => continue,
            }
        };
        assert!(
            declares(&module),
            "{} is not declared in {}, so it never runs",
            path.display(),
            parent.display()
        );
        checked += 1;
        if path.is_dir() {
            checked += declared_below(&path, &declaring);
        }
    }
    checked
}
