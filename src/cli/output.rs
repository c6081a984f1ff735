//! What the command line prints and writes: summaries of meshes and fills, volume files
//! (written atomically, with a warning when the format loses something), stdout that tolerates
//! a closed pipe.

use std::path::Path;

use voxd::app::ops;
use voxd::codec::VolumeFormat;
use voxd::engine::fill::FillReport;
use voxd::mesh::MeshDiagnostics;
use voxd::volume::Volume;

/// `println!` into a String.
macro_rules! outln {
    ($out:expr, $($arg:tt)*) => {{
        use std::fmt::Write as _;
        let _ = writeln!($out, $($arg)*);
    }};
}
pub(crate) use outln;

pub fn describe_fill(name: &str, f: &FillReport) -> String {
    let mut s = format!("{name}: fill {}", f.used);
    match &f.reason {
        Some(r) => s += &format!(" ({r})"),
        None if f.requested != f.used => s += &format!(" (asked for {})", f.requested),
        None => {}
    }
    s += &format!(", {} odd-parity columns", f.odd_parity_columns);
    if let Some(w) = &f.winding {
        s += &format!(
            ", {} cap triangles; voxels decided by the exact crossing count {}, by it against the caps' winding number over blocks {}, by the mesh's winding number over blocks {}, by the crossing count minus the caps' winding number {} (of which summed exactly over the near caps {}), by the mesh's winding number {}",
            w.cap_triangles,
            w.exact_voxels,
            w.cap_block_voxels,
            w.mesh_block_voxels,
            w.cap_evaluated_voxels + w.near_evaluated_voxels,
            w.near_evaluated_voxels,
            w.mesh_evaluated_voxels
        );
    }
    if let Some(w) = &f.warning {
        s += &format!("\n{name}: WARNING: {w}");
    }
    s
}

pub fn describe_mesh(name: &str, d: &MeshDiagnostics) -> String {
    format!(
        "{name}: {} triangles, {} vertices, {}, {} boundary edges, {} non-manifold edges, {} degenerate triangles, bbox {:?}..{:?}",
        d.triangles,
        d.vertices,
        if d.watertight {
            "watertight"
        } else {
            "NOT watertight (parity solid may streak; see docs/methods.md)"
        },
        d.boundary_edges,
        d.non_manifold_edges,
        d.degenerate_triangles,
        d.bbox_min,
        d.bbox_max
    )
}

/// Writes `v` to `path` in format `f` atomically (`.vxl` with `meta` in its header), warning on
/// stderr when the format loses part of the volume's grid.
pub fn write_volume(
    path: &Path,
    f: VolumeFormat,
    v: &Volume,
    meta: &serde_json::Map<String, serde_json::Value>,
) -> Result<(), String> {
    let err = |e: &dyn std::fmt::Display| format!("{}: {e}", path.display());
    ops::check_format(v.kind(), f).map_err(|e| err(&e))?;
    ops::check_dense(v.kind(), v.grid(), f, &voxd::limits::Limits::LOCAL).map_err(|e| err(&e))?;
    if let Some(w) = ops::conversion_warning(v.grid(), f) {
        eprintln!("{}: {w}", path.display());
    }
    // A channel volume as its format holds it by default (npy: occupancy; vox, points: with
    // colours), as the service's downloads without `attributes=`.
    if let Volume::Channels(_) = v {
        let v = voxd::app::attributes::select(v.clone(), f, None).map_err(|e| err(&e))?;
        return voxd::app::files::write_volume(path, f, &v, meta).map_err(|e| err(&e));
    }
    voxd::app::files::write_volume(path, f, v, meta).map_err(|e| err(&e))
}

/// [`read_volume`] with the material table a `.vxl`'s header holds (empty for other formats).
pub fn read_volume_with_materials(
    p: &Path,
) -> Result<(Volume, Vec<voxd::app::store::MaterialMeta>), String> {
    let bytes = std::fs::read(p).map_err(|e| format!("{}: {e}", p.display()))?;
    if VolumeFormat::sniff(&bytes) != Some(VolumeFormat::Vxl) {
        return Ok((read_volume(p)?, vec![]));
    }
    let (v, meta) =
        voxd::codec::vxl::decode_limited(&bytes, voxd::limits::Limits::LOCAL.max_voxels)
            .map_err(|e| format!("{}: {e}", p.display()))?;
    Ok((v, voxd::app::metadata::header_materials(&meta)))
}

pub fn read_volume(p: &Path) -> Result<Volume, String> {
    let bytes = std::fs::read(p).map_err(|e| format!("{}: {e}", p.display()))?;
    let f = VolumeFormat::sniff(&bytes)
        .or_else(|| VolumeFormat::from_path(p))
        .ok_or_else(|| {
            let readable: Vec<String> = voxd::codec::FORMATS
                .iter()
                .filter(|f| f.reads)
                .map(|f| format!(".{}", f.name))
                .collect();
            format!(
                "{}: not a volume file ({})",
                p.display(),
                readable.join(", ")
            )
        })?;
    // A few bytes of .vxl or .binvox can name a huge grid: refused before it is allocated.
    f.decode_limited(&bytes, voxd::limits::Limits::LOCAL.max_voxels)
        .map_err(|e| format!("{}: {e}", p.display()))
}

pub fn emit(out: String) -> Result<(), String> {
    use std::io::Write;
    match std::io::stdout().write_all(out.as_bytes()) {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => {
            Err(format!("writing to stdout: {e}"))
        }
        _ => Ok(()),
    }
}
