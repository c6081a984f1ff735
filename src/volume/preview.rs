//! Pictures of a volume for people: one slice, or a projection along an axis. Images look along
//! the chosen axis with the other two axes in their natural order (x before y before z), the
//! second of them pointing up: rows run from its top index down.

use super::{Volume, VolumeKind};

/// The kinds previews picture: occupancy levels (a density's, or a bit's 0/1), and bit volumes
/// with channels: in colour when they have a colour channel ([`colour`]).
pub const ACCEPTS: &[VolumeKind] = &[VolumeKind::Bits, VolumeKind::Density, VolumeKind::Channels];

/// An 8-bit picture, grayscale (one byte a pixel) or RGB (three).
pub struct Picture {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<u8>,
    pub rgb: bool,
}

/// A colour picture of a volume with a colour channel: slice `slice` across `axis` (each set
/// voxel's colour, black elsewhere), or with `None` the projection along `axis` showing, for
/// each line, the colour of its set voxel of highest index along the axis (the one seen from
/// the axis's positive end); black where the line is empty. `None` without a colour channel
/// or for a slice outside the grid.
pub fn colour(v: &Volume, axis: usize, slice: Option<u32>) -> Option<Picture> {
    let Volume::Channels(a) = v else { return None };
    let c = a.colours()?;
    let d = v.grid().dims;
    if slice.is_some_and(|k| k >= d[axis]) {
        return None;
    }
    let (u, w) = plane(axis);
    let (width, height) = (d[u], d[w]);
    let mut pixels = Vec::with_capacity(3 * width as usize * height as usize);
    for row in (0..height).rev() {
        for col in 0..width {
            let mut p = [0u32; 3];
            p[u] = col;
            p[w] = row;
            let hit = match slice {
                Some(k) => {
                    p[axis] = k;
                    a.rank(p[0], p[1], p[2])
                }
                None => (0..d[axis]).rev().find_map(|k| {
                    p[axis] = k;
                    a.rank(p[0], p[1], p[2])
                }),
            };
            pixels.extend_from_slice(&hit.map_or([0; 3], |r| [c[r][0], c[r][1], c[r][2]]));
        }
    }
    Some(Picture {
        width,
        height,
        pixels,
        rgb: true,
    })
}

crate::named_enum! {
    /// How a projection reduces the line of voxels behind each pixel.
    pub enum Projection: "projection" {
        /// 255 where any voxel along the line is occupied.
        Max = "max",
        /// Occupancy summed along the line, scaled so the fullest line is white (a shaded
        /// thickness).
        Sum = "sum",
    }
}

impl Projection {
    /// What a preview shows when neither a slice nor a projection is asked for.
    pub const DEFAULT: Projection = Projection::Max;
}

crate::named_enum! {
    /// The axis a preview looks along; its index in `[x, y, z]` is [`Axis::index`].
    pub enum Axis: "axis" {
        X = "x",
        Y = "y",
        Z = "z",
    }
}

impl Axis {
    /// A preview looks down z unless told otherwise.
    pub const DEFAULT: Axis = Axis::Z;

    pub fn index(self) -> usize {
        self as usize
    }
}

fn value(v: &Volume, p: [u32; 3]) -> (u32, u32) {
    match v {
        Volume::Density(d) => (d.get(p[0], p[1], p[2]) as u32, d.max() as u32),
        other => (other.occupied(p[0], p[1], p[2]) as u32, 1),
    }
}

/// (image width axis, image height axis) for a view along `axis`.
fn plane(axis: usize) -> (usize, usize) {
    match axis {
        0 => (1, 2),
        1 => (0, 2),
        _ => (0, 1),
    }
}

/// Slice `k` across `axis` (0 = x, 1 = y, 2 = z); `None` when k is outside the grid.
pub fn slice(v: &Volume, axis: usize, k: u32) -> Option<Picture> {
    let d = v.grid().dims;
    if k >= d[axis] {
        return None;
    }
    let (u, w) = plane(axis);
    let (width, height) = (d[u], d[w]);
    let mut pixels = Vec::with_capacity(width as usize * height as usize);
    for row in (0..height).rev() {
        for col in 0..width {
            let mut p = [0u32; 3];
            p[axis] = k;
            p[u] = col;
            p[w] = row;
            let (x, max) = value(v, p);
            pixels.push((x * 255 / max) as u8);
        }
    }
    Some(Picture {
        width,
        height,
        pixels,
        rgb: false,
    })
}

/// A projection along `axis`.
pub fn projection(v: &Volume, axis: usize, mode: Projection) -> Picture {
    let d = v.grid().dims;
    let (u, w) = plane(axis);
    let (width, height) = (d[u], d[w]);
    let mut sums = Vec::with_capacity(width as usize * height as usize);
    let mut top = 0u64;
    for row in (0..height).rev() {
        for col in 0..width {
            let mut s = 0u64;
            for k in 0..d[axis] {
                let mut p = [0u32; 3];
                p[axis] = k;
                p[u] = col;
                p[w] = row;
                s += value(v, p).0 as u64;
            }
            top = top.max(s);
            sums.push(s);
        }
    }
    let pixels = sums
        .iter()
        .map(|&s| match mode {
            Projection::Max => {
                if s > 0 {
                    255
                } else {
                    0
                }
            }
            Projection::Sum => (s * 255).checked_div(top).unwrap_or(0) as u8,
        })
        .collect();
    Picture {
        width,
        height,
        pixels,
        rgb: false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::names::choices;

    /// The preview route's refusals list these choices ("axis=… is not x, y or z", "projection=…
    /// is not max or sum"); the axis's index is its place in `[x, y, z]`.
    #[test]
    fn axes_and_projections_name_their_choices() {
        assert_eq!(choices::<Axis>(), "x, y or z");
        assert_eq!(choices::<Projection>(), "max or sum");
        assert_eq!(Axis::ALL.map(Axis::index), [0, 1, 2]);
        assert_eq!("y".parse::<Axis>(), Ok(Axis::Y));
        assert!("w".parse::<Axis>().is_err());
        assert_eq!("sum".parse::<Projection>(), Ok(Projection::Sum));
        assert_eq!(
            (Axis::DEFAULT, Projection::DEFAULT),
            (Axis::Z, Projection::Max)
        );
    }
}
