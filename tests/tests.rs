//! The integration tests, gathered into one binary (`cargo test --test integration`) so that
//! `common` and the library are compiled and linked once rather than once per file. Each file of
//! tests/ is one module; run one of them with a filter, e.g.
//! `cargo test --test integration service::`.

mod common;

mod cli;
mod codecs;
mod csg;
mod density;
mod fill;
mod gpu;
mod loaders;
mod morph;
mod oracles;
mod query;
mod real_meshes;
mod service;
mod stats;
