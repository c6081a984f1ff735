//! Where the tests find and put files: the committed fixtures (`tests/data`), the shared real
//! meshes (`../shared/meshes`), and scratch directories. Every scratch directory of the
//! integration tests lies under one root per test process, `$TMPDIR/voxd-tests-<pid>`, so the
//! tests' directories never meet another run's, and the roots that dead runs left behind are
//! removed the first time a scratch directory is asked for. Not meshes made in code (`meshes`).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// A committed fixture: `tests/data/<name>`.
pub fn data(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name)
}

/// A file of the repository by its path from the root (`openapi.yaml`, `docs/format.md`): what
/// the tests hold the code to.
pub fn repo_file(path: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(path)
}

/// The `voxd` command line with `args` (its log quiet but for errors): its output.
pub fn run_voxd(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_voxd"))
        .args(args)
        .env("VOXD_LOG", "error")
        .output()
        .unwrap()
}

/// `../shared/meshes`, or `None` with a printed notice.
pub fn shared_meshes() -> Option<PathBuf> {
    // VOXD_SHARED_MESHES: the folder elsewhere (a test binary run on another machine).
    let p = std::env::var_os("VOXD_SHARED_MESHES").map_or_else(
        || PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/meshes"),
        PathBuf::from,
    );
    if p.join("README.md").exists() {
        Some(p)
    } else {
        eprintln!(
            "NOTICE: {} is absent; skipping tests on the shared real meshes",
            p.display()
        );
        None
    }
}

/// `b` gzipped.
pub fn gz(b: &[u8]) -> Vec<u8> {
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    e.write_all(b).unwrap();
    e.finish().unwrap()
}

/// This process's scratch root, `$TMPDIR/voxd-tests-<pid>` (created on first use). On first use
/// it also removes the roots of test processes that are gone (no `/proc/<pid>`): a run that
/// panicked or was killed leaves its directories, the next run takes them away.
pub fn scratch_root() -> &'static Path {
    static ROOT: OnceLock<PathBuf> = OnceLock::new();
    ROOT.get_or_init(|| {
        let tmp = std::env::temp_dir();
        for entry in std::fs::read_dir(&tmp).into_iter().flatten().flatten() {
            let name = entry.file_name();
            let pid = name.to_str().and_then(|n| n.strip_prefix("voxd-tests-"));
            if let Some(pid) = pid.filter(|p| p.parse::<u32>().is_ok())
                && !Path::new("/proc").join(pid).exists()
            {
                let _ = std::fs::remove_dir_all(entry.path());
            }
        }
        let root = tmp.join(format!("voxd-tests-{}", std::process::id()));
        std::fs::create_dir_all(&root).unwrap();
        root
    })
}

/// A fresh, empty scratch directory `<scratch_root>/<name>`; `name` keeps the tests' directories
/// apart (they all run in one process). It stays until the run is over (a server started on it
/// may outlive the test's locals); [`Scratch`] is the one removed when dropped.
pub fn tmpdir(name: &str) -> PathBuf {
    let d = scratch_root().join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A scratch directory (as [`tmpdir`] makes it) removed when dropped, also when the test
/// panics: for a test whose directory holds nothing worth keeping once it ends.
pub struct Scratch(PathBuf);

impl Scratch {
    pub fn new(name: &str) -> Scratch {
        Scratch(tmpdir(name))
    }
}

impl std::ops::Deref for Scratch {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}
