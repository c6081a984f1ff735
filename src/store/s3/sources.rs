//! The S3 store's source objects (the meshes volumes were made from; what they hold and when
//! they are kept or removed is the application's: [`crate::app::sources`]):
//!
//! - `volumes/src-{key}.mesh`: the mesh, under `volumes/` so that the quota's LIST counts it
//!   (and its reservation, `volumes/src-{key}.reserve-{bytes}`, like a volume's);
//! - `sources/{key}/{id}`: an empty marker that volume `id` refers to it, written by the put
//!   before the volume's data and removed by its delete. A marker whose volume has no metadata
//!   is a put in progress while it is younger than [`super::ORPHAN_AGE`] (it refers), and a
//!   leftover after (removed when found).

use bytes::Bytes;
use futures_util::StreamExt;
use object_store::ObjectStore;
use object_store::path::Path;

use super::{ORPHAN_AGE, Shared};
use crate::app::store::source_key;
use crate::store::StoreError;

/// The group name a source's objects have under `volumes/` (never a volume id: those are hex).
pub(super) const GROUP: &str = "src-";

fn bad_key(key: &str) -> StoreError {
    StoreError::Corrupt(format!("bad source key {key:?}"))
}

impl Shared {
    fn source_key_path(&self, key: &str) -> Path {
        self.key(&format!("volumes/{GROUP}{key}.mesh"))
    }

    pub(super) fn marker_key(&self, key: &str, id: &str) -> Path {
        self.key(&format!("sources/{key}/{id}"))
    }

    pub(super) async fn put_source(&self, key: &str, bytes: Bytes) -> Result<(), StoreError> {
        if !source_key(key) {
            return Err(bad_key(key));
        }
        let path = self.source_key_path(key);
        let doing = format!("keeping source {key}");
        if self.exists(&doing, &path).await? {
            return Ok(());
        }
        let need = bytes.len() as u64;
        self.reserve(need).await?;
        let r = async {
            let marker = self.admit(&format!("{GROUP}{key}"), need).await?;
            let put = self.put_object(&doing, &path, bytes).await;
            if let Err(e) = self.delete_object(&doing, &marker).await {
                tracing::warn!("{e} (the sweep removes the reservation later)");
            }
            put
        }
        .await;
        let mut s = self.lock();
        s.reserved -= need;
        s.usage = None;
        r
    }

    pub(super) async fn get_source(&self, key: &str) -> Result<Option<Bytes>, StoreError> {
        if !source_key(key) {
            return Ok(None);
        }
        self.get_object(&format!("reading source {key}"), &self.source_key_path(key))
            .await
    }

    pub(super) async fn delete_source(&self, key: &str) -> Result<(), StoreError> {
        if !source_key(key) {
            return Ok(());
        }
        self.delete_object(
            &format!("removing source {key}"),
            &self.source_key_path(key),
        )
        .await?;
        self.lock().usage = None;
        Ok(())
    }

    /// A marker of a committed volume, or one young enough to be a put in progress; markers
    /// of neither are removed on the way.
    pub(super) async fn source_referred(&self, key: &str) -> Result<bool, StoreError> {
        if !source_key(key) {
            return Ok(false);
        }
        let doing = format!("listing the volumes of source {key}");
        let now = std::time::SystemTime::now();
        let mut stream = self.client.list(Some(&self.key(&format!("sources/{key}"))));
        let mut dead = vec![];
        let mut referred = false;
        while let Some(o) = stream.next().await {
            let o = o.map_err(|e| self.err(&doing, e))?;
            let Some(id) = o.location.filename().map(str::to_string) else {
                continue;
            };
            let age = now
                .duration_since(std::time::SystemTime::from(o.last_modified))
                .unwrap_or_default();
            if age < ORPHAN_AGE || self.read_meta(&id).await?.is_some() {
                referred = true;
                break;
            }
            dead.push(o.location);
        }
        drop(stream);
        for m in dead {
            tracing::warn!(marker = %m, "removing the source marker of a volume that is gone");
            self.delete_object(&doing, &m).await?;
        }
        Ok(referred)
    }

    pub(super) async fn list_sources(
        &self,
    ) -> Result<Vec<(String, std::time::SystemTime)>, StoreError> {
        let mut out = vec![];
        let mut stream = self.client.list(Some(&self.key("volumes")));
        while let Some(o) = stream.next().await {
            let o = o.map_err(|e| self.err("listing sources", e))?;
            let key = o
                .location
                .filename()
                .and_then(|n| n.strip_prefix(GROUP))
                .and_then(|n| n.strip_suffix(".mesh"));
            if let Some(key) = key.filter(|k| source_key(k)) {
                out.push((
                    key.to_string(),
                    std::time::SystemTime::from(o.last_modified),
                ));
            }
        }
        Ok(out)
    }
}
