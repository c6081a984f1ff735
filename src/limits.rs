//! Every default and cap of voxd, in one place. A limit is checked before the work it bounds
//! starts; the fronts only override the fields their flags name (`voxd serve --max-voxels`, a
//! request's `max_voxels`, which can only lower the server's).
//!
//! The [`serve`] module holds `voxd serve`'s other defaults (addresses, workers, connection
//! timeouts and caps): its flags' `default_value_t`s and the server's own `Default`s both read
//! them, so a default is written once. Not here: the shared queue's (Redis) options, which the
//! queue declares.
//!
//! Two profiles: [`Limits::SERVICE`] protects a shared server from its clients; [`Limits::LOCAL`]
//! is the command line and the library's defaults, where the only machine at risk is the
//! caller's own, so grids and meshes may be larger.

/// Caps on one request or job.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits {
    /// Voxels of one grid (a density grid counts its finer grid).
    pub max_voxels: u64,
    /// Triangles of one mesh.
    pub max_triangles: usize,
    /// Bytes of one request body (an uploaded mesh, a JSON document).
    pub max_body_bytes: usize,
    /// Bytes of one JSON request body (a CSG expression, a query), checked while reading,
    /// before it is parsed.
    pub max_json_bytes: usize,
    /// Bytes a gzip'd mesh may expand to.
    pub max_decompressed_bytes: u64,
    /// Bytes the decoded textures of one mesh may take (4 a texel: 256 MiB is one 8192²).
    pub max_texture_bytes: u64,
    /// Points plus rays of one query, points of one normals request.
    pub max_queries: usize,
    /// Pixels of one preview picture.
    pub max_preview_pixels: u64,
    /// Nesting depth of a CSG expression.
    pub max_csg_depth: usize,
    /// Operands of one CSG operation.
    pub max_csg_operands: usize,
    /// Voxels all nodes of one CSG expression may combine, in grids of `max_voxels`.
    pub max_csg_work: u64,
    /// Radius of a morphology kernel.
    pub max_morph_radius: u32,
    /// Seconds a request may wait for its job (`wait=`).
    pub max_wait_s: f64,
    /// Volumes listed per page at most; and when the caller does not say.
    pub max_list_page: usize,
    pub default_list_page: usize,
    /// Resolution used when no grid option is given.
    pub default_resolution: u32,
    /// Characters (Unicode scalar values) of a volume's name: what `maxLength` counts in
    /// openapi.yaml.
    pub max_name_chars: usize,
    /// Bytes of a derived volume's provenance (a CSG expression as JSON).
    pub max_provenance_bytes: usize,
    /// Bytes of one page of the volume list (fewer volumes are listed, with a `next` link).
    pub max_list_page_bytes: usize,
}

/// How many times its body a gzip'd upload may expand to (service).
pub const GZIP_EXPANSION: u64 = 16;

impl Limits {
    /// `voxd serve`'s defaults.
    pub const SERVICE: Limits = Limits {
        max_voxels: 1024 * 1024 * 1024,
        max_triangles: 20_000_000,
        max_body_bytes: 256 << 20,
        max_decompressed_bytes: GZIP_EXPANSION * (256 << 20),
        ..Limits::LOCAL
    };

    /// The command line's and the library's defaults.
    pub const LOCAL: Limits = Limits {
        max_voxels: 2048 * 2048 * 2048,
        max_triangles: 200_000_000,
        max_body_bytes: usize::MAX,
        max_json_bytes: 1 << 20,
        max_decompressed_bytes: 8 << 30,
        max_texture_bytes: 256 << 20,
        max_queries: 100_000,
        max_preview_pixels: 1 << 24,
        max_csg_depth: 32,
        max_csg_operands: 256,
        max_csg_work: 64,
        max_morph_radius: 64,
        max_wait_s: 300.0,
        max_list_page: 1000,
        default_list_page: 100,
        default_resolution: 256,
        max_name_chars: 256,
        max_provenance_bytes: 64 << 10,
        max_list_page_bytes: 4 << 20,
    };

    /// The service's limits with a different body cap (gzip expansion follows it).
    pub fn with_body_bytes(mut self, bytes: usize) -> Limits {
        self.max_body_bytes = bytes;
        self.max_decompressed_bytes = GZIP_EXPANSION.saturating_mul(bytes as u64);
        self
    }
}

impl Default for Limits {
    fn default() -> Limits {
        Limits::LOCAL
    }
}

/// `voxd serve`'s defaults that are not [`Limits`]: each flag's `default_value_t` and the
/// server's own defaults (`ConnectionLimits::default`) read these constants.
pub mod serve {
    /// `--lease-seconds`: the lease of a running job on the shared (Redis) queue.
    pub const LEASE_S: f64 = 30.0;
    /// `--max-attempts`: starts of one job at most (either queue).
    pub const MAX_ATTEMPTS: u32 = 3;
    /// `--addr`.
    pub const ADDR: &str = "127.0.0.1:8080";
    /// `--data-dir`.
    pub const DATA_DIR: &str = "./voxd-data";
    /// `--queue-capacity`: jobs that may wait.
    pub const QUEUE_CAPACITY: usize = 64;
    /// `--workers`: jobs run at once.
    pub const WORKERS: usize = 1;
    /// `--max-store-bytes`: total bytes of stored volumes.
    pub const MAX_STORE_BYTES: u64 = 10 << 30;
    /// `--header-timeout`, seconds: to send a request's head, or to sit idle between requests.
    pub const HEADER_TIMEOUT_S: f64 = 20.0;
    /// `--body-timeout`, seconds a request body may pause between chunks.
    pub const BODY_TIMEOUT_S: f64 = 20.0;
    /// `--min-body-rate`, bytes per second a body must average after its grace period.
    pub const MIN_BODY_RATE: u64 = 16 << 10;
    /// `--send-timeout`, seconds a response may wait for its client to read more.
    pub const SEND_TIMEOUT_S: f64 = 20.0;
    /// `--max-connections`: open connections at most; 0: derived from the file-descriptor
    /// limit (`service::server::connection_cap`).
    pub const MAX_CONNECTIONS: usize = 0;
    /// `--max-connections-per-client`: connections one client address may hold (0: no limit).
    pub const MAX_CONNECTIONS_PER_CLIENT: usize = 256;
    /// `--shutdown-timeout`, seconds shutdown waits for requests and running jobs.
    pub const SHUTDOWN_TIMEOUT_S: f64 = 30.0;
    /// `--job-timeout`, seconds one job may run (0: no limit).
    pub const JOB_TIMEOUT_S: f64 = 600.0;
}

/// Voxels of a narrow-band `sdf` grid at most, for a voxel limit of `max_voxels`: 64 times
/// it, and at most 4096³. The voxel limit itself counts the band's candidate voxels (8³ per
/// brick some triangle may reach); the grid's own cost is the solid's bits (one per voxel:
/// 8 GiB at 4096³), which the memory budget admits.
pub fn sdf_grid_voxels(max_voxels: u64) -> u64 {
    max_voxels.saturating_mul(64).min(4096 * 4096 * 4096)
}

/// Human form of a voxel budget: `1024³` when it is a cube, else the count.
pub fn describe_voxels(v: u64) -> String {
    let c = (v as f64).cbrt().round() as u64;
    if c * c * c == v {
        format!("{c}³")
    } else {
        format!("{v} voxels")
    }
}
