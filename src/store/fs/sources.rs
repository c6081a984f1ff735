//! The directory store's source objects: the meshes volumes were made from, one file
//! `sources/{sha256}` each (written atomically), their sizes catalogued in memory and counted
//! in the quota with the volumes. A source is referred to by the volumes whose metadata says
//! `source.kept` with its key: the catalogue answers that without reading a file. What the
//! bytes are, and when a source is kept or removed, is the application's
//! ([`crate::app::sources`]).

use std::collections::BTreeMap;
use std::path::Path;

use bytes::Bytes;

use super::{FsStore, blocking};
use crate::app::store::source_key;
use crate::store::{StoreError, atomic};

/// The sources in `dir` and their sizes; temporaries of interrupted writes are removed.
pub(super) fn open(dir: &Path) -> Result<BTreeMap<String, u64>, StoreError> {
    let mut out = BTreeMap::new();
    for e in std::fs::read_dir(dir)? {
        let e = e?;
        let name = e.file_name().to_string_lossy().to_string();
        if name.starts_with('.') {
            let _ = std::fs::remove_file(e.path());
            continue;
        }
        if source_key(&name) {
            out.insert(name, e.metadata()?.len());
        }
    }
    Ok(out)
}

fn bad_key(key: &str) -> StoreError {
    StoreError::Corrupt(format!("bad source key {key:?}"))
}

impl FsStore {
    pub(super) async fn put_source_file(&self, key: &str, bytes: Bytes) -> Result<(), StoreError> {
        if !source_key(key) {
            return Err(bad_key(key));
        }
        let need = bytes.len() as u64;
        {
            let mut i = self.lock();
            if i.sources.contains_key(key) {
                return Ok(());
            }
            i.reserve(need, self.limit)?;
        }
        let p = self.sources.join(key);
        let r = blocking(move || Ok(atomic::write(&p, &bytes)?)).await;
        self.note_write(r.is_ok());
        let mut i = self.lock();
        i.reserved -= need;
        if r.is_ok() && i.sources.insert(key.to_string(), need).is_none() {
            i.used += need;
        }
        r
    }

    pub(super) async fn get_source_file(&self, key: &str) -> Result<Option<Bytes>, StoreError> {
        if !source_key(key) {
            return Ok(None);
        }
        super::read_if_there(self.sources.join(key)).await
    }

    pub(super) async fn delete_source_file(&self, key: &str) -> Result<(), StoreError> {
        if !source_key(key) {
            return Ok(());
        }
        {
            let mut i = self.lock();
            if let Some(n) = i.sources.remove(key) {
                i.used -= n;
            }
        }
        let (p, dir) = (self.sources.join(key), self.sources.clone());
        let r = blocking(move || match std::fs::remove_file(&p) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(e.into()),
            _ => Ok(atomic::sync_dir(&dir)?),
        })
        .await;
        self.note_write(r.is_ok());
        r
    }

    pub(super) fn source_referred_here(&self, key: &str) -> bool {
        self.lock()
            .index
            .values()
            .any(|e| e.meta.source.kept && e.meta.source.sha256 == key)
    }

    pub(super) async fn list_source_files(
        &self,
    ) -> Result<Vec<(String, std::time::SystemTime)>, StoreError> {
        super::files_with_times(self.sources.clone(), source_key).await
    }
}
