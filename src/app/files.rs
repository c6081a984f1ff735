//! What a front that works on local files needs from the application (the command line, a
//! batch runner): the engine for a choice, a volume written to a path in a format, boundary
//! normals written as `.npy`. Every file is written atomically ([`crate::atomic`]): a reader
//! sees the old file or the whole new one. Not here: what a front prints, or reading volumes
//! from a store (see [`super::ops`]).

use std::path::Path;

use serde_json::{Map, Value};

use super::error::{Error, Result};
use super::ops;
use crate::codec::{VolumeFormat, vxl};
use crate::engine::gpu::GpuOptions;
use crate::engine::{Engine, EngineChoice};
use crate::volume::Volume;

/// The engine for `choice` (`auto`: the GPU when one is usable, else the CPU), on the GPU
/// adapter named `adapter` when given. Blocking (a GPU's device is opened).
pub fn open_engine(choice: EngineChoice, adapter: Option<String>) -> Result<Box<dyn Engine>> {
    crate::engine::open(
        choice,
        GpuOptions {
            adapter,
            ..Default::default()
        },
    )
    .map_err(Error::from)
}

/// Writes `v` to `path` in format `f` (`.vxl` with `meta` in its header), atomically. Encoded
/// before the file is created, so a volume the format cannot hold leaves no file; a format
/// that streams is written into the file piece by piece. A format that cannot hold the volume's kind is refused.
pub fn write_volume(
    path: &Path,
    f: VolumeFormat,
    v: &Volume,
    meta: &Map<String, Value>,
) -> Result<()> {
    ops::check_format(v.kind(), f)?;
    let io = |e: &dyn std::fmt::Display| Error::internal(e.to_string());
    // A format that streams (its row of the table) is written a piece at a time into the
    // temporary file; the others are encoded first.
    let bytes = match f {
        _ if f.spec().streams => None,
        VolumeFormat::Vxl => Some(vxl::encode(v, meta).map_err(|e| io(&e))?),
        other => Some(other.encode(v).map_err(|e| io(&e))?),
    };
    crate::atomic::write_with(path, |w| match &bytes {
        Some(b) => std::io::Write::write_all(w, b),
        None => f.write(v, w),
    })
    .map_err(|e| io(&e))
}

/// Writes the boundary normals of `v` to `path` as `.npy` (one `[i8; 3]` per voxel, zero where
/// there is none), atomically. The number of voxels with a normal.
pub fn write_normals(v: &Volume, path: &Path) -> Result<usize> {
    let n = crate::volume::normals::boundary_normals(v);
    let count = n.iter().filter(|c| **c != [0; 3]).count();
    let bytes = crate::codec::npy::encode_normals(v.grid().dims, &n);
    crate::atomic::write(path, &bytes).map_err(|e| Error::internal(e.to_string()))?;
    Ok(count)
}
