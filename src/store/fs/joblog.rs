//! The directory store's job records: one append-only log, `jobs/records.log`, instead of a file
//! per job.
//!
//! A file per record meant, per job, a new file for its first record and a new file renamed over
//! the old one for each later record (an inode allocated and one freed), each made durable by an
//! fsync of the file and one of the directory. On ext4 without a journal (this project's test
//! and CI machines) allocating an inode skips every inode freed in the last few seconds, one
//! inode-table lookup each: under a few hundred jobs a second, half of the server's CPU went to
//! that scan (`recently_deleted` in `perf`). An append costs one `fdatasync` and no inode.
//!
//! Each line is one change: `HASH ID PAYLOAD\n`, PAYLOAD the record's JSON (one line: JSON from
//! `serde_json` never holds a raw newline) or `-` for a removed record, HASH the first 8 bytes of
//! the sha256 of `ID PAYLOAD` in hex. Reading takes the last valid line of each id; a line that
//! does not check (the torn tail of an append a crash interrupted) is skipped. A batch is one
//! `write` and one `fdatasync`: durable as a whole, or (after a crash) a prefix of its lines and
//! at most one torn line, each record either in its new state or its old one.
//!
//! The log is rewritten with the live records only (atomically: a temporary file, fsync, rename,
//! directory sync) when it has grown past [`COMPACT_RATIO`] times their size (and past
//! [`COMPACT_MIN`]), at open when it held an invalid line (so that no append follows a torn
//! one), and after an append failed partway and the file could not be cut back. With at most
//! `queue::local::KEEP_FINISHED` records of ~300 bytes, a rewrite is a few MB.
//!
//! Records of earlier versions (`jobs/{ID}.json`) are read at open, written into the log, and
//! removed once the log holding them is durable.
//!
//! One process writes a directory's log (the in-process queue is the only user; two processes
//! with in-process queues on one directory are not supported, see docs/scaling.md).

use std::collections::HashMap;
use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};

use crate::store::fault;
use crate::store::{StoreError, atomic, safe_id, sha256_hex};
use bytes::Bytes;

/// Hex digits of a line's hash: the first 8 bytes of the sha256.
const HASH_HEX: usize = 16;

/// The log's file name in the jobs directory.
pub const LOG: &str = "records.log";
/// The log is rewritten once it is this many times the size of its live lines...
const COMPACT_RATIO: u64 = 4;
/// ...and at least this large.
const COMPACT_MIN: u64 = 1 << 20;

pub struct JobLog {
    path: PathBuf,
    /// Opened for appending; `None` while it must be rewritten before the next append.
    file: Option<File>,
    /// The file's length: where the next line starts.
    len: u64,
    /// The newest record of each job, as its line in the log.
    live: HashMap<String, Bytes>,
    /// Bytes of `live`'s lines.
    live_bytes: u64,
    /// Appends synced so far (the tests count them).
    syncs: u64,
}

/// One log line for `id`: its record, or a removal.
fn line(id: &str, record: Option<&[u8]>) -> Vec<u8> {
    let payload = record.unwrap_or(b"-");
    let mut body = Vec::with_capacity(id.len() + 1 + payload.len());
    body.extend_from_slice(id.as_bytes());
    body.push(b' ');
    body.extend_from_slice(payload);
    let mut out = Vec::with_capacity(HASH_HEX + 1 + body.len() + 1);
    out.extend_from_slice(&sha256_hex(&body).as_bytes()[..HASH_HEX]);
    out.push(b' ');
    out.extend_from_slice(&body);
    out.push(b'\n');
    out
}

/// A checked line (without its `\n`): the id and the record (`None`: removed).
fn parse(l: &[u8]) -> Option<(&str, Option<&[u8]>)> {
    let (hash, body) = (l.get(..HASH_HEX)?, l.get(HASH_HEX + 1..)?);
    if l[HASH_HEX] != b' ' || hash != &sha256_hex(body).as_bytes()[..HASH_HEX] {
        return None;
    }
    let sp = memchr::memchr(b' ', body)?;
    let id = std::str::from_utf8(&body[..sp])
        .ok()
        .filter(|id| safe_id(id))?;
    let payload = &body[sp + 1..];
    Some((id, if payload == b"-" { None } else { Some(payload) }))
}

impl JobLog {
    /// Opens the log in `dir`, creating it, and takes in the records of earlier versions'
    /// `{ID}.json` files (removed once the log holds them durably). Temporary files are the
    /// caller's to remove first.
    pub fn open(dir: &Path) -> std::io::Result<JobLog> {
        let path = dir.join(LOG);
        let mut live: HashMap<String, Option<Bytes>> = HashMap::new();
        let mut legacy = vec![];
        for e in std::fs::read_dir(dir)? {
            let p = e?.path();
            let Some(id) = p
                .file_name()
                .and_then(|n| n.to_str())
                .and_then(|n| n.strip_suffix(".json"))
                .filter(|id| safe_id(id))
            else {
                continue;
            };
            match std::fs::read(&p) {
                Ok(b) if !b.contains(&b'\n') => {
                    live.insert(id.to_string(), Some(Bytes::from(b)));
                }
                Ok(_) => {
                    tracing::warn!(path = %p.display(), "a job record with a line break: dropped")
                }
                Err(e) => tracing::warn!(path = %p.display(), "unreadable job record: {e}"),
            }
            legacy.push(p);
        }
        let (bytes, exists) = match std::fs::read(&path) {
            Ok(b) => (b, true),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => (vec![], false),
            Err(e) => return Err(e),
        };
        let mut invalid = 0usize;
        let mut rest = &bytes[..];
        while !rest.is_empty() {
            let Some(end) = memchr::memchr(b'\n', rest) else {
                invalid += 1; // a torn tail
                break;
            };
            match parse(&rest[..end]) {
                Some((id, record)) => {
                    live.insert(id.to_string(), record.map(Bytes::copy_from_slice));
                }
                None => invalid += 1,
            }
            rest = &rest[end + 1..];
        }
        if invalid > 0 {
            tracing::warn!(
                invalid,
                path = %path.display(),
                "job record log: skipped lines that do not check (a write a crash interrupted)"
            );
        }
        let mut log = JobLog {
            path,
            file: None,
            len: bytes.len() as u64,
            live: HashMap::new(),
            live_bytes: 0,
            syncs: 0,
        };
        for (id, record) in live {
            if let Some(r) = record {
                let l = Bytes::from(line(&id, Some(&r)));
                log.live_bytes += l.len() as u64;
                log.live.insert(id, l);
            }
        }
        if invalid > 0 || !legacy.is_empty() || !exists || log.wants_compaction() {
            log.compact()?;
            for p in &legacy {
                match std::fs::remove_file(p) {
                    Err(e) if e.kind() != std::io::ErrorKind::NotFound => return Err(e),
                    _ => {}
                }
            }
            if !legacy.is_empty() {
                atomic::sync_dir(dir)?;
                tracing::info!(records = legacy.len(), "job records moved into {LOG}");
            }
        } else {
            log.file = Some(OpenOptions::new().append(true).open(&log.path)?);
        }
        Ok(log)
    }

    /// The newest record of every job.
    pub fn records(&self) -> Vec<Bytes> {
        // A live line is `HASH ID RECORD\n`.
        self.live
            .iter()
            .map(|(id, l)| l.slice(HASH_HEX + 1 + id.len() + 1..l.len() - 1))
            .collect()
    }

    /// How many jobs have a record.
    #[cfg(test)]
    fn count(&self) -> usize {
        self.live.len()
    }

    /// Appends a batch of changes (a record, or `None`: removed) in one write and, when
    /// `durable`, one `fdatasync` (else the next durable batch's sync covers it: a sync makes
    /// every earlier write of the file durable): one result per change, all failing together
    /// when the write does (a bad id or a record with a line break fails alone, before anything
    /// is written).
    pub fn append(
        &mut self,
        batch: &[(String, Option<Bytes>)],
        durable: bool,
    ) -> Vec<Result<(), StoreError>> {
        let mut out: Vec<Result<(), StoreError>> = Vec::with_capacity(batch.len());
        let mut buf = vec![];
        let mut lines = vec![];
        for (id, record) in batch {
            let r = match record {
                // A removal of a job that cannot exist has nothing to do.
                None if !safe_id(id) => Ok(()),
                Some(_) if !safe_id(id) => Err(StoreError::Corrupt(format!("bad job id {id:?}"))),
                Some(r) if r.contains(&b'\n') => Err(StoreError::Corrupt(format!(
                    "job {id}: a record with a line break"
                ))),
                _ => {
                    let l = line(id, record.as_deref());
                    buf.extend_from_slice(&l);
                    lines.push((out.len(), id, record.is_some(), l));
                    Ok(())
                }
            };
            out.push(r);
        }
        if lines.is_empty() {
            return out;
        }
        if let Err(e) = self.write(&buf, durable) {
            let msg = e.to_string();
            for (i, ..) in &lines {
                out[*i] = Err(StoreError::Io(std::io::Error::new(e.kind(), msg.clone())));
            }
            return out;
        }
        for (_, id, is_record, l) in lines {
            if let Some(old) = self.live.remove(id) {
                self.live_bytes -= old.len() as u64;
            }
            if is_record {
                self.live_bytes += l.len() as u64;
                self.live.insert(id.clone(), Bytes::from(l));
            }
        }
        if self.wants_compaction() {
            // The batch is durable already; a failed rewrite is retried at the next append.
            if let Err(e) = self.compact() {
                tracing::warn!("rewriting the job record log: {e}");
            }
        }
        out
    }

    fn wants_compaction(&self) -> bool {
        self.len > COMPACT_MIN && self.len > COMPACT_RATIO * self.live_bytes
    }

    /// Appends `buf` and, when `durable`, syncs it. On failure the file is cut back to its last
    /// whole line, or, when even that fails, rewritten before the next append.
    fn write(&mut self, buf: &[u8], durable: bool) -> std::io::Result<()> {
        if self.file.is_none() {
            self.compact()?;
        }
        let f = self.file.as_mut().expect("opened by compact");
        if fault::fires(fault::Site::MidJobRecord) {
            // All but the second half of the last line: a torn tail, as a crash leaves.
            let last = buf[..buf.len() - 1]
                .iter()
                .rposition(|&b| b == b'\n')
                .map_or(0, |i| i + 1);
            let _ = f.write_all(&buf[..last + (buf.len() - last) / 2]);
            let _ = f.sync_data();
            fault::abort(fault::Site::MidJobRecord);
        }
        let r = f.write_all(buf).and_then(|()| {
            if durable {
                self.syncs += 1;
                f.sync_data()
            } else {
                Ok(())
            }
        });
        match r {
            Ok(()) => {
                self.len += buf.len() as u64;
                Ok(())
            }
            Err(e) => {
                if f.set_len(self.len).and_then(|()| f.sync_data()).is_err() {
                    self.file = None;
                }
                Err(e)
            }
        }
    }

    /// Rewrites the log with the live lines only, atomically, and reopens it for appending.
    fn compact(&mut self) -> std::io::Result<()> {
        self.file = None;
        let live = &self.live;
        atomic::write_with(&self.path, |w| {
            for l in live.values() {
                w.write_all(l)?;
            }
            Ok(())
        })?;
        self.len = self.live_bytes;
        self.file = Some(OpenOptions::new().append(true).open(&self.path)?);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::testkit::Scratch;

    fn dir(name: &str) -> Scratch {
        Scratch::new(&format!("joblog-{name}"))
    }

    fn rec(id: &str, v: u32) -> (String, Option<Bytes>) {
        (
            id.to_string(),
            Some(Bytes::from(format!("{{\"id\":\"{id}\",\"v\":{v}}}"))),
        )
    }

    fn sorted(log: &JobLog) -> Vec<String> {
        let mut v: Vec<String> = log
            .records()
            .iter()
            .map(|b| String::from_utf8(b.to_vec()).unwrap())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn the_newest_change_of_each_job_survives_a_reopen() {
        let d = dir("reopen");
        let mut log = JobLog::open(d.path()).unwrap();
        assert!(log.records().is_empty());
        let r = log.append(&[rec("a1", 1), rec("b2", 1), rec("a1", 2)], true);
        assert!(r.iter().all(Result::is_ok));
        let r = log.append(
            &[("b2".into(), None), rec("c3", 1), ("zz".into(), None)],
            true,
        );
        assert!(r.iter().all(Result::is_ok));
        let want = vec![
            "{\"id\":\"a1\",\"v\":2}".to_string(),
            "{\"id\":\"c3\",\"v\":1}".to_string(),
        ];
        assert_eq!(sorted(&log), want);
        drop(log);
        let log = JobLog::open(d.path()).unwrap();
        assert_eq!(sorted(&log), want);
        assert_eq!(log.count(), 2);
        // One file, no temporaries.
        let names: Vec<_> = std::fs::read_dir(d.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        assert_eq!(names, vec![LOG.to_string()]);
    }

    /// A batch nobody waits on is appended without a sync, and read back like any other; the
    /// next durable batch's sync covers it (one sync for both).
    #[test]
    fn batches_nobody_waits_on_are_written_without_a_sync() {
        let d = dir("lazy");
        let mut log = JobLog::open(d.path()).unwrap();
        let before = log.syncs;
        assert!(log.append(&[rec("a1", 1)], false).iter().all(Result::is_ok));
        assert!(
            log.append(&[rec("b2", 1), ("a1".into(), None)], false)
                .iter()
                .all(Result::is_ok)
        );
        assert_eq!(log.syncs, before);
        assert!(log.append(&[rec("c3", 1)], true).iter().all(Result::is_ok));
        assert_eq!(log.syncs, before + 1);
        drop(log);
        assert_eq!(
            sorted(&JobLog::open(d.path()).unwrap()),
            vec![
                "{\"id\":\"b2\",\"v\":1}".to_string(),
                "{\"id\":\"c3\",\"v\":1}".to_string()
            ]
        );
    }

    #[test]
    fn bad_ids_and_line_breaks_fail_alone() {
        let d = dir("bad");
        let mut log = JobLog::open(d.path()).unwrap();
        let r = log.append(
            &[
                ("../x".into(), Some(Bytes::from_static(b"{}"))),
                ("a1".into(), Some(Bytes::from_static(b"{\n}"))),
                rec("b2", 7),
                ("../y".into(), None),
            ],
            true,
        );
        assert!(matches!(r[0], Err(StoreError::Corrupt(_))));
        assert!(matches!(r[1], Err(StoreError::Corrupt(_))));
        assert!(r[2].is_ok() && r[3].is_ok());
        drop(log);
        assert_eq!(
            sorted(&JobLog::open(d.path()).unwrap()),
            vec!["{\"id\":\"b2\",\"v\":7}".to_string()]
        );
    }

    /// A torn tail (half a line, as a crash mid-append leaves) and a damaged line are skipped,
    /// the rest read; the log is rewritten at open so that the next append starts a whole line.
    #[test]
    fn torn_and_damaged_lines_are_skipped_and_the_log_rewritten() {
        let d = dir("torn");
        let mut log = JobLog::open(d.path()).unwrap();
        assert!(
            log.append(&[rec("a1", 1), rec("b2", 1)], true)
                .iter()
                .all(Result::is_ok)
        );
        drop(log);
        let p = d.join(LOG);
        let mut bytes = std::fs::read(&p).unwrap();
        // Damage b2's line (one byte of its payload) and tear a third one off.
        let b2 = bytes.windows(6).rposition(|w| w == b"\"v\":1}").unwrap();
        bytes[b2 + 4] = b'9';
        let third = line("c3", Some(b"{\"id\":\"c3\"}"));
        bytes.extend_from_slice(&third[..third.len() / 2]);
        std::fs::write(&p, &bytes).unwrap();
        let mut log = JobLog::open(d.path()).unwrap();
        assert_eq!(sorted(&log), vec!["{\"id\":\"a1\",\"v\":1}".to_string()]);
        let after_open = std::fs::read(&p).unwrap();
        assert_eq!(after_open.last(), Some(&b'\n'));
        assert!(log.append(&[rec("d4", 1)], true).iter().all(Result::is_ok));
        drop(log);
        assert_eq!(
            sorted(&JobLog::open(d.path()).unwrap()),
            vec![
                "{\"id\":\"a1\",\"v\":1}".to_string(),
                "{\"id\":\"d4\",\"v\":1}".to_string()
            ]
        );
    }

    /// Records of earlier versions (`{id}.json`) move into the log and their files go.
    #[test]
    fn per_file_records_of_earlier_versions_move_into_the_log() {
        let d = dir("legacy");
        std::fs::write(d.join("a1.json"), b"{\"id\":\"a1\",\"old\":true}").unwrap();
        std::fs::write(d.join("b2.json"), b"{\"id\":\"b2\",\"old\":true}").unwrap();
        std::fs::write(d.join("notes.txt"), b"kept").unwrap();
        let log = JobLog::open(d.path()).unwrap();
        assert_eq!(
            sorted(&log),
            vec![
                "{\"id\":\"a1\",\"old\":true}".to_string(),
                "{\"id\":\"b2\",\"old\":true}".to_string()
            ]
        );
        let mut names: Vec<_> = std::fs::read_dir(d.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        names.sort();
        assert_eq!(names, vec!["notes.txt".to_string(), LOG.to_string()]);
        drop(log);
        assert_eq!(JobLog::open(d.path()).unwrap().count(), 2);
    }

    /// The log stays within a bounded multiple of its live lines however many changes it takes.
    #[test]
    fn rewrites_keep_the_log_near_its_live_size() {
        let d = dir("compact");
        let mut log = JobLog::open(d.path()).unwrap();
        let pad = "x".repeat(200);
        let mut max_len = 0;
        for round in 0..400u32 {
            let batch: Vec<_> = (0..50u32)
                .map(|j| {
                    let id = format!("j{:03}", (round * 50 + j) % 300);
                    let body = format!("{{\"id\":\"{id}\",\"round\":{round},\"pad\":\"{pad}\"}}");
                    (id, Some(Bytes::from(body)))
                })
                .collect();
            assert!(log.append(&batch, true).iter().all(Result::is_ok));
            max_len = max_len.max(std::fs::metadata(d.join(LOG)).unwrap().len());
        }
        assert_eq!(log.count(), 300);
        let live = log.live_bytes;
        // 400 × 50 changes of ~250 bytes: 5 MB appended in all.
        assert!(
            max_len <= COMPACT_MIN.max(COMPACT_RATIO * live) + 50 * 300,
            "{max_len} {live}"
        );
        drop(log);
        let log = JobLog::open(d.path()).unwrap();
        assert_eq!(log.count(), 300);
        assert!(sorted(&log).iter().all(|r| r.contains("\"round\":")));
        // Every job's newest: j000..j299 last written in rounds 394..399.
        assert!(sorted(&log).iter().all(|r| r.contains("\"round\":39")));
    }
}
