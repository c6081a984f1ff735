//! The directory store's [`VolumeStore`] methods: puts handed to the committer, reads checked
//! against the metadata, deletes, the quota, job records and uploads. Not here: opening the
//! directory (`super`) and writing the files (`super::commit`).

use std::os::unix::fs::FileExt;

use async_trait::async_trait;
use bytes::Bytes;

use super::packs;
use super::{CHUNK, Data, FsStore, HEALTH_TTL, Pending, blocking, lock};
use crate::store::{
    ByteStream, StoreError, Usage, VolumeMeta, VolumeStore, Vxl, atomic, check, check_put, safe_id,
    verified,
};

#[async_trait]
impl VolumeStore for FsStore {
    async fn put(&self, meta: VolumeMeta, vxl: Vxl) -> Result<(), StoreError> {
        if !safe_id(&meta.id) {
            return Err(StoreError::Corrupt(format!("bad volume id {:?}", meta.id)));
        }
        // The metadata must describe the bytes (or every later read would fail; checked against
        // the hash `vxl` carries, not by hashing again), and the metadata file counts against
        // the quota as much as the data: both are known before anything is written.
        check_put(&meta, &vxl)?;
        let vxl = vxl.into_bytes();
        // A small volume goes to a pack (one record: its metadata and data), a large one to its
        // own two files.
        let packed = self.pack_writer.then(|| {
            let json = serde_json::to_vec(&meta).expect("metadata serialises");
            let len = packs::record_len(&meta.id, &json, vxl.len() as u64);
            (json.len() <= packs::META_MAX && len <= packs::RECORD_MAX).then_some((json, len))
        });
        let (json, packed, need) = match packed.flatten() {
            Some((json, len)) => (json, true, len),
            None => {
                let json = serde_json::to_vec_pretty(&meta).expect("metadata serialises");
                let need = (vxl.len() + json.len()) as u64;
                (json, false, need)
            }
        };
        self.lock().reserve(need, self.limit)?;
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
    /// and one `fdatasync` (`joblog.rs`).
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
        super::read_if_there(self.uploads.join(id)).await
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

    async fn list_uploads(&self) -> Result<Vec<(String, std::time::SystemTime)>, StoreError> {
        // Temporary files of atomic writes are not uploads (yet).
        super::files_with_times(self.uploads.clone(), safe_id).await
    }

    async fn put_source(&self, key: &str, bytes: Bytes) -> Result<(), StoreError> {
        self.put_source_file(key, bytes).await
    }

    async fn get_source(&self, key: &str) -> Result<Option<Bytes>, StoreError> {
        self.get_source_file(key).await
    }

    async fn delete_source(&self, key: &str) -> Result<(), StoreError> {
        self.delete_source_file(key).await
    }

    async fn source_referred(&self, key: &str) -> Result<bool, StoreError> {
        Ok(self.source_referred_here(key))
    }

    async fn list_sources(&self) -> Result<Vec<(String, std::time::SystemTime)>, StoreError> {
        self.list_source_files().await
    }

    fn describe(&self) -> String {
        format!("directory {}", self.volumes.display())
    }
}
