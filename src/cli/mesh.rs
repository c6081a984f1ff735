//! `voxd mesh`: a volume file's boundary as a mesh file (`voxd::extract`).

use std::path::Path;

use voxd::extract::write::{MeshFormat, write};
use voxd::extract::{Algorithm, check, cubes, marching_cubes, occupancy, surface_nets};

use super::output::read_volume;

pub fn mesh(input: &Path, output: &Path, algorithm: &str) -> Result<(), String> {
    let algorithm = Algorithm::parse(algorithm)?;
    let format = MeshFormat::of_path(output)?;
    let t0 = std::time::Instant::now();
    let v = read_volume(input)?;
    let t_read = t0.elapsed().as_secs_f64();
    let grid = *v.grid();
    let m = super::progress::with_bar(&input.display().to_string(), |ctl| match algorithm {
        Algorithm::Cubes => cubes::cubes(&occupancy(&v), ctl),
        Algorithm::SurfaceNets => surface_nets::surface_nets(&surface_nets::Field::of(&v), ctl),
        Algorithm::MarchingCubes => {
            marching_cubes::marching_cubes(&surface_nets::Field::of(&v), ctl)
        }
    })
    .map_err(|e| format!("{}: {e}", input.display()))?;
    let t_extract = t0.elapsed().as_secs_f64() - t_read;
    let r = check::check(&m);
    let t_check = t0.elapsed().as_secs_f64() - t_read - t_extract;
    if !r.is_valid() {
        return Err(format!(
            "{}: the extracted mesh failed its checks: {r:?}",
            input.display()
        ));
    }
    let world = m.to_world(&grid);
    let tmp = output.with_extension(format!("{}.part", format.as_str()));
    let mut f = std::fs::File::create(&tmp).map_err(|e| format!("{}: {e}", tmp.display()))?;
    write(&world, format, &mut f)
        .and_then(|()| f.sync_all())
        .and_then(|()| std::fs::rename(&tmp, output))
        .map_err(|e| {
            let _ = std::fs::remove_file(&tmp);
            format!("{}: {e}", output.display())
        })?;
    println!(
        "{} -> {}: {}, {} vertices, {} triangles, watertight, enclosing {} voxels \
         ({:.3} s: read {t_read:.3}, extract {t_extract:.3}, check {t_check:.3}, write {:.3})",
        input.display(),
        output.display(),
        algorithm.as_str(),
        world.positions.len(),
        world.triangles.len(),
        r.volume,
        t0.elapsed().as_secs_f64(),
        t0.elapsed().as_secs_f64() - t_read - t_extract - t_check,
    );
    Ok(())
}
