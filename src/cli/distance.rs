//! `voxd threshold` and `voxd sdf`, and `voxd csg` on distance volumes: the operations of
//! `app::distance` on files (definitions: docs/methods.md, "Operations on distance volumes").

use std::path::{Path, PathBuf};

use voxd::app::distance;
use voxd::app::metadata::{self, Origin};
use voxd::volume::csg::{self, CsgOp};
use voxd::volume::levelset::{self, DISTANCE_KINDS};
use voxd::volume::{Sparse, Volume};

use super::commands::volume_format_of;
use super::output::{read_volume, write_volume};

fn read_distance(p: &Path, what: &str) -> Result<Sparse<f32>, String> {
    levelset::into_distance(read_volume(p)?, what).map_err(|e| format!("{}: {e}", p.display()))
}

/// Is the file a distance volume (so `voxd csg` combines distances)?
pub fn is_distance(p: &Path) -> Result<bool, String> {
    Ok(DISTANCE_KINDS.contains(&read_volume(p)?.kind()))
}

pub fn threshold(input: &Path, level: f64, output: &Path) -> Result<(), String> {
    let level = distance::check_level(level).map_err(|e| e.to_string())?;
    let f = volume_format_of(output)?;
    let s = read_distance(input, "threshold")?;
    let r = super::progress::with_bar(&input.display().to_string(), |ctl| {
        Ok::<_, voxd::app::Error>(levelset::threshold_with(&s, level, ctl)?)
    })
    .map_err(|e| format!("{}: {e}", input.display()))?;
    let n = r.count_ones();
    let provenance = distance::threshold_provenance(&input.display().to_string(), level);
    let header = metadata::vxl_header(&Origin::Derived {
        method: "threshold",
        provenance: &provenance,
        materials: &[],
    });
    write_volume(output, f, &Volume::Bits(r), &header)?;
    println!(
        "{} -> {}: below {level}: {n} voxels set",
        input.display(),
        output.display()
    );
    Ok(())
}

pub fn sdf(input: &Path, band: u32, output: &Path) -> Result<(), String> {
    distance::check_band(band).map_err(|e| e.to_string())?;
    let f = volume_format_of(output)?;
    let b = voxd::app::ops::require_bits(read_volume(input)?, "the distance transform")
        .map_err(|e| format!("{}: {e}", input.display()))?;
    let r = super::progress::with_bar(&input.display().to_string(), |ctl| {
        Ok::<_, voxd::app::Error>(levelset::sdf_of_bits_with(&b, band, ctl)?)
    })
    .map_err(|e| format!("{}: {e}", input.display()))?;
    let (bricks, tiles) = (r.brick_count(), r.tile_count());
    let provenance = distance::sdf_provenance(&input.display().to_string(), band);
    let header = metadata::vxl_header(&Origin::Derived {
        method: "sdf",
        provenance: &provenance,
        materials: &[],
    });
    write_volume(output, f, &Volume::SparseDistance(r), &header)?;
    println!(
        "{} -> {}: band {band}: {bricks} bricks, {tiles} tiles",
        input.display(),
        output.display()
    );
    Ok(())
}

/// `voxd csg` when the inputs are distance volumes.
pub fn csg(op: CsgOp, inputs: &[PathBuf], output: &Path) -> Result<(), String> {
    let f = volume_format_of(output)?;
    let vols = inputs
        .iter()
        .map(|p| read_distance(p, "CSG with a distance volume"))
        .collect::<Result<Vec<_>, _>>()?;
    let refs: Vec<&Sparse<f32>> = vols.iter().collect();
    let r = csg::apply_distance(op, &refs).map_err(|e| e.to_string())?;
    let provenance = serde_json::json!({
        "op": op.to_string(),
        "operands": inputs.iter().map(|p| p.display().to_string()).collect::<Vec<_>>(),
    });
    let header = metadata::vxl_header(&Origin::Derived {
        method: "csg",
        provenance: &provenance,
        materials: &[],
    });
    let n = Volume::SparseDistance(r.clone()).count_occupied();
    write_volume(output, f, &Volume::SparseDistance(r), &header)?;
    println!(
        "{} -> {}: {n} voxels inside",
        inputs.len(),
        output.display()
    );
    Ok(())
}
