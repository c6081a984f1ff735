//! The S3 store's quota across replicas (reservation objects and a LIST, see the module
//! documentation of [`super`]) and the sweep of what interrupted puts leave.

use std::collections::{BTreeSet, HashMap};
use std::time::Duration;

use bytes::Bytes;
use futures_util::StreamExt;
use object_store::ObjectStore;
use object_store::path::Path;

use super::{Shared, volume_object};
use crate::store::StoreError;

impl Shared {
    /// Removes what interrupted puts left: every object of an uncommitted id older than `age`
    /// (data, a reservation), and the reservations of committed ids. How many objects.
    pub(super) async fn sweep(&self, age: Duration) -> Result<usize, StoreError> {
        let now = std::time::SystemTime::now();
        let mut committed = BTreeSet::new();
        let mut others = vec![];
        let mut stream = self.client.list(Some(&self.key("volumes")));
        while let Some(o) = stream.next().await {
            let o = o.map_err(|e| self.err("listing volumes", e))?;
            let Some((id, is_meta)) = volume_object(&o.location) else {
                continue;
            };
            // A source's objects are the application's to remove (its reservation: below).
            if id.starts_with(super::sources::GROUP) && reservation_of(&o.location).is_none() {
                continue;
            }
            if is_meta {
                committed.insert(id.to_string());
            } else {
                // Clock skew between here and the server only shifts the age a little: the
                // margin (an hour) is far larger.
                let modified = std::time::SystemTime::from(o.last_modified);
                let old = now.duration_since(modified).unwrap_or(Duration::ZERO);
                let reservation = reservation_of(&o.location).is_some();
                others.push((id.to_string(), old, reservation, o.location));
            }
        }
        let mut swept = 0;
        for (id, old, reservation, location) in others {
            // The listing goes in key order, `{id}.json` first: a put that committed while it
            // ran may look uncommitted here, but its objects are young.
            let leftover = if committed.contains(&id) {
                reservation
            } else {
                old >= age
            };
            if !leftover {
                continue;
            }
            tracing::warn!(object = %location, "removing what an interrupted put left");
            self.delete_object("removing a leftover", &location).await?;
            swept += 1;
        }
        if swept > 0 {
            self.lock().usage = None;
        }
        Ok(swept)
    }

    /// The quota's first check, and this process's reservation: refused when the recent sum,
    /// this process's other puts in flight and this one do not fit. Cheap (no request while
    /// the sum is recent); the check that holds across replicas is [`Shared::admit`].
    pub(super) async fn reserve(&self, need: u64) -> Result<(), StoreError> {
        let snap = self.recent_usage().await?;
        let mut s = self.lock();
        let used = snap.bytes + s.reserved;
        if used + need > self.limit {
            return Err(StoreError::Full {
                need,
                used,
                limit: self.limit,
            });
        }
        s.reserved += need;
        Ok(())
    }

    /// What `volumes/` holds for ids other than `id`: (everything: each id counted at the
    /// larger of its objects' sizes and its reservation; the objects alone).
    async fn tally(&self, id: &str) -> Result<(u64, u64), StoreError> {
        let mut per_id: HashMap<String, (u64, u64)> = HashMap::new();
        let mut stream = self.client.list(Some(&self.key("volumes")));
        while let Some(o) = stream.next().await {
            let o = o.map_err(|e| self.err("listing volumes", e))?;
            let Some((other, _)) = volume_object(&o.location) else {
                continue;
            };
            if other == id {
                continue;
            }
            let e = per_id.entry(other.to_string()).or_default();
            e.0 += o.size;
            e.1 = e.1.max(reservation_of(&o.location).unwrap_or(0));
        }
        let objects = per_id.values().map(|e| e.0).sum();
        let all = per_id.values().map(|e| e.0.max(e.1)).sum();
        Ok((all, objects))
    }

    /// The quota check that holds across replicas. A reservation object
    /// `volumes/{id}.reserve-{need}` (empty; its name says how much) is written, then
    /// `volumes/` is listed: everything there, with other puts' reservations, plus `need` must
    /// fit. S3 is strongly consistent, so of two puts checking at once the later to finish
    /// writing its reservation sees the other's: they cannot both pass when together they do
    /// not fit. They may both be refused: when what is committed leaves room, that is
    /// contention, and the put tries again after a random pause (a few times, then gives up
    /// with `Full`). The reservation stays until the volume is committed.
    pub(super) async fn admit(&self, id: &str, need: u64) -> Result<Path, StoreError> {
        let marker = self.key(&format!("volumes/{id}.reserve-{need}"));
        let doing = format!("reserving room for volume {id}");
        let mut attempt = 0;
        loop {
            self.put_object(&doing, &marker, Bytes::new()).await?;
            let tally = self.tally(id).await;
            let (all, objects) = match tally {
                Ok(t) => t,
                Err(e) => {
                    let _ = self.delete_object(&doing, &marker).await;
                    return Err(e);
                }
            };
            if all + need <= self.limit {
                return Ok(marker);
            }
            self.delete_object(&doing, &marker).await?;
            if objects + need > self.limit || attempt == ADMIT_ATTEMPTS {
                return Err(StoreError::Full {
                    need,
                    used: all,
                    limit: self.limit,
                });
            }
            attempt += 1;
            tokio::time::sleep(jitter(attempt)).await;
        }
    }
}

/// How many times a put refused by contention (not by what is stored) tries again.
const ADMIT_ATTEMPTS: u32 = 6;

/// A random pause before admission attempt `n` (from 1): up to 25 ms · 2ⁿ.
fn jitter(n: u32) -> Duration {
    use std::hash::{BuildHasher, Hasher};
    let mut h = std::collections::hash_map::RandomState::new().build_hasher();
    h.write_u32(n);
    let cap = 25u64 << n.min(8);
    Duration::from_millis(h.finish() % cap.max(1))
}

/// The bytes a reservation object (`{id}.reserve-{need}`) stands for.
fn reservation_of(location: &Path) -> Option<u64> {
    location
        .filename()?
        .rsplit_once(".reserve-")?
        .1
        .parse()
        .ok()
}
