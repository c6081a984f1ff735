//! The directory store: `volumes/{id}.vxl` (the native format) and `volumes/{id}.json`
//! (metadata), `jobs/records.log` (job records, an append-only log: [`super::joblog`]). Every
//! volume file is written atomically ([`super::atomic`]); the metadata is written last and is the commit point, so a process
//! killed mid-write leaves either a whole volume or nothing that is listed (leftovers are removed
//! at open).
//!
//! Every read checks the bytes against the metadata's length and sha256 (a mismatch, a torn or a
//! missing file is [`StoreError::Corrupt`], never silently served), and a put refuses metadata
//! that does not describe its bytes. The quota counts both files of a volume, data and metadata.
//!
//! Volumes are written by a group commit: puts that arrive while a group is being written wait
//! for the next one, which syncs all their files side by side and the directory once, instead of
//! four sequential syncs per volume ([`commit_group`]). A put returns once its volume is
//! durable, as before.
//!
//! The catalogue is held in memory (read once at open; a volume asked for by id that another
//! process sharing the directory stored since is read from disk and catalogued then); every
//! file operation runs on tokio's blocking pool or the store's committer thread, never on a
//! runtime worker, and never under the catalogue's lock.
//!
//! With the `fault-injection` feature (tests only), `VOXD_FAULT` makes the process abort at a
//! chosen point inside a write (see [`fault`]), so crash tests can stop it there.

use std::collections::BTreeMap;
use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use async_trait::async_trait;
use bytes::Bytes;

use super::joblog::JobLog;
use super::packs::{self, Loc, Packs};
use super::{
    ByteStream, StoreError, Usage, VolumeMeta, VolumeStore, atomic, check, safe_id, verified,
};

/// Bytes per chunk of a streamed read.
const CHUNK: usize = 256 << 10;

/// How long a successful write probe vouches for the store's health.
const HEALTH_TTL: Duration = Duration::from_secs(30);

pub struct FsStore {
    volumes: PathBuf,
    /// The job records: `jobs/records.log`.
    records: Arc<Mutex<JobLog>>,
    uploads: PathBuf,
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
    /// Bytes of the volumes in `index` (data and metadata files).
    used: u64,
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
        std::fs::create_dir_all(&volumes)?;
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
        let used = index.values().map(|e| e.stored).sum();
        let inner = Arc::new(Mutex::new(Inner {
            index,
            used,
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
        VolumeStore::put_job_records(self, batch, true)
            .await
            .pop()
            .expect("one result per record")
    }

    fn note_write(&self, ok: bool) {
        self.lock().note_write(ok);
    }
}

impl Inner {
    /// What the health check reads: whether the last write failed, and when one last succeeded.
    fn note_write(&mut self, ok: bool) {
        self.last_write_failed = !ok;
        if ok {
            self.last_ok_write = Some(Instant::now());
        }
    }
}

#[async_trait]
impl VolumeStore for FsStore {
    async fn put(&self, meta: VolumeMeta, vxl: Bytes) -> Result<(), StoreError> {
        if !safe_id(&meta.id) {
            return Err(StoreError::Corrupt(format!("bad volume id {:?}", meta.id)));
        }
        // The metadata must describe the bytes (or every later read would fail), and the
        // metadata file counts against the quota as much as the data: both are known before
        // anything is written.
        let (m, data, pack) = (meta.clone(), vxl.clone(), self.pack_writer);
        let (json, packed, need) = blocking(move || {
            check(&m.id, &data, &m)?;
            // A small volume goes to a pack (one record: its metadata and data), a large one
            // to its own two files.
            if pack {
                let json = serde_json::to_vec(&m).expect("metadata serialises");
                let len = packs::record_len(&m.id, &json, data.len() as u64);
                if json.len() <= packs::META_MAX && len <= packs::RECORD_MAX {
                    return Ok((json, true, len));
                }
            }
            let json = serde_json::to_vec_pretty(&m).expect("metadata serialises");
            let need = (data.len() + json.len()) as u64;
            Ok((json, false, need))
        })
        .await?;
        {
            let mut i = self.lock();
            let used = i.used + i.reserved;
            if used + need > self.limit {
                return Err(StoreError::Full {
                    need,
                    used,
                    limit: self.limit,
                });
            }
            i.reserved += need;
        }
        // The committer releases the reservation and catalogues the volume, whether or not
        // this future is still there to hear how it went.
        let (done, outcome) = tokio::sync::oneshot::channel();
        let pending = Pending {
            meta,
            vxl,
            json,
            packed,
            need,
            done,
        };
        if let Err(std::sync::mpsc::SendError(p)) = self.commits.send(pending) {
            self.lock().reserved -= p.need;
            return Err(StoreError::Io(std::io::Error::other(
                "the store's committer has stopped",
            )));
        }
        outcome.await.unwrap_or_else(|_| {
            Err(StoreError::Io(std::io::Error::other(
                "the store's committer stopped during the write",
            )))
        })
    }

    async fn get(&self, id: &str) -> Result<Option<VolumeMeta>, StoreError> {
        self.lookup(id).await
    }

    /// The bytes, checked against the metadata's length and sha256: a mismatch, a torn file
    /// or a missing one is `Corrupt`. (Ids are never reused, so the bytes under a listed id
    /// change only by damage.)
    async fn read(&self, id: &str) -> Result<Option<Bytes>, StoreError> {
        let Some((meta, data)) = self.open_data(id).await? else {
            return Ok(None);
        };
        let read = blocking(move || {
            let mut b = vec![0u8; data.len as usize];
            data.file.read_exact_at(&mut b, data.at)?;
            check(&meta.id, &b, &meta)?;
            Ok(Bytes::from(b))
        })
        .await;
        if let Err(e @ StoreError::Corrupt(_)) = &read {
            tracing::error!("{e}");
        }
        read.map(Some)
    }

    /// Chunks of the volume's bytes read on the blocking pool, checked by [`verified`]; data
    /// of another length than the metadata's is `Corrupt` before anything streams.
    async fn read_stream(&self, id: &str) -> Result<Option<ByteStream>, StoreError> {
        let Some((meta, data)) = self.open_data(id).await? else {
            return Ok(None);
        };
        let chunks = futures_util::stream::unfold(Some(data), |data| async move {
            let data = data?;
            if data.len == 0 {
                return None;
            }
            let r = blocking(move || {
                let n = data.len.min(CHUNK as u64) as usize;
                let mut buf = vec![0u8; n];
                data.file.read_exact_at(&mut buf, data.at)?;
                let rest = Data {
                    at: data.at + n as u64,
                    len: data.len - n as u64,
                    ..data
                };
                Ok((rest, buf))
            })
            .await;
            match r {
                Ok((rest, buf)) => Some((Ok(Bytes::from(buf)), Some(rest))),
                Err(e) => Some((Err(e), None)),
            }
        });
        Ok(Some(verified(&meta, chunks)))
    }

    async fn list(
        &self,
        after: Option<&str>,
        limit: usize,
    ) -> Result<(Vec<VolumeMeta>, bool), StoreError> {
        let i = self.lock();
        let mut it = i
            .index
            .values()
            .map(|e| &e.meta)
            .filter(|m| after.is_none_or(|a| m.id.as_str() > a));
        let page: Vec<VolumeMeta> = it.by_ref().take(limit).cloned().collect();
        let more = it.next().is_some();
        Ok((page, more))
    }

    async fn delete(&self, id: &str) -> Result<bool, StoreError> {
        self.lookup(id).await?;
        if self.lock().index.get(id).is_some_and(|e| e.at.is_some()) {
            return self.delete_packed(id).await;
        }
        {
            let mut i = self.lock();
            let Some(old) = i.index.remove(id) else {
                return Ok(false);
            };
            i.used -= old.stored;
        }
        let dir = self.volumes.clone();
        let id = id.to_string();
        blocking(move || {
            // Metadata first: once it is gone the volume is gone, whatever happens next.
            std::fs::remove_file(dir.join(format!("{id}.json")))?;
            let _ = std::fs::remove_file(dir.join(format!("{id}.vxl")));
            atomic::sync_dir(&dir)?;
            Ok(true)
        })
        .await
    }

    async fn usage(&self) -> Result<Usage, StoreError> {
        let i = self.lock();
        Ok(Usage {
            bytes: i.used,
            volumes: i.index.len() as u64,
            limit: self.limit,
        })
    }

    /// Healthy when a write succeeded within the last 30 s and the last write did not fail;
    /// otherwise one probe file is written and removed (so an idle store is probed at most
    /// twice a minute, not on every readiness check).
    async fn health(&self) -> Result<(), StoreError> {
        {
            let i = self.lock();
            if !i.last_write_failed && i.last_ok_write.is_some_and(|t| t.elapsed() < HEALTH_TTL) {
                return Ok(());
            }
        }
        let dir = self.volumes.clone();
        let r = blocking(move || {
            let p = dir.join(".probe");
            atomic::write(&p, b"ok")?;
            std::fs::remove_file(&p)?;
            Ok(())
        })
        .await;
        self.note_write(r.is_ok());
        r
    }

    async fn put_job_record(&self, id: &str, record: Bytes) -> Result<(), StoreError> {
        self.one_job_record(id, Some(record)).await
    }

    /// A group commit: every change of the batch appended to the job record log in one write
    /// and one `fdatasync` ([`super::joblog`]).
    async fn put_job_records(
        &self,
        batch: Vec<(String, Option<Bytes>)>,
        durable: bool,
    ) -> Vec<Result<(), StoreError>> {
        let log = self.records.clone();
        let n = batch.len();
        let r = blocking(move || Ok(lock(&log).append(&batch, durable))).await;
        let r = match r {
            Ok(each) => each,
            Err(e) => (0..n)
                .map(|_| Err(StoreError::Io(std::io::Error::other(e.to_string()))))
                .collect(),
        };
        self.note_write(r.iter().all(Result::is_ok));
        r
    }

    async fn delete_job_record(&self, id: &str) -> Result<(), StoreError> {
        self.one_job_record(id, None).await
    }

    async fn job_records(&self) -> Result<Vec<Bytes>, StoreError> {
        let log = self.records.clone();
        blocking(move || Ok(lock(&log).records())).await
    }

    async fn put_upload(&self, id: &str, bytes: Bytes) -> Result<(), StoreError> {
        if !safe_id(id) {
            return Err(StoreError::Corrupt(format!("bad job id {id:?}")));
        }
        let p = self.uploads.join(id);
        let r = blocking(move || Ok(atomic::write(&p, &bytes)?)).await;
        self.note_write(r.is_ok());
        r
    }

    async fn get_upload(&self, id: &str) -> Result<Option<Bytes>, StoreError> {
        if !safe_id(id) {
            return Ok(None);
        }
        let p = self.uploads.join(id);
        blocking(move || match std::fs::read(&p) {
            Ok(b) => Ok(Some(Bytes::from(b))),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
            Err(e) => Err(e.into()),
        })
        .await
    }

    async fn delete_upload(&self, id: &str) -> Result<(), StoreError> {
        if !safe_id(id) {
            return Ok(());
        }
        let p = self.uploads.join(id);
        blocking(move || match std::fs::remove_file(&p) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(e.into()),
            _ => Ok(()),
        })
        .await
    }

    fn describe(&self) -> String {
        format!("directory {}", self.volumes.display())
    }
}

fn lock<T>(inner: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    // A panic while holding the lock cannot leave the maps half-updated (each update is one
    // statement; the job log changes its map only after a write is durable), so a poisoned
    // lock is still usable.
    inner.lock().unwrap_or_else(|p| p.into_inner())
}

/// Compacts the packs while they are due ([`Packs::due`]; at most 4 packs at a time, each at
/// most [`packs::PACK_MAX`] and a volume): their live volumes move to the newest pack and the
/// catalogue follows them.
fn compact(p: &mut Packs, inner: &Mutex<Inner>) -> Result<(), StoreError> {
    for _ in 0..4 {
        let packed = || {
            let i = lock(inner);
            i.index
                .values()
                .filter(|e| e.at.is_some())
                .map(|e| e.stored)
                .sum()
        };
        let Some(n) = p.due(packed) else {
            return Ok(());
        };
        let live: std::collections::HashMap<String, Loc> = lock(inner)
            .index
            .iter()
            .filter_map(|(id, e)| e.at.filter(|l| l.pack == n).map(|l| (id.clone(), l)))
            .collect();
        p.compact(n, &live, |moved| {
            let mut i = lock(inner);
            for (id, loc) in moved {
                if let Some(e) = i.index.get_mut(&id) {
                    e.at = Some(loc);
                }
            }
        })?;
    }
    Ok(())
}

/// The committer thread: takes the puts queued while the previous group was being written (up
/// to [`GROUP_MAX`], without waiting for more) and writes them as one group ([`commit_group`]),
/// until the store is dropped. A lone put is written as soon as it arrives.
fn commit_volumes(
    dir: &Path,
    packs: &Mutex<Packs>,
    inner: &Mutex<Inner>,
    queued: &std::sync::mpsc::Receiver<Pending>,
) {
    while let Ok(first) = queued.recv() {
        let mut group = vec![first];
        while group.len() < GROUP_MAX {
            match queued.try_recv() {
                Ok(p) => group.push(p),
                Err(_) => break,
            }
        }
        let outcomes = commit_group(dir, packs, &group);
        let mut i = lock(inner);
        i.note_write(outcomes.iter().all(Result::is_ok));
        let mut replies = Vec::with_capacity(group.len());
        for (p, outcome) in group.into_iter().zip(outcomes) {
            i.reserved -= p.need;
            if let Ok(at) = outcome {
                i.used += p.need;
                let entry = Entry {
                    meta: p.meta,
                    stored: p.need,
                    at,
                };
                if let Some(old) = i.index.insert(entry.meta.id.clone(), entry) {
                    i.used -= old.stored;
                }
            }
            replies.push((p.done, outcome.map(drop)));
        }
        drop(i);
        for (done, outcome) in replies {
            let _ = done.send(outcome);
        }
    }
}

/// `f` of every item, on up to [`GROUP_THREADS`] threads (a lone item on this one): the
/// file writes and syncs of a group commit run side by side, so that the file system can fold
/// their syncs into shared journal commits rather than make each wait for the one before.
fn in_parallel<T: Sync, R: Send>(items: &[T], f: impl Fn(&T) -> R + Sync) -> Vec<R> {
    if items.len() <= 1 {
        return items.iter().map(f).collect();
    }
    let threads = items.len().min(GROUP_THREADS);
    let per = items.len().div_ceil(threads);
    let mut out: Vec<Option<R>> = (0..items.len()).map(|_| None).collect();
    std::thread::scope(|s| {
        for (items, out) in items.chunks(per).zip(out.chunks_mut(per)) {
            let f = &f;
            s.spawn(move || {
                for (item, o) in items.iter().zip(out) {
                    *o = Some(f(item));
                }
            });
        }
    });
    out.into_iter()
        .map(|r| r.expect("every item done"))
        .collect()
}

/// Writes a group of volumes, each durable when its outcome is `Ok` (with its place in a
/// pack, or `None` for its own files): those that go to a pack in one append
/// ([`Packs::put`]), the others by [`commit_files`].
fn commit_group(
    dir: &Path,
    packs: &Mutex<Packs>,
    group: &[Pending],
) -> Vec<Result<Option<Loc>, StoreError>> {
    let mut outcomes: Vec<Option<Result<Option<Loc>, StoreError>>> =
        (0..group.len()).map(|_| None).collect();
    let packed: Vec<usize> = (0..group.len()).filter(|&k| group[k].packed).collect();
    if !packed.is_empty() {
        let records: Vec<(&str, &[u8], &[u8])> = packed
            .iter()
            .map(|&k| {
                (
                    group[k].meta.id.as_str(),
                    &group[k].json[..],
                    &group[k].vxl[..],
                )
            })
            .collect();
        let put = lock(packs).put(&records);
        match put {
            Ok(locs) => {
                for (&k, loc) in packed.iter().zip(locs) {
                    fault::point(fault::Site::AfterCommit);
                    outcomes[k] = Some(Ok(Some(loc)));
                }
            }
            Err(e) => {
                for &k in &packed {
                    let e = std::io::Error::new(e.kind(), e.to_string());
                    outcomes[k] = Some(Err(e.into()));
                }
            }
        }
    }
    let files: Vec<usize> = (0..group.len()).filter(|&k| !group[k].packed).collect();
    if !files.is_empty() {
        let each: Vec<&Pending> = files.iter().map(|&k| &group[k]).collect();
        for (&k, o) in files.iter().zip(commit_files(dir, &each)) {
            outcomes[k] = Some(o.map(|()| None));
        }
    }
    outcomes
        .into_iter()
        .map(|o| o.expect("every volume written"))
        .collect()
}

/// Writes a group of volumes with the guarantees of one atomic put each and a fraction of the
/// syncs: every volume's two files are written to temporary files and fsynced (on up to
/// [`GROUP_THREADS`] threads, so the file system can fold their syncs into shared journal
/// commits); then every `.vxl` is renamed into place, then every `.json` (the commit record), and
/// the directory is synced once. A live reader never sees metadata without its data (each
/// volume's data is renamed before its metadata), and every `Ok` means both files are durable.
/// A crash before the directory sync may keep some of the group's renames and not others;
/// those volumes were never acknowledged, and [`FsStore::open`] removes whichever half is left
/// (data without metadata, or metadata whose data is missing). A volume whose files could not be
/// written fails alone; a failed directory sync fails the group.
fn commit_files(dir: &Path, group: &[&Pending]) -> Vec<Result<(), StoreError>> {
    let stage = |p: &&Pending| -> Result<(atomic::Staged, atomic::Staged), StoreError> {
        let id = &p.meta.id;
        let data = atomic::stage_with(&dir.join(format!("{id}.vxl")), |w| {
            fault::write(fault::Site::MidData, w, &p.vxl)
        })?;
        let json = atomic::stage_with(&dir.join(format!("{id}.json")), |w| {
            std::io::Write::write_all(w, &p.json)
        })?;
        Ok((data, json))
    };
    let staged = in_parallel(group, stage);
    let mut outcomes: Vec<Result<(), StoreError>> = Vec::with_capacity(group.len());
    let mut records = Vec::with_capacity(group.len());
    for s in staged {
        match s {
            Ok((data, json)) => match data.commit() {
                Ok(()) => {
                    outcomes.push(Ok(()));
                    records.push(Some(json));
                }
                Err(e) => {
                    outcomes.push(Err(e.into()));
                    records.push(None);
                }
            },
            Err(e) => {
                outcomes.push(Err(e));
                records.push(None);
            }
        }
    }
    let fail_all = |outcomes: &mut Vec<Result<(), StoreError>>, e: std::io::Error| {
        for o in outcomes.iter_mut().filter(|o| o.is_ok()) {
            *o = Err(StoreError::Io(std::io::Error::new(e.kind(), e.to_string())));
        }
    };
    for _ in records.iter().flatten() {
        fault::point(fault::Site::AfterData);
    }
    for (o, json) in outcomes.iter_mut().zip(records) {
        if let Some(json) = json
            && let Err(e) = json.commit()
        {
            *o = Err(e.into());
        }
    }
    if let Err(e) = atomic::sync_dir(dir) {
        fail_all(&mut outcomes, e);
        return outcomes;
    }
    for _ in outcomes.iter().filter(|o| o.is_ok()) {
        fault::point(fault::Site::AfterCommit);
    }
    outcomes
}

/// Fault injection for crash tests: with the `fault-injection` feature, `VOXD_FAULT=SPEC`
/// aborts the process (`std::process::abort`, as abrupt as SIGKILL) at one point of the
/// store's writes. `SPEC` is `abort-SITE` or `abort-SITE:N` (the N-th time this process reaches
/// that point, from 1; default 1), with `SITE` one of
///
/// - `mid-data`: inside a put's `.vxl` write, half the bytes in the temporary file, not renamed
///   (the S3 store: a data object of half the bytes);
/// - `after-data` (alias `before-commit`): a put's `.vxl` is written and in place, its metadata
///   not;
/// - `after-commit`: both files durable, the catalogue and the caller not told;
/// - `mid-job-record`: inside an append to the job record log, its last line half written (the S3
///   store: before the PUT, which is atomic).
///
/// The S3 store (`super::s3`) stops at the same points.
///
/// Without the feature every hook is an empty inline function and `VOXD_FAULT` is ignored.
pub mod fault {
    use std::io::Write;

    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    pub enum Site {
        MidData,
        AfterData,
        AfterCommit,
        MidJobRecord,
    }

    /// Writes `bytes` to `w` (a temporary file of an atomic write), aborting halfway when the
    /// fault at `site` fires.
    #[inline]
    pub fn write(site: Site, w: &mut impl Write, bytes: &[u8]) -> std::io::Result<()> {
        #[cfg(feature = "fault-injection")]
        if armed::hit(site) {
            w.write_all(&bytes[..bytes.len() / 2])?;
            w.flush()?;
            abort(site);
        }
        let _ = site;
        w.write_all(bytes)
    }

    /// Aborts here when the fault at `site` fires.
    #[inline]
    pub fn point(site: Site) {
        #[cfg(feature = "fault-injection")]
        if armed::hit(site) {
            abort(site);
        }
        let _ = site;
    }

    /// Does the fault at `site` fire at this visit? For writes that tear themselves (an S3
    /// put sends half its bytes), which then call [`abort`].
    #[inline]
    pub fn fires(site: Site) -> bool {
        #[cfg(feature = "fault-injection")]
        if armed::hit(site) {
            return true;
        }
        let _ = site;
        false
    }

    /// Aborts the process, saying where (after [`fires`]).
    pub fn abort(site: Site) -> ! {
        eprintln!("voxd: fault injection: aborting at {site:?}");
        std::process::abort()
    }

    /// Parses a `VOXD_FAULT` value: the site and the hit that fires (from 1).
    pub fn parse(spec: &str) -> Option<(Site, u64)> {
        let (name, n) = match spec.trim().split_once(':') {
            Some((name, n)) => (name, n.parse().ok().filter(|n| *n > 0)?),
            None => (spec.trim(), 1),
        };
        let site = match name.strip_prefix("abort-")? {
            "mid-data" => Site::MidData,
            "after-data" | "before-commit" => Site::AfterData,
            "after-commit" => Site::AfterCommit,
            "mid-job-record" => Site::MidJobRecord,
            _ => return None,
        };
        Some((site, n))
    }

    #[cfg(feature = "fault-injection")]
    mod armed {
        use super::Site;
        use std::sync::OnceLock;
        use std::sync::atomic::{AtomicU64, Ordering};

        static FAULT: OnceLock<Option<(Site, u64)>> = OnceLock::new();
        static HITS: AtomicU64 = AtomicU64::new(0);

        /// Is this visit of `site` the one that fires?
        pub fn hit(site: Site) -> bool {
            let fault = FAULT.get_or_init(|| {
                let spec = std::env::var("VOXD_FAULT").ok()?;
                let f = super::parse(&spec);
                if f.is_none() {
                    eprintln!("voxd: VOXD_FAULT={spec:?} is not a fault this build knows; ignored");
                }
                f
            });
            match *fault {
                Some((s, n)) if s == site => HITS.fetch_add(1, Ordering::SeqCst) + 1 == n,
                _ => false,
            }
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::store::{SourceInfo, sha256_hex};

    /// Metadata that describes `data` truthfully.
    pub(crate) fn meta(id: &str, data: &[u8]) -> VolumeMeta {
        VolumeMeta {
            id: id.into(),
            name: None,
            kind: "bits".into(),
            method: "solid".into(),
            grid: crate::Grid {
                origin: [0.0; 3],
                voxel_size: 1.0,
                dims: [1; 3],
            },
            solid_voxels: 0,
            volume: 0.0,
            source: SourceInfo {
                format: "obj".into(),
                sha256: String::new(),
                triangles: 1,
            },
            diagnostics: None,
            fill: None,
            engine: "cpu".into(),
            created: String::new(),
            bytes: data.len() as u64,
            sha256: sha256_hex(data),
            provenance: None,
        }
    }

    pub(crate) fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("voxd-fsstore-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        dir
    }

    /// Bytes of every file in `dir/volumes`.
    fn bytes_on_disk(dir: &Path) -> u64 {
        std::fs::read_dir(dir.join("volumes"))
            .unwrap()
            .map(|e| e.unwrap().metadata().unwrap().len())
            .sum()
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn quota_is_checked_and_reserved_in_one_step() {
        let dir = scratch("quota");
        // One volume takes its 30 data bytes and its metadata file; the ids are of one length,
        // so every volume takes the same.
        let data = vec![0u8; 30];
        let per = 30 + serde_json::to_vec_pretty(&meta("v0", &data)).unwrap().len() as u64;
        let limit = 3 * per + per / 2;
        let store = std::sync::Arc::new(FsStore::open_files(&dir, limit).unwrap());
        // Eight concurrent puts into room for three and a half: exactly three fit.
        let puts: Vec<_> = (0..8)
            .map(|n| {
                let s = store.clone();
                let data = data.clone();
                tokio::spawn(async move {
                    s.put(meta(&format!("v{n}"), &data), Bytes::from(data))
                        .await
                })
            })
            .collect();
        let mut ok = 0;
        for p in puts {
            match p.await.unwrap() {
                Ok(()) => ok += 1,
                Err(StoreError::Full { .. }) => {}
                Err(e) => panic!("{e}"),
            }
        }
        assert_eq!(ok, 3);
        assert_eq!(store.usage().await.unwrap().bytes, 3 * per);
        assert_eq!(bytes_on_disk(&dir), 3 * per);
        assert!(store.health().await.is_ok());
        // Reopened, the same three are there and count the same.
        let again = FsStore::open_files(&dir, limit).unwrap();
        assert_eq!(again.list(None, 10).await.unwrap().0.len(), 3);
        assert_eq!(again.usage().await.unwrap().bytes, 3 * per);
        let listed = store.list(None, 10).await.unwrap().0;
        assert!(store.delete(&listed[0].id).await.unwrap());
        assert_eq!(store.usage().await.unwrap().bytes, 2 * per);
        assert_eq!(bytes_on_disk(&dir), 2 * per);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn metadata_counts_against_the_quota() {
        let dir = scratch("metaquota");
        let data = vec![7u8; 1000];
        let plain = meta("plain", &data);
        let plain_json = serde_json::to_vec_pretty(&plain).unwrap().len() as u64;
        // Room for the data and a small metadata file, not for 100 KB of provenance.
        let limit = 2 * (1000 + plain_json) + 10_000;
        let store = FsStore::open_files(&dir, limit).unwrap();
        let mut big = meta("big", &data);
        big.provenance = Some(serde_json::json!({
            "op": "union",
            "operands": ["x".repeat(100_000)],
        }));
        match store.put(big, Bytes::from(data.clone())).await {
            Err(StoreError::Full {
                need,
                used,
                limit: l,
            }) => {
                assert!(need > 100_000, "{need}");
                assert_eq!((used, l), (0, limit));
            }
            other => panic!("a 100 KB provenance fitted: {other:?}"),
        }
        assert_eq!(store.usage().await.unwrap().bytes, 0);
        assert!(store.get("big").await.unwrap().is_none());
        assert!(!dir.join("volumes/big.vxl").exists());
        // The same data with small metadata fits, and counts both files.
        store.put(plain, Bytes::from(data.clone())).await.unwrap();
        assert_eq!(store.usage().await.unwrap().bytes, 1000 + plain_json);
        assert_eq!(bytes_on_disk(&dir), 1000 + plain_json);
        let again = FsStore::open_files(&dir, limit).unwrap();
        assert_eq!(again.usage().await.unwrap().bytes, 1000 + plain_json);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn streamed_reads_are_checked_before_their_last_byte() {
        use futures_util::StreamExt;
        let dir = scratch("stream");
        let store = FsStore::open_files(&dir, 16 << 20).unwrap();
        let data: Vec<u8> = (0..3 * CHUNK as u32 + 17)
            .map(|i| (i % 253) as u8)
            .collect();
        for id in ["a", "b", "c"] {
            store
                .put(meta(id, &data), Bytes::from(data.clone()))
                .await
                .unwrap();
        }
        // Drains a stream: the bytes that came out, and the error that ended it.
        async fn drain(mut s: ByteStream) -> (Vec<u8>, Option<StoreError>) {
            let mut out = vec![];
            while let Some(c) = s.next().await {
                match c {
                    Ok(c) => out.extend_from_slice(&c),
                    Err(e) => return (out, Some(e)),
                }
            }
            (out, None)
        }
        let (got, err) = drain(store.read_stream("a").await.unwrap().unwrap()).await;
        assert!(err.is_none(), "{err:?}");
        assert_eq!(got, data);
        // A byte flipped in the first chunk: everything but the last chunk streams, then the
        // stream ends with Corrupt (the client never holds a whole, damaged volume).
        let a = dir.join("volumes/a.vxl");
        let mut bytes = std::fs::read(&a).unwrap();
        bytes[100] ^= 1;
        std::fs::write(&a, &bytes).unwrap();
        let (got, err) = drain(store.read_stream("a").await.unwrap().unwrap()).await;
        assert!(
            matches!(&err, Some(StoreError::Corrupt(m)) if m.contains("sha256")),
            "{err:?}"
        );
        assert!(got.len() < data.len(), "{} bytes streamed", got.len());
        // Torn or missing: refused before anything streams.
        std::fs::write(dir.join("volumes/b.vxl"), &data[..1000]).unwrap();
        assert!(
            matches!(store.read_stream("b").await, Err(StoreError::Corrupt(m)) if m.contains("1000 bytes"))
        );
        std::fs::remove_file(dir.join("volumes/c.vxl")).unwrap();
        assert!(
            matches!(store.read_stream("c").await, Err(StoreError::Corrupt(m)) if m.contains("missing"))
        );
        assert!(store.read_stream("nope").await.unwrap().is_none());
        // Uploads: kept, read back, removed; an absent one is None, a hostile id never a path.
        store
            .put_upload("j1", Bytes::from_static(b"mesh"))
            .await
            .unwrap();
        assert_eq!(store.get_upload("j1").await.unwrap().unwrap(), "mesh");
        store.delete_upload("j1").await.unwrap();
        store.delete_upload("j1").await.unwrap();
        assert!(store.get_upload("j1").await.unwrap().is_none());
        assert!(
            store
                .get_upload("../volumes/a.vxl")
                .await
                .unwrap()
                .is_none()
        );
        assert!(store.put_upload("../x", Bytes::new()).await.is_err());
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn reads_verify_length_and_checksum() {
        let dir = scratch("checksum");
        let store = FsStore::open_files(&dir, 1 << 20).unwrap();
        let data: Vec<u8> = (0..4096u32).map(|i| (i * 7 % 251) as u8).collect();
        for id in ["a", "b", "c", "d"] {
            store
                .put(meta(id, &data), Bytes::from(data.clone()))
                .await
                .unwrap();
        }
        assert_eq!(store.read("a").await.unwrap().unwrap(), data);
        let corrupt = |r: Result<Option<Bytes>, StoreError>, what: &str| match r {
            Err(StoreError::Corrupt(m)) => assert!(m.contains(what), "{m}"),
            other => panic!("expected Corrupt ({what}), got {other:?}"),
        };
        // One byte flipped on disk.
        let a = dir.join("volumes/a.vxl");
        let mut bytes = std::fs::read(&a).unwrap();
        bytes[1234] ^= 0x10;
        std::fs::write(&a, &bytes).unwrap();
        corrupt(store.read("a").await, "sha256");
        // Torn: cut short.
        std::fs::write(dir.join("volumes/b.vxl"), &data[..1000]).unwrap();
        corrupt(store.read("b").await, "1000 bytes");
        // Missing.
        std::fs::remove_file(dir.join("volumes/c.vxl")).unwrap();
        corrupt(store.read("c").await, "missing");
        // Still corrupt after a reopen (it is listed, and says so when read).
        let again = FsStore::open_files(&dir, 1 << 20).unwrap();
        corrupt(again.read("a").await, "sha256");
        corrupt(again.read("b").await, "1000 bytes");
        assert_eq!(again.read("d").await.unwrap().unwrap(), data);
        // A deleted volume is absent, not corrupt; an unknown one too.
        assert!(store.delete("d").await.unwrap());
        assert!(store.read("d").await.unwrap().is_none());
        assert!(store.read("nope").await.unwrap().is_none());
        // Metadata that does not describe its bytes is refused, and nothing is stored.
        let mut lying = meta("e", &data);
        lying.sha256 = sha256_hex(b"something else");
        corrupt(
            store
                .put(lying, Bytes::from(data.clone()))
                .await
                .map(|_| None),
            "sha256",
        );
        let mut short = meta("f", &data);
        short.bytes -= 1;
        corrupt(
            store
                .put(short, Bytes::from(data.clone()))
                .await
                .map(|_| None),
            "bytes",
        );
        assert!(store.get("e").await.unwrap().is_none() && store.get("f").await.unwrap().is_none());
        assert!(!dir.join("volumes/e.vxl").exists() && !dir.join("volumes/f.vxl").exists());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// Two stores on one directory (two replicas in the tests): a volume one of them stored is
    /// found, read and deleted through the other, which catalogues it from then on.
    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_volume_another_process_stored_is_found_on_disk() {
        let dir = scratch("shared");
        let a = FsStore::open_files(&dir, 1 << 20).unwrap();
        let b = FsStore::open_files(&dir, 1 << 20).unwrap();
        let data = vec![5u8; 300];
        a.put(meta("v1", &data), Bytes::from(data.clone()))
            .await
            .unwrap();
        assert!(b.list(None, 10).await.unwrap().0.is_empty());
        assert_eq!(b.get("v1").await.unwrap().unwrap().id, "v1");
        assert_eq!(b.read("v1").await.unwrap().unwrap(), data);
        assert_eq!(b.list(None, 10).await.unwrap().0.len(), 1);
        assert_eq!(b.usage().await.unwrap(), a.usage().await.unwrap());
        assert!(b.get("nope").await.unwrap().is_none());
        assert!(b.get("../volumes/v1").await.unwrap().is_none());
        assert!(b.delete("v1").await.unwrap());
        assert!(
            a.read("v1").await.is_err(),
            "gone on disk, still in a's catalogue"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// A group of volumes (as many as the committer takes at once) written by one group commit:
    /// each is whole on disk with its metadata, a volume whose data cannot be put in place
    /// (a directory squats its name) fails alone, and no temporary file is left.
    #[test]
    fn a_group_commit_writes_every_volume_and_fails_only_the_one_that_fails() {
        let dir = scratch("group");
        let volumes = dir.join("volumes");
        std::fs::create_dir_all(volumes.join("v3.vxl")).unwrap();
        let mut replies = vec![];
        let group: Vec<Pending> = (0..GROUP_MAX as u8)
            .map(|n| {
                let data = vec![n; 100 + n as usize];
                let m = meta(&format!("v{n}"), &data);
                let json = serde_json::to_vec_pretty(&m).unwrap();
                let (done, reply) = tokio::sync::oneshot::channel();
                replies.push(reply);
                Pending {
                    packed: false,
                    need: (data.len() + json.len()) as u64,
                    meta: m,
                    vxl: Bytes::from(data),
                    json,
                    done,
                }
            })
            .collect();
        let outcomes = commit_group(
            &volumes,
            &Mutex::new(Packs::open(&volumes, false).unwrap().0),
            &group,
        );
        assert_eq!(outcomes.len(), group.len());
        for (n, o) in outcomes.iter().enumerate() {
            let (vxl, json) = (
                volumes.join(format!("v{n}.vxl")),
                volumes.join(format!("v{n}.json")),
            );
            if n == 3 {
                assert!(o.is_err());
                assert!(!json.exists(), "no commit record for the failed volume");
                continue;
            }
            assert!(o.is_ok(), "v{n}: {o:?}");
            assert_eq!(std::fs::read(vxl).unwrap(), vec![n as u8; 100 + n]);
            let m: VolumeMeta = serde_json::from_slice(&std::fs::read(json).unwrap()).unwrap();
            assert_eq!(m.id, format!("v{n}"));
        }
        let leftovers: Vec<_> = std::fs::read_dir(&volumes)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.starts_with('.'))
            .collect();
        assert!(leftovers.is_empty(), "{leftovers:?}");
        // Reopened, the store has every committed volume and reads each whole.
        let store = FsStore::open_files(&dir, 1 << 30).unwrap();
        let rt = tokio::runtime::Builder::new_current_thread()
            .build()
            .unwrap();
        rt.block_on(async {
            let (listed, _) = store.list(None, 1000).await.unwrap();
            assert_eq!(listed.len(), GROUP_MAX - 1);
            for m in listed {
                assert_eq!(
                    store.read(&m.id).await.unwrap().unwrap().len() as u64,
                    m.bytes
                );
            }
        });
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// What an interrupted group commit can leave, either half of a volume, is removed at open;
    /// whole volumes stay.
    #[test]
    fn open_removes_either_half_of_an_interrupted_volume() {
        let dir = scratch("halves");
        let volumes = dir.join("volumes");
        std::fs::create_dir_all(&volumes).unwrap();
        let data = vec![9u8; 64];
        for (id, vxl, json) in [
            ("whole", true, true),
            ("nodata", false, true),
            ("nometa", true, false),
        ] {
            if vxl {
                std::fs::write(volumes.join(format!("{id}.vxl")), &data).unwrap();
            }
            if json {
                let m = serde_json::to_vec_pretty(&meta(id, &data)).unwrap();
                std::fs::write(volumes.join(format!("{id}.json")), m).unwrap();
            }
        }
        let store = FsStore::open_files(&dir, 1 << 20).unwrap();
        let mut names: Vec<String> = std::fs::read_dir(&volumes)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n != packs::LOCK)
            .collect();
        names.sort();
        assert_eq!(names, ["whole.json", "whole.vxl"]);
        let rt = tokio::runtime::Builder::new_current_thread()
            .build()
            .unwrap();
        let listed = rt.block_on(store.list(None, 10)).unwrap().0;
        assert_eq!(listed.len(), 1);
        assert_eq!(listed[0].id, "whole");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// Concurrent puts through the committer: each caller hears its own outcome, the failed
    /// one's reservation is released, and the quota counts exactly the volumes stored.
    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn concurrent_puts_each_hear_their_own_outcome() {
        let dir = scratch("concurrent");
        let store = std::sync::Arc::new(FsStore::open_files(&dir, 1 << 30).unwrap());
        std::fs::create_dir_all(dir.join("volumes/v5.vxl")).unwrap();
        let puts: Vec<_> = (0..40u8)
            .map(|n| {
                let s = store.clone();
                tokio::spawn(async move {
                    let data = vec![n; 50];
                    s.put(meta(&format!("v{n}"), &data), Bytes::from(data))
                        .await
                })
            })
            .collect();
        for (n, p) in puts.into_iter().enumerate() {
            let r = p.await.unwrap();
            assert_eq!(r.is_ok(), n != 5, "v{n}: {r:?}");
        }
        let usage = store.usage().await.unwrap();
        assert_eq!(usage.volumes, 39);
        assert_eq!(
            usage.bytes,
            bytes_on_disk(&dir) - bytes_dir_entry(&dir, "v5.vxl")
        );
        assert_eq!(store.lock().reserved, 0);
        for n in (0..40u8).filter(|&n| n != 5) {
            assert_eq!(
                store.read(&format!("v{n}")).await.unwrap().unwrap(),
                vec![n; 50]
            );
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// What the directory `name` in `dir/volumes` adds to [`bytes_on_disk`].
    fn bytes_dir_entry(dir: &Path, name: &str) -> u64 {
        std::fs::metadata(dir.join("volumes").join(name))
            .unwrap()
            .len()
    }

    #[test]
    fn fault_specs_parse() {
        use fault::{Site, parse};
        assert_eq!(parse("abort-before-commit"), Some((Site::AfterData, 1)));
        assert_eq!(parse("abort-after-data:3"), Some((Site::AfterData, 3)));
        assert_eq!(parse("abort-mid-data:2"), Some((Site::MidData, 2)));
        assert_eq!(parse("abort-after-commit"), Some((Site::AfterCommit, 1)));
        assert_eq!(
            parse("abort-mid-job-record:5"),
            Some((Site::MidJobRecord, 5))
        );
        for bad in [
            "",
            "abort",
            "abort-after-data:0",
            "abort-after-data:x",
            "after-data",
            "abort-elsewhere",
        ] {
            assert_eq!(parse(bad), None, "{bad}");
        }
    }
}
