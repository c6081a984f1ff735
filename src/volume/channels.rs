//! Per-voxel attribute channels attached to a bit volume ([`Attributed`]): each channel holds one
//! value per *set* voxel, in the order [`BitVolume::iter_ones`] visits them (column by column,
//! z upwards), so a channel costs nothing for empty space. Colour from a textured mesh, a
//! material id, a distance: any [`Voxel`] type. Not here: filling channels from a mesh (that is
//! the engine's), nor dense per-voxel values (`dense.rs`).

use super::BitVolume;
use super::kind::{ValueType, Voxel, VoxelValue, valid_from_le_bytes};

/// The values of one channel, one per set voxel.
#[derive(Clone, Debug, PartialEq)]
pub enum ChannelValues {
    U8(Vec<u8>),
    U16(Vec<u16>),
    F32(Vec<f32>),
    Rgba8(Vec<[u8; 4]>),
}

impl ChannelValues {
    pub fn value_type(&self) -> ValueType {
        match self {
            ChannelValues::U8(_) => ValueType::U8,
            ChannelValues::U16(_) => ValueType::U16,
            ChannelValues::F32(_) => ValueType::F32,
            ChannelValues::Rgba8(_) => ValueType::Rgba8,
        }
    }
    pub fn len(&self) -> usize {
        match self {
            ChannelValues::U8(v) => v.len(),
            ChannelValues::U16(v) => v.len(),
            ChannelValues::F32(v) => v.len(),
            ChannelValues::Rgba8(v) => v.len(),
        }
    }
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Value `i`, in its own type.
    pub fn get(&self, i: usize) -> VoxelValue {
        match self {
            ChannelValues::U8(v) => v[i].value(),
            ChannelValues::U16(v) => v[i].value(),
            ChannelValues::F32(v) => v[i].value(),
            ChannelValues::Rgba8(v) => v[i].value(),
        }
    }
    /// The values' little-endian bytes (the `.vxl` payload's) where they lie: the crate runs
    /// on little-endian targets only (`lib.rs`).
    pub fn le_bytes(&self) -> &[u8] {
        match self {
            ChannelValues::U8(v) => v,
            ChannelValues::U16(v) => bytemuck::cast_slice(v),
            ChannelValues::F32(v) => bytemuck::cast_slice(v),
            ChannelValues::Rgba8(v) => bytemuck::cast_slice(v),
        }
    }
    /// [`ChannelValues::le_bytes`], copied.
    pub fn to_le_bytes(&self) -> Vec<u8> {
        self.le_bytes().to_vec()
    }
    /// From little-endian bytes, a whole number of values of `t` (checked by the caller); a
    /// NaN is refused ([`Voxel::is_valid`]).
    pub fn from_le_bytes(t: ValueType, b: &[u8]) -> Result<ChannelValues, String> {
        Ok(match t {
            ValueType::U8 => ChannelValues::U8(valid_from_le_bytes(b)?),
            ValueType::U16 => ChannelValues::U16(valid_from_le_bytes(b)?),
            ValueType::F32 => ChannelValues::F32(valid_from_le_bytes(b)?),
            ValueType::Rgba8 => ChannelValues::Rgba8(valid_from_le_bytes(b)?),
        })
    }
}

/// A named channel.
#[derive(Clone, Debug, PartialEq)]
pub struct Channel {
    pub name: String,
    pub values: ChannelValues,
}

/// The colour channel's name: sRGB bytes, alpha linear (`engine::colour`).
pub const RGBA: &str = "rgba";
/// The material channel's name: u16 ids into the mesh's material table.
pub const MATERIAL: &str = "material";

/// Longest channel name.
pub const MAX_CHANNEL_NAME: usize = 64;
/// Most channels on one volume (bounds what a `.vxl` header can make a reader allocate).
pub const MAX_CHANNELS: usize = 64;

/// A bit volume with attribute channels.
#[derive(Clone, Debug, PartialEq)]
pub struct Attributed {
    bits: BitVolume,
    channels: Vec<Channel>,
    /// `starts[c]`: the rank of column c's first set voxel (X·Y + 1 entries, the last the
    /// count), so a voxel's value is found without counting the columns before it.
    starts: Vec<u64>,
}

impl Attributed {
    /// `bits` with no channels yet.
    pub fn new(bits: BitVolume) -> Attributed {
        let wpc = bits.words_per_column();
        let mut starts = Vec::with_capacity(bits.words().len() / wpc.max(1) + 1);
        let mut n = 0u64;
        starts.push(0);
        for col in bits.words().chunks_exact(wpc) {
            n += col.iter().map(|w| w.count_ones() as u64).sum::<u64>();
            starts.push(n);
        }
        Attributed {
            bits,
            channels: vec![],
            starts,
        }
    }

    /// Adds a channel: one value per set voxel, a name of 1 to [`MAX_CHANNEL_NAME`] bytes not
    /// already used.
    pub fn add(&mut self, name: &str, values: ChannelValues) -> Result<(), String> {
        if name.is_empty() || name.len() > MAX_CHANNEL_NAME {
            return Err(format!(
                "a channel name has 1 to {MAX_CHANNEL_NAME} bytes, got {name:?}"
            ));
        }
        if self.channels.len() == MAX_CHANNELS {
            return Err(format!("a volume has at most {MAX_CHANNELS} channels"));
        }
        if self.channel(name).is_some() {
            return Err(format!("there is already a channel {name:?}"));
        }
        let set = self.len();
        if values.len() as u64 != set {
            return Err(format!(
                "channel {name:?} has {} values for {set} set voxels",
                values.len()
            ));
        }
        self.channels.push(Channel {
            name: name.into(),
            values,
        });
        Ok(())
    }

    pub fn bits(&self) -> &BitVolume {
        &self.bits
    }
    /// The bits, the channels dropped.
    pub fn into_bits(self) -> BitVolume {
        self.bits
    }
    pub fn channels(&self) -> &[Channel] {
        &self.channels
    }
    pub fn channel(&self, name: &str) -> Option<&Channel> {
        self.channels.iter().find(|c| c.name == name)
    }
    /// Set voxels: the length of every channel.
    pub fn len(&self) -> u64 {
        *self.starts.last().expect("at least one entry")
    }
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The colours of the set voxels, in rank order, when there is an [`RGBA`] channel.
    pub fn colours(&self) -> Option<&[[u8; 4]]> {
        match &self.channel(RGBA)?.values {
            ChannelValues::Rgba8(c) => Some(c),
            _ => None,
        }
    }

    /// The rank of column (x, y)'s first set voxel (its lowest z).
    pub fn column_start(&self, x: u32, y: u32) -> u64 {
        self.starts[x as usize * self.bits.dims()[1] as usize + y as usize]
    }

    /// The rank of voxel (x, y, z) among the set voxels (its index in every channel), or `None`
    /// when it is not set.
    pub fn rank(&self, x: u32, y: u32, z: u32) -> Option<usize> {
        if !self.bits.get(x, y, z) {
            return None;
        }
        let col = self.bits.column(x, y);
        let (w, b) = ((z / 64) as usize, z % 64);
        let below: u64 = col[..w].iter().map(|v| v.count_ones() as u64).sum::<u64>()
            + (col[w] & ((1u64 << b) - 1)).count_ones() as u64;
        Some((self.column_start(x, y) + below) as usize)
    }

    /// Channel `name`'s value at voxel (x, y, z); `None` for an unset voxel or no such channel.
    pub fn value(&self, name: &str, x: u32, y: u32, z: u32) -> Option<VoxelValue> {
        let c = self.channel(name)?;
        Some(c.values.get(self.rank(x, y, z)?))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::Grid;

    #[test]
    fn values_follow_the_set_voxels_in_column_order() {
        let g = Grid {
            origin: [0.0; 3],
            voxel_size: 1.0,
            dims: [2, 3, 70],
        };
        let mut b = BitVolume::new(g);
        let pts = [[0, 0, 3], [0, 2, 65], [1, 0, 0], [1, 0, 69]];
        for p in pts {
            b.set(p[0], p[1], p[2], true);
        }
        let mut a = Attributed::new(b);
        a.add("id", ChannelValues::U16(vec![10, 20, 30, 40]))
            .unwrap();
        assert!(a.add("id", ChannelValues::U8(vec![0; 4])).is_err());
        assert!(a.add("short", ChannelValues::U8(vec![0; 3])).is_err());
        for (i, p) in pts.iter().enumerate() {
            assert_eq!(a.rank(p[0], p[1], p[2]), Some(i));
            assert_eq!(
                a.value("id", p[0], p[1], p[2]),
                Some(VoxelValue::U16(10 * (i as u16 + 1)))
            );
        }
        assert_eq!(a.rank(1, 1, 1), None);
        assert_eq!(a.value("colour", 0, 0, 3), None);
    }
}
