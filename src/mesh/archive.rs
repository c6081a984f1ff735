//! Zip uploads (issue 34): a `.zip` holding one mesh and the files it refers to (an OBJ with its
//! `.mtl`; a `.gltf` with its buffers), recognised by its bytes (`PK\x03\x04`) like gzip. Read by
//! the zip crate, every entry checked before its bytes are kept:
//!
//! * at most [`MAX_ENTRIES`] entries;
//! * names that stay inside the archive (no absolute path, no `..`, no drive): else refused
//!   naming the entry;
//! * no symbolic links, no encrypted entries;
//! * each entry's inflated size (as declared, and as read: inflating stops one byte past the
//!   declared size) within what is left of the upload's decompressed-byte limit, all entries
//!   together within it;
//! * an entry that inflates more than [`MAX_RATIO`] times its compressed size (past 1 MiB) is
//!   refused as a bomb.
//!
//! The mesh is the one entry whose extension names a mesh format (`.obj`, `.glb`, `.gltf`,
//! `.stl`, `.ply`, optionally `.gz`); none or several is refused. Directories are skipped. The
//! other entries are what the mesh may read ([`super::ExternalResources::Archive`]), by paths
//! relative to the mesh's own directory in the archive.

use std::collections::HashMap;
use std::io::Read;
use std::sync::Arc;

use super::{Format, MeshError};

/// Entries an archive may hold.
pub const MAX_ENTRIES: usize = 1024;
/// Largest inflated / compressed size of an entry over 1 MiB.
pub const MAX_RATIO: u64 = 256;

/// Is it a zip (a local file header first)?
pub fn is_zip(bytes: &[u8]) -> bool {
    bytes.starts_with(b"PK\x03\x04")
}

/// The files of an archive, by their normalised names (`/`-separated, no `.` parts).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Archive {
    pub files: HashMap<String, Vec<u8>>,
    /// The mesh's directory inside the archive (`""` at the top), where relative references
    /// start.
    pub dir: String,
}

impl Archive {
    /// The file `rel` refers to from the mesh's directory, `None` when it escapes the archive
    /// or is not in it.
    pub fn get(&self, rel: &str) -> Option<&[u8]> {
        let mut parts: Vec<&str> = self.dir.split('/').filter(|p| !p.is_empty()).collect();
        for p in rel.split(['/', '\\']) {
            match p {
                "" | "." => {}
                ".." => {
                    parts.pop()?;
                }
                p if p.contains(':') => return None,
                p => parts.push(p),
            }
        }
        self.files.get(&parts.join("/")).map(Vec::as_slice)
    }
}

fn refuse(detail: String) -> MeshError {
    MeshError::Malformed {
        format: "zip",
        detail,
    }
}

/// An opened zip: the mesh's bytes, its format by name, its name, and the other files.
pub type Opened = (Vec<u8>, Option<Format>, String, Arc<Archive>);

/// Opens a zip upload within `max_bytes` of inflated entries: the mesh's bytes, its format
/// (from its name), and the archive of the other files.
pub fn open(bytes: &[u8], max_bytes: u64) -> Result<Opened, MeshError> {
    let mut zip = zip::ZipArchive::new(std::io::Cursor::new(bytes))
        .map_err(|e| refuse(format!("not a readable zip archive: {e}")))?;
    if zip.len() > MAX_ENTRIES {
        return Err(refuse(format!(
            "{} entries, more than the {MAX_ENTRIES} an upload may hold",
            zip.len()
        )));
    }
    let mut files = HashMap::new();
    let mut left = max_bytes;
    let mut meshes: Vec<String> = vec![];
    for i in 0..zip.len() {
        let mut f = zip
            .by_index(i)
            .map_err(|e| refuse(format!("entry {i}: {e}")))?;
        let name = f
            .name()
            .map_or_else(|_| format!("entry {i}"), |n| n.into_owned());
        if f.is_symlink() {
            return Err(refuse(format!("entry {name:?} is a symbolic link")));
        }
        // The name as stored: the zip crate's own check forgives a leading `/`.
        let escapes = name.starts_with(['/', '\\'])
            || name.contains(':')
            || name.split(['/', '\\']).any(|p| p == "..");
        let Some(path) = f.enclosed_name().filter(|_| !escapes) else {
            return Err(refuse(format!(
                "entry {name:?} names a path outside the archive (absolute or through ..)"
            )));
        };
        if f.is_dir() {
            continue;
        }
        if f.encrypted() {
            return Err(refuse(format!("entry {name:?} is encrypted")));
        }
        let size = f.size();
        if size > left {
            return Err(MeshError::Malformed {
                format: "zip",
                detail: format!(
                    "entry {name:?} inflates to {size} bytes, over the {left} left of the upload's limit of {max_bytes} inflated bytes"
                ),
            });
        }
        let packed = f.compressed_size().max(1);
        if size > 1 << 20 && size / packed > MAX_RATIO {
            return Err(refuse(format!(
                "entry {name:?} inflates {} times ({packed} bytes to {size}): refused as a zip bomb (at most {MAX_RATIO} times)",
                size / packed
            )));
        }
        let mut data = Vec::with_capacity(size as usize);
        (&mut f)
            .take(size + 1)
            .read_to_end(&mut data)
            .map_err(|e| refuse(format!("entry {name:?}: {e}")))?;
        if data.len() as u64 != size {
            return Err(refuse(format!(
                "entry {name:?} inflates to other than the {size} bytes its header declares"
            )));
        }
        left -= size;
        let norm: Vec<String> = path
            .components()
            .filter_map(|c| match c {
                std::path::Component::Normal(p) => Some(p.to_string_lossy().into_owned()),
                _ => None,
            })
            .collect();
        let norm = norm.join("/");
        let lower = norm.to_ascii_lowercase();
        let stem = lower.strip_suffix(".gz").unwrap_or(&lower);
        if [".obj", ".glb", ".gltf", ".stl", ".ply"]
            .iter()
            .any(|e| stem.ends_with(e))
        {
            meshes.push(norm.clone());
        }
        files.insert(norm, data);
    }
    let mesh = match meshes.as_slice() {
        [one] => one.clone(),
        [] => {
            return Err(refuse(
                "the archive holds no mesh (.obj, .glb, .gltf, .stl or .ply)".into(),
            ));
        }
        several => {
            return Err(refuse(format!(
                "the archive holds several meshes ({}); upload one at a time",
                several.join(", ")
            )));
        }
    };
    let data = files.remove(&mesh).expect("listed");
    let format = Format::from_path(std::path::Path::new(&mesh));
    let dir = mesh.rsplit_once('/').map_or("", |(d, _)| d).to_string();
    Ok((data, format, mesh, Arc::new(Archive { files, dir })))
}

/// The sum of the inflated sizes an archive's entries declare (its central directory, read
/// without inflating anything), for the upload's memory estimate; `None` when it is not a
/// readable zip or has too many entries (the load refuses it).
pub fn declared_size(bytes: &[u8]) -> Option<u64> {
    let mut zip = zip::ZipArchive::new(std::io::Cursor::new(bytes)).ok()?;
    if zip.len() > MAX_ENTRIES {
        return None;
    }
    let mut total = 0u64;
    for i in 0..zip.len() {
        total = total.saturating_add(zip.by_index_raw(i).ok()?.size());
    }
    Some(total)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn references_resolve_from_the_meshs_folder_and_never_leave_the_archive() {
        let a = Archive {
            files: [("m/a.mtl", b"a"), ("t/b.png", b"b"), ("c.bin", b"c")]
                .into_iter()
                .map(|(k, v)| (k.to_string(), v.to_vec()))
                .collect(),
            dir: "m".into(),
        };
        assert_eq!(a.get("a.mtl"), Some(&b"a"[..]));
        assert_eq!(a.get("./a.mtl"), Some(&b"a"[..]));
        assert_eq!(a.get("../t/b.png"), Some(&b"b"[..]));
        assert_eq!(a.get("..\\c.bin"), Some(&b"c"[..]));
        assert_eq!(a.get("../../c.bin"), None);
        assert_eq!(a.get("C:/c.bin"), None);
        assert_eq!(a.get("b.png"), None);
    }
}
