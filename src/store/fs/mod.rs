//! The directory store: `volumes/{id}.vxl` (the native format) and `volumes/{id}.json`
//! (metadata), small volumes in packs (`packs.rs`), `jobs/records.log` (job records, an
//! append-only log: `joblog.rs`). Every volume file is written atomically ([`crate::atomic`]);
//! the metadata is written last and is the commit point, so a process killed mid-write leaves
//! either a whole volume or nothing that is listed (leftovers are removed at open).
//!
//! Every read checks the bytes against the metadata's length and sha256 (a mismatch, a torn or a
//! missing file is [`StoreError::Corrupt`], never silently served), and a put refuses metadata
//! that does not describe its bytes. The quota counts both files of a volume, data and metadata.
//!
//! Volumes are written by a group commit: puts that arrive while a group is being written wait
//! for the next one, which syncs all their files side by side and the directory once, instead of
//! four sequential syncs per volume (`commit.rs`). A put returns once its volume is durable.
//!
//! The catalogue is held in memory (read once at open; a volume asked for by id that another
//! process sharing the directory stored since is read from disk and catalogued then); every
//! file operation runs on tokio's blocking pool or the store's committer thread, never on a
//! runtime worker, and never under the catalogue's lock.
//!
//! With the `fault-injection` feature (tests only), `VOXD_FAULT` makes the process abort at a
//! chosen point inside a write (see [`super::fault`]), so crash tests can stop it there.
//!
//! Here: opening the directory and the catalogue; the trait's methods are in `volumes.rs`, the
//! writer in `commit.rs`, the tests in `tests.rs`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use bytes::Bytes;

mod commit;
mod joblog;
mod packs;
mod sources;
#[cfg(test)]
pub(crate) mod tests;
mod volumes;

use commit::{commit_volumes, compact};
use joblog::JobLog;
use packs::{Loc, Packs};

use super::{StoreError, VolumeMeta, safe_id};

/// Bytes per chunk of a streamed read.
const CHUNK: usize = 256 << 10;

/// How long a successful write probe vouches for the store's health.
const HEALTH_TTL: Duration = Duration::from_secs(30);

pub struct FsStore {
    volumes: PathBuf,
    /// The job records: `jobs/records.log`.
    records: Arc<Mutex<JobLog>>,
    uploads: PathBuf,
    /// The meshes volumes were made from (`sources/{sha256}`: `sources.rs`).
    sources: PathBuf,
    limit: u64,
    inner: Arc<Mutex<Inner>>,
    /// The packs small volumes are kept in ([`super::packs`]). Lock order: the packs, then
    /// `inner`.
    packs: Arc<Mutex<Packs>>,
    /// Does this process write the packs (hold their lock)?
    pack_writer: bool,
    /// Puts go to the committer thread ([`commit_volumes`]), which writes them in groups.
    commits: std::sync::mpsc::Sender<Pending>,
    /// The committer, joined on drop: once a store is dropped its writes are done and the packs'
    /// lock is free for the next store opened on the directory.
    committer: Option<std::thread::JoinHandle<()>>,
}

impl Drop for FsStore {
    fn drop(&mut self) {
        // Closing the channel ends the committer after the group it is writing.
        drop(std::mem::replace(
            &mut self.commits,
            std::sync::mpsc::channel().0,
        ));
        if let Some(t) = self.committer.take() {
            let _ = t.join();
        }
    }
}

/// The most volumes one group commit writes.
const GROUP_MAX: usize = 64;
/// The most threads a group commit writes and syncs its files on.
const GROUP_THREADS: usize = 8;

/// A volume waiting for the committer: its files' bytes, the quota it reserved, and who hears
/// the outcome.
struct Pending {
    meta: VolumeMeta,
    vxl: Bytes,
    /// The metadata: compact JSON for a pack's record, else the `{id}.json` file's bytes.
    json: Vec<u8>,
    /// Goes to a pack (else to its own two files).
    packed: bool,
    need: u64,
    done: tokio::sync::oneshot::Sender<Result<(), StoreError>>,
}

struct Inner {
    index: BTreeMap<String, Entry>,
    /// Bytes of the volumes in `index` (data and metadata files) and of the source objects.
    used: u64,
    /// The source objects' sizes by key (`sources.rs`).
    sources: BTreeMap<String, u64>,
    /// Bytes of puts in progress: counted against the quota from the check to the commit.
    reserved: u64,
    /// When a write last succeeded (a put or a probe) and whether the last write failed.
    last_ok_write: Option<Instant>,
    last_write_failed: bool,
}

/// A catalogue entry: the metadata, what the volume takes on disk, and where.
struct Entry {
    meta: VolumeMeta,
    /// Bytes of `{id}.vxl` + `{id}.json`, or of its pack record, as counted against the quota.
    stored: u64,
    /// Its record in a pack (`None`: its own files).
    at: Option<Loc>,
}

/// Where a volume's bytes are: its own file, or a record in a pack.
enum Place {
    File(PathBuf),
    Pack(PathBuf, Loc),
}

/// A volume's bytes, open: `len` bytes of `file` from `at`.
struct Data {
    file: std::fs::File,
    at: u64,
    len: u64,
}

/// The files of `dir` whose names `keep` takes, each with when it was written (on the
/// blocking pool; a file removed meanwhile is left out).
async fn files_with_times(
    dir: PathBuf,
    keep: fn(&str) -> bool,
) -> Result<Vec<(String, std::time::SystemTime)>, StoreError> {
    blocking(move || {
        let mut out = vec![];
        for e in std::fs::read_dir(&dir)? {
            let e = e?;
            let Some(name) = e.file_name().to_str().map(str::to_string) else {
                continue;
            };
            if !keep(&name) {
                continue;
            }
            match e.metadata().and_then(|m| m.modified()) {
                Ok(t) => out.push((name, t)),
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
                Err(e) => return Err(e.into()),
            }
        }
        Ok(out)
    })
    .await
}

/// The bytes of file `p`, `None` when there is none (on the blocking pool).
async fn read_if_there(p: PathBuf) -> Result<Option<Bytes>, StoreError> {
    blocking(move || match std::fs::read(&p) {
        Ok(b) => Ok(Some(Bytes::from(b))),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(e.into()),
    })
    .await
}

/// Runs blocking file work off the async runtime.
async fn blocking<T: Send + 'static>(
    f: impl FnOnce() -> Result<T, StoreError> + Send + 'static,
) -> Result<T, StoreError> {
    tokio::task::spawn_blocking(f)
        .await
        .map_err(|e| StoreError::Io(std::io::Error::other(e)))?
}

impl FsStore {
    /// Opens (creating) `data_dir/volumes` and `data_dir/jobs`, removes leftovers of interrupted
    /// writes and indexes what is there. Blocking: call it before serving, or off the runtime.
    pub fn open(data_dir: &Path, limit: u64) -> Result<FsStore, StoreError> {
        FsStore::open_as(data_dir, limit, true)
    }

    /// Opens as a process that does not write the packs (as when another holds their lock):
    /// every volume it stores gets its own files. For tests of that layout.
    #[cfg(test)]
    pub(crate) fn open_files(data_dir: &Path, limit: u64) -> Result<FsStore, StoreError> {
        FsStore::open_as(data_dir, limit, false)
    }

    fn open_as(data_dir: &Path, limit: u64, packs: bool) -> Result<FsStore, StoreError> {
        let volumes = data_dir.join("volumes");
        let jobs = data_dir.join("jobs");
        let uploads = data_dir.join("uploads");
        let sources_dir = data_dir.join("sources");
        std::fs::create_dir_all(&volumes)?;
        std::fs::create_dir_all(&sources_dir)?;
        std::fs::create_dir_all(&jobs)?;
        std::fs::create_dir_all(&uploads)?;
        let mut index = BTreeMap::new();
        let mut files: Vec<PathBuf> = std::fs::read_dir(&volumes)?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .collect();
        files.sort();
        for p in &files {
            let name = p.file_name().and_then(|n| n.to_str()).unwrap_or("");
            if name.starts_with('.') {
                let _ = std::fs::remove_file(p); // an interrupted temporary file
                continue;
            }
            if p.extension().is_some_and(|e| e == "json") {
                let parsed = std::fs::read(p).ok().and_then(|b| {
                    let m = serde_json::from_slice::<VolumeMeta>(&b).ok()?;
                    Some((m, b.len() as u64))
                });
                let data = parsed
                    .as_ref()
                    .map(|(m, _)| std::fs::metadata(volumes.join(format!("{}.vxl", m.id))));
                match (parsed, data) {
                    (Some((m, json_len)), Some(Ok(data))) => {
                        if data.len() != m.bytes {
                            // Kept listed, so that reading it says what is wrong (Corrupt).
                            tracing::error!(
                                id = %m.id,
                                "stored volume data is {} bytes, its metadata says {}",
                                data.len(),
                                m.bytes
                            );
                        }
                        let stored = data.len() + json_len;
                        let at = None;
                        index.insert(
                            m.id.clone(),
                            Entry {
                                meta: m,
                                stored,
                                at,
                            },
                        );
                    }
                    (Some((m, _)), Some(Err(e))) if e.kind() == std::io::ErrorKind::NotFound => {
                        // Metadata whose data file is missing: a group commit interrupted before
                        // its directory sync kept this rename and not the data's. Never
                        // acknowledged, so nothing is lost by removing it.
                        tracing::warn!(id = %m.id, "removing the metadata of a volume whose data was never stored (an interrupted write)");
                        let _ = std::fs::remove_file(p);
                    }
                    _ => tracing::warn!(path = %p.display(), "ignoring unreadable volume metadata"),
                }
            }
        }
        for p in &files {
            if p.extension().is_some_and(|e| e == "vxl") {
                let id = p.file_stem().and_then(|s| s.to_str()).unwrap_or("");
                if !index.contains_key(id) {
                    let _ = std::fs::remove_file(p); // data without its commit record
                }
            }
        }
        for e in std::fs::read_dir(&jobs)?.chain(std::fs::read_dir(&uploads)?) {
            let p = e?.path();
            if p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with('.'))
            {
                let _ = std::fs::remove_file(&p);
            }
        }
        let (packs, found) = Packs::open(&volumes, packs)?;
        let pack_writer = packs.writer();
        for (meta, loc) in found {
            let (stored, at) = (loc.len, Some(loc));
            index.insert(meta.id.clone(), Entry { meta, stored, at });
        }
        let packs = Arc::new(Mutex::new(packs));
        let records = Arc::new(Mutex::new(JobLog::open(&jobs)?));
        tracing::info!(volumes = index.len(), dir = %volumes.display(), "store opened");
        let sources = sources::open(&sources_dir)?;
        let used = index.values().map(|e| e.stored).sum::<u64>() + sources.values().sum::<u64>();
        let inner = Arc::new(Mutex::new(Inner {
            index,
            used,
            sources,
            reserved: 0,
            last_ok_write: None,
            last_write_failed: false,
        }));
        let (commits, queued) = std::sync::mpsc::channel();
        let (dir, shared, packs_) = (volumes.clone(), inner.clone(), packs.clone());
        // Ends when the store (the channel's only sender) is dropped.
        let committer = std::thread::Builder::new()
            .name("voxd-commit".into())
            .spawn(move || commit_volumes(&dir, &packs_, &shared, &queued))?;
        Ok(FsStore {
            volumes,
            records,
            uploads,
            sources: sources_dir,
            limit,
            inner,
            packs,
            pack_writer,
            commits,
            committer: Some(committer),
        })
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Inner> {
        lock(&self.inner)
    }

    /// The metadata of volume `id`: from the catalogue, or else from its committed files or
    /// the packs (a volume another process sharing this directory stored, as replicas do in
    /// tests), which then join the catalogue. Listing shows only the catalogue: a directory is
    /// not a store for replicas (an object store is).
    async fn lookup(&self, id: &str) -> Result<Option<VolumeMeta>, StoreError> {
        if let Some(e) = self.lock().index.get(id) {
            return Ok(Some(e.meta.clone()));
        }
        if !safe_id(id) {
            return Ok(None);
        }
        let dir = self.volumes.clone();
        let id_ = id.to_string();
        let found = blocking(move || {
            let json = match std::fs::read(dir.join(format!("{id_}.json"))) {
                Ok(b) => b,
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
                Err(e) => return Err(e.into()),
            };
            let meta: VolumeMeta = serde_json::from_slice(&json).map_err(|e| {
                StoreError::Corrupt(format!("volume {id_}: unreadable metadata: {e}"))
            })?;
            let data = std::fs::metadata(dir.join(format!("{id_}.vxl")))?.len();
            Ok(Some((meta, data + json.len() as u64)))
        })
        .await?;
        let Some((meta, stored)) = found.filter(|(m, _)| m.id == id) else {
            if self.pack_writer {
                return Ok(None);
            }
            self.refresh_packs().await?;
            return Ok(self.lock().index.get(id).map(|e| e.meta.clone()));
        };
        let mut i = self.lock();
        if !i.index.contains_key(id) {
            i.used += stored;
            let at = None;
            let meta = meta.clone();
            i.index.insert(id.to_string(), Entry { meta, stored, at });
        }
        Ok(Some(meta))
    }

    /// A process that does not write the packs reads what the writer appended since it last
    /// looked: new volumes join the catalogue (a moved one at its new place), removed ones
    /// leave it.
    async fn refresh_packs(&self) -> Result<(), StoreError> {
        let (packs, inner) = (self.packs.clone(), self.inner.clone());
        blocking(move || {
            let mut p = lock(&packs);
            let (found, removed) = p.refresh()?;
            let mut i = lock(&inner);
            for id in removed {
                if let Some(e) = i.index.get(&id)
                    && e.at.is_some()
                {
                    let old = i.index.remove(&id).expect("listed");
                    i.used -= old.stored;
                }
            }
            for (meta, loc) in found {
                let (stored, at) = (loc.len, Some(loc));
                i.used += stored;
                if let Some(old) = i.index.insert(meta.id.clone(), Entry { meta, stored, at }) {
                    i.used -= old.stored;
                }
            }
            Ok(())
        })
        .await
    }

    /// Where volume `id`'s bytes are: its file, or its pack record. `None`: not stored.
    async fn place(&self, id: &str) -> Result<Option<(VolumeMeta, Place)>, StoreError> {
        let Some(meta) = self.lookup(id).await? else {
            return Ok(None);
        };
        let place = match self.lock().index.get(id).and_then(|e| e.at) {
            Some(loc) => Place::Pack(self.volumes.join(packs::name(loc.pack)), loc),
            None => Place::File(self.volumes.join(format!("{id}.vxl"))),
        };
        Ok(Some((meta, place)))
    }

    /// Opens volume `id`'s bytes (its file, or its pack at its record's data), checking their
    /// length against the metadata: `Corrupt` when they are missing or of another length. A
    /// pack a compaction removed in between is looked up again.
    async fn open_data(&self, id: &str) -> Result<Option<(VolumeMeta, Data)>, StoreError> {
        for _ in 0..3 {
            let Some((meta, place)) = self.place(id).await? else {
                return Ok(None);
            };
            let (want, id_) = (meta.bytes, id.to_string());
            let moved = matches!(place, Place::Pack(..));
            let opened = blocking(move || {
                let (path, at, len) = match &place {
                    Place::File(p) => (p, 0, None),
                    Place::Pack(p, loc) => (p, loc.data, Some(loc.data_len())),
                };
                let file = match std::fs::File::open(path) {
                    Ok(f) => f,
                    Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
                    Err(e) => return Err(e.into()),
                };
                let len = match len {
                    Some(len) => len,
                    None => file.metadata()?.len(),
                };
                if len != want {
                    return Err(StoreError::Corrupt(format!(
                        "volume {id_}: the data is {len} bytes but its metadata says {want} (a torn or damaged file)"
                    )));
                }
                Ok(Some(Data {
                    file,
                    at,
                    len,
                }))
            })
            .await
            .inspect_err(|e| {
                if matches!(e, StoreError::Corrupt(_)) {
                    tracing::error!("{e}")
                }
            })?;
            match opened {
                Some(data) => return Ok(Some((meta, data))),
                // Moved by a compaction: look again (a process that does not write the packs
                // reads where the writer put it).
                None if moved && self.lock().index.contains_key(id) => {
                    if !self.pack_writer {
                        self.refresh_packs().await?;
                    }
                }
                // Gone although still listed: lost, not deleted (a delete unlists first).
                None if self.lock().index.contains_key(id) => break,
                None => return Ok(None),
            }
        }
        let e = StoreError::Corrupt(format!("volume {id}: its data is missing"));
        tracing::error!("{e}");
        Err(e)
    }

    /// Removes a volume kept in a pack: unlisted and a removal record appended (both under the
    /// packs' lock, so no compaction moves it in between; listed again if the append fails),
    /// then the packs are compacted if they are due.
    async fn delete_packed(&self, id: &str) -> Result<bool, StoreError> {
        if !self.pack_writer {
            return Err(StoreError::Io(std::io::Error::other(format!(
                "volume {id} is kept in a pack, which only the process holding {} removes from",
                self.volumes.join(packs::LOCK).display()
            ))));
        }
        let (packs, inner, id) = (self.packs.clone(), self.inner.clone(), id.to_string());
        let removed = blocking(move || {
            let mut p = lock(&packs);
            let old = {
                let mut i = lock(&inner);
                match i.index.remove(&id) {
                    Some(old) => {
                        i.used -= old.stored;
                        old
                    }
                    None => return Ok(false),
                }
            };
            let loc = old.at.expect("a packed volume");
            if let Err(e) = p.remove(&id, loc) {
                let mut i = lock(&inner);
                i.used += old.stored;
                i.index.insert(id, old);
                return Err(e.into());
            }
            if let Err(e) = compact(&mut p, &inner) {
                // The removal stands; the garbage waits for the next one.
                tracing::error!("compacting the volume packs: {e}");
            }
            Ok(true)
        })
        .await;
        self.note_write(removed.is_ok());
        removed
    }

    /// One job record written (`Some`) or removed, as a batch of one.
    async fn one_job_record(&self, id: &str, bytes: Option<Bytes>) -> Result<(), StoreError> {
        let batch = vec![(id.to_string(), bytes)];
        super::VolumeStore::put_job_records(self, batch, true)
            .await
            .pop()
            .expect("one result per record")
    }

    fn note_write(&self, ok: bool) {
        self.lock().note_write(ok);
    }
}

impl Inner {
    /// Reserves `need` bytes against the quota `limit` until the write that needs them ends
    /// (the caller gives them back from `reserved`); `Full` with the numbers when what is
    /// stored, what other writes reserved and `need` do not fit.
    fn reserve(&mut self, need: u64, limit: u64) -> Result<(), StoreError> {
        let used = self.used + self.reserved;
        if used + need > limit {
            return Err(StoreError::Full { need, used, limit });
        }
        self.reserved += need;
        Ok(())
    }

    /// What the health check reads: whether the last write failed, and when one last succeeded.
    fn note_write(&mut self, ok: bool) {
        self.last_write_failed = !ok;
        if ok {
            self.last_ok_write = Some(Instant::now());
        }
    }
}

pub(super) fn lock<T>(inner: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    // A panic while holding the lock cannot leave the maps half-updated (each update is one
    // statement; the job log changes its map only after a write is durable), so a poisoned
    // lock is still usable.
    inner.lock().unwrap_or_else(|p| p.into_inner())
}
