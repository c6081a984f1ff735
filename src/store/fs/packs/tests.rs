//! The packs' tests: records written, read back, torn, compacted, and a store reopened on
//! them.

use super::*;
use crate::store::fs::FsStore;
use crate::store::fs::tests::{meta, scratch};
use crate::store::{VolumeStore, Vxl};

/// Volume `n`'s bytes: `len` bytes that differ from every other volume's.
fn bytes(n: usize, len: usize) -> Vec<u8> {
    (0..len).map(|k| (k * 31 + n * 7 + k / 251) as u8).collect()
}

/// A store on `dir` given volumes `v0`.. of `lens` bytes, then closed: the volumes, and
/// the one pack's path and length.
async fn stored(dir: &Path, lens: &[usize]) -> (BTreeMap<String, Vec<u8>>, PathBuf, u64) {
    let mut want = BTreeMap::new();
    let store = FsStore::open(dir, 1 << 30).unwrap();
    for (n, &len) in lens.iter().enumerate() {
        let (id, data) = (format!("v{n}"), bytes(n, len));
        store
            .put(meta(&id, &data), Vxl::from(data.clone()))
            .await
            .unwrap();
        want.insert(id, data);
    }
    drop(store);
    let (name, whole) = pack_files(dir).into_iter().next().unwrap();
    (want, dir.join("volumes").join(name), whole)
}

/// Pack files of `dir/volumes`: name → length.
fn pack_files(dir: &Path) -> BTreeMap<String, u64> {
    std::fs::read_dir(dir.join("volumes"))
        .unwrap()
        .map(|e| e.unwrap())
        .filter(|e| e.file_name().to_string_lossy().ends_with(".pack"))
        .map(|e| {
            let n = e.file_name().to_string_lossy().into_owned();
            (n, e.metadata().unwrap().len())
        })
        .collect()
}

/// Every volume in `want` reads back whole from `store`, and nothing else is listed.
async fn holds(store: &FsStore, want: &BTreeMap<String, Vec<u8>>) {
    let listed: Vec<String> = store
        .list(None, 10_000)
        .await
        .unwrap()
        .0
        .into_iter()
        .map(|m| m.id)
        .collect();
    assert_eq!(listed, want.keys().cloned().collect::<Vec<_>>());
    for (id, data) in want {
        assert_eq!(
            &store.read(id).await.unwrap().unwrap()[..],
            &data[..],
            "{id}"
        );
        let mut s = store.read_stream(id).await.unwrap().unwrap();
        let mut got = vec![];
        while let Some(c) = futures_util::StreamExt::next(&mut s).await {
            got.extend_from_slice(&c.unwrap());
        }
        assert_eq!(got, *data, "{id} streamed");
    }
}

/// Small volumes go to one pack (no file of their own), large ones to their own files;
/// after removals and a reopen the same volumes are there, the removed ones stay removed,
/// and the quota counts each pack record's bytes.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn small_volumes_share_a_pack_and_survive_reopening() {
    let dir = scratch("basic");
    let store = std::sync::Arc::new(FsStore::open(&dir, 1 << 30).unwrap());
    let mut want = BTreeMap::new();
    let mut puts = vec![];
    for n in 0..40 {
        // Volume 7 is too large for a pack.
        let len = if n == 7 {
            RECORD_MAX as usize
        } else {
            100 + 37 * n
        };
        let data = bytes(n, len);
        let id = format!("v{n:03}");
        want.insert(id.clone(), data.clone());
        let s = store.clone();
        puts.push(tokio::spawn(async move {
            s.put(meta(&id, &data), Vxl::from(data)).await
        }));
    }
    for p in puts {
        p.await.unwrap().unwrap();
    }
    let names: Vec<String> = std::fs::read_dir(dir.join("volumes"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    let mut own: Vec<&String> = names.iter().filter(|n| n.starts_with('v')).collect();
    own.sort();
    assert_eq!(
        own,
        ["v007.json", "v007.vxl"],
        "only the large volume has files"
    );
    assert_eq!(pack_files(&dir).len(), 1);
    holds(&store, &want).await;
    for n in [3, 7, 20, 39] {
        let id = format!("v{n:03}");
        assert!(store.delete(&id).await.unwrap());
        assert!(!store.delete(&id).await.unwrap());
        want.remove(&id);
    }
    holds(&store, &want).await;
    let usage = store.usage().await.unwrap();
    drop(store);
    let again = FsStore::open(&dir, 1 << 30).unwrap();
    holds(&again, &want).await;
    assert_eq!(again.usage().await.unwrap(), usage);
    // The quota: every live record's bytes (header, id, compact metadata, data).
    let expect: u64 = want
        .iter()
        .map(|(id, d)| {
            let json = serde_json::to_vec(&meta(id, d)).unwrap();
            (HEADER + id.len() + json.len() + d.len()) as u64
        })
        .sum();
    assert_eq!(usage.bytes, expect);
}

/// What a crash leaves at a pack's end (half a record, a record whose length is there but
/// whose bytes are not, garbage) is cut off at open; the whole records stay.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_torn_tail_is_cut_off_at_open() {
    let dir = scratch("torn");
    let (want, path, whole) = stored(&dir, &[1000, 1001, 1002, 1003, 1004]).await;
    let record = |id: &str, data: &[u8]| {
        let mut buf = vec![];
        encode(
            &mut buf,
            PUT,
            id,
            &serde_json::to_vec(&meta(id, data)).unwrap(),
            data,
        );
        buf
    };
    let extra = record("late", &bytes(9, 500));
    let zeroed = {
        // Header and metadata there, the data never written.
        let mut r = record("zeroed", &bytes(8, 700));
        let n = r.len();
        r[n - 700..].fill(0);
        r
    };
    for tail in [
        extra[..extra.len() / 2].to_vec(),
        extra[..HEADER - 3].to_vec(),
        zeroed,
        b"not a record at all, but long enough to be read as a header".to_vec(),
    ] {
        let mut f = OpenOptions::new().append(true).open(&path).unwrap();
        std::io::Write::write_all(&mut f, &tail).unwrap();
        drop(f);
        let store = FsStore::open(&dir, 1 << 30).unwrap();
        assert_eq!(std::fs::metadata(&path).unwrap().len(), whole);
        holds(&store, &want).await;
    }
}

/// A volume damaged after it was stored (its data no longer matches its metadata) and
/// followed by whole ones is not taken for a torn end: it stays listed and its reads say
/// it is damaged; the volumes after it stay.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn damage_inside_a_pack_cuts_nothing_off() {
    let dir = scratch("damaged");
    let (mut want, path, whole) = stored(&dir, &[2000, 2001, 2002, 2003]).await;
    let mut b = std::fs::read(&path).unwrap();
    let at = b
        .windows(want["v1"].len())
        .position(|w| w == &want["v1"][..])
        .unwrap();
    b[at + 100] ^= 1;
    std::fs::write(&path, &b).unwrap();
    let store = FsStore::open(&dir, 1 << 30).unwrap();
    assert_eq!(std::fs::metadata(&path).unwrap().len(), whole);
    assert!(matches!(
        store.read("v1").await,
        Err(StoreError::Corrupt(_))
    ));
    want.remove("v1");
    for (id, data) in &want {
        assert_eq!(
            &store.read(id).await.unwrap().unwrap()[..],
            &data[..],
            "{id}"
        );
    }
    assert_eq!(store.list(None, 10).await.unwrap().0.len(), 4);
}

/// Removing most volumes of a sealed pack compacts it: the live ones move to the newest
/// pack (and read back, also after a reopen), the removed ones stay removed, and the
/// packs' bytes stay within twice the live bytes plus GARBAGE_MIN and a pack.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn compaction_moves_live_volumes_and_bounds_the_garbage() {
    let dir = scratch("compact");
    let store = FsStore::open(&dir, 1 << 32).unwrap();
    let len = 900 << 10;
    let mut want = BTreeMap::new();
    for n in 0..90 {
        let (id, data) = (format!("v{n:03}"), bytes(n, len + n));
        store
            .put(meta(&id, &data), Vxl::from(data.clone()))
            .await
            .unwrap();
        want.insert(id, data);
    }
    let before = pack_files(&dir);
    assert!(before.len() >= 2, "{before:?}");
    let first = before.keys().next().unwrap().clone();
    // Remove all but every tenth volume.
    for n in 0..90 {
        if n % 10 != 0 {
            let id = format!("v{n:03}");
            assert!(store.delete(&id).await.unwrap());
            want.remove(&id);
        }
    }
    let after = pack_files(&dir);
    assert!(
        !after.contains_key(&first),
        "the first pack was compacted: {after:?}"
    );
    let live: u64 = store.usage().await.unwrap().bytes;
    let on_disk: u64 = after.values().sum();
    assert!(
        on_disk <= 2 * live + GARBAGE_MIN + PACK_MAX,
        "{on_disk} bytes of packs for {live} live"
    );
    holds(&store, &want).await;
    drop(store);
    let again = FsStore::open(&dir, 1 << 32).unwrap();
    holds(&again, &want).await;
    assert_eq!(again.usage().await.unwrap().bytes, live);
}

/// Reads running while deletes compact the pack under them each get their whole, right
/// volume (a stress test of the catalogue's moves; the retry of a read whose pack was removed
/// is pinned down by `a_second_process_reads_the_packs_and_writes_files`, where the stale
/// location is certain).
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn reads_during_compaction_get_whole_volumes() {
    let dir = scratch("racing");
    let store = std::sync::Arc::new(FsStore::open(&dir, 1 << 32).unwrap());
    let mut kept = vec![];
    for n in 0..80 {
        let (id, data) = (format!("v{n:03}"), bytes(n, (900 << 10) + n));
        store
            .put(meta(&id, &data), Vxl::from(data.clone()))
            .await
            .unwrap();
        if n % 8 == 0 {
            kept.push((id, data));
        }
    }
    let kept = std::sync::Arc::new(kept);
    let done = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let readers: Vec<_> = (0..3)
        .map(|r| {
            let (store, kept, done) = (store.clone(), kept.clone(), done.clone());
            tokio::spawn(async move {
                let mut reads = 0;
                for round in 0..10_000 {
                    if done.load(std::sync::atomic::Ordering::SeqCst) && round > 0 {
                        break;
                    }
                    let (id, data) = &kept[(round + r) % kept.len()];
                    let got = store.read(id).await.unwrap().unwrap();
                    assert!(got[..] == data[..], "{id}");
                    reads += 1;
                }
                reads
            })
        })
        .collect();
    let first = pack_files(&dir).keys().next().unwrap().clone();
    for n in (0..80).filter(|n| n % 8 != 0) {
        assert!(store.delete(&format!("v{n:03}")).await.unwrap());
    }
    done.store(true, std::sync::atomic::Ordering::SeqCst);
    for r in readers {
        assert!(r.await.unwrap() > 0);
    }
    assert!(!pack_files(&dir).contains_key(&first), "no compaction ran");
}

/// A second process on the directory (here a second store in this one: the lock is per
/// open file) does not write the packs: its volumes get their own files, it finds the
/// writer's volumes in the packs, also after the writer moved them, and it cannot remove
/// them.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_second_process_reads_the_packs_and_writes_files() {
    let dir = scratch("reader");
    let a = FsStore::open(&dir, 1 << 32).unwrap();
    let b = FsStore::open(&dir, 1 << 32).unwrap();
    let (da, db) = (bytes(1, 3000), bytes(2, 4000));
    a.put(meta("va", &da), Vxl::from(da.clone())).await.unwrap();
    b.put(meta("vb", &db), Vxl::from(db.clone())).await.unwrap();
    assert!(dir.join("volumes/vb.vxl").exists());
    assert!(!dir.join("volumes/va.vxl").exists());
    assert_eq!(&b.read("va").await.unwrap().unwrap()[..], &da[..]);
    assert_eq!(&a.read("vb").await.unwrap().unwrap()[..], &db[..]);
    assert!(b.delete("va").await.is_err());
    // Fill and empty a pack so that it is compacted and "va" moves.
    for n in 0..80 {
        let (id, data) = (format!("w{n:03}"), bytes(n, 900 << 10));
        a.put(meta(&id, &data), Vxl::from(data)).await.unwrap();
    }
    for n in 0..80 {
        a.delete(&format!("w{n:03}")).await.unwrap();
    }
    assert!(
        !pack_files(&dir).contains_key(&name(1)),
        "pack 1 was compacted"
    );
    assert_eq!(&b.read("va").await.unwrap().unwrap()[..], &da[..]);
    assert!(a.delete("va").await.unwrap());
    assert!(b.get("nope").await.unwrap().is_none());
}
