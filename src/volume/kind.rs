//! The closed set of volume kinds ([`VolumeKind`]), the element types a voxel can hold
//! ([`ValueType`], [`Voxel`]), a voxel's value in its own type ([`VoxelValue`]), and the refusal
//! every operation gives a kind it does not take ([`WrongKind`]).
//!
//! Not here: the volumes themselves (`mod.rs`, `dense.rs`, `channels.rs`, `sparse.rs`), nor which
//! kinds an operation takes: each operation states that beside its code (`csg::ACCEPTS`,
//! `morph::ACCEPTS`, ...), and each download format in its row of `codec::format`.

use serde::Serialize;

pub use crate::names::Named;

/// What a stored volume holds, and how. Its name is the `kind` of the volume's metadata and of
/// its `.vxl` header.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum VolumeKind {
    /// One bit per voxel, in Z-column words.
    Bits,
    /// One byte per voxel, 0..=max (the fraction of the voxel inside, in 1/max).
    Density,
    /// One `f32` per voxel: a distance (signed distance fields: negative inside).
    Distance,
    /// One `u16` per voxel: a material id (0: none).
    Material,
    /// One RGBA colour per voxel (alpha 0: none).
    Colour,
    /// A bit volume with per-voxel attribute channels (one value per set voxel).
    Channels,
    /// [`VolumeKind::Distance`] in 8³ bricks around a background value.
    SparseDistance,
    /// [`VolumeKind::Material`] in 8³ bricks.
    SparseMaterial,
    /// [`VolumeKind::Colour`] in 8³ bricks.
    SparseColour,
}

impl Named for VolumeKind {
    const WHAT: &'static str = "volume kind";
    const ALL: &'static [VolumeKind] = &[
        VolumeKind::Bits,
        VolumeKind::Density,
        VolumeKind::Distance,
        VolumeKind::Material,
        VolumeKind::Colour,
        VolumeKind::Channels,
        VolumeKind::SparseDistance,
        VolumeKind::SparseMaterial,
        VolumeKind::SparseColour,
    ];
    fn name(self) -> &'static str {
        self.row().0
    }
}

crate::impl_named!(VolumeKind);

impl VolumeKind {
    /// (name, how messages describe volumes of the kind, bits each voxel takes when decoded
    /// densely). The one table of the kinds.
    const fn row(self) -> (&'static str, &'static str, u64) {
        match self {
            VolumeKind::Bits => (
                "bits",
                "bit volumes (solid, surface, conservative, interior)",
                1,
            ),
            VolumeKind::Density => ("density", "density volumes", 8),
            VolumeKind::Distance => ("distance", "distance volumes", 32),
            VolumeKind::Material => ("material", "material volumes", 16),
            VolumeKind::Colour => ("colour", "colour volumes", 32),
            VolumeKind::Channels => ("channels", "bit volumes with attribute channels", 1),
            VolumeKind::SparseDistance => ("sparse-distance", "sparse distance volumes", 32),
            VolumeKind::SparseMaterial => ("sparse-material", "sparse material volumes", 16),
            VolumeKind::SparseColour => ("sparse-colour", "sparse colour volumes", 32),
        }
    }

    /// The kind's name (`bits`, `density`, ...), as metadata and `.vxl` headers spell it.
    pub const fn as_str(self) -> &'static str {
        self.row().0
    }

    /// How messages describe volumes of this kind ("density volumes").
    pub const fn describe(self) -> &'static str {
        self.row().1
    }

    /// An upper bound on the bytes a volume of this kind with `voxels` voxels takes decoded
    /// (sparse kinds: as if every brick were occupied; channels: the bits alone).
    pub fn decoded_bytes(self, voxels: u64) -> u64 {
        voxels.saturating_mul(self.row().2).div_ceil(8)
    }

    /// `Ok` when `accepts` holds this kind, else the refusal naming both.
    pub fn require(self, accepts: &'static [VolumeKind], what: &str) -> Result<(), WrongKind> {
        if accepts.contains(&self) {
            Ok(())
        } else {
            Err(WrongKind {
                given: self,
                accepts,
                what: what.into(),
            })
        }
    }
}

impl From<VolumeKind> for String {
    fn from(k: VolumeKind) -> String {
        k.as_str().to_string()
    }
}

/// An operation given a kind of volume it does not take: `wrong-volume-kind` in the API.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("a {given} volume; {what} works on {}", describe_all(accepts))]
pub struct WrongKind {
    pub given: VolumeKind,
    pub accepts: &'static [VolumeKind],
    /// The operation ("CSG", "morphology", "statistics", ...).
    pub what: String,
}

fn describe_all(kinds: &[VolumeKind]) -> String {
    let d: Vec<&str> = kinds.iter().map(|k| k.describe()).collect();
    match d.split_last() {
        Some((last, rest)) if !rest.is_empty() => format!("{} or {last}", rest.join(", ")),
        _ => d.concat(),
    }
}

crate::named_enum! {
    /// The element types a voxel, or an attribute channel, can hold; the names are the `.vxl`
    /// header's `value_type`.
    pub enum ValueType: "value type" {
        U8 = "u8",
        U16 = "u16le",
        F32 = "f32le",
        Rgba8 = "rgba8",
    }
}

impl ValueType {
    /// Bytes of one value in a `.vxl` payload.
    pub const fn bytes(self) -> usize {
        match self {
            ValueType::U8 => 1,
            ValueType::U16 => 2,
            ValueType::F32 | ValueType::Rgba8 => 4,
        }
    }
}

/// A voxel's value in its own type. Serialises as the bare value (a number, or an array of four
/// numbers for a colour), so bit (0/1) and density answers read as they always have.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(untagged)]
pub enum VoxelValue {
    U8(u8),
    U16(u16),
    F32(f32),
    Rgba8([u8; 4]),
}

/// An element type of dense and sparse volumes and of attribute channels: how it is stored in a
/// `.vxl` (little-endian) and whether a voxel holding it is occupied (rays, previews).
pub trait Voxel: Copy + PartialEq + std::fmt::Debug + Send + Sync + 'static {
    const TYPE: ValueType;
    /// The value a new volume is filled with (empty).
    const EMPTY: Self;
    fn write_le(self, out: &mut Vec<u8>);
    /// From exactly `TYPE.bytes()` bytes.
    fn read_le(b: &[u8]) -> Self;
    /// Occupied: non-zero ids and densities, alpha above zero, distances with the sign bit set
    /// (the inside of a signed distance field: −0.0 is a centre on the surface that is inside,
    /// +0.0 one that is outside).
    fn occupied(self) -> bool;
    fn value(self) -> VoxelValue;
    /// Can a volume hold this value? Every value but a NaN distance (which equals nothing, so a
    /// volume holding one would not equal itself read back).
    fn is_valid(self) -> bool {
        true
    }
}

impl Voxel for u8 {
    const TYPE: ValueType = ValueType::U8;
    const EMPTY: u8 = 0;
    fn write_le(self, out: &mut Vec<u8>) {
        out.push(self)
    }
    fn read_le(b: &[u8]) -> u8 {
        b[0]
    }
    fn occupied(self) -> bool {
        self != 0
    }
    fn value(self) -> VoxelValue {
        VoxelValue::U8(self)
    }
}

impl Voxel for u16 {
    const TYPE: ValueType = ValueType::U16;
    const EMPTY: u16 = 0;
    fn write_le(self, out: &mut Vec<u8>) {
        out.extend_from_slice(&self.to_le_bytes())
    }
    fn read_le(b: &[u8]) -> u16 {
        u16::from_le_bytes([b[0], b[1]])
    }
    fn occupied(self) -> bool {
        self != 0
    }
    fn value(self) -> VoxelValue {
        VoxelValue::U16(self)
    }
}

impl Voxel for f32 {
    const TYPE: ValueType = ValueType::F32;
    /// Far outside: no surface anywhere near.
    const EMPTY: f32 = f32::INFINITY;
    fn write_le(self, out: &mut Vec<u8>) {
        out.extend_from_slice(&self.to_le_bytes())
    }
    fn read_le(b: &[u8]) -> f32 {
        f32::from_le_bytes([b[0], b[1], b[2], b[3]])
    }
    fn occupied(self) -> bool {
        self.is_sign_negative() && !self.is_nan()
    }
    fn is_valid(self) -> bool {
        !self.is_nan()
    }
    fn value(self) -> VoxelValue {
        VoxelValue::F32(self)
    }
}

impl Voxel for [u8; 4] {
    const TYPE: ValueType = ValueType::Rgba8;
    const EMPTY: [u8; 4] = [0; 4];
    fn write_le(self, out: &mut Vec<u8>) {
        out.extend_from_slice(&self)
    }
    fn read_le(b: &[u8]) -> [u8; 4] {
        [b[0], b[1], b[2], b[3]]
    }
    fn occupied(self) -> bool {
        self[3] != 0
    }
    fn value(self) -> VoxelValue {
        VoxelValue::Rgba8(self)
    }
}

/// `values` as their little-endian bytes, back to back.
pub fn to_le_bytes<T: Voxel>(values: &[T]) -> Vec<u8> {
    let mut out = Vec::with_capacity(values.len() * T::TYPE.bytes());
    for &v in values {
        v.write_le(&mut out);
    }
    out
}

/// The values of `bytes` (a whole number of `T`s, checked by the caller).
pub fn from_le_bytes<T: Voxel>(bytes: &[u8]) -> Vec<T> {
    bytes
        .chunks_exact(T::TYPE.bytes())
        .map(T::read_le)
        .collect()
}

/// [`from_le_bytes`], refusing a value that is not [`Voxel::is_valid`].
pub fn valid_from_le_bytes<T: Voxel>(bytes: &[u8]) -> Result<Vec<T>, String> {
    let v = from_le_bytes::<T>(bytes);
    match v.iter().find(|x| !x.is_valid()) {
        Some(x) => Err(format!("{x:?} is not a valid {} value", T::TYPE)),
        None => Ok(v),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_parse_back_and_refusals_name_both_kinds() {
        for &k in VolumeKind::ALL {
            assert_eq!(k.as_str().parse::<VolumeKind>(), Ok(k));
            assert_eq!(serde_json::to_value(k).unwrap(), k.as_str());
        }
        let e = VolumeKind::Density
            .require(&[VolumeKind::Bits], "CSG")
            .unwrap_err();
        assert_eq!(
            e.to_string(),
            "a density volume; CSG works on bit volumes (solid, surface, conservative, interior)"
        );
        assert!(VolumeKind::Bits.require(&[VolumeKind::Bits], "CSG").is_ok());
        assert_eq!(VolumeKind::Density.decoded_bytes(10), 10);
        assert_eq!(VolumeKind::Bits.decoded_bytes(10), 2);
    }

    #[test]
    fn values_serialise_bare() {
        assert_eq!(serde_json::to_string(&VoxelValue::U8(1)).unwrap(), "1");
        assert_eq!(
            serde_json::to_string(&VoxelValue::F32(-0.5)).unwrap(),
            "-0.5"
        );
        assert_eq!(
            serde_json::to_string(&VoxelValue::Rgba8([1, 2, 3, 4])).unwrap(),
            "[1,2,3,4]"
        );
        let xs = [1.5f32, -2.0, f32::INFINITY];
        assert_eq!(from_le_bytes::<f32>(&to_le_bytes(&xs)), xs);
    }
}
