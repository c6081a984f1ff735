//! Stored volumes on local disk: `volumes/{id}.vxl` (the native format) and `volumes/{id}.json`
//! (metadata). Every file is written to a temporary name, fsynced, renamed and the directory
//! fsynced; the metadata is written last and is the commit point, so a process killed mid-write
//! leaves either a whole volume or nothing that is listed (leftovers are removed at start).

use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use serde::{Deserialize, Serialize};

use crate::grid::Grid;
use crate::mesh::MeshDiagnostics;

/// What the API says about a stored volume.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct VolumeMeta {
    pub id: String,
    pub name: Option<String>,
    pub kind: String,
    pub method: String,
    pub grid: Grid,
    /// Set voxels.
    pub solid_voxels: u64,
    /// `solid_voxels · voxel_size³`, in mesh units cubed.
    pub volume: f64,
    pub source: SourceInfo,
    pub diagnostics: Option<MeshDiagnostics>,
    /// How the solid was filled: the fill asked for and used, odd-parity columns, a warning
    /// for parity on a mesh that is not watertight (absent for derived volumes).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fill: Option<crate::engine::fill::FillReport>,
    pub engine: String,
    /// RFC 3339, UTC.
    pub created: String,
    /// Size of the stored `.vxl`.
    pub bytes: u64,
    /// sha256 of the stored `.vxl`, the basis of download ETags.
    pub sha256: String,
    /// For volumes computed from others: the CSG expression.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub provenance: Option<serde_json::Value>,
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct SourceInfo {
    pub format: String,
    pub sha256: String,
    pub triangles: usize,
}

#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    #[error(
        "storing this volume ({need} bytes) would exceed the store's limit of {limit} bytes ({used} used); delete volumes first"
    )]
    Full { need: u64, used: u64, limit: u64 },
    #[error("storage I/O: {0}")]
    Io(#[from] std::io::Error),
}

pub struct Store {
    dir: PathBuf,
    limit: u64,
    index: Mutex<BTreeMap<String, VolumeMeta>>,
}

impl Store {
    /// Opens (creating) `data_dir/volumes`, removes leftovers of interrupted writes and indexes
    /// what is there.
    pub fn open(data_dir: &Path, limit: u64) -> Result<Store, StoreError> {
        let dir = data_dir.join("volumes");
        std::fs::create_dir_all(&dir)?;
        let mut index = BTreeMap::new();
        let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .collect();
        files.sort();
        for p in &files {
            let name = p.file_name().and_then(|n| n.to_str()).unwrap_or("");
            if name.starts_with('.') {
                let _ = std::fs::remove_file(p); // an interrupted temporary file
                continue;
            }
            if p.extension().is_some_and(|e| e == "json") {
                match std::fs::read(p)
                    .ok()
                    .and_then(|b| serde_json::from_slice::<VolumeMeta>(&b).ok())
                {
                    Some(m) if dir.join(format!("{}.vxl", m.id)).exists() => {
                        index.insert(m.id.clone(), m);
                    }
                    _ => tracing::warn!(path = %p.display(), "ignoring unreadable volume metadata"),
                }
            }
        }
        for p in &files {
            if p.extension().is_some_and(|e| e == "vxl") {
                let id = p.file_stem().and_then(|s| s.to_str()).unwrap_or("");
                if !index.contains_key(id) {
                    let _ = std::fs::remove_file(p); // data without its commit record
                }
            }
        }
        tracing::info!(volumes = index.len(), dir = %dir.display(), "store opened");
        Ok(Store {
            dir,
            limit,
            index: Mutex::new(index),
        })
    }

    pub fn used_bytes(&self) -> u64 {
        self.index.lock().unwrap().values().map(|m| m.bytes).sum()
    }

    /// Stores a volume's `.vxl` bytes and metadata.
    pub fn put(&self, meta: VolumeMeta, vxl: &[u8]) -> Result<(), StoreError> {
        let used = self.used_bytes();
        if used + vxl.len() as u64 > self.limit {
            return Err(StoreError::Full {
                need: vxl.len() as u64,
                used,
                limit: self.limit,
            });
        }
        write_atomic(&self.dir, &format!("{}.vxl", meta.id), vxl)?;
        write_atomic(
            &self.dir,
            &format!("{}.json", meta.id),
            &serde_json::to_vec_pretty(&meta).expect("metadata serialises"),
        )?;
        self.index.lock().unwrap().insert(meta.id.clone(), meta);
        Ok(())
    }

    pub fn get(&self, id: &str) -> Option<VolumeMeta> {
        self.index.lock().unwrap().get(id).cloned()
    }

    /// Up to `limit` volumes with ids after `after`, in id order, and whether more follow.
    pub fn list(&self, after: Option<&str>, limit: usize) -> (Vec<VolumeMeta>, bool) {
        let idx = self.index.lock().unwrap();
        let mut it = idx
            .values()
            .filter(|m| after.is_none_or(|a| m.id.as_str() > a));
        let page: Vec<VolumeMeta> = it.by_ref().take(limit).cloned().collect();
        let more = it.next().is_some();
        (page, more)
    }

    pub fn read(&self, id: &str) -> Result<Option<Vec<u8>>, StoreError> {
        if !self.index.lock().unwrap().contains_key(id) {
            return Ok(None);
        }
        Ok(Some(std::fs::read(self.dir.join(format!("{id}.vxl")))?))
    }

    /// Removes a volume; false when there was none.
    pub fn delete(&self, id: &str) -> Result<bool, StoreError> {
        if self.index.lock().unwrap().remove(id).is_none() {
            return Ok(false);
        }
        // Metadata first: once it is gone the volume is gone, whatever happens next.
        std::fs::remove_file(self.dir.join(format!("{id}.json")))?;
        let _ = std::fs::remove_file(self.dir.join(format!("{id}.vxl")));
        sync_dir(&self.dir)?;
        Ok(true)
    }

    /// Can a file be written and removed in the store right now?
    pub fn writable(&self) -> bool {
        write_atomic(&self.dir, ".probe", b"ok").is_ok()
            && std::fs::remove_file(self.dir.join(".probe")).is_ok()
    }
}

/// Writes `dir/name` so that it is either the old file or the whole new one, durably.
pub(super) fn write_atomic(dir: &Path, name: &str, bytes: &[u8]) -> std::io::Result<()> {
    let tmp = dir.join(format!(".{name}.{}.tmp", std::process::id()));
    let result = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, dir.join(name))?;
        sync_dir(dir)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

fn sync_dir(dir: &Path) -> std::io::Result<()> {
    std::fs::File::open(dir)?.sync_all()
}
