//! The commands: each turns its arguments into application requests, calls the application
//! layer and prints the result. Errors are one line naming the file (`voxd: error: FILE: …`).

use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use voxd::app::metadata::{self, Origin};
use voxd::app::{self, CsgExpr, MorphologyRequest, files, ops};
use voxd::codec::VolumeFormat;
use voxd::limits::Limits;
use voxd::mesh::{self, Format};
use voxd::volume::Volume;
use voxd::volume::csg::CsgOp;
use voxd::volume::morph::{Kernel, MorphOp};

use super::args::VoxelizeArgs;
use super::output::{
    describe_fill, describe_mesh, emit, outln, read_volume, read_volume_with_materials,
    write_volume,
};

pub fn voxelize(a: &VoxelizeArgs) -> Result<(), String> {
    let t0 = Instant::now();
    let out_format = volume_format_of(&a.output)?;
    let name = a.mesh.display().to_string();
    let named = |e: app::Error| format!("{name}: {e}");
    let req = a.request().map_err(named)?;
    let loaded = app::voxelize::load(&req).map_err(named)?;
    eprintln!("{}", describe_mesh(&name, &loaded.diagnostics));
    let prepared = loaded.fit(&req).map_err(named)?;
    let engine = files::open_engine(a.engine, a.adapter.clone()).map_err(named)?;
    let v = super::progress::with_bar(&name, |ctl| app::voxelize::run(&prepared, &*engine, ctl))
        .map_err(named)?;
    let t_write = Instant::now();
    let header = metadata::vxl_header(&Origin::Mesh {
        prepared: &prepared,
        fill: &v.fill,
        job: None,
    });
    write_volume(&a.output, out_format, &v.volume, &header)?;
    let write_s = t_write.elapsed().as_secs_f64();
    eprintln!("{}", describe_fill(&name, &v.fill));
    let (set, _) = metadata::counts(&v.volume);
    let g = prepared.grid;
    let d = g.dims;
    println!(
        "{name}: {}x{}x{} {} -> {}: {set} voxels set ({:.2}%), engine {}, {:.3} s (load {:.3}, diagnose {:.3}, voxelize {:.3}, write {:.3})",
        d[0],
        d[1],
        d[2],
        prepared.method.name(),
        a.output.display(),
        100.0 * set as f64 / g.voxel_count() as f64,
        engine.describe(),
        t0.elapsed().as_secs_f64(),
        prepared.load_s,
        prepared.diagnose_s,
        v.voxelize_s,
        write_s,
    );
    Ok(())
}

pub fn volume_format_of(p: &Path) -> Result<VolumeFormat, String> {
    VolumeFormat::from_path(p).ok_or_else(|| {
        format!(
            "{}: unknown volume format; use one of the extensions {}",
            p.display(),
            voxd::codec::FORMATS
                .iter()
                .map(|f| format!(".{}", f.extension))
                .collect::<Vec<_>>()
                .join(", ")
        )
    })
}

pub fn info(p: &Path) -> Result<(), String> {
    // Built first and written once: a reader that closes early (`| head`) is not an error.
    let mut out = String::new();
    if VolumeFormat::from_path(p).is_none() && Format::from_path(p).is_some() {
        let m = mesh::load_file(p, usize::MAX).map_err(|e| format!("{}: {e}", p.display()))?;
        outln!(
            out,
            "{}",
            describe_mesh(&p.display().to_string(), &m.diagnostics())
        );
        outln!(
            out,
            "{}: attributes: {}",
            p.display(),
            m.attributes().describe()
        );
        return emit(out);
    }
    let v = read_volume(p)?;
    let g = v.grid();
    outln!(out, "file:       {}", p.display());
    outln!(out, "kind:       {}", v.kind());
    outln!(
        out,
        "dims:       {} x {} x {} ({} voxels)",
        g.dims[0],
        g.dims[1],
        g.dims[2],
        g.voxel_count()
    );
    outln!(out, "origin:     {:?}", g.origin);
    outln!(out, "voxel size: {}", g.voxel_size);
    outln!(out, "extent:     {:?} .. {:?}", g.origin, g.max_corner());
    match &v {
        Volume::Bits(b) => {
            let n = b.count_ones();
            outln!(
                out,
                "set voxels: {n} ({:.3}%), volume {}",
                100.0 * n as f64 / g.voxel_count() as f64,
                g.volume_of(n)
            );
            match b.solid_bounds() {
                Some((lo, hi)) => {
                    let wlo = g.corner(lo.map(i64::from));
                    let whi = g.corner(hi.map(|h| i64::from(h) + 1));
                    outln!(
                        out,
                        "set bounds: index {lo:?} ..= {hi:?}, world {wlo:?} .. {whi:?}"
                    );
                }
                None => outln!(out, "set bounds: empty"),
            }
            let st = voxd::volume::stats::stats(b);
            outln!(
                out,
                "surface:    {} voxels with an empty face neighbour",
                st.surface_voxels
            );
            outln!(
                out,
                "components: {} (6-connected), {} (26-connected)",
                st.components_6,
                st.components_26
            );
            if let (Some(c), Some(i)) = (st.centre_of_mass, st.inertia) {
                outln!(out, "centre of mass: {c:?}");
                outln!(out, "inertia:    {:?}", i);
            }
        }
        Volume::Density(d) => {
            outln!(
                out,
                "density:    0..={}, {} voxels occupied, {:.3} voxels of volume",
                d.max(),
                d.count_nonzero(),
                d.occupied_voxels()
            );
        }
        Volume::SparseDistance(s) => {
            let d = voxd::app::store::DistanceMeta::of_sparse(s);
            let show = |v: Option<serde_json::Value>| v.map(|v| v.to_string()).unwrap_or_default();
            outln!(
                out,
                "distance:   signed, band {} voxels, background {} (inside: {})",
                show(d.band).trim_matches('"'),
                s.background(),
                s.tile_value()
            );
            outln!(
                out,
                "bricks:     {} of 8³ stored ({} voxels in band), {} tiles inside",
                d.bricks.unwrap_or(0),
                d.active_voxels.unwrap_or(0),
                d.tiles.unwrap_or(0)
            );
            let n = s.count_occupied();
            outln!(out, "inside:     {n} voxels, volume {}", g.volume_of(n));
        }
        Volume::Channels(a) => {
            outln!(out, "set voxels: {}", a.len());
            let names: Vec<String> = a
                .channels()
                .iter()
                .map(|c| format!("{} ({})", c.name, c.values.value_type()))
                .collect();
            outln!(out, "channels:   {}", names.join(", "));
        }
        other => outln!(out, "occupied:   {} voxels", other.count_occupied()),
    }
    emit(out)
}

pub fn csg(op: CsgOp, inputs: &[std::path::PathBuf], output: &Path) -> Result<(), String> {
    let f = volume_format_of(output)?;
    let mut loaded = vec![];
    let mut operands = vec![];
    for p in inputs {
        let id = p.display().to_string();
        let (v, table) = read_volume_with_materials(p)?;
        ops::require(&v, voxd::volume::csg::ACCEPTS, "CSG")
            .map_err(|e| format!("{}: {e}", p.display()))?;
        loaded.push((id.clone(), v, table));
        operands.push(CsgExpr::Volume(id));
    }
    let expr = CsgExpr::Op { op, operands };
    let provenance = expr.to_json();
    let (r, table) = if loaded.iter().any(|o| matches!(o.1, Volume::Channels(_))) {
        // Colour and material channels carried (app::carry), the tables merged.
        let with_attributes = loaded
            .into_iter()
            .map(|(id, v, materials)| {
                let attrs = match &v {
                    Volume::Channels(a) => Some(voxd::app::store::AttributesMeta {
                        channels: a.channels().iter().map(|c| c.name.clone()).collect(),
                        materials,
                    }),
                    _ => None,
                };
                (id, v, attrs)
            })
            .collect();
        let (a, table) =
            app::carry::combine(&expr, with_attributes, &voxd::cancel::Control::none())
                .map_err(|e| e.to_string())?;
        (Volume::Channels(a), table)
    } else {
        let mut vols = HashMap::new();
        for (id, v, _) in loaded {
            vols.insert(
                id,
                Arc::new(ops::require_bits(v, "CSG").map_err(|e| e.to_string())?),
            );
        }
        let r = ops::eval_csg(&expr, &vols).map_err(|e| e.to_string())?;
        (Volume::Bits(r), vec![])
    };
    let (g, n) = (*r.grid(), r.count_occupied());
    let header = metadata::vxl_header(&Origin::Derived {
        method: "csg",
        provenance: &provenance,
        materials: &table,
    });
    write_volume(output, f, &r, &header)?;
    println!(
        "{} -> {}: {}x{}x{} grid at {:?}, {n} voxels set",
        inputs.len(),
        output.display(),
        g.dims[0],
        g.dims[1],
        g.dims[2],
        g.origin
    );
    Ok(())
}

pub fn morph(
    op: MorphOp,
    input: &Path,
    output: &Path,
    radius: u32,
    kernel: Kernel,
    grow: bool,
) -> Result<(), String> {
    let req = MorphologyRequest {
        op,
        kernel,
        radius,
        grow,
    };
    let limits = Limits::LOCAL;
    req.check(&limits).map_err(|e| e.to_string())?;
    let f = volume_format_of(output)?;
    let (v, table) = read_volume_with_materials(input)?;
    ops::require(&v, voxd::volume::morph::ACCEPTS, "morphology")
        .map_err(|e| format!("{}: {e}", input.display()))?;
    let r = super::progress::with_bar(&input.display().to_string(), |ctl| match &v {
        // Colour and material channels carried: added voxels take their nearest source's.
        Volume::Channels(a) => app::carry::morphology(a, &req, &limits, ctl).map(Volume::Channels),
        Volume::Bits(b) => ops::morphology_with(b, &req, &limits, ctl).map(Volume::Bits),
        _ => unreachable!("required above"),
    })
    .map_err(|e| format!("{}: {e}", input.display()))?;
    let (d, n) = (r.grid().dims, r.count_occupied());
    let provenance = ops::morphology_provenance(&input.display().to_string(), &req);
    let header = metadata::vxl_header(&Origin::Derived {
        method: "morphology",
        provenance: &provenance,
        materials: &table,
    });
    write_volume(output, f, &r, &header)?;
    println!(
        "{} -> {}: {}x{}x{}, {n} voxels set",
        input.display(),
        output.display(),
        d[0],
        d[1],
        d[2]
    );
    Ok(())
}

pub fn normals(input: &Path, output: &Path) -> Result<(), String> {
    if output.extension().is_none_or(|e| e != "npy") {
        return Err(format!("{}: normals are written as .npy", output.display()));
    }
    let v = read_volume(input)?;
    let count =
        files::write_normals(&v, output).map_err(|e| format!("{}: {e}", output.display()))?;
    println!(
        "{} -> {}: {count} boundary voxels with a normal",
        input.display(),
        output.display()
    );
    Ok(())
}

pub fn convert(input: &Path, output: &Path) -> Result<(), String> {
    let f = volume_format_of(output)?;
    let v = read_volume(input)?;
    write_volume(output, f, &v, &serde_json::Map::new())?;
    println!("{} -> {} ({})", input.display(), output.display(), f.name());
    Ok(())
}
