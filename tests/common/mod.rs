//! Test helpers, the one place the integration tests take them from: the random generator
//! (`rng`), fixtures and scratch directories (`fixtures`), meshes and volumes made in code
//! (`meshes`), independent oracles (`oracles`, themselves checked in `oracles/checks.rs`),
//! talking HTTP to a running server (`http`), and the servers started beside it (`nginx`,
//! `redis_server`, `s3`).
//! A test file takes what it needs with `use crate::common::*` (or by name) and keeps no
//! generator, scratch-directory code or HTTP plumbing of its own: its helpers only wrap these (a
//! content type added, a server's address filled in). Not for `src/`'s unit tests, which are
//! another crate and cannot see this module.

mod fixtures;
mod http;
mod meshes;
#[cfg(all(feature = "redis", feature = "s3"))]
pub mod nginx;
mod oracles;
#[cfg(feature = "redis")]
pub mod redis_server;
mod rng;
#[cfg(feature = "s3")]
pub mod s3;

pub use fixtures::*;
pub use http::*;
pub use meshes::*;
pub use oracles::*;
pub use rng::*;
