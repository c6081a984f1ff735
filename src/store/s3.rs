//! The S3 store: one bucket (and a prefix in it) shared by every replica, through the
//! `object_store` crate (SigV4, retries with backoff, paged listing). Under the prefix:
//!
//! - `volumes/{id}.vxl`: the data, one PUT;
//! - `volumes/{id}.json`: the metadata, one PUT after the data: the commit point. A volume
//!   exists when its metadata object does, so an interrupted put leaves nothing listed;
//! - `volumes/{id}.reserve-{bytes}`: an empty object holding a put's room while it runs;
//! - `jobs/{id}.json`: job records; `uploads/{id}`: the meshes of queued jobs;
//! - `probes/{instance}`: the health probe of one process (written and removed).
//!
//! Reads are checked like the directory store's: the bytes against the metadata's length and
//! sha256 (`read`), or as they stream ([`super::verified`]). A delete removes the metadata
//! first. Objects of uncommitted ids older than [`ORPHAN_AGE`] (an interrupted put; far longer
//! than any put in progress on another replica) are swept at open and every [`SWEEP_EVERY`].
//!
//! **Listing** asks S3 which ids exist (a LIST from `after`, stopped once a page is full, so a
//! page costs one LIST request or so however large the bucket), and reads metadata objects
//! only for ids not seen before: ids are never reused and metadata is never rewritten, so a
//! cache by id is right for every id the LIST still shows. `get` always reads the metadata
//! object, so a volume deleted on another replica is gone here too.
//!
//! **Quota** (`--max-store-bytes`) counts every object under `volumes/`: data, metadata and
//! leftovers not yet swept, summed from a LIST. A put is checked twice. First against a recent
//! sum ([`USAGE_TTL`]) plus this process's puts in flight: a refusal without a request while
//! the store is plainly full. Then across replicas ([`Shared::admit`]): the put writes its
//! reservation object, lists `volumes/`, and goes on only if everything there (each other
//! put in flight counted at its reservation) plus its own data and metadata fits. S3 is
//! strongly consistent (a LIST shows every PUT that finished before it), so of two puts that
//! check at once the later to finish writing its reservation sees the other's: two puts that
//! together do not fit are never both admitted, whatever the number of replicas. Both may be
//! refused; when what is stored leaves room that is contention, and the put tries again after
//! a random pause, a few times, before it answers `Full`. The cost: a PUT, a DELETE and a LIST
//! of `volumes/` (one request per 1,000 objects) per put.
//!
//! Errors: an unreachable store, a timeout or a 5xx (after the bounded retries of
//! [`retry_config`]) is [`StoreError::Io`], which the service answers with `503
//! storage-unavailable`; refused credentials say so, naming the bucket. [`S3Store::open`]
//! writes a probe object and lists the prefix, so `voxd serve` does not start on a bucket it
//! cannot use. Credentials are read by `object_store` from the environment and never logged
//! nor shown: errors name the bucket, the endpoint and the key, not the credentials.

use std::collections::HashMap;
use std::sync::{Arc, Mutex, Weak};
use std::time::{Duration, Instant};

use async_trait::async_trait;
use bytes::Bytes;
use futures_util::{StreamExt, TryStreamExt};
use object_store::aws::{AmazonS3, AmazonS3ConfigKey};
use object_store::path::Path;
use object_store::{ClientConfigKey, ObjectStore, ObjectStoreExt, PutPayload};

mod connect;
mod quota;
mod sources;

pub use connect::{Location, retry_config};
use connect::{builder, endpoint_of, instance_name};

use super::fault;
use super::{
    ByteStream, StoreError, Usage, VolumeMeta, VolumeStore, Vxl, check, check_put, safe_id,
    verified,
};

/// How long a successful write vouches for the store's health (as the directory store's).
const HEALTH_TTL: Duration = Duration::from_secs(30);
/// How old a usage sum may be for the first (cheap) quota check of a put and for `usage`.
pub const USAGE_TTL: Duration = Duration::from_secs(5);
/// Objects of an uncommitted id younger than this may be a put in progress: never swept.
pub const ORPHAN_AGE: Duration = Duration::from_secs(3600);
/// How often leftovers are swept while serving.
pub const SWEEP_EVERY: Duration = Duration::from_secs(15 * 60);
/// Metadata objects read at once (listing, job records).
const READ_CONCURRENCY: usize = 16;
/// Metadata kept in memory at most (then the cache starts again).
const CACHE_ENTRIES: usize = 1 << 16;

pub struct S3Store {
    shared: Arc<Shared>,
}

struct Shared {
    /// Requests with a bounded total time.
    client: AmazonS3,
    /// Streamed downloads: no total time (a slow reader may take long), an idle-read limit.
    streamer: AmazonS3,
    loc: Location,
    /// Where requests go, for messages.
    endpoint: String,
    limit: u64,
    probe: Path,
    state: Mutex<State>,
}

#[derive(Default)]
struct State {
    /// Metadata by id (ids are never reused, metadata never rewritten).
    metas: HashMap<String, Arc<VolumeMeta>>,
    /// The last sum of the objects under `volumes/`.
    usage: Option<Snapshot>,
    /// Bytes of this process's puts between their first check and their end.
    reserved: u64,
    last_ok_write: Option<Instant>,
    last_write_failed: bool,
}

#[derive(Clone, Copy)]
struct Snapshot {
    at: Instant,
    bytes: u64,
    volumes: u64,
}

/// `PREFIX/rest` as an object key.
fn key_in(prefix: &str, rest: &str) -> Path {
    if prefix.is_empty() {
        Path::from(rest)
    } else {
        Path::from(format!("{prefix}/{rest}"))
    }
}

/// A listed object's key under `volumes/` as (id, is it the metadata).
fn volume_object(location: &Path) -> Option<(&str, bool)> {
    let name = location.filename()?;
    Some(match name.rsplit_once('.') {
        Some((id, "json")) => (id, true),
        Some((id, _)) => (id, false),
        None => (name, false),
    })
}

impl S3Store {
    /// Connects to `loc` with the environment's credentials and endpoint, checks that the
    /// bucket takes writes and lists (a probe object is written and removed, then `volumes/`
    /// is listed to sweep leftovers) and starts the periodic sweep, which ends with the store.
    /// Wrong credentials, a missing bucket or an unreachable endpoint are an error naming the
    /// bucket. Call it on a tokio runtime.
    pub async fn open(loc: &Location, limit: u64) -> Result<S3Store, StoreError> {
        let vars = std::env::vars_os()
            .filter_map(|(k, v)| Some((k.into_string().ok()?, v.into_string().ok()?)))
            .filter(|(k, _)| k.starts_with("AWS_"))
            .collect();
        S3Store::open_with(loc, limit, vars).await
    }

    /// [`S3Store::open`] configured from `vars` (`AWS_*` names and values) instead of the
    /// process's environment.
    pub async fn open_with(
        loc: &Location,
        limit: u64,
        vars: Vec<(String, String)>,
    ) -> Result<S3Store, StoreError> {
        let endpoint = endpoint_of(&vars);
        let shown = endpoint.clone().unwrap_or_else(|| "AWS".into());
        let fail = |e: object_store::Error| {
            StoreError::Io(std::io::Error::other(format!(
                "S3 bucket {:?} (endpoint {shown}): cannot configure the client: {e}",
                loc.bucket
            )))
        };
        let client = builder(loc, &vars, endpoint.as_deref())
            .with_config(AmazonS3ConfigKey::Client(ClientConfigKey::Timeout), "120s")
            .build()
            .map_err(fail)?;
        let streamer = builder(loc, &vars, endpoint.as_deref())
            .with_config(
                AmazonS3ConfigKey::Client(ClientConfigKey::ReadTimeout),
                "60s",
            )
            .build()
            .map_err(fail)?;
        let shared = Arc::new(Shared {
            client,
            streamer,
            probe: key_in(&loc.prefix, &format!("probes/{}", instance_name())),
            loc: loc.clone(),
            endpoint: shown,
            limit,
            state: Mutex::new(State::default()),
        });
        shared.probe().await?;
        let swept = shared.sweep(ORPHAN_AGE).await?;
        let store = S3Store { shared };
        tracing::info!(store = %store.describe(), swept, "store opened");
        tokio::spawn(sweep_periodically(Arc::downgrade(&store.shared)));
        Ok(store)
    }

    /// Removes data objects without metadata older than `age` (left by an interrupted put);
    /// how many. `open` and a periodic task call it with [`ORPHAN_AGE`]; tests with less.
    pub async fn sweep(&self, age: Duration) -> Result<usize, StoreError> {
        self.shared.sweep(age).await
    }
}

async fn sweep_periodically(store: Weak<Shared>) {
    loop {
        tokio::time::sleep(SWEEP_EVERY).await;
        let Some(s) = store.upgrade() else { return };
        if let Err(e) = s.sweep(ORPHAN_AGE).await {
            tracing::warn!("sweeping leftovers: {e}");
        }
    }
}

impl Shared {
    fn lock(&self) -> std::sync::MutexGuard<'_, State> {
        // Every update is one statement: a poisoned lock holds consistent data.
        self.state.lock().unwrap_or_else(|p| p.into_inner())
    }

    fn key(&self, rest: &str) -> Path {
        key_in(&self.loc.prefix, rest)
    }

    fn meta_key(&self, id: &str) -> Path {
        self.key(&format!("volumes/{id}.json"))
    }

    fn data_key(&self, id: &str) -> Path {
        self.key(&format!("volumes/{id}.vxl"))
    }

    /// An `object_store` error as a store error naming the bucket and what was being done.
    fn err(&self, doing: &str, e: object_store::Error) -> StoreError {
        use object_store::Error as E;
        let b = &self.loc.bucket;
        let (kind, msg) = match &e {
            E::Unauthenticated { .. } | E::PermissionDenied { .. } => (
                std::io::ErrorKind::PermissionDenied,
                format!(
                    "S3 bucket {b:?} at {}: {doing}: the credentials were refused: {e}; check AWS_ACCESS_KEY_ID, AWS_SECRET_ACCESS_KEY and the bucket's policy",
                    self.endpoint
                ),
            ),
            E::NotFound { .. } => (
                std::io::ErrorKind::NotFound,
                format!(
                    "S3 bucket {b:?} at {}: {doing}: not found: {e}; does the bucket exist?",
                    self.endpoint
                ),
            ),
            _ => (
                std::io::ErrorKind::Other,
                format!("S3 bucket {b:?} at {}: {doing}: {e}", self.endpoint),
            ),
        };
        StoreError::Io(std::io::Error::new(kind, msg))
    }

    fn note_write(&self, ok: bool) {
        let mut s = self.lock();
        s.last_write_failed = !ok;
        if ok {
            s.last_ok_write = Some(Instant::now());
        }
    }

    /// A PUT (whole object, replacing); it counts for health.
    async fn put_object(&self, doing: &str, key: &Path, bytes: Bytes) -> Result<(), StoreError> {
        let r = self.client.put(key, PutPayload::from(bytes)).await;
        self.note_write(r.is_ok());
        r.map(|_| ()).map_err(|e| self.err(doing, e))
    }

    /// A GET of a whole (small) object; `None` when there is none.
    async fn get_object(&self, doing: &str, key: &Path) -> Result<Option<Bytes>, StoreError> {
        let got = match self.client.get(key).await {
            Ok(g) => g.bytes().await,
            Err(e) => Err(e),
        };
        match got {
            Ok(b) => Ok(Some(b)),
            Err(object_store::Error::NotFound { .. }) => Ok(None),
            Err(e) => Err(self.err(doing, e)),
        }
    }

    /// Does the object exist?
    async fn exists(&self, doing: &str, key: &Path) -> Result<bool, StoreError> {
        match self.client.head(key).await {
            Ok(_) => Ok(true),
            Err(object_store::Error::NotFound { .. }) => Ok(false),
            Err(e) => Err(self.err(doing, e)),
        }
    }

    /// A DELETE (none there is not an error); it counts for health.
    async fn delete_object(&self, doing: &str, key: &Path) -> Result<(), StoreError> {
        let r = match self.client.delete(key).await {
            Err(object_store::Error::NotFound { .. }) => Ok(()),
            r => r,
        };
        self.note_write(r.is_ok());
        r.map_err(|e| self.err(doing, e))
    }

    /// Writes and removes this process's probe object.
    async fn probe(&self) -> Result<(), StoreError> {
        let doing = "writing a probe object";
        self.put_object(doing, &self.probe, Bytes::from_static(b"voxd"))
            .await?;
        self.delete_object(doing, &self.probe).await
    }

    /// The metadata of volume `id`, read from its object (and kept in the cache).
    async fn read_meta(&self, id: &str) -> Result<Option<Arc<VolumeMeta>>, StoreError> {
        if !safe_id(id) {
            return Ok(None);
        }
        let doing = format!("reading volume {id}'s metadata");
        let Some(bytes) = self.get_object(&doing, &self.meta_key(id)).await? else {
            self.lock().metas.remove(id);
            return Ok(None);
        };
        let meta: VolumeMeta = serde_json::from_slice(&bytes).map_err(|e| {
            StoreError::Corrupt(format!(
                "volume {id}: its metadata object is unreadable: {e}"
            ))
        })?;
        if meta.id != id {
            return Err(StoreError::Corrupt(format!(
                "volume {id}: its metadata object describes volume {:?}",
                meta.id
            )));
        }
        let meta = Arc::new(meta);
        let mut s = self.lock();
        if s.metas.len() >= CACHE_ENTRIES {
            s.metas.clear();
        }
        s.metas.insert(id.to_string(), meta.clone());
        Ok(Some(meta))
    }

    /// Metadata of a listed id: from the cache, else from its object (`None`: deleted since).
    async fn listed_meta(&self, id: String) -> Result<Option<Arc<VolumeMeta>>, StoreError> {
        let cached = self.lock().metas.get(&id).cloned();
        match cached {
            Some(m) => Ok(Some(m)),
            None => self.read_meta(&id).await,
        }
    }

    /// Sums the objects under `volumes/` (a fresh LIST) and keeps the sum.
    async fn fresh_usage(&self) -> Result<Snapshot, StoreError> {
        let at = Instant::now();
        let mut stream = self.client.list(Some(&self.key("volumes")));
        let (mut bytes, mut volumes) = (0, 0);
        while let Some(o) = stream.next().await {
            let o = o.map_err(|e| self.err("listing volumes", e))?;
            bytes += o.size;
            volumes += u64::from(volume_object(&o.location).is_some_and(|(_, meta)| meta));
        }
        let snap = Snapshot { at, bytes, volumes };
        self.lock().usage = Some(snap);
        Ok(snap)
    }

    /// The kept sum while it is recent, else a fresh one.
    async fn recent_usage(&self) -> Result<Snapshot, StoreError> {
        let kept = self.lock().usage.filter(|s| s.at.elapsed() < USAGE_TTL);
        match kept {
            Some(s) => Ok(s),
            None => self.fresh_usage().await,
        }
    }

    /// The put after its first check: admission, the data, the commit.
    async fn put_reserved(
        &self,
        meta: &VolumeMeta,
        vxl: Bytes,
        json: Bytes,
    ) -> Result<(), StoreError> {
        let id = &meta.id;
        let need = (vxl.len() + json.len()) as u64;
        let marker = self.admit(id, need).await?;
        let (data_key, meta_key) = (self.data_key(id), self.meta_key(id));
        let doing = format!("writing volume {id}'s data");
        if fault::fires(fault::Site::MidData) {
            // A torn data object: the worst an interrupted put could leave, were S3's PUT not
            // atomic (it is).
            let _ = self
                .put_object(&doing, &data_key, vxl.slice(..vxl.len() / 2))
                .await;
            fault::abort(fault::Site::MidData);
        }
        // A volume that keeps its mesh says so before its data (`sources.rs`).
        let source_marker = meta
            .source
            .kept
            .then(|| self.marker_key(&meta.source.sha256, id));
        let committed = async {
            if let Some(m) = &source_marker {
                self.put_object(&doing, m, Bytes::new()).await?;
            }
            self.put_object(&doing, &data_key, vxl).await?;
            fault::point(fault::Site::AfterData);
            self.put_object(&format!("committing volume {id}"), &meta_key, json)
                .await
        }
        .await;
        if committed.is_err() {
            // Undo what may have been written, metadata first (the commit may have landed with
            // its answer lost): while the metadata might still be there its data stays, so a
            // listed volume is never left without data. What cannot be removed now is swept.
            if self.delete_object(&doing, &meta_key).await.is_ok() {
                let _ = self.delete_object(&doing, &data_key).await;
                if let Some(m) = &source_marker {
                    let _ = self.delete_object(&doing, m).await;
                }
            }
            let _ = self.delete_object(&doing, &marker).await;
            return committed;
        }
        fault::point(fault::Site::AfterCommit);
        if let Err(e) = self.delete_object(&doing, &marker).await {
            tracing::warn!("{e} (the sweep removes the reservation later)");
        }
        let mut s = self.lock();
        s.usage = None;
        if s.metas.len() >= CACHE_ENTRIES {
            s.metas.clear();
        }
        s.metas.insert(id.clone(), Arc::new(meta.clone()));
        Ok(())
    }
}

/// Runs CPU work (hashing a volume) off the async runtime.
async fn blocking<T: Send + 'static>(
    f: impl FnOnce() -> Result<T, StoreError> + Send + 'static,
) -> Result<T, StoreError> {
    tokio::task::spawn_blocking(f)
        .await
        .map_err(|e| StoreError::Io(std::io::Error::other(e)))?
}

fn bad_id(what: &str, id: &str) -> StoreError {
    StoreError::Corrupt(format!("bad {what} id {id:?}"))
}

#[async_trait]
impl VolumeStore for S3Store {
    async fn put(&self, meta: VolumeMeta, vxl: Vxl) -> Result<(), StoreError> {
        let s = &self.shared;
        if !safe_id(&meta.id) {
            return Err(bad_id("volume", &meta.id));
        }
        check_put(&meta, &vxl)?;
        let vxl = vxl.into_bytes();
        let json = Bytes::from(serde_json::to_vec_pretty(&meta).expect("metadata serialises"));
        let need = (vxl.len() + json.len()) as u64;
        s.reserve(need).await?;
        let r = s.put_reserved(&meta, vxl, json).await;
        s.lock().reserved -= need;
        r
    }

    async fn get(&self, id: &str) -> Result<Option<VolumeMeta>, StoreError> {
        Ok(self.shared.read_meta(id).await?.map(|m| (*m).clone()))
    }

    async fn read(&self, id: &str) -> Result<Option<Bytes>, StoreError> {
        let s = &self.shared;
        let Some(meta) = s.read_meta(id).await? else {
            return Ok(None);
        };
        let doing = format!("reading volume {id}'s data");
        let Some(bytes) = s.get_object(&doing, &s.data_key(id)).await? else {
            return missing(s, id).await;
        };
        let checked = bytes.clone();
        blocking(move || check(&meta.id, &checked, &meta))
            .await
            .inspect_err(|e| tracing::error!("{e}"))?;
        Ok(Some(bytes))
    }

    async fn read_stream(&self, id: &str) -> Result<Option<ByteStream>, StoreError> {
        let s = &self.shared;
        let Some(meta) = s.read_meta(id).await? else {
            return Ok(None);
        };
        let got = match s.streamer.get(&s.data_key(id)).await {
            Ok(g) => g,
            Err(object_store::Error::NotFound { .. }) => {
                return missing::<ByteStream>(s, id).await;
            }
            Err(e) => return Err(s.err(&format!("reading volume {id}'s data"), e)),
        };
        if got.meta.size != meta.bytes {
            let e = StoreError::Corrupt(format!(
                "volume {id}: the data is {} bytes but its metadata says {} (a torn or damaged object)",
                got.meta.size, meta.bytes
            ));
            tracing::error!("{e}");
            return Err(e);
        }
        let shared = s.clone();
        let doing = format!("reading volume {id}'s data");
        let chunks = got.into_stream().map_err(move |e| shared.err(&doing, e));
        Ok(Some(verified(&meta, chunks)))
    }

    async fn list(
        &self,
        after: Option<&str>,
        limit: usize,
    ) -> Result<(Vec<VolumeMeta>, bool), StoreError> {
        let s = &self.shared;
        let prefix = s.key("volumes");
        // Every id after `after` has a key after `volumes/{after}` (ids are [A-Za-z0-9-]).
        // Keys come in byte order, which is id order for ids of one length (voxd's: 16 hex
        // digits); the page is sorted by id all the same.
        let mut stream = match after {
            Some(a) => s
                .client
                .list_with_offset(Some(&prefix), &s.key(&format!("volumes/{a}"))),
            None => s.client.list(Some(&prefix)),
        };
        let mut ids = vec![];
        while ids.len() <= limit {
            let Some(o) = stream.next().await else { break };
            let o = o.map_err(|e| s.err("listing volumes", e))?;
            if let Some((id, true)) = volume_object(&o.location)
                && after.is_none_or(|a| id > a)
                && safe_id(id)
            {
                ids.push(id.to_string());
            }
        }
        drop(stream);
        let more = ids.len() > limit;
        ids.truncate(limit);
        let metas: Vec<Option<Arc<VolumeMeta>>> = futures_util::stream::iter(ids)
            .map(|id| s.listed_meta(id))
            .buffered(READ_CONCURRENCY)
            .try_collect()
            .await?;
        let mut page: Vec<VolumeMeta> = metas.into_iter().flatten().map(|m| (*m).clone()).collect();
        page.sort_by(|a, b| a.id.cmp(&b.id));
        Ok((page, more))
    }

    async fn delete(&self, id: &str) -> Result<bool, StoreError> {
        let s = &self.shared;
        if !safe_id(id) {
            return Ok(false);
        }
        let meta_key = s.meta_key(id);
        // The metadata says whether a source marker goes with it. Unreadable metadata is
        // deleted all the same (a marker it may have had is removed as dead when next met).
        let meta = match s.read_meta(id).await {
            Ok(Some(m)) => Some(m),
            Ok(None) => return Ok(false),
            Err(StoreError::Corrupt(e)) => {
                tracing::warn!("deleting volume {id}, whose metadata is unreadable: {e}");
                None
            }
            Err(e) => return Err(e),
        };
        // Metadata first: once it is gone the volume is gone, whatever happens next.
        s.delete_object(&format!("deleting volume {id}"), &meta_key)
            .await?;
        {
            let mut st = s.lock();
            st.metas.remove(id);
            st.usage = None;
        }
        if let Err(e) = s
            .delete_object(&format!("deleting volume {id}'s data"), &s.data_key(id))
            .await
        {
            // Unlisted already; the sweep removes the data later.
            tracing::warn!("{e}");
        }
        if let Some(meta) = meta.filter(|m| m.source.kept)
            && let Err(e) = s
                .delete_object(
                    &format!("deleting volume {id}'s source marker"),
                    &s.marker_key(&meta.source.sha256, id),
                )
                .await
        {
            // Its volume is gone: whoever next asks whether the source is referred removes it.
            tracing::warn!("{e}");
        }
        Ok(true)
    }

    async fn usage(&self) -> Result<Usage, StoreError> {
        let s = &self.shared;
        let snap = s.recent_usage().await?;
        Ok(Usage {
            bytes: snap.bytes,
            volumes: snap.volumes,
            limit: s.limit,
        })
    }

    /// Healthy when a write succeeded within the last 30 s and the last write did not fail;
    /// otherwise the probe object is written and removed (an idle store is probed at most
    /// twice a minute, not on every readiness check).
    async fn health(&self) -> Result<(), StoreError> {
        let s = &self.shared;
        {
            let st = s.lock();
            if !st.last_write_failed && st.last_ok_write.is_some_and(|t| t.elapsed() < HEALTH_TTL) {
                return Ok(());
            }
        }
        s.probe().await
    }

    async fn put_job_record(&self, id: &str, record: Bytes) -> Result<(), StoreError> {
        let s = &self.shared;
        if !safe_id(id) {
            return Err(bad_id("job", id));
        }
        // An S3 PUT is atomic: an interrupted one leaves nothing, as if aborted before it.
        fault::point(fault::Site::MidJobRecord);
        s.put_object(
            &format!("writing job {id}'s record"),
            &s.key(&format!("jobs/{id}.json")),
            record,
        )
        .await
    }

    async fn delete_job_record(&self, id: &str) -> Result<(), StoreError> {
        let s = &self.shared;
        if !safe_id(id) {
            return Ok(());
        }
        s.delete_object(
            &format!("removing job {id}'s record"),
            &s.key(&format!("jobs/{id}.json")),
        )
        .await
    }

    async fn job_records(&self) -> Result<Vec<Bytes>, StoreError> {
        let s = &self.shared;
        let keys: Vec<Path> = s
            .client
            .list(Some(&s.key("jobs")))
            .map_ok(|o| o.location)
            .try_collect()
            .await
            .map_err(|e| s.err("listing job records", e))?;
        let records: Vec<Option<Bytes>> = futures_util::stream::iter(keys)
            .map(|k| async move { s.get_object("reading a job record", &k).await })
            .buffered(READ_CONCURRENCY)
            .try_collect()
            .await?;
        // A record removed since the listing is simply not there.
        Ok(records.into_iter().flatten().collect())
    }

    async fn put_source(&self, key: &str, bytes: Bytes) -> Result<(), StoreError> {
        self.shared.put_source(key, bytes).await
    }

    async fn get_source(&self, key: &str) -> Result<Option<Bytes>, StoreError> {
        self.shared.get_source(key).await
    }

    async fn delete_source(&self, key: &str) -> Result<(), StoreError> {
        self.shared.delete_source(key).await
    }

    async fn source_referred(&self, key: &str) -> Result<bool, StoreError> {
        self.shared.source_referred(key).await
    }

    async fn list_sources(&self) -> Result<Vec<(String, std::time::SystemTime)>, StoreError> {
        self.shared.list_sources().await
    }

    async fn put_upload(&self, id: &str, bytes: Bytes) -> Result<(), StoreError> {
        let s = &self.shared;
        if !safe_id(id) {
            return Err(bad_id("job", id));
        }
        s.put_object(
            &format!("keeping job {id}'s upload"),
            &s.key(&format!("uploads/{id}")),
            bytes,
        )
        .await
    }

    async fn get_upload(&self, id: &str) -> Result<Option<Bytes>, StoreError> {
        let s = &self.shared;
        if !safe_id(id) {
            return Ok(None);
        }
        s.get_object(
            &format!("reading job {id}'s upload"),
            &s.key(&format!("uploads/{id}")),
        )
        .await
    }

    async fn delete_upload(&self, id: &str) -> Result<(), StoreError> {
        let s = &self.shared;
        if !safe_id(id) {
            return Ok(());
        }
        s.delete_object(
            &format!("removing job {id}'s upload"),
            &s.key(&format!("uploads/{id}")),
        )
        .await
    }

    async fn list_uploads(&self) -> Result<Vec<(String, std::time::SystemTime)>, StoreError> {
        let s = &self.shared;
        s.client
            .list(Some(&s.key("uploads")))
            .try_filter_map(|o| async move {
                let id = o.location.filename().filter(|id| safe_id(id));
                Ok(id.map(|id| (id.to_string(), std::time::SystemTime::from(o.last_modified))))
            })
            .try_collect()
            .await
            .map_err(|e| s.err("listing uploads", e))
    }

    fn describe(&self) -> String {
        format!("{} at {}", self.shared.loc, self.shared.endpoint)
    }
}

/// A listed volume whose data object is missing: lost (`Corrupt`), unless its metadata went
/// too (deleted meanwhile: `None`).
async fn missing<T>(s: &Shared, id: &str) -> Result<Option<T>, StoreError> {
    if !s
        .exists(&format!("reading volume {id}"), &s.meta_key(id))
        .await?
    {
        return Ok(None);
    }
    let e = StoreError::Corrupt(format!(
        "volume {id}: its data object volumes/{id}.vxl is missing"
    ));
    tracing::error!("{e}");
    Err(e)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn locations_parse() {
        let l = Location::parse("bucket/some/prefix/").unwrap();
        assert_eq!(
            (l.bucket.as_str(), l.prefix.as_str()),
            ("bucket", "some/prefix")
        );
        assert_eq!(l.to_string(), "s3://bucket/some/prefix");
        let l = Location::parse("b-1.x").unwrap();
        assert_eq!((l.bucket.as_str(), l.prefix.as_str()), ("b-1.x", ""));
        for bad in ["", "/p", "bu cket/p", "b/../x", "b/a//c", &"x".repeat(64)] {
            assert!(Location::parse(bad).is_err(), "{bad:?}");
        }
        assert_eq!(key_in("", "volumes/a.json").as_ref(), "volumes/a.json");
        assert_eq!(
            key_in("p/q", "volumes/a.json").as_ref(),
            "p/q/volumes/a.json"
        );
        assert_eq!(
            volume_object(&Path::from("p/volumes/ab12.json")),
            Some(("ab12", true))
        );
        assert_eq!(
            volume_object(&Path::from("p/volumes/ab12.vxl")),
            Some(("ab12", false))
        );
    }
}
