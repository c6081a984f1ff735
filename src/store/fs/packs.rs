//! The directory store's small volumes: append-only pack files (`volumes/{SEQ}.pack`) instead of
//! two files per volume.
//!
//! Two files per volume meant, per volume, two inodes allocated, two files fsynced and two
//! renames. On ext4 without a journal (this project's test and CI machines) allocating an inode
//! scans the inodes freed in the last seconds (`recently_deleted` in `perf`): under a few hundred
//! small jobs a second that scan took a fifth of the machine's CPU, more than voxelizing. A
//! group of volumes now costs one `write` and one `fdatasync` of a pack, and no inode.
//!
//! **Records.** A pack is a sequence of records, each a 32-byte header, the volume id, its
//! metadata (compact JSON) and its `.vxl` bytes:
//!
//! | bytes | field |
//! |---|---|
//! | 0..4 | magic `VXP1` |
//! | 4 | kind: 0 a volume, 1 the removal of a volume (no metadata, no data) |
//! | 5..8 | zero |
//! | 8..12 | id length (u32, little-endian), at most 128 |
//! | 12..16 | metadata length (u32), at most [`META_MAX`] |
//! | 16..24 | data length (u64) |
//! | 24..32 | the first 8 bytes of the sha256 of bytes 0..24, the id and the metadata |
//!
//! The header's hash covers everything but the data; the data is checked against the
//! metadata's length and sha256 on every read, as the volume files are. A record that does not
//! check, or that the file does not hold whole, ends the pack (the torn tail of a write a crash
//! interrupted): the writer cuts it off at open.
//!
//! **Writing.** One process writes a directory's packs: the one holding an exclusive lock on
//! `volumes/packs.lock` (others sharing the directory, as replicas on one Redis do in tests,
//! write volume files and read the packs). It appends a group of records to the newest pack in
//! one write and one `fdatasync`; a group that fails is cut off again (or, if that fails too,
//! the next group starts a new pack). A pack past [`PACK_MAX`] is sealed and the next group
//! starts a new one (its creation made durable by a directory sync). Only volumes whose record
//! is at most [`RECORD_MAX`] go to packs; larger ones keep their own files.
//!
//! **Removing and compacting.** A removal appends a removal record. Ids are never reused, so a
//! volume is live when its record is in a pack and no removal of its id is. A removal record is
//! kept (copied on compaction) while the pack holding the volume's record exists. When the dead
//! bytes of all packs exceed both [`GARBAGE_MIN`] and the live bytes, the sealed pack with the
//! most dead bytes is compacted: its live records are appended to the newest pack and synced,
//! then it is removed. So packs take at most twice the live bytes plus [`GARBAGE_MIN`] and one
//! pack. A reader that finds its pack removed looks the volume up again and retries.
//!
//! **Opening.** Every pack's headers and metadata are read (the data is skipped); the writer
//! also reads the data of the newest pack's records and checks it against their metadata, so
//! that a group a crash interrupted after its size was written but not its bytes is cut off
//! rather than listed as damaged.

use std::collections::{BTreeMap, HashMap};
use std::fs::{File, OpenOptions};
use std::io::{Seek, SeekFrom};
use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};

use sha2::Digest;

use crate::store::fault;
use crate::store::{StoreError, VolumeMeta, atomic, check, safe_id};

/// The lock file whose holder writes the packs.
pub const LOCK: &str = "packs.lock";
/// A pack's file name ends so.
pub const EXT: &str = "pack";
/// Bytes of a record's header.
pub const HEADER: usize = 32;
/// A record's magic bytes.
const MAGIC: &[u8; 4] = b"VXP1";
/// The longest metadata a record may hold.
pub const META_MAX: usize = 1 << 20;
/// The longest record a volume goes to a pack with; larger volumes keep their own files.
pub const RECORD_MAX: u64 = 1 << 20;
/// A pack this large is sealed: the next group starts a new one.
pub const PACK_MAX: u64 = 64 << 20;
/// Packs are compacted only once their dead bytes exceed this (and the live bytes).
pub const GARBAGE_MIN: u64 = 16 << 20;

const PUT: u8 = 0;
const REMOVE: u8 = 1;

/// Where a volume's record is: the pack, where its data starts, and its whole record's bytes
/// (what the quota counts).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Loc {
    pub pack: u64,
    pub record: u64,
    pub data: u64,
    pub len: u64,
}

impl Loc {
    /// Bytes of the volume's data (the record's tail from `data`).
    pub fn data_len(&self) -> u64 {
        self.record + self.len - self.data
    }
}

/// One record read back from a pack.
struct Record {
    id: String,
    /// `None`: a removal record.
    meta: Option<VolumeMeta>,
    loc: Loc,
}

/// What is known of one pack.
#[derive(Default)]
struct PackInfo {
    /// Bytes read so far (the writer: the whole file).
    scanned: u64,
    /// Bytes of records that are no longer needed (removed volumes and their removal records
    /// once the volume's record is gone).
    dead: u64,
}

/// Every pack of a directory: the writer's state (when this process holds the lock) and what
/// was read.
pub struct Packs {
    dir: PathBuf,
    /// The lock, held while this process writes the packs.
    lock: Option<File>,
    /// The pack being appended to (writer only): its number, file and length.
    active: Option<(u64, File, u64)>,
    packs: BTreeMap<u64, PackInfo>,
    /// Removed volumes whose record is still in a pack: id → that pack (their removal records
    /// must be kept).
    removed: HashMap<String, u64>,
    /// Removal records: id → where the one that counts is.
    removals: HashMap<String, Loc>,
}

/// The file name of pack `pack`.
pub fn name(pack: u64) -> String {
    format!("{pack:012}.{EXT}")
}

fn header_hash(head: &[u8], id: &[u8], meta: &[u8]) -> [u8; 8] {
    let mut h = sha2::Sha256::new();
    h.update(head);
    h.update(id);
    h.update(meta);
    h.finalize()[..8].try_into().expect("8 bytes")
}

/// Appends one record to `buf`; returns where its data starts, relative to the record.
fn encode(buf: &mut Vec<u8>, kind: u8, id: &str, meta: &[u8], data: &[u8]) -> u64 {
    let mut head = [0u8; HEADER];
    head[..4].copy_from_slice(MAGIC);
    head[4] = kind;
    head[8..12].copy_from_slice(&(id.len() as u32).to_le_bytes());
    head[12..16].copy_from_slice(&(meta.len() as u32).to_le_bytes());
    head[16..24].copy_from_slice(&(data.len() as u64).to_le_bytes());
    let hash = header_hash(&head[..24], id.as_bytes(), meta);
    head[24..].copy_from_slice(&hash);
    buf.extend_from_slice(&head);
    buf.extend_from_slice(id.as_bytes());
    buf.extend_from_slice(meta);
    buf.extend_from_slice(data);
    (HEADER + id.len() + meta.len()) as u64
}

/// The bytes of a volume's record: what it takes in a pack.
pub fn record_len(id: &str, meta_json: &[u8], data: u64) -> u64 {
    (HEADER + id.len() + meta_json.len()) as u64 + data
}

/// Reads the record at `at` of a file of `len` bytes: `None` where no whole, valid record
/// starts (the end, or a torn tail).
fn read_record(f: &File, pack: u64, at: u64, len: u64) -> std::io::Result<Option<Record>> {
    if len.saturating_sub(at) < HEADER as u64 {
        return Ok(None);
    }
    let mut head = [0u8; HEADER];
    f.read_exact_at(&mut head, at)?;
    let word = |r: std::ops::Range<usize>| u32::from_le_bytes(head[r].try_into().unwrap());
    let (id_len, meta_len) = (word(8..12) as usize, word(12..16) as usize);
    let data_len = u64::from_le_bytes(head[16..24].try_into().unwrap());
    if &head[..4] != MAGIC || head[4] > REMOVE || head[5..8] != [0; 3] || id_len > 128 {
        return Ok(None);
    }
    if meta_len > META_MAX || (head[4] == REMOVE && (meta_len, data_len) != (0, 0)) {
        return Ok(None);
    }
    let body = (id_len + meta_len) as u64;
    let Some(end) = (at + HEADER as u64 + body).checked_add(data_len) else {
        return Ok(None);
    };
    if end > len {
        return Ok(None);
    }
    let mut rest = vec![0u8; id_len + meta_len];
    f.read_exact_at(&mut rest, at + HEADER as u64)?;
    let (id, meta) = rest.split_at(id_len);
    if header_hash(&head[..24], id, meta) != head[24..] {
        return Ok(None);
    }
    let Ok(id) = String::from_utf8(id.to_vec()) else {
        return Ok(None);
    };
    if !safe_id(&id) {
        return Ok(None);
    }
    let meta = if head[4] == PUT {
        match serde_json::from_slice::<VolumeMeta>(meta) {
            Ok(m) if m.id == id && m.bytes == data_len => Some(m),
            _ => return Ok(None),
        }
    } else {
        None
    };
    Ok(Some(Record {
        id,
        meta,
        loc: Loc {
            pack,
            record: at,
            data: at + HEADER as u64 + body,
            len: end - at,
        },
    }))
}

/// The records of a pack from `from`, and where the valid ones end. With `verify` (the
/// writer, on the newest pack at open), each volume's data is read and checked against its
/// metadata too: records that fail it at the end of the pack end it (a group a crash
/// interrupted after its length reached the disk but before all its bytes did); one followed by
/// a record that checks is kept (damaged after it was acknowledged: listed, its reads say so).
fn scan(f: &File, pack: u64, from: u64, verify: bool) -> std::io::Result<(Vec<Record>, u64)> {
    let len = f.metadata()?.len();
    let mut out = vec![];
    let mut bad = vec![];
    let (mut at, mut end, mut whole) = (from, from, 0);
    while let Some(r) = read_record(f, pack, at, len)? {
        at += r.loc.len;
        if let (Some(m), true) = (&r.meta, verify) {
            let mut data = vec![0u8; r.loc.data_len() as usize];
            f.read_exact_at(&mut data, r.loc.data)?;
            if let Err(e) = check(&r.id, &data, m) {
                bad.push((out.len(), e));
                out.push(r);
                continue;
            }
        }
        out.push(r);
        (end, whole) = (at, out.len());
    }
    for (_, e) in bad.iter().filter(|(k, _)| *k < whole) {
        tracing::error!(pack = %name(pack), "{e}");
    }
    out.truncate(whole);
    Ok((out, end))
}

/// The numbers of the packs in `dir`, in order.
fn pack_numbers(dir: &Path) -> std::io::Result<Vec<u64>> {
    let mut numbers = vec![];
    for e in std::fs::read_dir(dir)? {
        let n = e?.file_name();
        if let Some(n) = n.to_str().and_then(|n| n.strip_suffix(&format!(".{EXT}")))
            && n.len() == 12
            && let Ok(n) = n.parse()
        {
            numbers.push(n);
        }
    }
    numbers.sort_unstable();
    Ok(numbers)
}

/// The volumes found by [`Packs::open`] or [`Packs::refresh`].
pub type Found = Vec<(VolumeMeta, Loc)>;

impl Packs {
    /// Reads the packs of `dir` ([`Packs::refresh`]), taking the writer's lock when it is free
    /// (and `write`). Returns the live volumes.
    pub fn open(dir: &Path, write: bool) -> Result<(Packs, Found), StoreError> {
        let lock = OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .open(dir.join(LOCK))?;
        let lock = match lock.try_lock() {
            Ok(()) if write => Some(lock),
            Ok(()) => None,
            Err(std::fs::TryLockError::WouldBlock) => None,
            Err(std::fs::TryLockError::Error(e)) => return Err(e.into()),
        };
        let mut packs = Packs {
            dir: dir.to_path_buf(),
            lock,
            active: None,
            packs: BTreeMap::new(),
            removed: HashMap::new(),
            removals: HashMap::new(),
        };
        for n in pack_numbers(dir)? {
            packs.packs.insert(n, PackInfo::default());
        }
        let (found, _) = packs.refresh()?;
        if packs.lock.is_some()
            && let Some((&n, info)) = packs.packs.iter().next_back()
            && info.scanned < PACK_MAX
        {
            let mut f = OpenOptions::new()
                .read(true)
                .write(true)
                .open(dir.join(name(n)))?;
            f.seek(SeekFrom::Start(info.scanned))?;
            packs.active = Some((n, f, info.scanned));
        }
        Ok((packs, found))
    }

    /// Does this process write the packs?
    pub fn writer(&self) -> bool {
        self.lock.is_some()
    }

    /// Reads what was appended to the packs since the last read (the writer: everything, once,
    /// at open, cutting off torn ends and checking the newest pack's data; a reader: also later,
    /// other processes' writes): the live volumes among the new records (a volume the writer
    /// moved appears again, at its new place) and the ids whose removal was read.
    pub fn refresh(&mut self) -> Result<(Found, Vec<String>), StoreError> {
        if !self.writer() {
            // New packs the writer started.
            for n in pack_numbers(&self.dir)? {
                self.packs.entry(n).or_default();
            }
        }
        let numbers: Vec<u64> = self.packs.keys().copied().collect();
        let newest = numbers.last().copied();
        let mut puts: Vec<(VolumeMeta, Loc)> = vec![];
        let mut removed_ids = vec![];
        for n in numbers {
            let from = self.packs[&n].scanned;
            let opened = OpenOptions::new()
                .read(true)
                .write(self.writer())
                .open(self.dir.join(name(n)));
            let f = match opened {
                Ok(f) => f,
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                    self.packs.remove(&n); // compacted away by the writer
                    continue;
                }
                Err(e) => return Err(e.into()),
            };
            let verify = self.writer() && Some(n) == newest;
            let (records, end) = scan(&f, n, from, verify)?;
            if self.writer() && end < f.metadata()?.len() {
                tracing::warn!(
                    pack = %name(n),
                    "cutting off the torn end of a pack at byte {end} (a write a crash interrupted, never acknowledged)"
                );
                f.set_len(end)?;
                f.sync_all()?;
            }
            self.packs.get_mut(&n).expect("listed").scanned = end;
            for r in records {
                match r.meta {
                    Some(m) => puts.push((m, r.loc)),
                    None => {
                        // A second removal record of one id (a compaction a crash cut short
                        // copied it): the first is dead weight.
                        if let Some(old) = self.removals.insert(r.id.clone(), r.loc) {
                            self.dead(old);
                        }
                        removed_ids.push(r.id);
                    }
                }
            }
        }
        // The newest record of each id (a compaction a crash cut short may have left a volume's
        // record in two packs: the older is dead weight).
        let mut newest: HashMap<String, (VolumeMeta, Loc)> = HashMap::new();
        for (m, loc) in puts {
            if let Some((_, old)) = newest.insert(m.id.clone(), (m, loc)) {
                self.dead(old);
            }
        }
        let mut live = vec![];
        for (id, (m, loc)) in newest {
            if self.removals.contains_key(&id) {
                self.dead(loc);
                self.removed.insert(id, loc.pack);
            } else {
                live.push((m, loc));
            }
        }
        if self.writer() {
            // At open (the writer's only refresh): removal records whose volume is in no pack
            // any more are dead weight.
            self.drop_orphans();
        }
        Ok((live, removed_ids))
    }

    /// Counts the record at `loc` as dead.
    fn dead(&mut self, loc: Loc) {
        if let Some(p) = self.packs.get_mut(&loc.pack) {
            p.dead += loc.len;
        }
    }

    /// Removal records whose volume's record is in no pack: no longer needed, dead weight.
    fn drop_orphans(&mut self) {
        let orphans: Vec<String> = self
            .removals
            .keys()
            .filter(|id| !self.removed.contains_key(*id))
            .cloned()
            .collect();
        for id in orphans {
            let loc = self.removals.remove(&id).expect("listed");
            self.dead(loc);
        }
    }

    /// Appends `buf` (whole records) to the newest pack and makes it durable; returns the pack
    /// and the offset it starts at. `records` is how many records `buf` holds (for the fault
    /// points). On failure nothing of `buf` is kept.
    fn append(&mut self, buf: &[u8], records: usize) -> std::io::Result<(u64, u64)> {
        assert!(self.writer(), "only the lock holder writes packs");
        if self.active.is_none() {
            let n = self.packs.keys().next_back().map_or(1, |n| n + 1);
            let f = OpenOptions::new()
                .read(true)
                .write(true)
                .create_new(true)
                .open(self.dir.join(name(n)))?;
            // Listed before the directory sync: if that fails, the next try starts pack n + 1
            // (this one stays, empty).
            self.packs.insert(n, PackInfo::default());
            atomic::sync_dir(&self.dir)?;
            self.active = Some((n, f, 0));
        }
        let (n, f, len) = self.active.as_mut().expect("just made");
        let (n, start) = (*n, *len);
        let wrote = fault::write(fault::Site::MidData, f, buf).and_then(|()| {
            for _ in 0..records {
                fault::point(fault::Site::AfterData);
            }
            f.sync_data()
        });
        if let Err(e) = wrote {
            // Cut the group off again; failing that, the next group starts a new pack (readers
            // stop at the first invalid record, and the writer cuts it off at its next open).
            let cut = f
                .set_len(start)
                .and_then(|()| f.seek(SeekFrom::Start(start)).map(drop));
            if cut.is_err() {
                self.active = None;
            }
            return Err(e);
        }
        *len += buf.len() as u64;
        let end = *len;
        self.packs.get_mut(&n).expect("active").scanned = end;
        if end >= PACK_MAX {
            self.active = None;
        }
        Ok((n, start))
    }

    /// Appends the records of a group of volumes `(id, metadata JSON, data)`, durably; the
    /// location of each.
    pub fn put(&mut self, group: &[(&str, &[u8], &[u8])]) -> std::io::Result<Vec<Loc>> {
        let mut buf = Vec::with_capacity(
            group
                .iter()
                .map(|(id, m, d)| record_len(id, m, d.len() as u64) as usize)
                .sum(),
        );
        let mut at = vec![];
        for (id, meta, data) in group {
            let start = buf.len() as u64;
            let data_at = encode(&mut buf, PUT, id, meta, data);
            at.push((start, data_at, buf.len() as u64 - start));
        }
        let (pack, base) = self.append(&buf, group.len())?;
        Ok(at
            .into_iter()
            .map(|(start, data, len)| Loc {
                pack,
                record: base + start,
                data: base + start + data,
                len,
            })
            .collect())
    }

    /// Records the removal of the volume at `loc`, durably.
    pub fn remove(&mut self, id: &str, loc: Loc) -> std::io::Result<()> {
        let mut buf = vec![];
        encode(&mut buf, REMOVE, id, b"", b"");
        let (pack, at) = self.append(&buf, 0)?;
        self.dead(loc);
        self.removed.insert(id.to_string(), loc.pack);
        let len = buf.len() as u64;
        let removal = Loc {
            pack,
            record: at,
            data: at + len,
            len,
        };
        self.removals.insert(id.to_string(), removal);
        Ok(())
    }

    /// Bytes of dead records, in all packs.
    fn garbage(&self) -> u64 {
        self.packs.values().map(|p| p.dead).sum()
    }

    /// The sealed pack to compact, when the dead bytes exceed [`GARBAGE_MIN`] and the live ones
    /// (`live`, asked only then). Never the newest pack, so that a pack's number is never used
    /// twice (a reader's stale location can only miss, never read another volume's bytes).
    pub fn due(&self, live: impl FnOnce() -> u64) -> Option<u64> {
        let g = self.garbage();
        if !self.writer() || g <= GARBAGE_MIN || g <= live() {
            return None;
        }
        let newest = self.packs.keys().next_back().copied();
        self.packs
            .iter()
            .filter(|(n, p)| Some(**n) != newest && p.dead > 0)
            .max_by_key(|(_, p)| p.dead)
            .map(|(n, _)| *n)
    }

    /// Copies the records of pack `n` still needed (the volumes whose catalogue entry is there,
    /// `live`, and removal records whose volume's record is in another pack) to the newest
    /// pack, durably; tells `relocate` the moved volumes' new locations (for the catalogue),
    /// then removes pack `n` (a reader of an old location retries).
    pub fn compact(
        &mut self,
        n: u64,
        live: &HashMap<String, Loc>,
        relocate: impl FnOnce(Vec<(String, Loc)>),
    ) -> Result<(), StoreError> {
        let f = File::open(self.dir.join(name(n)))?;
        let (records, _) = scan(&f, n, 0, false)?;
        let mut buf = vec![];
        let mut moved = vec![];
        let mut kept = vec![];
        for r in &records {
            let keep = match r.meta {
                Some(_) => live.get(&r.id) == Some(&r.loc),
                None => {
                    self.removals.get(&r.id) == Some(&r.loc)
                        && self.removed.get(&r.id).is_some_and(|&p| p != n)
                }
            };
            if !keep {
                continue;
            }
            let start = buf.len() as u64;
            buf.resize(buf.len() + r.loc.len as usize, 0);
            f.read_exact_at(&mut buf[start as usize..], r.loc.record)?;
            let to = (r.id.clone(), start, r.loc.data - r.loc.record, r.loc.len);
            if r.meta.is_some() {
                moved.push(to);
            } else {
                kept.push(to);
            }
        }
        let (pack, base) = if buf.is_empty() {
            (0, 0)
        } else {
            self.append(&buf, 0)?
        };
        let at = move |(id, start, data, len): (String, u64, u64, u64)| {
            let loc = Loc {
                pack,
                record: base + start,
                data: base + start + data,
                len,
            };
            (id, loc)
        };
        relocate(moved.into_iter().map(at).collect());
        std::fs::remove_file(self.dir.join(name(n)))?;
        atomic::sync_dir(&self.dir)?;
        self.packs.remove(&n);
        self.removed.retain(|_, p| *p != n);
        self.removals.retain(|_, loc| loc.pack != n);
        self.removals.extend(kept.into_iter().map(at));
        self.drop_orphans();
        Ok(())
    }
}

#[cfg(test)]
mod tests;
