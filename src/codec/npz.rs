//! `.npz` files: numpy's zip of named `.npy` arrays (`numpy.load` reads them). Written here for
//! the Hermite data (docs/format.md, "Hermite data"); each array deflated.

use std::io::{Seek, Write};

use zip::write::SimpleFileOptions;

use super::npy::array_header;
use crate::engine::hermite::Hermite;

/// One array: its name (without `.npy`), dtype, shape and little-endian C-ordered bytes.
pub struct Array {
    pub name: &'static str,
    pub descr: &'static str,
    pub shape: Vec<u64>,
    pub data: Vec<u8>,
}

/// Writes `arrays` as an `.npz` to `out`.
pub fn write(arrays: &[Array], out: impl Write + Seek) -> std::io::Result<()> {
    let mut z = zip::ZipWriter::new(out);
    let opts = SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Deflated)
        .large_file(
            arrays
                .iter()
                .any(|a| a.data.len() as u64 >= u64::from(u32::MAX) / 2),
        );
    for a in arrays {
        z.start_file(format!("{}.npy", a.name), opts)
            .map_err(std::io::Error::other)?;
        z.write_all(&array_header(&a.shape, a.descr))?;
        z.write_all(&a.data)?;
    }
    z.finish().map_err(std::io::Error::other)?;
    Ok(())
}

fn bytes<T: Copy, const N: usize>(
    items: impl Iterator<Item = [T; N]>,
    f: impl Fn(T) -> Vec<u8>,
) -> Vec<u8> {
    items.flat_map(|a| a.into_iter().flat_map(&f)).collect()
}

/// The arrays of Hermite data `h` (docs/format.md): `edges` (N, 4) uint32 (x, y, z of the
/// lower voxel, axis), `t` (N,) float64, `points` (N, 3) float64 in world units, `normals`
/// (N, 3) float64, `crossed` and `lower_inside` (N,) bool, and the grid: `origin` (3,)
/// float64, `voxel_size` (1,) float64, `dims` (3,) uint32.
pub fn hermite_arrays(h: &Hermite) -> Vec<Array> {
    let n = h.edges.len() as u64;
    let g = &h.grid;
    let f64s = |v: f64| v.to_le_bytes().to_vec();
    let world = |p: [f64; 3]| [0, 1, 2].map(|a| g.origin[a] + p[a] * g.voxel_size);
    let e = &h.edges;
    vec![
        Array {
            name: "edges",
            descr: "<u4",
            shape: vec![n, 4],
            data: bytes(
                e.iter()
                    .map(|e| [e.voxel[0], e.voxel[1], e.voxel[2], u32::from(e.axis)]),
                |v| v.to_le_bytes().to_vec(),
            ),
        },
        Array {
            name: "t",
            descr: "<f8",
            shape: vec![n],
            data: bytes(e.iter().map(|e| [e.t]), f64s),
        },
        Array {
            name: "points",
            descr: "<f8",
            shape: vec![n, 3],
            data: bytes(e.iter().map(|e| world(e.point())), f64s),
        },
        Array {
            name: "normals",
            descr: "<f8",
            shape: vec![n, 3],
            data: bytes(e.iter().map(|e| e.normal), f64s),
        },
        Array {
            name: "crossed",
            descr: "|b1",
            shape: vec![n],
            data: e.iter().map(|e| u8::from(e.crossed)).collect(),
        },
        Array {
            name: "lower_inside",
            descr: "|b1",
            shape: vec![n],
            data: e.iter().map(|e| u8::from(e.lower_inside)).collect(),
        },
        Array {
            name: "origin",
            descr: "<f8",
            shape: vec![3],
            data: bytes([g.origin].into_iter(), f64s),
        },
        Array {
            name: "voxel_size",
            descr: "<f8",
            shape: vec![1],
            data: f64s(g.voxel_size),
        },
        Array {
            name: "dims",
            descr: "<u4",
            shape: vec![3],
            data: bytes([g.dims].into_iter(), |v| v.to_le_bytes().to_vec()),
        },
    ]
}

/// The `.npz` bytes of Hermite data `h`.
pub fn encode_hermite(h: &Hermite) -> Vec<u8> {
    let mut out = std::io::Cursor::new(Vec::new());
    write(&hermite_arrays(h), &mut out).expect("writing to memory");
    out.into_inner()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::hermite::HermiteEdge;
    use crate::grid::Grid;
    use std::io::Read;

    /// Read back by the zip crate: every array's header names its dtype and shape, and its
    /// data has the size they say.
    #[test]
    fn hermite_arrays_read_back() {
        let g = Grid {
            origin: [1.0, 2.0, 3.0],
            voxel_size: 0.5,
            dims: [4, 5, 6],
        };
        let e = HermiteEdge {
            voxel: [1, 2, 3],
            axis: 2,
            lower_inside: true,
            t: 0.25,
            normal: [0.0, 0.0, 1.0],
            crossed: true,
        };
        let h = Hermite {
            grid: g,
            edges: vec![e, e],
        };
        let bytes = encode_hermite(&h);
        let mut z = zip::ZipArchive::new(std::io::Cursor::new(bytes)).unwrap();
        let mut points = Vec::new();
        z.by_name("points.npy")
            .unwrap()
            .read_to_end(&mut points)
            .unwrap();
        let text = String::from_utf8_lossy(&points[10..80]).to_string();
        assert!(
            text.contains("'descr': '<f8'") && text.contains("'shape': (2, 3)"),
            "{text}"
        );
        assert_eq!(points.len() % 64, 48);
        let x = f64::from_le_bytes(
            points[points.len() - 24..points.len() - 16]
                .try_into()
                .unwrap(),
        );
        let zc = f64::from_le_bytes(points[points.len() - 8..].try_into().unwrap());
        assert_eq!((x, zc), (1.0 + 1.5 * 0.5, 3.0 + 3.75 * 0.5));
        assert_eq!(z.len(), 9);
    }
}
