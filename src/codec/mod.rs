//! Volumes to bytes and back: the native `.vxl` (zstd), `.binvox` and `.npy`, `.png`
//! pictures, and OpenVDB's `.vdb` (written only). Which formats there are, and what each holds, is the table of `format.rs`; every
//! format states its axis and bit order in its own module docs. Nothing here knows about meshes
//! or engines.

pub mod binvox;
pub mod format;
pub mod indices;
pub mod npy;
pub mod npz;
pub mod palette;
pub mod png;
pub mod points;
pub mod vdb;
pub mod vox;
pub mod vxl;

pub use format::{FORMATS, FormatSpec, VolumeFormat};

use crate::volume::Volume;

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum CodecError {
    #[error("{format}: {detail}")]
    Malformed {
        format: &'static str,
        detail: String,
    },
    #[error("{format} cannot hold this volume: {detail}")]
    Unsupported {
        format: &'static str,
        detail: String,
    },
}

pub(crate) fn malformed(format: &'static str, detail: impl Into<String>) -> CodecError {
    CodecError::Malformed {
        format,
        detail: detail.into(),
    }
}

impl VolumeFormat {
    /// From the first bytes of a file (its row's `magic`).
    pub fn sniff(bytes: &[u8]) -> Option<VolumeFormat> {
        FORMATS
            .iter()
            .find(|f| f.magic.is_some_and(|m| bytes.starts_with(m)))
            .map(|f| f.format)
    }

    /// Can this format hold `v` (its row's `holds`)? Checked before anything is written.
    pub fn check(self, v: &Volume) -> Result<(), CodecError> {
        let holds = self.holds();
        if holds.contains(&v.kind()) {
            return Ok(());
        }
        let names: Vec<&str> = holds.iter().map(|k| k.as_str()).collect();
        Err(CodecError::Unsupported {
            format: self.name(),
            detail: format!(
                "it holds {} volumes, not {}; use vxl",
                names.join(" or "),
                v.kind()
            ),
        })
    }

    pub fn encode(self, v: &Volume) -> Result<Vec<u8>, CodecError> {
        self.check(v)?;
        let mut out = vec![];
        match self {
            VolumeFormat::Vxl => return vxl::encode(v, &serde_json::Map::new()),
            VolumeFormat::Vdb => return Ok(vdb::encode(v).expect("checked above")),
            _ => self.write(v, &mut out).expect("writing to memory"),
        }
        Ok(out)
    }

    /// Writes `v` in this format to `out` a piece at a time: `.npy`, `.raw` and `.binvox` are
    /// generated column by column (a 2048³ volume is 8 GiB as `.npy`, and the padded cube of
    /// a long, thin grid far more than the grid), `.vxl` is compressed first (it is small).
    /// A volume the format cannot hold is `InvalidInput`: call [`VolumeFormat::check`] first
    /// for the reason.
    pub fn write(self, v: &Volume, out: &mut impl std::io::Write) -> std::io::Result<()> {
        match self {
            VolumeFormat::Vxl => {
                let b = vxl::encode(v, &serde_json::Map::new())
                    .map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidInput, e))?;
                out.write_all(&b)
            }
            VolumeFormat::Vdb => match vdb::encode(v) {
                Some(b) => out.write_all(&b),
                None => Err(std::io::Error::new(
                    std::io::ErrorKind::InvalidInput,
                    format!("vdb holds sparse distance or bit volumes, not {}", v.kind()),
                )),
            },
            VolumeFormat::Binvox => binvox::write(v, out),
            VolumeFormat::Npy => npy::write(v, out),
            VolumeFormat::Raw => npy::write_data(v, out),
            VolumeFormat::Vox => vox::write(v, out),
            VolumeFormat::Indices => indices::write(v, out),
            VolumeFormat::Points => points::write(v, out),
        }
    }

    /// The exact length of `v` in this format, where it is known without encoding (`.npy`,
    /// `.raw`, `.vox`, `indices`: counted first).
    pub fn encoded_len(self, v: &Volume) -> Option<u64> {
        let n = v
            .grid()
            .voxel_count()
            .saturating_mul(npy::value_bytes_of(v));
        match self {
            VolumeFormat::Npy => Some(npy::header_of(v).len() as u64 + n),
            VolumeFormat::Raw => Some(n),
            VolumeFormat::Vox => vox::Plan::new(v).ok().map(|p| p.len()),
            VolumeFormat::Indices => indices::len(v),
            VolumeFormat::Points => points::len(v),
            VolumeFormat::Vxl | VolumeFormat::Binvox | VolumeFormat::Vdb => None,
        }
    }

    pub fn decode(self, bytes: &[u8]) -> Result<Volume, CodecError> {
        self.decode_limited(bytes, u64::MAX)
    }

    /// [`VolumeFormat::decode`], refusing a grid of more than `max_voxels` voxels before it is
    /// allocated (a compressed `.vxl` or run-length `.binvox` of a few bytes can name a huge
    /// grid; a `.npy` holds one byte per voxel, so it is bounded by its own size).
    pub fn decode_limited(self, bytes: &[u8], max_voxels: u64) -> Result<Volume, CodecError> {
        match self {
            VolumeFormat::Vxl => vxl::decode_limited(bytes, max_voxels).map(|(v, _)| v),
            VolumeFormat::Binvox => binvox::decode_limited(bytes, max_voxels).map(Volume::Bits),
            VolumeFormat::Npy => npy::decode(bytes),
            VolumeFormat::Raw => Err(CodecError::Unsupported {
                format: "raw",
                detail: "a .raw file has no header (no dims, no grid), so it cannot be read back; use .vxl or .npy".into(),
            }),
            VolumeFormat::Vdb => Err(CodecError::Unsupported {
                format: "vdb",
                detail: "voxd writes .vdb files but does not read them; use .vxl".into(),
            }),
            VolumeFormat::Vox => Err(CodecError::Unsupported {
                format: "vox",
                detail: "voxd writes .vox files but does not read them; use .vxl".into(),
            }),
            VolumeFormat::Indices => Err(CodecError::Unsupported {
                format: "indices",
                detail: "a list of voxel indices has no grid, so it cannot be read back; use .vxl or .npy".into(),
            }),
            VolumeFormat::Points => Err(CodecError::Unsupported {
                format: "points",
                detail: "a point cloud has no grid, so it cannot be read back; use .vxl or .npy".into(),
            }),
        }
    }
}
