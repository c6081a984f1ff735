//! The meshes volumes were made from, kept in the store while a volume refers to them (issue
//! 33: the Hermite data and dual contouring of a stored volume are computed from its mesh).
//!
//! A source object is the mesh in its binary form ([`crate::mesh::binary`]) behind [`MAGIC`]
//! and the sha256 of that form, under the key of the upload's sha256 (`source.sha256` of the
//! volumes made from it, which say `source.kept`): volumes made from the same upload share one
//! object, counted once in the quota. Reads check the hash, so damage is `Corrupt`, never a
//! wrong mesh.
//!
//! **Keeping and removing, without a lost mesh.** A store is shared by replicas and offers no
//! conditional writes, so the steps are ordered so that neither of two processes racing can
//! leave a volume without its mesh:
//! - a put keeps the source ([`keep`]) before it commits the volume, and makes sure it is
//!   still there after ([`kept`]), writing it again if a removal came in between;
//! - a removal ([`release`]) after a volume's delete removes the source only when no volume
//!   (nor a put in progress, in a shared store) refers to it, then asks again: a reference
//!   that appeared meanwhile gets the bytes back, written by the removal itself.
//!
//! A source left behind (a process killed between keeping it and committing its volume) is
//! removed by [`sweep`] once older than its grace.

use std::time::{Duration, SystemTime};

use bytes::Bytes;
use sha2::Digest;

use super::error::{Error, ErrorKind, Result};
use super::store::{StoreError, VolumeMeta, VolumeStore};
use crate::mesh::{LoadOptions, Mesh, binary};

/// The first bytes of a source object.
pub const MAGIC: [u8; 8] = *b"\x89VXSRC\n\x00";

/// A source object's bytes for `mesh`: [`MAGIC`], the sha256 of the binary form, the form.
pub fn encode(mesh: &Mesh) -> Bytes {
    let body = binary::encode(mesh);
    let mut out = Vec::with_capacity(40 + body.len());
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&sha2::Sha256::digest(&body));
    out.extend_from_slice(&body);
    Bytes::from(out)
}

/// The mesh of a source object, its hash checked, within `opts`' limits. Blocking.
pub fn decode(bytes: &[u8], opts: &LoadOptions) -> Result<Mesh> {
    let corrupt = |why: &str| {
        Error::from(StoreError::Corrupt(format!(
            "the volume's kept mesh is unreadable: {why}"
        )))
    };
    if bytes.len() < 40 || bytes[..8] != MAGIC {
        return Err(corrupt("not a source object"));
    }
    let (hash, body) = bytes[8..].split_at(32);
    if sha2::Sha256::digest(body).as_slice() != hash {
        return Err(corrupt("its bytes do not match their sha256 (damaged)"));
    }
    Ok(binary::decode(body, opts)?)
}

/// Before a volume that keeps its mesh is committed: the source under `key`.
pub async fn keep(store: &dyn VolumeStore, key: &str, bytes: &Bytes) -> Result<()> {
    store
        .put_source(key, bytes.clone())
        .await
        .map_err(|e| Error::from(e).context("cannot keep the volume's mesh"))
}

/// After the volume is committed: the source is still there (written again if a removal took
/// it meanwhile). A failure is logged: the volume stands, its mesh-based downloads say the
/// mesh is missing.
pub async fn kept(store: &dyn VolumeStore, key: &str, bytes: Bytes) {
    if let Err(e) = store.put_source(key, bytes).await {
        tracing::error!(
            source = key,
            "the kept mesh could not be written again: {e}"
        );
    }
}

/// After a volume's delete (or a failed put): removes source `key` if nothing refers to it
/// (see the module's documentation for why it asks twice). Whether it was removed.
pub async fn release(store: &dyn VolumeStore, key: &str) -> std::result::Result<bool, StoreError> {
    if store.source_referred(key).await? {
        return Ok(false);
    }
    let Some(bytes) = store.get_source(key).await? else {
        return Ok(false);
    };
    store.delete_source(key).await?;
    if store.source_referred(key).await? {
        // A volume came to refer to it meanwhile: it gets its mesh back.
        store.put_source(key, bytes).await?;
        return Ok(false);
    }
    Ok(true)
}

/// [`release`] after deleting `meta`'s volume, logged, never failing the delete: what cannot
/// be removed now is left to [`sweep`].
async fn released(store: &dyn VolumeStore, meta: &VolumeMeta) {
    if !meta.source.kept {
        return;
    }
    if let Err(e) = release(store, &meta.source.sha256).await {
        tracing::warn!(source = %meta.source.sha256, "cannot remove a mesh no volume keeps: {e}");
    }
}

/// Deletes volume `id` and then, if no other volume keeps it, the mesh it kept ([`released`]):
/// every delete of a volume goes through here. `meta` is its metadata when the caller has read
/// it already; unreadable metadata does not stop the delete (such a mesh is left to [`sweep`]).
/// Whether there was a volume.
pub async fn delete_volume(
    store: &dyn VolumeStore,
    id: &str,
    meta: Option<VolumeMeta>,
) -> std::result::Result<bool, StoreError> {
    let meta = match meta {
        Some(m) => Some(m),
        None => store.get(id).await.ok().flatten(),
    };
    let deleted = store.delete(id).await?;
    if deleted && let Some(meta) = &meta {
        released(store, meta).await;
    }
    Ok(deleted)
}

/// Removes the sources older than `grace` that no volume refers to; how many.
pub async fn sweep(store: &dyn VolumeStore, grace: Duration) -> usize {
    let sources = match store.list_sources().await {
        Ok(s) => s,
        Err(e) => {
            tracing::warn!("cannot list kept meshes to sweep: {e}");
            return 0;
        }
    };
    let now = SystemTime::now();
    let mut swept = 0;
    for (key, written) in sources {
        if now.duration_since(written).unwrap_or_default() < grace {
            continue;
        }
        match release(store, &key).await {
            Ok(true) => swept += 1,
            Ok(false) => {}
            Err(e) => tracing::warn!(source = %key, "cannot sweep a kept mesh: {e}"),
        }
    }
    if swept > 0 {
        tracing::info!(swept, "kept meshes no volume refers to removed");
    }
    swept
}

/// `source-not-kept` unless volume `meta` keeps the mesh it was made from (`why`: the mesh is
/// missing from the store).
fn not_kept(meta: &VolumeMeta, why: &str) -> Error {
    Error::new(
        ErrorKind::SourceNotKept,
        format!(
            "volume {} {why}: voxelize the mesh again to have it kept",
            meta.id
        ),
    )
}

/// `source-not-kept` unless volume `meta` keeps the mesh it was made from: what a caller asks
/// before it admits any work on that mesh.
pub fn require_kept(meta: &VolumeMeta) -> Result<()> {
    if meta.source.kept {
        return Ok(());
    }
    Err(not_kept(
        meta,
        "does not keep the mesh it was made from (derived volumes and volumes stored before meshes were kept do not)",
    ))
}

/// The mesh volume `meta` was made from, read from the store; `source-not-kept` when the
/// volume did not keep one (or it is missing).
pub async fn load(store: &dyn VolumeStore, meta: &VolumeMeta, opts: LoadOptions) -> Result<Mesh> {
    require_kept(meta)?;
    let Some(bytes) = store.get_source(&meta.source.sha256).await? else {
        return Err(not_kept(meta, "kept its mesh, but the store has lost it"));
    };
    super::ops::blocking(move || decode(&bytes, &opts)).await
}
