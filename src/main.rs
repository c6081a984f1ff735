//! The `voxd` command line: voxelize meshes, inspect and convert volumes, benchmark engines.

mod bench;

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use clap::{Args, Parser, Subcommand};
use voxd::codec::{VolumeFormat, vxl};
use voxd::engine::gpu::{GpuOptions, SolidStrategy};
use voxd::engine::{EngineChoice, Method};
use voxd::grid::{Grid, GridLimits, GridSpec};
use voxd::mesh::{self, Format, MeshDiagnostics};
use voxd::volume::Volume;

#[derive(Parser)]
#[command(
    name = "voxd",
    version,
    about = "Exact voxelization of triangle meshes"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Voxelize a mesh (.obj .gltf .glb .stl .ply, optionally .gz) into a volume file.
    Voxelize(VoxelizeArgs),
    /// Describe a volume (.vxl .binvox .npy) or a mesh file.
    Info { file: PathBuf },
    /// Convert a volume between formats, chosen by the files' extensions.
    Convert { input: PathBuf, output: PathBuf },
    /// Combine bit volumes on aligned grids: union, intersection, difference (first minus the rest), xor.
    Csg {
        /// union | intersection | difference | xor
        op: String,
        /// Volumes (.vxl .binvox .npy), at least one.
        #[arg(required = true)]
        inputs: Vec<PathBuf>,
        #[arg(short, long)]
        output: PathBuf,
    },
    /// Dilate, erode, open or close a bit volume.
    Morph {
        /// dilate | erode | open | close
        op: String,
        input: PathBuf,
        #[arg(short, long)]
        output: PathBuf,
        #[arg(long, default_value_t = 1)]
        radius: u32,
        /// cube | cross | sphere
        #[arg(long, default_value = "cube")]
        kernel: String,
        /// Enlarge the grid by the radius so dilation is not clipped.
        #[arg(long)]
        grow: bool,
    },
    /// Export outward normals of boundary voxels as .npy (int8, shape X×Y×Z×3, scaled to ±127).
    Normals {
        input: PathBuf,
        #[arg(short, long)]
        output: PathBuf,
    },
    /// Run the HTTP service.
    Serve(ServeArgs),
    /// Time the CPU and GPU engines per method and resolution on a mesh (a markdown table).
    Bench {
        mesh: PathBuf,
        /// Cubic resolutions, comma-separated.
        #[arg(long, default_value = "256,512,1024", value_delimiter = ',')]
        resolutions: Vec<u32>,
        /// Methods, comma-separated.
        #[arg(
            long,
            default_value = "solid,surface,conservative",
            value_delimiter = ','
        )]
        methods: Vec<Method>,
        /// Timed runs per cell (after one warm-up).
        #[arg(long, default_value_t = 3)]
        runs: usize,
        #[arg(long, env = "VOXD_ADAPTER")]
        adapter: Option<String>,
        /// Only the CPU engine.
        #[arg(long)]
        cpu_only: bool,
        /// GPU solid strategy: scan (toggle bits + prefix XOR) or masks (XOR every word above).
        #[arg(long, default_value = "scan", value_parser = ["scan", "masks"])]
        gpu_solid: String,
    },
}

#[derive(Args)]
struct VoxelizeArgs {
    /// Mesh file.
    mesh: PathBuf,
    /// Output volume; its extension picks the format (.vxl, .binvox, .npy).
    #[arg(short, long)]
    output: PathBuf,
    /// solid | surface | conservative | interior | density
    #[arg(long, default_value = "solid")]
    method: MethodArg,
    /// How solid-based methods (solid, conservative, interior, density) decide inside: parity
    /// (exact for watertight meshes), vote (parity along x, y and z, majority), winding
    /// (generalised winding number ≥ ½), flood (exterior flood fill outside the surface) or auto
    /// (parity when the mesh is watertight, else winding).
    #[arg(long, default_value = "parity")]
    fill: voxd::engine::fill::Fill,
    /// Sub-voxels per axis for density: 2 (values 0..8) or 4 (0..64).
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u32).range(2..=4))]
    density_factor: u32,
    /// Voxels along the mesh's longest axis (default 256 when no other grid option is given).
    #[arg(long, conflicts_with = "voxel_size")]
    resolution: Option<u32>,
    /// Edge length of a voxel in mesh units.
    #[arg(long)]
    voxel_size: Option<f64>,
    /// Explicit grid origin X,Y,Z (needs --voxel-size and --dims).
    #[arg(long, value_parser = parse_f64x3, requires_all = ["voxel_size", "dims"], allow_hyphen_values = true)]
    origin: Option<[f64; 3]>,
    /// Explicit grid dims X,Y,Z (needs --origin and --voxel-size).
    #[arg(long, value_parser = parse_u32x3, requires = "origin")]
    dims: Option<[u32; 3]>,
    /// Make every axis as long as the longest (N×N×N).
    #[arg(long, conflicts_with = "origin")]
    cubic: bool,
    /// Empty voxels added on every side.
    #[arg(long, default_value_t = 0)]
    padding: u32,
    /// auto (the GPU when an adapter exists, else the CPU), gpu or cpu.
    #[arg(long, default_value = "auto")]
    engine: EngineChoice,
    /// Use the GPU adapter whose name contains this (e.g. llvmpipe); also VOXD_ADAPTER.
    #[arg(long, env = "VOXD_ADAPTER")]
    adapter: Option<String>,
    /// Refuse grids with more voxels than this.
    #[arg(long, default_value_t = voxd::grid::DEFAULT_MAX_VOXELS)]
    max_voxels: u64,
    /// Mesh format, when the extension does not say (obj, gltf, glb, stl, ply).
    #[arg(long, value_parser = parse_format)]
    format: Option<Format>,
}

#[derive(Args)]
struct ServeArgs {
    /// Address to listen on (port 0 picks a free port; the bound address is printed).
    #[arg(long, env = "VOXD_ADDR", default_value = "127.0.0.1:8080")]
    addr: std::net::SocketAddr,
    /// Where volumes are stored.
    #[arg(long, env = "VOXD_DATA_DIR", default_value = "./voxd-data")]
    data_dir: PathBuf,
    /// auto, gpu or cpu.
    #[arg(long, env = "VOXD_ENGINE", default_value = "auto")]
    engine: EngineChoice,
    #[arg(long, env = "VOXD_ADAPTER")]
    adapter: Option<String>,
    /// Jobs that may wait; more are refused with 429.
    #[arg(long, env = "VOXD_QUEUE_CAPACITY", default_value_t = 64)]
    queue_capacity: usize,
    /// Jobs run at once on the CPU engine (the GPU engine runs one at a time).
    #[arg(long, env = "VOXD_WORKERS", default_value_t = 1)]
    workers: usize,
    /// Largest request body in bytes.
    #[arg(long, env = "VOXD_MAX_BODY_BYTES", default_value_t = 256 << 20)]
    max_body_bytes: usize,
    #[arg(long, env = "VOXD_MAX_TRIANGLES", default_value_t = 20_000_000)]
    max_triangles: usize,
    /// Voxel budget of one job.
    #[arg(long, env = "VOXD_MAX_VOXELS", default_value_t = 1024 * 1024 * 1024)]
    max_voxels: u64,
    /// Total bytes of stored volumes.
    #[arg(long, env = "VOXD_MAX_STORE_BYTES", default_value_t = 10 << 30)]
    max_store_bytes: u64,
}

fn serve(a: ServeArgs) -> Result<(), String> {
    let config = voxd::service::Config {
        addr: a.addr,
        data_dir: a.data_dir,
        engine: a.engine,
        adapter: a.adapter,
        queue_capacity: a.queue_capacity.max(1),
        workers: a.workers.max(1),
        max_body_bytes: a.max_body_bytes,
        max_triangles: a.max_triangles,
        max_voxels: a.max_voxels,
        max_store_bytes: a.max_store_bytes,
    };
    let rt = tokio::runtime::Runtime::new().map_err(|e| e.to_string())?;
    rt.block_on(voxd::service::serve(config, shutdown_signal(), |addr| {
        println!("voxd listening on http://{addr}");
        use std::io::Write;
        let _ = std::io::stdout().flush();
    }))
}

/// SIGTERM or Ctrl-C.
async fn shutdown_signal() {
    let term = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut s) => {
                s.recv().await;
            }
            Err(_) => std::future::pending().await,
        }
    };
    tokio::select! {
        _ = tokio::signal::ctrl_c() => {},
        _ = term => {},
    }
    tracing::info!("shutdown signal received");
}

/// A bit method, or density.
#[derive(Clone, Copy, Debug, PartialEq)]
enum MethodArg {
    Bits(Method),
    Density,
}

impl std::str::FromStr for MethodArg {
    type Err = String;
    fn from_str(s: &str) -> Result<MethodArg, String> {
        if s == "density" {
            Ok(MethodArg::Density)
        } else {
            s.parse::<Method>()
                .map(MethodArg::Bits)
                .map_err(|e| e.replace("interior", "interior, density"))
        }
    }
}

impl std::fmt::Display for MethodArg {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            MethodArg::Bits(m) => m.fmt(f),
            MethodArg::Density => f.write_str("density"),
        }
    }
}

fn parse_f64x3(s: &str) -> Result<[f64; 3], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|p| {
            p.trim()
                .parse::<f64>()
                .map_err(|_| format!("{p:?} is not a number"))
        })
        .collect::<Result<_, _>>()?;
    v.try_into()
        .map_err(|_| "expected three comma-separated numbers X,Y,Z".to_string())
}

fn parse_u32x3(s: &str) -> Result<[u32; 3], String> {
    let v: Vec<u32> = s
        .split(',')
        .map(|p| {
            p.trim()
                .parse::<u32>()
                .map_err(|_| format!("{p:?} is not a whole number"))
        })
        .collect::<Result<_, _>>()?;
    v.try_into()
        .map_err(|_| "expected three comma-separated whole numbers X,Y,Z".to_string())
}

fn parse_format(s: &str) -> Result<Format, String> {
    Format::from_name(s)
        .ok_or_else(|| format!("unknown mesh format {s:?}; expected obj, gltf, glb, stl or ply"))
}

/// `println!` into a String.
macro_rules! outln {
    ($out:expr, $($arg:tt)*) => {{
        use std::fmt::Write as _;
        let _ = writeln!($out, $($arg)*);
    }};
}

fn main() -> ExitCode {
    if std::env::var_os("XDG_RUNTIME_DIR").is_none() {
        // Mesa prints "XDG_RUNTIME_DIR is invalid" on every start without it; nothing is
        // written there by a compute-only device.
        // SAFETY: single-threaded at this point, before any thread or engine is started.
        unsafe { std::env::set_var("XDG_RUNTIME_DIR", std::env::temp_dir()) };
    }
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_env("VOXD_LOG")
                .unwrap_or_else(|_| "warn".into()),
        )
        .with_writer(std::io::stderr)
        .init();
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Voxelize(a) => voxelize(a),
        Command::Info { file } => info(&file),
        Command::Convert { input, output } => convert(&input, &output),
        Command::Serve(a) => serve(a),
        Command::Normals { input, output } => normals(&input, &output),
        Command::Morph {
            op,
            input,
            output,
            radius,
            kernel,
            grow,
        } => morph(&op, &input, &output, radius, &kernel, grow),
        Command::Csg { op, inputs, output } => csg(&op, &inputs, &output),
        Command::Bench {
            mesh,
            resolutions,
            methods,
            runs,
            adapter,
            cpu_only,
            gpu_solid,
        } => bench::run(bench::BenchArgs {
            mesh: &mesh,
            resolutions: &resolutions,
            methods: &methods,
            runs: runs.max(1),
            adapter,
            cpu_only,
            solid_strategy: if gpu_solid == "masks" {
                SolidStrategy::Masks
            } else {
                SolidStrategy::ToggleScan
            },
        }),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("voxd: error: {e}");
            ExitCode::FAILURE
        }
    }
}

fn voxelize(a: VoxelizeArgs) -> Result<(), String> {
    let t0 = Instant::now();
    let out_format = volume_format_of(&a.output)?;
    let name = a.mesh.display().to_string();
    let mesh = match a.format {
        Some(f) => {
            let bytes = std::fs::read(&a.mesh).map_err(|e| format!("{name}: {e}"))?;
            let dir = a.mesh.parent().map(Path::to_path_buf).unwrap_or_default();
            let opts = mesh::LoadOptions {
                external: mesh::ExternalResources::BesideFile(dir),
                ..Default::default()
            };
            mesh::load_bytes(&bytes, Some(f), &opts)
        }
        None => mesh::load_file(&a.mesh, mesh::LoadOptions::default().max_triangles),
    }
    .map_err(|e| format!("{name}: {e}"))?;
    let t_load = t0.elapsed();
    let t_diag0 = Instant::now();
    let diag = mesh.diagnostics();
    let t_diag = t_diag0.elapsed();
    eprintln!("{}", describe_mesh(&name, &diag));

    let spec = match (a.origin, a.dims, a.voxel_size, a.resolution) {
        (Some(origin), Some(dims), Some(voxel_size), _) => GridSpec::Explicit {
            origin,
            voxel_size,
            dims,
        },
        (_, _, Some(size), _) => GridSpec::VoxelSize {
            size,
            cubic: a.cubic,
        },
        (_, _, None, r) => GridSpec::Resolution {
            n: r.unwrap_or(256),
            cubic: a.cubic,
        },
    };
    let grid = Grid::fit(
        diag.bbox_min,
        diag.bbox_max,
        spec,
        a.padding,
        GridLimits {
            max_voxels: a.max_voxels,
        },
    )
    .map_err(|e| format!("{name}: {e}"))?;
    let engine = voxd::engine::open(
        a.engine,
        GpuOptions {
            adapter: a.adapter.clone(),
            ..Default::default()
        },
    )
    .map_err(|e| format!("{name}: {e}"))?;
    let t1 = Instant::now();
    if a.density_factor == 3 {
        return Err("--density-factor must be 2 or 4".into());
    }
    let (vol, fill) = match a.method {
        MethodArg::Bits(m) => {
            let (v, r) = voxd::engine::fill::voxelize(&*engine, &mesh, &grid, m, a.fill, &diag)
                .map_err(|e| format!("{name}: {e}"))?;
            (Volume::Bits(v), r)
        }
        MethodArg::Density => {
            let (d, r) = voxd::engine::density::density(
                &*engine,
                &mesh,
                &grid,
                a.density_factor,
                GridLimits {
                    max_voxels: a.max_voxels,
                },
                a.fill,
                &diag,
            )
            .map_err(|e| format!("{name}: {e}"))?;
            (Volume::Density(d), r)
        }
    };
    let t_vox = t1.elapsed();
    let t2 = Instant::now();
    let set = match &vol {
        Volume::Bits(b) => b.count_ones(),
        Volume::Density(d) => d.count_nonzero(),
    };
    let mut meta = serde_json::Map::new();
    meta.insert("method".into(), a.method.to_string().into());
    meta.insert(
        "source".into(),
        a.mesh
            .file_name()
            .map(|f| f.to_string_lossy().into_owned())
            .unwrap_or_default()
            .into(),
    );
    meta.insert("triangles".into(), diag.triangles.into());
    meta.insert("fill".into(), fill.used.name().into());
    write_volume(&a.output, out_format, &vol, &meta)?;
    let t_write = t2.elapsed();
    eprintln!("{}", describe_fill(&name, &fill));
    let d = grid.dims;
    println!(
        "{name}: {}x{}x{} {} -> {}: {set} voxels set ({:.2}%), engine {}, {:.3} s (load {:.3}, diagnose {:.3}, voxelize {:.3}, write {:.3})",
        d[0],
        d[1],
        d[2],
        a.method,
        a.output.display(),
        100.0 * set as f64 / grid.voxel_count() as f64,
        engine.describe(),
        t0.elapsed().as_secs_f64(),
        t_load.as_secs_f64(),
        t_diag.as_secs_f64(),
        t_vox.as_secs_f64(),
        t_write.as_secs_f64(),
    );
    Ok(())
}

fn describe_fill(name: &str, f: &voxd::engine::fill::FillReport) -> String {
    let mut s = format!("{name}: fill {}", f.used);
    if f.requested != f.used {
        s += &format!(" (asked for {})", f.requested);
    }
    s += &format!(", {} odd-parity columns", f.odd_parity_columns);
    if let Some(w) = &f.winding {
        s += &format!(
            ", {} cap triangles; voxels decided by the exact crossing count {}, minus the caps' winding number {}, by the mesh's winding number {}",
            w.cap_triangles, w.exact_voxels, w.cap_evaluated_voxels, w.mesh_evaluated_voxels
        );
    }
    if let Some(w) = &f.warning {
        s += &format!("\n{name}: WARNING: {w}");
    }
    s
}

fn describe_mesh(name: &str, d: &MeshDiagnostics) -> String {
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

fn volume_format_of(p: &Path) -> Result<VolumeFormat, String> {
    VolumeFormat::from_path(p).ok_or_else(|| {
        format!(
            "{}: unknown volume format; use the extension .vxl, .binvox or .npy",
            p.display()
        )
    })
}

/// Writes atomically: a temporary file beside the target, then a rename.
fn write_volume(
    path: &Path,
    f: VolumeFormat,
    v: &Volume,
    meta: &serde_json::Map<String, serde_json::Value>,
) -> Result<(), String> {
    let err = |e: &dyn std::fmt::Display| format!("{}: {e}", path.display());
    if let (VolumeFormat::Binvox, Volume::Bits(b)) = (f, v) {
        let d = b.dims();
        if d[0] != d[1] || d[1] != d[2] {
            eprintln!(
                "{}: binvox is cubic; the {}x{}x{} grid is padded with empty voxels to {n}x{n}x{n}",
                path.display(),
                d[0],
                d[1],
                d[2],
                n = d.iter().max().unwrap()
            );
        }
    }
    let tmp = path.with_file_name(format!(
        ".{}.tmp{}",
        path.file_name()
            .map(|f| f.to_string_lossy())
            .unwrap_or_default(),
        std::process::id()
    ));
    let result = (|| -> Result<(), String> {
        let mut file = std::io::BufWriter::new(std::fs::File::create(&tmp).map_err(|e| err(&e))?);
        match f {
            VolumeFormat::Npy => voxd::codec::npy::write(v, &mut file).map_err(|e| err(&e))?,
            VolumeFormat::Vxl => {
                std::io::Write::write_all(&mut file, &vxl::encode(v, meta).map_err(|e| err(&e))?)
                    .map_err(|e| err(&e))?
            }
            other => std::io::Write::write_all(&mut file, &other.encode(v).map_err(|e| err(&e))?)
                .map_err(|e| err(&e))?,
        }
        let file = file.into_inner().map_err(|e| err(&e))?;
        file.sync_all().map_err(|e| err(&e))?;
        std::fs::rename(&tmp, path).map_err(|e| err(&e))
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

fn read_volume(p: &Path) -> Result<Volume, String> {
    let bytes = std::fs::read(p).map_err(|e| format!("{}: {e}", p.display()))?;
    let f = VolumeFormat::sniff(&bytes)
        .or_else(|| VolumeFormat::from_path(p))
        .ok_or_else(|| format!("{}: not a volume file (.vxl, .binvox, .npy)", p.display()))?;
    f.decode(&bytes)
        .map_err(|e| format!("{}: {e}", p.display()))
}

fn info(p: &Path) -> Result<(), String> {
    // Built first and written once: a reader that closes early (`| head`) is not an error.
    let mut out = String::new();
    if VolumeFormat::from_path(p).is_none() && Format::from_path(p).is_some() {
        let m = mesh::load_file(p, usize::MAX).map_err(|e| format!("{}: {e}", p.display()))?;
        outln!(
            out,
            "{}",
            describe_mesh(&p.display().to_string(), &m.diagnostics())
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
                n as f64 * g.voxel_size.powi(3)
            );
            match b.solid_bounds() {
                Some((lo, hi)) => {
                    let wlo = [0, 1, 2].map(|a| g.origin[a] + lo[a] as f64 * g.voxel_size);
                    let whi = [0, 1, 2].map(|a| g.origin[a] + (hi[a] + 1) as f64 * g.voxel_size);
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
    }
    emit(out)
}

fn csg(op: &str, inputs: &[PathBuf], output: &Path) -> Result<(), String> {
    use voxd::volume::csg::{CsgOp, apply};
    let op = CsgOp::from_name(op).ok_or_else(|| {
        format!("unknown operation {op:?}; expected union, intersection, difference or xor")
    })?;
    let f = volume_format_of(output)?;
    let mut vols = Vec::new();
    for p in inputs {
        match read_volume(p)? {
            Volume::Bits(b) => vols.push(b),
            Volume::Density(_) => {
                return Err(format!(
                    "{}: a density volume; CSG combines bit volumes",
                    p.display()
                ));
            }
        }
    }
    let refs: Vec<&voxd::BitVolume> = vols.iter().collect();
    let r = apply(op, &refs).map_err(|e| e.to_string())?;
    let (g, n) = (*r.grid(), r.count_ones());
    write_volume(output, f, &Volume::Bits(r), &serde_json::Map::new())?;
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

fn morph(
    op: &str,
    input: &Path,
    output: &Path,
    radius: u32,
    kernel: &str,
    grow: bool,
) -> Result<(), String> {
    use voxd::volume::morph::{self, Kernel, MorphOp};
    let op = MorphOp::from_name(op).ok_or_else(|| {
        format!("unknown operation {op:?}; expected dilate, erode, open or close")
    })?;
    let kernel = Kernel::from_name(kernel)
        .ok_or_else(|| format!("unknown kernel {kernel:?}; expected cube, cross or sphere"))?;
    if radius > morph::MAX_RADIUS {
        return Err(format!(
            "radius {radius} is over the limit of {}",
            morph::MAX_RADIUS
        ));
    }
    let f = volume_format_of(output)?;
    let Volume::Bits(v) = read_volume(input)? else {
        return Err(format!(
            "{}: a density volume; morphology works on bit volumes",
            input.display()
        ));
    };
    let r = morph::apply(&v, op, radius, kernel, grow);
    let (d, n) = (r.dims(), r.count_ones());
    write_volume(output, f, &Volume::Bits(r), &serde_json::Map::new())?;
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

fn normals(input: &Path, output: &Path) -> Result<(), String> {
    if output.extension().is_none_or(|e| e != "npy") {
        return Err(format!("{}: normals are written as .npy", output.display()));
    }
    let v = read_volume(input)?;
    let n = voxd::volume::normals::boundary_normals(&v);
    let count = n.iter().filter(|c| **c != [0; 3]).count();
    let bytes = voxd::codec::npy::encode_normals(v.grid().dims, &n);
    std::fs::write(output, bytes).map_err(|e| format!("{}: {e}", output.display()))?;
    println!(
        "{} -> {}: {count} boundary voxels with a normal",
        input.display(),
        output.display()
    );
    Ok(())
}

fn emit(out: String) -> Result<(), String> {
    use std::io::Write;
    match std::io::stdout().write_all(out.as_bytes()) {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => {
            Err(format!("writing to stdout: {e}"))
        }
        _ => Ok(()),
    }
}

fn convert(input: &Path, output: &Path) -> Result<(), String> {
    let f = volume_format_of(output)?;
    let v = read_volume(input)?;
    write_volume(output, f, &v, &serde_json::Map::new())?;
    println!("{} -> {} ({})", input.display(), output.display(), f.name());
    Ok(())
}
