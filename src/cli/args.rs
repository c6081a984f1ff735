//! The command line's arguments (clap), and their translation into the application's typed
//! requests. Value lists come from the library's [`Named`] types, so `--help` lists them and a
//! bad value is a usage error (exit 2) like every other.

use std::path::PathBuf;

use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
use clap::{Args, Parser, Subcommand};
use voxd::app::request::{Band, MethodName, MethodParams};
use voxd::app::{GridOptions, Limits, MeshSource, MethodSpec, VoxelizeRequest};
use voxd::engine::fill::Fill;
use voxd::engine::gpu::SolidStrategy;
use voxd::engine::{EngineChoice, Method};
use voxd::limits::serve;
use voxd::mesh::Format;
use voxd::names::Named;
use voxd::service::auth::KeyLimits;
use voxd::store::StoreSpec;
use voxd::volume::csg::CsgOp;
use voxd::volume::morph::{Kernel, MorphOp};

/// A value parser for a [`Named`] type: its names are the possible values.
fn named<T: Named + Clone + Send + Sync>() -> impl TypedValueParser<Value = T> {
    PossibleValuesParser::new(T::ALL.iter().map(|v| PossibleValue::new(v.name())))
        .map(|s| voxd::names::parse::<T>(&s).expect("clap checked the name"))
}

fn parse_f64x3(s: &str) -> Result<[f64; 3], String> {
    voxd::names::parse_triple(s)
}

fn parse_u32x3(s: &str) -> Result<[u32; 3], String> {
    voxd::names::parse_triple(s)
}

/// Seconds from a flag (negative or NaN counts as 0).
fn secs(s: f64) -> std::time::Duration {
    std::time::Duration::from_secs_f64(if s.is_finite() { s.max(0.0) } else { 0.0 })
}

fn parse_band(s: &str) -> Result<Band, String> {
    Band::parse(s)
}

fn parse_format(s: &str) -> Result<Format, String> {
    Format::from_name(s).ok_or_else(|| {
        format!(
            "unknown mesh format {s:?}; expected {}",
            voxd::names::choices::<Format>()
        )
    })
}

#[derive(Parser)]
#[command(
    name = "voxd",
    version,
    about = "Exact voxelization of triangle meshes"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
    /// How log lines (stderr) are written: `text` for people, `json` (one object per line)
    /// for log shippers. Which lines: `VOXD_LOG` (an env filter; `serve` shows info, the
    /// access log and job lines, by default; other commands warnings).
    #[arg(
        long,
        global = true,
        env = "VOXD_LOG_FORMAT",
        value_enum,
        default_value_t = LogFormat::Text
    )]
    pub log_format: LogFormat,
}

/// `--log-format`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum LogFormat {
    Text,
    Json,
}

#[derive(Subcommand)]
pub enum Command {
    /// Voxelize a mesh (.obj .gltf .glb .stl .ply, optionally .gz) into a volume file.
    Voxelize(VoxelizeArgs),
    /// Describe a volume (.vxl .binvox .npy) or a mesh file.
    Info { file: PathBuf },
    /// Convert a volume between formats, chosen by the files' extensions.
    Convert { input: PathBuf, output: PathBuf },
    /// Combine bit volumes on aligned grids: union, intersection, difference (first minus the rest), xor; or distance volumes on one grid by min/max (no xor).
    Csg {
        #[arg(value_parser = named::<CsgOp>())]
        op: CsgOp,
        /// Volumes (.vxl .binvox .npy), at least one.
        #[arg(required = true)]
        inputs: Vec<PathBuf>,
        #[arg(short, long)]
        output: PathBuf,
    },
    /// A distance volume's voxels below LEVEL (under IEEE totalOrder), as a bit volume: level 0
    /// gives the inside, negative levels erode, positive ones dilate.
    Threshold {
        /// A distance volume (.vxl of `voxelize --method sdf` or `voxd sdf`).
        input: PathBuf,
        /// The level L, in world units: a voxel is set iff its distance is below L.
        #[arg(long, allow_hyphen_values = true)]
        level: f64,
        /// The bit volume (.vxl .binvox .npy .vdb).
        #[arg(short, long)]
        output: PathBuf,
    },
    /// A volume's boundary as a triangle mesh (docs/methods.md, "Meshes out").
    Mesh(MeshArgs),
    /// The Hermite data of a mesh's solid as .npz (docs/format.md, "Hermite data"): every
    /// edge between neighbouring voxel centres that differs in solid, where the mesh crosses
    /// it and the crossed triangle's normal.
    Hermite(VoxelizeArgs),
    /// The exact signed distance transform of a bit volume, in a sparse band of BAND voxels
    /// (negative at its set voxels; docs/methods.md).
    Sdf {
        /// A bit volume (.vxl .binvox .npy).
        input: PathBuf,
        /// The band's half width in voxels, 1..=64.
        #[arg(long, default_value_t = voxd::volume::levelset::DEFAULT_BAND)]
        band: u32,
        /// The distance volume (.vxl .vdb .npy .raw).
        #[arg(short, long)]
        output: PathBuf,
    },
    /// Dilate, erode, open or close a bit volume.
    Morph {
        #[arg(value_parser = named::<MorphOp>())]
        op: MorphOp,
        input: PathBuf,
        #[arg(short, long)]
        output: PathBuf,
        #[arg(long, default_value_t = 1)]
        radius: u32,
        #[arg(long, default_value = "cube", value_parser = named::<Kernel>())]
        kernel: Kernel,
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
    Serve(Box<ServeArgs>),
    /// Time the CPU and GPU engines per method and resolution on a mesh (a markdown table).
    Bench(BenchArgs),
    /// Make an API key for NAME: prints the key (first line; give it to the caller, it is not
    /// kept) and the line for --api-keys-file (second line; only the key's SHA-256).
    Keygen {
        /// The key's name, as logs, job records and metrics show it (A-Z a-z 0-9 . _ -).
        name: String,
    },
}

#[derive(Args)]
pub struct MeshArgs {
    /// A volume (.vxl .binvox .npy: its occupied voxels, or its values for surface nets and
    /// marching cubes of distance and density volumes), or a mesh (.obj .gltf .glb .stl .ply,
    /// optionally .gz: its solid on the grid the options below give; dual-contouring needs one).
    pub input: PathBuf,
    /// The mesh (.obj .stl .ply .glb, by extension).
    #[arg(short, long)]
    pub output: PathBuf,
    /// cubes (the exact boundary of the voxels), surface-nets, marching-cubes or
    /// dual-contouring (from the mesh's Hermite data: sharp edges stay sharp).
    #[arg(long, default_value = "cubes")]
    pub algorithm: String,
    /// A mesh input: voxels along its longest axis (default 256 when no voxel size is given).
    #[arg(long, conflicts_with = "voxel_size")]
    pub resolution: Option<u32>,
    /// A mesh input: the voxel's edge length in mesh units.
    #[arg(long)]
    pub voxel_size: Option<f64>,
    /// A mesh input: how its solid decides inside (as `voxelize --fill`).
    #[arg(long, value_parser = named::<Fill>())]
    pub fill: Option<Fill>,
    /// A mesh input: empty voxels added on every side.
    #[arg(long, default_value_t = 1)]
    pub padding: u32,
    /// A mesh input: refuse grids with more voxels than this.
    #[arg(long, default_value_t = Limits::LOCAL.max_voxels)]
    pub max_voxels: u64,
}

impl MeshArgs {
    /// The solid voxelization of a mesh input.
    pub fn request(&self) -> voxd::app::Result<VoxelizeRequest> {
        let limits = Limits {
            max_voxels: self.max_voxels,
            ..Limits::LOCAL
        };
        let method = MethodSpec::Bits(Method::Solid);
        Ok(VoxelizeRequest {
            source: MeshSource::File {
                path: self.input.clone(),
                format: None,
            },
            grid: GridOptions {
                resolution: self.resolution,
                voxel_size: self.voxel_size,
                origin: None,
                dims: None,
                cubic: false,
            }
            .spec(limits.default_resolution)?,
            padding: self.padding,
            method,
            fill: method.fill(self.fill)?,
            attributes: Default::default(),
            limits,
        })
    }
}

#[derive(Args)]
pub struct VoxelizeArgs {
    /// Mesh file.
    pub mesh: PathBuf,
    /// Output volume; its extension picks the format (.vxl, .binvox, .npy, .raw).
    #[arg(short, long)]
    pub output: PathBuf,
    #[arg(long, default_value_t = MethodName::Bits(Method::Solid), value_parser = named::<MethodName>())]
    pub method: MethodName,
    /// How solid-based methods (solid, conservative, interior, density, sdf) decide inside: parity
    /// (exact for watertight meshes), vote (parity along x, y and z, majority), winding
    /// (generalised winding number ≥ ½), flood (exterior flood fill outside the surface) or auto
    /// (parity when the mesh is watertight, else winding; the default). Not with surface.
    #[arg(long, value_parser = named::<Fill>())]
    pub fill: Option<Fill>,
    /// Sub-voxels per axis for density only: 2 (values 0..8; the default) or 4 (0..64).
    #[arg(long, value_parser = clap::value_parser!(u32).range(2..=4))]
    pub density_factor: Option<u32>,
    /// distance only: voxels whose centre is within this distance (mesh units) of the surface
    /// (default half the voxel diagonal; at most 32 voxels).
    #[arg(long, allow_hyphen_values = true)]
    pub thickness: Option<f64>,
    /// sdf only: the narrow band's half width in voxels, 1..=64 (default 3), or all.
    #[arg(long, value_parser = parse_band)]
    pub band: Option<Band>,
    /// Voxels along the mesh's longest axis (default 256 when no other grid option is given).
    #[arg(long, conflicts_with = "voxel_size")]
    pub resolution: Option<u32>,
    /// Edge length of a voxel in mesh units.
    #[arg(long)]
    pub voxel_size: Option<f64>,
    /// Explicit grid origin X,Y,Z (needs --voxel-size and --dims).
    #[arg(long, value_parser = parse_f64x3, requires_all = ["voxel_size", "dims"], allow_hyphen_values = true)]
    pub origin: Option<[f64; 3]>,
    /// Explicit grid dims X,Y,Z (needs --origin and --voxel-size).
    #[arg(long, value_parser = parse_u32x3, requires = "origin")]
    pub dims: Option<[u32; 3]>,
    /// Make every axis as long as the longest (N×N×N).
    #[arg(long, conflicts_with = "origin")]
    pub cubic: bool,
    /// Empty voxels added on every side.
    #[arg(long, default_value_t = 0)]
    pub padding: u32,
    /// auto (the GPU on a hardware adapter when one exists, else the CPU: a software adapter
    /// such as lavapipe only when named with --adapter), gpu (any adapter, lavapipe included)
    /// or cpu.
    #[arg(long, default_value_t = EngineChoice::DEFAULT, value_parser = named::<EngineChoice>())]
    pub engine: EngineChoice,
    /// Use the GPU adapter whose name contains this (e.g. llvmpipe); also VOXD_ADAPTER.
    #[arg(long, env = "VOXD_ADAPTER")]
    pub adapter: Option<String>,
    /// Refuse grids with more voxels than this.
    #[arg(long, default_value_t = Limits::LOCAL.max_voxels)]
    pub max_voxels: u64,
    /// Mesh format, when the extension does not say (obj, gltf, glb, stl, ply).
    #[arg(long, value_parser = parse_format)]
    pub format: Option<Format>,
    /// Give each set voxel the colour of the surface in it (area-weighted, textures sampled;
    /// inner voxels the nearest surface voxel's): solid, surface, conservative, interior and
    /// distance only. The mesh needs vertex colours or materials.
    #[arg(long)]
    pub color: bool,
    /// Give each set voxel a material id (the material with the most area in it; inner voxels
    /// the nearest surface voxel's). The mesh needs materials.
    #[arg(long)]
    pub material: bool,
}

impl VoxelizeArgs {
    /// The request these arguments ask for.
    pub fn request(&self) -> voxd::app::Result<VoxelizeRequest> {
        let limits = Limits {
            max_voxels: self.max_voxels,
            ..Limits::LOCAL
        };
        let method = MethodSpec::with(
            self.method.name(),
            MethodParams {
                density_factor: self.density_factor,
                thickness: self.thickness,
                band: self.band,
            },
        )?;
        Ok(VoxelizeRequest {
            source: MeshSource::File {
                path: self.mesh.clone(),
                format: self.format,
            },
            grid: GridOptions {
                resolution: self.resolution,
                voxel_size: self.voxel_size,
                origin: self.origin,
                dims: self.dims,
                cubic: self.cubic,
            }
            .spec(limits.default_resolution)?,
            padding: self.padding,
            method,
            fill: method.fill(self.fill)?,
            attributes: method.attributes(voxd::app::request::Want {
                colour: self.color,
                material: self.material,
            })?,
            limits,
        })
    }
}

#[derive(Args)]
pub struct ServeArgs {
    /// Address to listen on (port 0 picks a free port; the bound address is printed).
    #[arg(long, env = "VOXD_ADDR", default_value = serve::ADDR)]
    pub addr: std::net::SocketAddr,
    /// A second address that answers only /healthz, /readyz and /metrics, with connection
    /// places of its own: probes and scrapes are answered while clients hold every place of
    /// --addr (unset: none; the probes are on --addr as well either way).
    #[arg(long, env = "VOXD_ADMIN_ADDR")]
    pub admin_addr: Option<std::net::SocketAddr>,
    /// Where volumes and job records are stored.
    #[arg(long, env = "VOXD_DATA_DIR", default_value = serve::DATA_DIR)]
    pub data_dir: PathBuf,
    /// Where volumes and job records are stored instead: s3://BUCKET/PREFIX (credentials and
    /// endpoint from AWS_* variables), file:///PATH or a directory. Default: --data-dir.
    #[arg(long, env = "VOXD_STORE", value_name = "URL", value_parser = StoreSpec::parse)]
    pub store: Option<StoreSpec>,
    /// auto (the GPU on a hardware adapter when one exists, else the CPU: a software adapter
    /// such as lavapipe only when named with --adapter), gpu (any adapter) or cpu.
    #[arg(long, env = "VOXD_ENGINE", default_value_t = EngineChoice::DEFAULT, value_parser = named::<EngineChoice>())]
    pub engine: EngineChoice,
    #[arg(long, env = "VOXD_ADAPTER")]
    pub adapter: Option<String>,
    /// Jobs that may wait; more are refused with 429.
    #[arg(long, env = "VOXD_QUEUE_CAPACITY", default_value_t = serve::QUEUE_CAPACITY)]
    pub queue_capacity: usize,
    /// Jobs run at once. On a GPU each records its own work and their submissions are batched.
    #[arg(long, env = "VOXD_WORKERS", default_value_t = serve::WORKERS)]
    pub workers: usize,
    /// Largest request body in bytes (gzip'd meshes may expand 16× this).
    #[arg(long, env = "VOXD_MAX_BODY_BYTES", default_value_t = Limits::SERVICE.max_body_bytes)]
    pub max_body_bytes: usize,
    /// Largest JSON request body in bytes (CSG expressions, queries), checked while reading.
    #[arg(long, env = "VOXD_MAX_JSON_BYTES", default_value_t = Limits::SERVICE.max_json_bytes)]
    pub max_json_bytes: usize,
    /// Triangles of an uploaded mesh, and of a mesh extracted from a volume (`…/mesh`, counted
    /// from the boundary before it is built).
    #[arg(long, env = "VOXD_MAX_TRIANGLES", default_value_t = Limits::SERVICE.max_triangles)]
    pub max_triangles: usize,
    /// Voxel budget of one job.
    #[arg(long, env = "VOXD_MAX_VOXELS", default_value_t = Limits::SERVICE.max_voxels)]
    pub max_voxels: u64,
    /// Total bytes of stored volumes.
    #[arg(long, env = "VOXD_MAX_STORE_BYTES", default_value_t = serve::MAX_STORE_BYTES)]
    pub max_store_bytes: u64,
    /// Bytes of memory all requests, volume operations and jobs may use at once, by their
    /// estimates, before they start (0: half the machine's or the cgroup's memory).
    #[arg(
        long,
        env = "VOXD_MAX_MEMORY",
        default_value_t = 0,
        value_name = "BYTES"
    )]
    pub max_memory: u64,
    /// Seconds a connection may take to send a request's head, or sit idle between requests.
    #[arg(long, env = "VOXD_HEADER_TIMEOUT", default_value_t = serve::HEADER_TIMEOUT_S)]
    pub header_timeout: f64,
    /// Seconds a request body may pause between chunks (then 408).
    #[arg(long, env = "VOXD_BODY_TIMEOUT", default_value_t = serve::BODY_TIMEOUT_S)]
    pub body_timeout: f64,
    /// Bytes per second a request body must average after its first 10 s (then 408).
    #[arg(long, env = "VOXD_MIN_BODY_RATE", default_value_t = serve::MIN_BODY_RATE)]
    pub min_body_rate: u64,
    /// Seconds a response may wait for its client to read more of it; past it the connection
    /// is closed and the work behind the response stops.
    #[arg(long, env = "VOXD_SEND_TIMEOUT", default_value_t = serve::SEND_TIMEOUT_S)]
    pub send_timeout: f64,
    /// Open connections at most; 0: the file-descriptor limit less an eighth (at least 256),
    /// within 64..32768. At the cap the connection idle longest is closed for a new one.
    #[arg(long, env = "VOXD_MAX_CONNECTIONS", default_value_t = serve::MAX_CONNECTIONS)]
    pub max_connections: usize,
    /// Connections one client address may hold at once; more are closed at once (0: no limit;
    /// raise it or turn it off behind a balancer, where every client has its address).
    #[arg(
        long,
        env = "VOXD_MAX_CONNECTIONS_PER_CLIENT",
        default_value_t = serve::MAX_CONNECTIONS_PER_CLIENT
    )]
    pub max_connections_per_client: usize,
    /// Seconds shutdown waits for requests and running jobs.
    #[arg(long, env = "VOXD_SHUTDOWN_TIMEOUT", default_value_t = serve::SHUTDOWN_TIMEOUT_S)]
    pub shutdown_timeout: f64,
    /// Seconds one job may run; past it the job is stopped and fails (0: no limit).
    #[arg(
        long,
        env = "VOXD_JOB_TIMEOUT",
        default_value_t = serve::JOB_TIMEOUT_S,
        value_name = "SECONDS"
    )]
    pub job_timeout: f64,
    /// The job queue: unset for the in-process queue, or redis://HOST:PORT[/DB] for one that
    /// replicas share (jobs' uploads then go to the store, so replicas must share it too).
    #[arg(long, env = "VOXD_QUEUE", value_name = "URL")]
    pub queue: Option<String>,
    /// With a shared queue: seconds after which a job whose replica stopped renewing its lease
    /// is taken over by another.
    #[arg(
        long,
        env = "VOXD_LEASE_SECONDS",
        default_value_t = voxd::limits::serve::LEASE_S,
        value_name = "SECONDS"
    )]
    pub lease_seconds: f64,
    /// Starts of one job at most (its process or replica dying each time, on either queue);
    /// then it fails.
    #[arg(long, env = "VOXD_MAX_ATTEMPTS", default_value_t = voxd::limits::serve::MAX_ATTEMPTS)]
    pub max_attempts: u32,
    /// Seconds after which an upload whose job is unknown is deleted (swept at start and
    /// periodically; an ended job's upload goes at the next sweep).
    #[arg(
        long,
        env = "VOXD_UPLOAD_GRACE",
        default_value_t = voxd::app::jobs::sweep::UPLOAD_GRACE_S,
        value_name = "SECONDS"
    )]
    pub upload_grace: u64,
    /// API keys, one `NAME:SHA256-HEX[:rate=R,burst=B,jobs=J]` per line (`voxd keygen NAME`
    /// prints one): every /v1 route then needs `Authorization: Bearer KEY`.
    #[arg(long, env = "VOXD_API_KEYS_FILE", value_name = "FILE")]
    pub api_keys_file: Option<PathBuf>,
    /// With keys: /metrics needs a key too (/healthz and /readyz stay open).
    #[arg(long, env = "VOXD_PROTECT_METRICS")]
    pub protect_metrics: bool,
    /// With keys: requests per second per key on this replica, unless its line says (0: no limit).
    #[arg(long, env = "VOXD_KEY_RATE", default_value_t = KeyLimits::DEFAULT.rate)]
    pub key_rate: u32,
    /// With keys: requests a key may make at once above its rate, unless its line says.
    #[arg(long, env = "VOXD_KEY_BURST", default_value_t = KeyLimits::DEFAULT.burst)]
    pub key_burst: u32,
    /// With keys: jobs a key may have queued or running at once, over all replicas, unless its
    /// line says (0: no limit).
    #[arg(long, env = "VOXD_KEY_MAX_JOBS", default_value_t = KeyLimits::DEFAULT.max_jobs)]
    pub key_max_jobs: usize,
}

impl ServeArgs {
    pub fn config(&self) -> voxd::service::Config {
        voxd::service::Config {
            addr: self.addr,
            admin_addr: self.admin_addr,
            data_dir: self.data_dir.clone(),
            store: self.store.clone(),
            engine: self.engine,
            adapter: self.adapter.clone(),
            queue_capacity: self.queue_capacity.max(1),
            workers: self.workers.max(1),
            limits: Limits {
                max_triangles: self.max_triangles,
                max_voxels: self.max_voxels,
                max_json_bytes: self.max_json_bytes,
                ..Limits::SERVICE
            }
            .with_body_bytes(self.max_body_bytes),
            max_store_bytes: self.max_store_bytes,
            max_memory: match self.max_memory {
                0 => voxd::app::memory::MemoryBudget::default_total(),
                n => n,
            },
            connections: voxd::service::server::ConnectionLimits {
                header_read_timeout: secs(self.header_timeout),
                max_connections: self.max_connections,
                max_connections_per_client: self.max_connections_per_client,
                send_timeout: secs(self.send_timeout.max(1.0)),
                body_idle_timeout: secs(self.body_timeout.max(0.1)),
                min_body_rate: self.min_body_rate,
                ..Default::default()
            },
            shutdown_timeout: secs(self.shutdown_timeout),
            // 0 (or anything not a positive duration, such as inf) is no limit.
            job_timeout: std::time::Duration::try_from_secs_f64(self.job_timeout)
                .ok()
                .filter(|d| !d.is_zero()),
            queue: self.queue.clone().filter(|q| !q.is_empty()),
            // At least a tenth of a second: renewals come every third of it.
            lease: secs(self.lease_seconds.max(0.1)),
            max_attempts: self.max_attempts.max(1),
            upload_grace: std::time::Duration::from_secs(self.upload_grace),
            api_keys_file: self.api_keys_file.clone(),
            key_limits: KeyLimits {
                rate: self.key_rate,
                burst: self.key_burst,
                max_jobs: self.key_max_jobs,
            },
            protect_metrics: self.protect_metrics,
        }
    }
}

#[derive(Args)]
pub struct BenchArgs {
    pub mesh: PathBuf,
    /// Cubic resolutions, comma-separated.
    #[arg(long, default_value = "256,512,1024", value_delimiter = ',')]
    pub resolutions: Vec<u32>,
    /// Methods, comma-separated.
    #[arg(
        long,
        default_value = "solid,surface,conservative",
        value_delimiter = ',',
        value_parser = named::<Method>()
    )]
    pub methods: Vec<Method>,
    /// Timed runs per cell (after one warm-up).
    #[arg(long, default_value_t = 3)]
    pub runs: usize,
    #[arg(long, env = "VOXD_ADAPTER")]
    pub adapter: Option<String>,
    /// Only the CPU engine.
    #[arg(long)]
    pub cpu_only: bool,
    /// GPU solid strategy: scan (toggle bits + prefix XOR) or masks (XOR every word above).
    #[arg(long, default_value = "scan", value_parser = named::<SolidStrategy>())]
    pub gpu_solid: SolidStrategy,
}
