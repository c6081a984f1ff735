//! A compact binary form of a [`Mesh`] that has already been loaded and validated: what a job
//! submitted to one process keeps in the store so that the process that runs it gets the same
//! mesh back without parsing the uploaded file again (the text formats cost far more to parse
//! than this costs to copy). Not a file format for users, and not a way in for untrusted
//! meshes: decoding checks every count against the bytes at hand and the limits before it
//! allocates, and the decoded mesh passes [`Mesh::new`]'s checks, but nothing else about the
//! file it came from is kept here (its name, format and hash are the caller's).
//!
//! Layout (all integers and floats little-endian), [`HEADER`] bytes then the data:
//!
//! | bytes | what |
//! |---|---|
//! | 8 | [`MAGIC`] |
//! | 4 | version, [`VERSION`] |
//! | 4 | reserved, zero |
//! | 8 | vertex count `v` |
//! | 8 | triangle count `t` |
//! | 24·v | positions, `[f64; 3]` each |
//! | 12·t | triangles, `[u32; 3]` each (vertex indices) |

use super::{LoadOptions, Mesh, MeshError};

/// The first bytes of every encoded mesh. The leading 0x89 byte and the line ends (as PNG's
/// signature has them) keep it from being taken for a text mesh, and a text mesh for it.
pub const MAGIC: [u8; 8] = *b"\x89VXMESH\n";

/// The layout's version; a decoder refuses one it does not know.
pub const VERSION: u32 = 1;

/// Bytes before the positions.
pub const HEADER: usize = 32;

const FORMAT: &str = "voxd binary mesh";

/// Whether `bytes` start as an encoded mesh does (whether they decode is another matter).
pub fn is_binary(bytes: &[u8]) -> bool {
    bytes.starts_with(&MAGIC)
}

/// Bytes [`encode`] writes for a mesh of `vertices` and `triangles` (what a caller can check
/// against a budget before encoding).
pub fn encoded_len(vertices: usize, triangles: usize) -> usize {
    HEADER + 24 * vertices + 12 * triangles
}

/// The mesh in the binary form, [`encoded_len`] bytes.
pub fn encode(mesh: &Mesh) -> Vec<u8> {
    let (p, t) = (mesh.positions(), mesh.triangles());
    let mut out = Vec::with_capacity(encoded_len(p.len(), t.len()));
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&VERSION.to_le_bytes());
    out.extend_from_slice(&0u32.to_le_bytes());
    out.extend_from_slice(&(p.len() as u64).to_le_bytes());
    out.extend_from_slice(&(t.len() as u64).to_le_bytes());
    if cfg!(target_endian = "little") {
        // The in-memory layout is the file's: one copy each.
        out.extend_from_slice(bytemuck::cast_slice(p));
        out.extend_from_slice(bytemuck::cast_slice(t));
    } else {
        for c in p.iter().flatten() {
            out.extend_from_slice(&c.to_le_bytes());
        }
        for i in t.iter().flatten() {
            out.extend_from_slice(&i.to_le_bytes());
        }
    }
    debug_assert_eq!(out.len(), encoded_len(p.len(), t.len()));
    out
}

/// The mesh [`encode`] wrote, held to `opts`' triangle and vertex limits: a count over a limit
/// is refused before anything is allocated (the same problem as a parsed file's,
/// [`MeshError::CountOverLimit`]), and so are counts that do not match the bytes' length, an
/// unknown version and a mesh [`Mesh::new`] refuses (an error, never a panic).
pub fn decode(bytes: &[u8], opts: &LoadOptions) -> Result<Mesh, MeshError> {
    let bad = |detail: String| super::malformed(FORMAT, detail);
    if bytes.len() < HEADER || !is_binary(bytes) {
        return Err(bad(format!(
            "not an encoded mesh ({} bytes, without the {HEADER}-byte header)",
            bytes.len()
        )));
    }
    let u32_at = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().expect("4 bytes"));
    let u64_at = |at: usize| u64::from_le_bytes(bytes[at..at + 8].try_into().expect("8 bytes"));
    let version = u32_at(8);
    if version != VERSION {
        return Err(bad(format!(
            "version {version}, but this build reads version {VERSION} only"
        )));
    }
    // Zero now; a later version may use it, and this one would not know what for.
    if u32_at(12) != 0 {
        return Err(bad(format!("reserved field {:#x}, not zero", u32_at(12))));
    }
    let (vertices, triangles) = (u64_at(16), u64_at(24));
    let over = |what, count: u64, limit: usize| MeshError::CountOverLimit {
        format: FORMAT,
        what,
        count,
        limit: limit as u64,
    };
    if triangles > opts.max_triangles as u64 {
        return Err(over("triangles", triangles, opts.max_triangles));
    }
    if vertices > opts.max_vertices() as u64 {
        return Err(over("vertices", vertices, opts.max_vertices()));
    }
    // The length the counts need, computed without overflow (limits may be huge), is
    // compared with the bytes' before either count is used as a size.
    let want = 24u64
        .checked_mul(vertices)
        .zip(12u64.checked_mul(triangles))
        .and_then(|(p, t)| p.checked_add(t)?.checked_add(HEADER as u64));
    if want != Some(bytes.len() as u64) {
        let want = want.map_or_else(|| "more than 2^64".into(), |w| w.to_string());
        return Err(bad(format!(
            "{vertices} vertices and {triangles} triangles take {want} bytes, but there are {}",
            bytes.len()
        )));
    }
    let (v, t) = (vertices as usize, triangles as usize);
    let (pos_bytes, tri_bytes) = bytes[HEADER..].split_at(24 * v);
    // Copied into vectors of the right alignment (the bytes may be anywhere).
    let mut positions = vec![[0f64; 3]; v];
    bytemuck::cast_slice_mut::<[f64; 3], u8>(&mut positions).copy_from_slice(pos_bytes);
    let mut tris = vec![[0u32; 3]; t];
    bytemuck::cast_slice_mut::<[u32; 3], u8>(&mut tris).copy_from_slice(tri_bytes);
    if cfg!(target_endian = "big") {
        for c in positions.iter_mut().flatten() {
            *c = f64::from_bits(u64::from_le(c.to_bits()));
        }
        for i in tris.iter_mut().flatten() {
            *i = u32::from_le(*i);
        }
    }
    Mesh::new(positions, tris)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tetra() -> Mesh {
        Mesh::new(
            vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, -0.0],
                [0.1, 0.2, 1e-300],
            ],
            vec![[0, 2, 1], [0, 1, 4], [0, 4, 2], [1, 2, 4]],
        )
        .unwrap()
    }

    fn opts(max_triangles: usize) -> LoadOptions {
        LoadOptions {
            max_triangles,
            ..LoadOptions::default()
        }
    }

    fn detail(e: MeshError) -> String {
        match e {
            MeshError::Malformed { format, detail } => {
                assert_eq!(format, FORMAT);
                detail
            }
            other => panic!("not malformed: {other:?}"),
        }
    }

    /// The same mesh comes back, bit for bit (signed zeros, subnormals), from bytes at any
    /// alignment; the length is the one announced.
    #[test]
    fn a_mesh_round_trips_bit_for_bit() {
        let m = tetra();
        let bytes = encode(&m);
        assert_eq!(bytes.len(), encoded_len(5, 4));
        assert!(is_binary(&bytes));
        for shift in 0..8 {
            let mut at = vec![0u8; shift];
            at.extend_from_slice(&bytes);
            let back = decode(&at[shift..], &opts(4)).unwrap();
            assert_eq!(back.triangles(), m.triangles());
            let bits = |m: &Mesh| -> Vec<u64> {
                m.positions()
                    .iter()
                    .flatten()
                    .map(|c| c.to_bits())
                    .collect()
            };
            assert_eq!(bits(&back), bits(&m), "shift {shift}");
        }
        // Positions are stored as they are, little-endian, after the header.
        assert_eq!(&bytes[HEADER + 24..HEADER + 32], &1f64.to_le_bytes());
        // The fuzz target's seed is a valid encoded mesh, and what decodes encodes back.
        let seed = include_bytes!("../../fuzz/corpus/mesh_binary/tetra.bin");
        let m = decode(seed, &opts(4)).unwrap();
        assert_eq!((m.positions().len(), m.triangles().len()), (4, 4));
        assert_eq!(encode(&m), seed);
    }

    /// Every prefix of an encoded mesh, and the mesh with a byte too many, is refused.
    #[test]
    fn truncated_or_padded_bytes_are_refused() {
        let bytes = encode(&tetra());
        for n in 0..bytes.len() {
            assert!(decode(&bytes[..n], &opts(10)).is_err(), "prefix of {n}");
        }
        let mut longer = bytes.clone();
        longer.push(0);
        assert!(detail(decode(&longer, &opts(10)).unwrap_err()).contains("take"));
    }

    /// Counts over the limits are refused as a parsed file's are, before any allocation (a
    /// count of 2⁶⁴−1 with a few bytes behind it); counts that disagree with the length are
    /// refused too, even within the limits, without overflow.
    #[test]
    fn oversized_or_inconsistent_counts_are_refused_without_panic() {
        let bytes = encode(&tetra());
        assert!(matches!(
            decode(&bytes, &opts(3)),
            Err(MeshError::CountOverLimit {
                what: "triangles",
                count: 4,
                limit: 3,
                ..
            })
        ));
        for (at, what) in [(16, "vertices"), (24, "triangles")] {
            let mut b = bytes.clone();
            b[at..at + 8].copy_from_slice(&u64::MAX.to_le_bytes());
            match decode(&b, &opts(usize::MAX / 64)) {
                Err(MeshError::CountOverLimit { what: w, .. }) => assert_eq!(w, what),
                other => panic!("{what}: {other:?}"),
            }
            // No limit at all: the length the counts need overflows, and says so.
            let e = detail(decode(&b, &opts(usize::MAX)).unwrap_err());
            assert!(e.contains("more than 2^64"), "{e}");
            // Within the limits but not what the bytes hold.
            b[at..at + 8].copy_from_slice(&3u64.to_le_bytes());
            assert!(detail(decode(&b, &opts(10)).unwrap_err()).contains("take"));
        }
    }

    /// A wrong magic or version, an index out of range and a non-finite coordinate are errors.
    #[test]
    fn corrupt_bytes_are_refused() {
        let bytes = encode(&tetra());
        let mut b = bytes.clone();
        b[1] = b'W';
        assert!(detail(decode(&b, &opts(10)).unwrap_err()).contains("not an encoded mesh"));
        let mut b = bytes.clone();
        b[8] = 2;
        assert!(detail(decode(&b, &opts(10)).unwrap_err()).contains("version 2"));
        let mut b = bytes.clone();
        b[13] = 1;
        assert!(detail(decode(&b, &opts(10)).unwrap_err()).contains("reserved"));
        let mut b = bytes.clone();
        let tri0 = HEADER + 24 * 5;
        b[tri0..tri0 + 4].copy_from_slice(&9u32.to_le_bytes());
        assert!(matches!(
            decode(&b, &opts(10)),
            Err(MeshError::IndexOutOfRange {
                triangle: 0,
                index: 9,
                vertices: 5
            })
        ));
        let mut b = bytes;
        b[HEADER..HEADER + 8].copy_from_slice(&f64::NAN.to_le_bytes());
        assert!(matches!(
            decode(&b, &opts(10)),
            Err(MeshError::NonFinite { vertex: 0, .. })
        ));
        // No triangles at all: what `Mesh::new` refuses.
        let mut empty = Vec::from(MAGIC);
        empty.extend_from_slice(&VERSION.to_le_bytes());
        empty.extend_from_slice(&[0; 20]);
        assert!(matches!(
            decode(&empty, &opts(10)),
            Err(MeshError::NoTriangles(_))
        ));
    }

    /// The text formats do not start as the binary form does.
    #[test]
    fn text_meshes_are_not_taken_for_binary_ones() {
        for text in [
            &b"v 0 0 0\n"[..],
            b"ply\n",
            b"solid x",
            b"glTF",
            b"{\"asset\"",
            b"",
        ] {
            assert!(!is_binary(text));
        }
    }
}
