//! Durable, atomic file writes: the one implementation behind the store and every file the
//! command line writes. A reader sees either the old file or the whole new one, never a part.
//! Below every other module (it knows files only), so that the application and the store
//! adapters can both use it. Not here: what the files hold.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Writes `path` through `write`: to a temporary file beside it (`.NAME.PID.N.tmp`, which a
/// store removes at start as a leftover), flushed and fsynced, renamed over `path`, and the
/// directory fsynced. On failure the temporary file is removed and `path` is untouched.
pub fn write_with(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> std::io::Result<()>,
) -> std::io::Result<()> {
    stage_with(path, write)?.commit()?;
    sync_dir(parent(path))
}

fn parent(path: &Path) -> &Path {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

/// A complete, synced temporary file beside `path` (`.NAME.PID.N.tmp`) that is not yet in
/// place: [`Staged::commit`] renames it over `path`; dropped uncommitted, it is removed. Lets a
/// group commit sync many files before it renames any.
#[must_use = "a staged file is removed unless committed"]
pub struct Staged {
    tmp: PathBuf,
    path: PathBuf,
    committed: bool,
}

impl Staged {
    /// Renames the file into place (durable once the directory is synced).
    pub fn commit(mut self) -> std::io::Result<()> {
        std::fs::rename(&self.tmp, &self.path)?;
        self.committed = true;
        Ok(())
    }
}

impl Drop for Staged {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}

/// Writes `path`'s future contents through `write` to a temporary file beside it, flushed and
/// fsynced, and leaves it there ([`Staged`]). On failure the temporary file is removed.
pub fn stage_with(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> std::io::Result<()>,
) -> std::io::Result<Staged> {
    static SEQ: AtomicU64 = AtomicU64::new(0);
    let dir = parent(path);
    let name = path
        .file_name()
        .map(|f| f.to_string_lossy().into_owned())
        .unwrap_or_default();
    let staged = Staged {
        tmp: dir.join(format!(
            ".{name}.{}.{}.tmp",
            std::process::id(),
            SEQ.fetch_add(1, Ordering::Relaxed)
        )),
        path: path.to_path_buf(),
        committed: false,
    };
    let mut w = BufWriter::new(File::create(&staged.tmp)?);
    write(&mut w)?;
    let f = w.into_inner().map_err(|e| e.into_error())?;
    f.sync_all()?;
    Ok(staged)
}

/// [`write_with`] for bytes in memory.
pub fn write(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    write_with(path, |w| w.write_all(bytes))
}

/// Makes renames and removals in `dir` durable.
pub fn sync_dir(dir: &Path) -> std::io::Result<()> {
    File::open(dir)?.sync_all()
}

#[cfg(test)]
mod tests {
    #[test]
    fn replaces_whole_files_and_leaves_no_temporaries() {
        let dir = crate::testkit::Scratch::new("atomic");
        let p = dir.join("a.bin");
        super::write(&p, b"one").unwrap();
        super::write(&p, b"two!").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"two!");
        let failed = super::write_with(&p, |w| {
            std::io::Write::write_all(w, b"partial")?;
            Err(std::io::Error::other("interrupted"))
        });
        assert!(failed.is_err());
        assert_eq!(std::fs::read(&p).unwrap(), b"two!");
        let names: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, vec![std::ffi::OsString::from("a.bin")]);
    }
}
