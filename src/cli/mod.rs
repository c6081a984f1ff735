//! The `voxd` command line: arguments (`args.rs`) translated into application requests, the
//! commands (`commands.rs`), what they print and write (`output.rs`), the progress bar on long
//! work (`progress.rs`), and `voxd bench`.

pub mod args;
pub mod bench;
pub mod commands;
pub mod distance;
pub mod mesh;
pub mod output;
pub mod progress;
