//! Volumes to bytes and back: the native `.vxl` (zstd), `.binvox` and `.npy`. Nothing here knows
//! about meshes or engines; every format states its axis and bit order in its own module docs.

pub mod binvox;
pub mod npy;
pub mod png;
pub mod vxl;

use std::path::Path;

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

/// Volume file formats.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VolumeFormat {
    Vxl,
    Binvox,
    Npy,
    /// One byte per voxel, C order of (X, Y, Z), no header: written, never read back.
    Raw,
}

impl VolumeFormat {
    pub const ALL: [VolumeFormat; 4] = [
        VolumeFormat::Vxl,
        VolumeFormat::Binvox,
        VolumeFormat::Npy,
        VolumeFormat::Raw,
    ];

    pub fn name(self) -> &'static str {
        match self {
            VolumeFormat::Vxl => "vxl",
            VolumeFormat::Binvox => "binvox",
            VolumeFormat::Npy => "npy",
            VolumeFormat::Raw => "raw",
        }
    }
    pub fn from_name(s: &str) -> Option<VolumeFormat> {
        VolumeFormat::ALL
            .into_iter()
            .find(|f| f.name().eq_ignore_ascii_case(s))
    }
    pub fn from_path(p: &Path) -> Option<VolumeFormat> {
        VolumeFormat::from_name(p.extension()?.to_str()?)
    }
    /// From the first bytes of a file.
    pub fn sniff(bytes: &[u8]) -> Option<VolumeFormat> {
        if bytes.starts_with(vxl::MAGIC) {
            Some(VolumeFormat::Vxl)
        } else if bytes.starts_with(b"#binvox") {
            Some(VolumeFormat::Binvox)
        } else if bytes.starts_with(npy::MAGIC) {
            Some(VolumeFormat::Npy)
        } else {
            None
        }
    }

    pub fn encode(self, v: &Volume) -> Result<Vec<u8>, CodecError> {
        match self {
            VolumeFormat::Vxl => vxl::encode(v, &serde_json::Map::new()),
            VolumeFormat::Binvox => binvox::encode(v),
            VolumeFormat::Npy => Ok(npy::encode(v)),
            VolumeFormat::Raw => {
                let n = npy::encode(v);
                let hlen = u16::from_le_bytes([n[8], n[9]]) as usize;
                Ok(n[10 + hlen..].to_vec())
            }
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
        }
    }
}
