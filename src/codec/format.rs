//! The download formats, one row each ([`FORMATS`]): name (also the file extension), media
//! type, the volume kinds it can hold, whether it is written a piece at a time, whether it
//! can be read back, and the bytes its files start with. The codecs, `app::ops`, the volume
//! routes and the command line all read this table; adding a format is its codec file plus one
//! row (and the arms of [`VolumeFormat`]'s `write`/`decode` in `codec/mod.rs`). Not here: the
//! bytes (each codec's module).

use crate::names::Named;
use crate::volume::VolumeKind;

/// Volume file formats.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VolumeFormat {
    Vxl,
    Binvox,
    Npy,
    /// One byte per voxel (a `f32` for distances), C order of (X, Y, Z), no header: written,
    /// never read back.
    Raw,
    /// OpenVDB: a sparse distance volume as a level-set FloatGrid, a bit volume as a BoolGrid.
    /// Written, never read back.
    Vdb,
    /// MagicaVoxel `.vox`: a bit volume cut into models of at most 256³ placed by the scene
    /// graph. Written, never read back.
    Vox,
    /// The set voxels of a bit volume as an (N, 3) `uint32` `.npy`. Written, never read back.
    Indices,
    /// The set voxels' centres as a PLY point cloud. Written, never read back.
    Points,
}

/// One format's row.
#[derive(Debug)]
pub struct FormatSpec {
    pub format: VolumeFormat,
    /// Its name in `?format=`.
    pub name: &'static str,
    /// Its file extension (without the first dot): the name, but for `indices.npy`.
    pub extension: &'static str,
    pub media_type: &'static str,
    /// The kinds it can hold.
    pub holds: &'static [VolumeKind],
    /// Written a piece at a time (a column, a run): never held whole in memory. The others
    /// are encoded whole first (`.vxl` is compressed, so it is small).
    pub streams: bool,
    /// Can a file of it be read back (it carries its dims)?
    pub reads: bool,
    /// The bytes a file of it starts with, for recognising it (`None`: no header).
    pub magic: Option<&'static [u8]>,
}

/// A dense array: one byte per voxel (a bit's 0/1 or a density's level) or one `f32` (a
/// distance, dense or sparse: every voxel written).
const ARRAY_KINDS: &[VolumeKind] = &[
    VolumeKind::Bits,
    VolumeKind::Channels,
    VolumeKind::Density,
    VolumeKind::Distance,
    VolumeKind::SparseDistance,
];

/// OpenVDB grids: a level set of a sparse distance volume, a BoolGrid of a bit volume.
const VDB_KINDS: &[VolumeKind] = &[
    VolumeKind::SparseDistance,
    VolumeKind::Bits,
    VolumeKind::Channels,
];

/// The formats, in the order messages list them; row `i` is `VolumeFormat` value `i`.
pub const FORMATS: &[FormatSpec] = &[
    FormatSpec {
        format: VolumeFormat::Vxl,
        name: "vxl",
        extension: "vxl",
        media_type: "application/vnd.voxd.vxl",
        holds: <VolumeKind as Named>::ALL,
        streams: false,
        reads: true,
        magic: Some(super::vxl::MAGIC),
    },
    FormatSpec {
        format: VolumeFormat::Binvox,
        name: "binvox",
        extension: "binvox",
        media_type: "application/x-binvox",
        holds: crate::volume::BITS_AND_CHANNELS,
        streams: true,
        reads: true,
        magic: Some(b"#binvox"),
    },
    FormatSpec {
        format: VolumeFormat::Npy,
        name: "npy",
        extension: "npy",
        media_type: "application/x-npy",
        holds: ARRAY_KINDS,
        streams: true,
        reads: true,
        magic: Some(super::npy::MAGIC),
    },
    FormatSpec {
        format: VolumeFormat::Raw,
        name: "raw",
        extension: "raw",
        media_type: "application/octet-stream",
        holds: ARRAY_KINDS,
        streams: true,
        reads: false,
        magic: None,
    },
    FormatSpec {
        format: VolumeFormat::Vdb,
        name: "vdb",
        extension: "vdb",
        media_type: "application/x-vdb",
        holds: VDB_KINDS,
        streams: false,
        reads: false,
        magic: Some(super::vdb::MAGIC),
    },
    FormatSpec {
        format: VolumeFormat::Vox,
        name: "vox",
        extension: "vox",
        media_type: "application/x-vox",
        holds: crate::volume::BITS_AND_CHANNELS,
        streams: true,
        reads: false,
        magic: Some(super::vox::MAGIC),
    },
    FormatSpec {
        format: VolumeFormat::Indices,
        name: "indices",
        extension: "indices.npy",
        media_type: "application/x-npy",
        holds: crate::volume::BITS_AND_CHANNELS,
        streams: true,
        reads: false,
        // A `.npy` like any other: recognised by its extension, not its bytes.
        magic: None,
    },
    FormatSpec {
        format: VolumeFormat::Points,
        name: "points",
        // Not `.ply`: that names a mesh to read (`voxd info x.ply`).
        extension: "points.ply",
        media_type: "application/x-ply",
        holds: crate::volume::BITS_AND_CHANNELS,
        streams: true,
        reads: false,
        magic: None,
    },
];

const _: () = {
    let mut i = 0;
    while i < FORMATS.len() {
        assert!(
            FORMATS[i].format as usize == i,
            "FORMATS is in VolumeFormat's order"
        );
        i += 1;
    }
};

impl Named for VolumeFormat {
    const WHAT: &'static str = "format";
    const ALL: &'static [VolumeFormat] = &[
        VolumeFormat::Vxl,
        VolumeFormat::Binvox,
        VolumeFormat::Npy,
        VolumeFormat::Raw,
        VolumeFormat::Vdb,
        VolumeFormat::Vox,
        VolumeFormat::Indices,
        VolumeFormat::Points,
    ];
    fn name(self) -> &'static str {
        self.spec().name
    }
}

crate::impl_named!(VolumeFormat);

impl VolumeFormat {
    /// This format's row.
    pub const fn spec(self) -> &'static FormatSpec {
        &FORMATS[self as usize]
    }
    pub const fn name(self) -> &'static str {
        self.spec().name
    }
    /// The file extension (without the first dot).
    pub const fn extension(self) -> &'static str {
        self.spec().extension
    }
    pub const fn media_type(self) -> &'static str {
        self.spec().media_type
    }
    /// The kinds this format can hold.
    pub const fn holds(self) -> &'static [VolumeKind] {
        self.spec().holds
    }
    /// The format named `s`, in any case.
    pub fn from_name(s: &str) -> Option<VolumeFormat> {
        FORMATS
            .iter()
            .find(|f| f.name.eq_ignore_ascii_case(s))
            .map(|f| f.format)
    }
    /// By file extension, the longest that matches (`a.indices.npy` is `indices`, `a.npy`
    /// is `npy`), in any case.
    pub fn from_path(p: &std::path::Path) -> Option<VolumeFormat> {
        let name = p.file_name()?.to_str()?.to_ascii_lowercase();
        FORMATS
            .iter()
            .filter(|f| name.ends_with(&format!(".{}", f.extension)))
            .max_by_key(|f| f.extension.len())
            .map(|f| f.format)
    }
    /// The names, comma-separated ("vxl, binvox, npy, raw, vdb, vox, indices, points"), for messages.
    pub fn names() -> String {
        FORMATS
            .iter()
            .map(|f| f.name)
            .collect::<Vec<_>>()
            .join(", ")
    }
    /// The extensions of the formats that read back, as a command line lists them
    /// (".vxl, .binvox or .npy").
    pub fn readable_extensions() -> String {
        let e: Vec<String> = FORMATS
            .iter()
            .filter(|f| f.reads)
            .map(|f| format!(".{}", f.name))
            .collect();
        match e.split_last() {
            Some((last, rest)) if !rest.is_empty() => format!("{} or {last}", rest.join(", ")),
            _ => e.concat(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_name_their_formats() {
        assert_eq!(
            VolumeFormat::names(),
            "vxl, binvox, npy, raw, vdb, vox, indices, points"
        );
        let p = |s: &str| VolumeFormat::from_path(std::path::Path::new(s));
        assert_eq!(p("a/b.INDICES.npy"), Some(VolumeFormat::Indices));
        assert_eq!(p("b.npy"), Some(VolumeFormat::Npy));
        assert_eq!(p("b.vox"), Some(VolumeFormat::Vox));
        assert_eq!(p("indices.npy"), Some(VolumeFormat::Npy));
        assert_eq!(p("b.obj"), None);
        assert_eq!(p("b.points.ply"), Some(VolumeFormat::Points));
        assert_eq!(p("b.ply"), None);
        assert_eq!(VolumeFormat::readable_extensions(), ".vxl, .binvox or .npy");
        for &f in <VolumeFormat as Named>::ALL {
            assert_eq!(VolumeFormat::from_name(&f.name().to_uppercase()), Some(f));
            assert_eq!(f.name().parse::<VolumeFormat>(), Ok(f));
        }
        assert!(VolumeFormat::Npy.holds().contains(&VolumeKind::Density));
        assert!(!VolumeFormat::Binvox.holds().contains(&VolumeKind::Density));
        assert!(
            VolumeFormat::Vdb
                .holds()
                .contains(&VolumeKind::SparseDistance)
        );
        assert!(!VolumeFormat::Vdb.holds().contains(&VolumeKind::Density));
        assert!(
            VolumeFormat::Npy
                .holds()
                .contains(&VolumeKind::SparseDistance)
        );
    }

    /// The contract's `?format=` of a download lists this table's names, in its order.
    #[test]
    fn the_openapi_download_formats_are_the_table() {
        let spec = include_str!("../../openapi.yaml");
        let want = format!("enum: [{}], default: vxl", VolumeFormat::names());
        assert!(spec.contains(&want), "openapi.yaml lacks {want:?}");
    }
}
