//! `voxd mesh`: a volume's (or a mesh's solid's) boundary as a mesh file (`voxd::extract`);
//! `voxd hermite`: a mesh's Hermite data as `.npz`.

use voxd::app::hermite::{Solid, dual_contour, solid_and_hermite};
use voxd::app::{self, files};
use voxd::engine::EngineChoice;
use voxd::extract::write::{MeshFormat, write};
use voxd::extract::{Algorithm, TriMesh, check, cubes, marching_cubes, occupancy, surface_nets};
use voxd::volume::Volume;

use super::args::{MeshArgs, VoxelizeArgs};
use super::output::read_volume;

/// Memory the Hermite data of a command-line run may take (the service bounds its own).
const HERMITE_BYTES: u64 = 8 << 30;

/// The solid and Hermite data of a mesh input.
fn solid(req: &app::VoxelizeRequest, name: &str) -> Result<Solid, String> {
    let engine =
        files::open_engine(EngineChoice::DEFAULT, None).map_err(|e| format!("{name}: {e}"))?;
    super::progress::with_bar(name, |ctl| {
        solid_and_hermite(req, &*engine, HERMITE_BYTES, ctl)
    })
    .map_err(|e| format!("{name}: {e}"))
}

pub fn mesh(a: &MeshArgs) -> Result<(), String> {
    let (input, output) = (&a.input, &a.output);
    let name = input.display().to_string();
    let algorithm = Algorithm::parse(&a.algorithm)?;
    let format = MeshFormat::of_path(output)?;
    let t0 = std::time::Instant::now();
    let is_mesh = voxd::mesh::Format::from_path(input).is_some();
    if algorithm == Algorithm::DualContouring && !is_mesh {
        return Err(format!(
            "{name}: dual-contouring needs Hermite data, which is taken from the mesh: give \
             the mesh file (with --resolution or --voxel-size) instead of a volume"
        ));
    }
    let (m, t_read) = if is_mesh {
        let req = a.request().map_err(|e| format!("{name}: {e}"))?;
        let s = solid(&req, &name)?;
        let t_read = t0.elapsed().as_secs_f64();
        match algorithm {
            Algorithm::DualContouring => {
                let w = super::progress::with_bar(&name, |ctl| dual_contour(&s, ctl))
                    .map_err(|e| format!("{name}: {e}"))?;
                (w, t_read)
            }
            _ => {
                let v = Volume::Bits(s.bits);
                (extract(&v, algorithm, &name)?.to_world(v.grid()), t_read)
            }
        }
    } else {
        let v = read_volume(input)?;
        let t_read = t0.elapsed().as_secs_f64();
        (extract(&v, algorithm, &name)?.to_world(v.grid()), t_read)
    };
    let t_extract = t0.elapsed().as_secs_f64() - t_read;
    let r = check::check(&m);
    let t_check = t0.elapsed().as_secs_f64() - t_read - t_extract;
    if !r.is_valid() {
        return Err(format!(
            "{name}: the extracted mesh failed its checks: {r:?}"
        ));
    }
    let tmp = output.with_extension(format!("{}.part", format.as_str()));
    let mut f = std::fs::File::create(&tmp).map_err(|e| format!("{}: {e}", tmp.display()))?;
    write(&m, format, &mut f)
        .and_then(|()| f.sync_all())
        .and_then(|()| std::fs::rename(&tmp, output))
        .map_err(|e| {
            let _ = std::fs::remove_file(&tmp);
            format!("{}: {e}", output.display())
        })?;
    println!(
        "{name} -> {}: {}, {} vertices, {} triangles, watertight, volume {:.6} \
         ({:.3} s: read {t_read:.3}, extract {t_extract:.3}, check {t_check:.3}, write {:.3})",
        output.display(),
        algorithm.as_str(),
        m.positions.len(),
        m.triangles.len(),
        r.volume,
        t0.elapsed().as_secs_f64(),
        t0.elapsed().as_secs_f64() - t_read - t_extract - t_check,
    );
    Ok(())
}

/// The mesh of volume `v` in lattice units (not dual contouring).
/// The mesh of `v` (lattice coordinates), its vertices coloured when `v` has colours.
fn extract(v: &Volume, algorithm: Algorithm, name: &str) -> Result<TriMesh, String> {
    let mut m = extract_shape(v, algorithm, name)?;
    if let Volume::Channels(a) = v {
        m.colors = voxd::extract::colour::vertex_colours(&m, a);
    }
    Ok(m)
}

fn extract_shape(v: &Volume, algorithm: Algorithm, name: &str) -> Result<TriMesh, String> {
    super::progress::with_bar(name, |ctl| match algorithm {
        Algorithm::Cubes => cubes::cubes(&occupancy(v), ctl),
        Algorithm::SurfaceNets => surface_nets::surface_nets(&surface_nets::Field::of(v), ctl),
        Algorithm::MarchingCubes => {
            marching_cubes::marching_cubes(&surface_nets::Field::of(v), ctl)
        }
        Algorithm::DualContouring => unreachable!("dual contouring is taken from the mesh"),
    })
    .map_err(|e| format!("{name}: {e}"))
}

pub fn hermite(a: &VoxelizeArgs) -> Result<(), String> {
    let t0 = std::time::Instant::now();
    let name = a.mesh.display().to_string();
    if a.output.extension().and_then(|e| e.to_str()) != Some("npz") {
        return Err(format!(
            "{}: Hermite data is written as .npz",
            a.output.display()
        ));
    }
    let req = a.request().map_err(|e| format!("{name}: {e}"))?;
    let s = solid(&req, &name)?;
    let bytes = voxd::codec::npz::encode_hermite(&s.hermite);
    voxd::atomic::write_with(&a.output, |w| std::io::Write::write_all(w, &bytes))
        .map_err(|e| format!("{}: {e}", a.output.display()))?;
    let d = s.grid.dims;
    println!(
        "{name}: {}x{}x{} solid -> {}: {} edges ({} uncrossed), {:.3} s",
        d[0],
        d[1],
        d[2],
        a.output.display(),
        s.hermite.edges.len(),
        s.hermite.uncrossed(),
        t0.elapsed().as_secs_f64()
    );
    Ok(())
}
