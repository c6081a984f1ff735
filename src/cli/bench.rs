//! `voxd bench`: times the CPU and GPU engines per method and resolution on one mesh, with the
//! GPU time split into upload, dispatch and readback, and checks that both give the same bits.
//! Built without the `gpu` feature it times the CPU engine alone (as `--cpu-only`), once it has
//! said why.

use std::time::{Duration, Instant};

use super::args::BenchArgs;
use voxd::engine::cpu::CpuEngine;
use voxd::engine::gpu::GpuTimings;
use voxd::engine::{Engine, GridMesh, Method};
use voxd::grid::{Grid, GridLimits, GridSpec};
use voxd::volume::BitVolume;

/// The engine timed against the CPU: none can exist without the `gpu` feature.
#[cfg(feature = "gpu")]
type Gpu = voxd::engine::gpu::GpuEngine;
#[cfg(not(feature = "gpu"))]
enum Gpu {}

#[cfg(feature = "gpu")]
fn open_gpu(a: &BenchArgs) -> Result<Option<Gpu>, String> {
    let t = Instant::now();
    let g = Gpu::new(voxd::engine::gpu::GpuOptions {
        adapter: a.adapter.clone(),
        solid_strategy: a.gpu_solid,
        ..Default::default()
    })
    .map_err(|e| e.to_string())?;
    println!(
        "gpu: {:?}, opened in {} ms, solid strategy {:?}",
        g.adapter(),
        ms(t.elapsed()),
        a.gpu_solid
    );
    Ok(Some(g))
}

#[cfg(not(feature = "gpu"))]
fn open_gpu(_: &BenchArgs) -> Result<Option<Gpu>, String> {
    println!("gpu: none (this voxd was built without the gpu feature)");
    Ok(None)
}

#[cfg(feature = "gpu")]
fn timed(g: &Gpu, gm: &GridMesh, m: Method) -> Result<(BitVolume, GpuTimings), String> {
    g.voxelize_timed(gm, m).map_err(|e| e.to_string())
}

#[cfg(not(feature = "gpu"))]
fn timed(g: &Gpu, _: &GridMesh, _: Method) -> Result<(BitVolume, GpuTimings), String> {
    match *g {}
}

fn median(mut v: Vec<Duration>) -> Duration {
    v.sort();
    v[v.len() / 2]
}

fn ms(d: Duration) -> String {
    format!("{:.1}", d.as_secs_f64() * 1000.0)
}

pub fn run(a: &BenchArgs) -> Result<(), String> {
    let runs = a.runs.max(1);
    let name = a.mesh.display().to_string();
    let t = Instant::now();
    let mesh = voxd::mesh::load_file(&a.mesh, usize::MAX).map_err(|e| format!("{name}: {e}"))?;
    println!(
        "mesh: {name}, {} triangles, loaded in {} ms",
        mesh.triangles().len(),
        ms(t.elapsed())
    );
    let gpu = if a.cpu_only { None } else { open_gpu(a)? };
    println!(
        "cpu: {} threads, {}",
        rayon::current_num_threads(),
        std::env::consts::ARCH
    );
    println!("medians of {} runs after one warm-up; times in ms\n", runs);
    println!(
        "| method | grid | snap | cpu | gpu total | gpu upload | gpu dispatch | gpu readback | cpu / gpu | identical |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    let (lo, hi) = mesh.bounds();
    for &n in &a.resolutions {
        let grid = Grid::fit(
            lo,
            hi,
            GridSpec::Resolution { n, cubic: true },
            0,
            GridLimits::default(),
        )
        .map_err(|e| e.to_string())?;
        let t = Instant::now();
        let gm = GridMesh::new(&mesh, &grid).map_err(|e| e.to_string())?;
        let snap = t.elapsed();
        for &m in &a.methods {
            let mut cpu_times = vec![];
            let mut cpu_vol = None;
            for i in 0..=runs {
                let t = Instant::now();
                let v = CpuEngine.voxelize(&gm, m).map_err(|e| e.to_string())?;
                if i > 0 {
                    cpu_times.push(t.elapsed());
                }
                cpu_vol = Some(v);
            }
            let cpu = median(cpu_times);
            let row = match &gpu {
                None => "| | | | | n/a |".to_string(),
                Some(g) => {
                    let (mut tot, mut up, mut disp, mut read) = (vec![], vec![], vec![], vec![]);
                    let mut same = true;
                    for i in 0..=runs {
                        let t = Instant::now();
                        let (v, tm) = timed(g, &gm, m)?;
                        let el = t.elapsed();
                        same &= Some(&v) == cpu_vol.as_ref();
                        if i > 0 {
                            tot.push(el);
                            up.push(tm.upload);
                            disp.push(tm.dispatch);
                            read.push(tm.readback);
                        }
                    }
                    let total = median(tot);
                    format!(
                        "| {} | {} | {} | {} | {:.2}× | {} |",
                        ms(total),
                        ms(median(up)),
                        ms(median(disp)),
                        ms(median(read)),
                        cpu.as_secs_f64() / total.as_secs_f64(),
                        if same { "yes" } else { "NO" }
                    )
                }
            };
            println!("| {m} | {n}³ | {} | {} {row}", ms(snap), ms(cpu));
        }
    }
    Ok(())
}
