//! The directory store's tests: puts, reads of damaged data, the quota, reopening, group
//! commits; `meta` and `scratch` are shared with the packs' tests and the queue's.

use super::commit::commit_group;
use super::*;
use crate::store::{ByteStream, SourceInfo, VolumeStore, Vxl, sha256_hex};
use crate::testkit::Scratch;

/// Metadata that describes `data` truthfully.
pub(crate) fn meta(id: &str, data: &[u8]) -> VolumeMeta {
    VolumeMeta {
        id: id.into(),
        name: None,
        kind: crate::volume::VolumeKind::Bits,
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
            compression: None,
            sha256: String::new(),
            triangles: 1,
            kept: false,
        },
        diagnostics: None,
        fill: None,
        engine: "cpu".into(),
        created: String::new(),
        bytes: data.len() as u64,
        sha256: sha256_hex(data),
        provenance: None,
        distance: None,
        attributes: None,
        owner: None,
    }
}

/// An empty scratch directory for a store, removed when the test ends.
pub(crate) fn scratch(name: &str) -> Scratch {
    Scratch::new(&format!("fsstore-{name}"))
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
            tokio::spawn(async move { s.put(meta(&format!("v{n}"), &data), Vxl::from(data)).await })
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
    match store.put(big, Vxl::from(data.clone())).await {
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
    store.put(plain, Vxl::from(data.clone())).await.unwrap();
    assert_eq!(store.usage().await.unwrap().bytes, 1000 + plain_json);
    assert_eq!(bytes_on_disk(&dir), 1000 + plain_json);
    let again = FsStore::open_files(&dir, limit).unwrap();
    assert_eq!(again.usage().await.unwrap().bytes, 1000 + plain_json);
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
            .put(meta(id, &data), Vxl::from(data.clone()))
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
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn reads_verify_length_and_checksum() {
    let dir = scratch("checksum");
    let store = FsStore::open_files(&dir, 1 << 20).unwrap();
    let data: Vec<u8> = (0..4096u32).map(|i| (i * 7 % 251) as u8).collect();
    for id in ["a", "b", "c", "d"] {
        store
            .put(meta(id, &data), Vxl::from(data.clone()))
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
            .put(lying, Vxl::from(data.clone()))
            .await
            .map(|_| None),
        "sha256",
    );
    let mut short = meta("f", &data);
    short.bytes -= 1;
    corrupt(
        store
            .put(short, Vxl::from(data.clone()))
            .await
            .map(|_| None),
        "bytes",
    );
    assert!(store.get("e").await.unwrap().is_none() && store.get("f").await.unwrap().is_none());
    assert!(!dir.join("volumes/e.vxl").exists() && !dir.join("volumes/f.vxl").exists());
}

/// Two stores on one directory (two replicas in the tests): a volume one of them stored is
/// found, read and deleted through the other, which catalogues it from then on.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_volume_another_process_stored_is_found_on_disk() {
    let dir = scratch("shared");
    let a = FsStore::open_files(&dir, 1 << 20).unwrap();
    let b = FsStore::open_files(&dir, 1 << 20).unwrap();
    let data = vec![5u8; 300];
    a.put(meta("v1", &data), Vxl::from(data.clone()))
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
                s.put(meta(&format!("v{n}"), &data), Vxl::from(data)).await
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
}

/// What the directory `name` in `dir/volumes` adds to [`bytes_on_disk`].
fn bytes_dir_entry(dir: &Path, name: &str) -> u64 {
    std::fs::metadata(dir.join("volumes").join(name))
        .unwrap()
        .len()
}

/// Kept meshes (`app::sources`): one file per key whatever the number of puts, counted in the
/// usage (and again when reopened), refused past the quota, referred to by the volumes whose
/// metadata keeps them, and removed by a release only once no volume refers to them.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn kept_sources_count_once_and_go_with_their_last_volume() {
    use crate::app::sources;
    let dir = scratch("sources");
    let store = FsStore::open_files(&dir, 1 << 20).unwrap();
    let key = sha256_hex(b"an upload");
    let mesh = crate::mesh::Mesh::new(
        vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        vec![[0, 1, 2]],
    )
    .unwrap();
    let bytes = sources::encode(&mesh);
    let keeping = |id: &str| {
        let mut m = meta(id, b"data");
        m.source.kept = true;
        m.source.sha256 = key.clone();
        m
    };
    for _ in 0..3 {
        sources::keep(&store, &key, &bytes).await.unwrap();
    }
    let one = store.usage().await.unwrap().bytes;
    assert_eq!(one, bytes.len() as u64);
    assert!(!store.source_referred(&key).await.unwrap());
    for id in ["k1", "k2"] {
        store
            .put(keeping(id), Vxl::from(b"data".to_vec()))
            .await
            .unwrap();
    }
    assert!(store.source_referred(&key).await.unwrap());
    let two = store.usage().await.unwrap().bytes;
    // Reopened, the mesh still counts (once).
    drop(store);
    let store = FsStore::open_files(&dir, 1 << 20).unwrap();
    assert_eq!(store.usage().await.unwrap().bytes, two);
    let got = store.get_source(&key).await.unwrap().unwrap();
    let opts = crate::mesh::LoadOptions {
        external: crate::mesh::ExternalResources::Deny,
        max_triangles: 10,
        max_decompressed_bytes: 1 << 20,
        ..Default::default()
    };
    assert_eq!(sources::decode(&got, &opts).unwrap(), mesh);
    // Damage is found, never decoded into another mesh.
    let mut bad = got.to_vec();
    *bad.last_mut().unwrap() ^= 1;
    assert!(sources::decode(&bad, &opts).is_err());
    // Released while a volume refers to it: kept.
    assert!(store.delete("k1").await.unwrap());
    assert!(!sources::release(&store, &key).await.unwrap());
    assert!(store.get_source(&key).await.unwrap().is_some());
    assert!(store.delete("k2").await.unwrap());
    assert!(sources::release(&store, &key).await.unwrap());
    assert!(store.get_source(&key).await.unwrap().is_none());
    assert_eq!(store.usage().await.unwrap().bytes, 0);
    assert_eq!(std::fs::read_dir(dir.join("sources")).unwrap().count(), 0);
    // Past the quota: refused with the numbers, nothing written.
    let small = FsStore::open_files(&dir, 10).unwrap();
    match small.put_source(&key, bytes.clone()).await {
        Err(StoreError::Full {
            need, limit: 10, ..
        }) => assert_eq!(need, bytes.len() as u64),
        other => panic!("{other:?}"),
    }
    assert_eq!(std::fs::read_dir(dir.join("sources")).unwrap().count(), 0);
    // A key that is not a sha256 is refused.
    assert!(small.put_source("../x", Bytes::new()).await.is_err());
}
