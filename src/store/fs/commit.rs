//! The directory store's writer: the committer thread that writes puts in group commits, to
//! packs or to their own files, and the packs' compaction. Not here: the catalogue's reads
//! (`super::volumes`).

use std::path::Path;
use std::sync::Mutex;

use super::packs::{Loc, Packs};
use super::{Entry, GROUP_MAX, GROUP_THREADS, Inner, Pending, lock};
use crate::store::fault;
use crate::store::{StoreError, atomic};

/// Compacts the packs while they are due ([`Packs::due`]; at most 4 packs at a time, each at
/// most [`packs::PACK_MAX`] and a volume): their live volumes move to the newest pack and the
/// catalogue follows them.
pub(super) fn compact(p: &mut Packs, inner: &Mutex<Inner>) -> Result<(), StoreError> {
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
pub(super) fn commit_volumes(
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
pub(super) fn commit_group(
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
