//! What parsing a mesh will cost in memory at most, estimated before it is parsed from what is
//! known by then: the format, the decoded size (an upload's length, or the size a gzip trailer
//! states) and the counts a header declares (a binary STL's triangle count, a PLY's element
//! counts). A front admits the estimate against its memory budget before it parses, and parses
//! with the decoded size as the limit, so that the estimate holds for the file as parsed.
//!
//! The figures are upper bounds of what the loaders and the diagnosis allocate per vertex and
//! per triangle, with the `Vec`s' growth (up to twice what is used) and the diagnosis' tables
//! (hashes, ids, edges), plus a fixed part for the decode windows. Where a format says no count
//! before its data (OBJ, ASCII STL, glTF), counts are bounded by the decoded bytes: an OBJ
//! vertex line takes 8 bytes at least (`v 0 0 0\n`), an ASCII STL facet 50, a glTF vertex 12
//! (three f32) and a triangle 6 (three u16 indices). Every count is also bounded by the limits
//! the parse enforces.

use super::stream::{GZIP_MAGIC, Stream};
use super::{Format, LoadOptions, sniff_stream};

/// The part of [`FIXED`] every parse takes: decoder state and the first step's buffers.
const BASE: u64 = 2 << 20;
/// The largest block a line parser reads at once (`stl::BLOCK`); a parse holds up to three
/// blocks' worth while one is parsed and the next is read.
const MAX_BLOCK: u64 = 8 << 20;
/// Decode windows, blocks and thread buffers of one parse at most.
pub const FIXED: u64 = BASE + 3 * MAX_BLOCK;

/// The fixed part of a parse of a file that decodes to `decoded` bytes: small files do not get
/// the windows of large ones.
pub fn fixed_part(decoded: u64) -> u64 {
    BASE + 3 * decoded.min(MAX_BLOCK)
}
/// Bytes per vertex at most: its position (24) twice over while its `Vec` grows, and the
/// diagnosis' hash, id and table slot. (64 was measured short: a gzip OBJ of 60 M vertices
/// peaked at 72.7 bytes a vertex, bench/hostile.)
pub const PER_VERTEX: u64 = 80;
/// Bytes per triangle at most: its indices (12) twice over while its `Vec` grows, and its three
/// edges in the diagnosis.
pub const PER_TRIANGLE: u64 = 64;

/// Bytes per vertex of a format that can carry vertex colours (glTF, PLY): its RGBA (16)
/// twice over while its `Vec` grows. glTF's material id per triangle (2, twice over) is in
/// [`PER_MATERIAL_ID`].
pub const PER_COLOUR: u64 = 32;
/// Bytes per triangle of glTF's material ids.
pub const PER_MATERIAL_ID: u64 = 4;
/// A triangle's corner texture coordinates (six f32) and their share of the growth.
pub const PER_CORNER_UVS: u64 = 48;

/// A parse's estimate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Estimate {
    /// Bytes of memory the parse (and the diagnosis of its mesh) may use at most.
    pub bytes: u64,
    /// Bytes the file decodes to, as far as is known before decoding it (a gzip trailer's
    /// size): the parse must use it as its decoded-size limit for `bytes` to hold.
    pub decoded: u64,
}

/// The size a gzip file's trailer states (ISIZE: the last member's decoded size mod 2^32), or
/// `None` for a file that is not gzip.
pub fn gzip_size(upload: &[u8]) -> Option<u64> {
    if !upload.starts_with(&GZIP_MAGIC) || upload.len() < 18 {
        return None;
    }
    let t = &upload[upload.len() - 4..];
    Some(u32::from_le_bytes(t.try_into().expect("4 bytes")) as u64)
}

fn mesh_cost(vertices: u64, triangles: u64) -> u64 {
    PER_VERTEX
        .saturating_mul(vertices)
        .saturating_add(PER_TRIANGLE.saturating_mul(triangles))
}

/// The most memory parsing `upload` (as [`super::load_bytes`] would, with `format` and `opts`)
/// may take, and the decoded size it assumes. A file that will be refused before its data is
/// read (an unknown format, a count over the limits) costs its [`fixed_part`].
pub fn estimate(upload: &[u8], format: Option<Format>, opts: &LoadOptions) -> Estimate {
    if super::archive::is_zip(upload) {
        // A zip upload: its entries held inflated (as their headers declare; the load holds
        // them to it), the mesh parsed from one of them (counted as a glTF of that size, the
        // costliest per byte) and textures up to their limit.
        let decoded = super::archive::declared_size(upload)
            .unwrap_or(0)
            .min(opts.max_decompressed_bytes);
        return Estimate {
            bytes: fixed_part(decoded).saturating_add(gltf_cost(
                decoded,
                texture_limit(opts),
                opts,
            )),
            decoded,
        };
    }
    let decoded = match gzip_size(upload) {
        // A gzip that is smaller than its trailer size is a lie or a gzip of several members;
        // either way, what is decoded past the stated size is refused by the parse.
        Some(size) => size.min(opts.max_decompressed_bytes),
        None => upload.len() as u64,
    };
    let fixed = |bytes: u64| Estimate {
        bytes: fixed_part(decoded).saturating_add(bytes),
        decoded,
    };
    let mut s = Stream::of(upload, decoded);
    let format = match format {
        Some(f) => Some(f),
        None => sniff_stream(&mut s).ok().flatten(),
    };
    let Some(format) = format else {
        return fixed(0);
    };
    if s.fill_to(super::HEAD).is_err() {
        return fixed(0);
    }
    let head = s.available();
    let max_t = opts.max_triangles as u64;
    let max_v = opts.max_vertices() as u64;
    let at_most = |v: u64, t: u64| mesh_cost(v.min(max_v), t.min(max_t));
    let bytes = match format {
        Format::Stl => {
            let binary_count = (head.len() >= 84)
                .then(|| u32::from_le_bytes(head[80..84].try_into().unwrap()) as u64)
                .filter(|&n| 84 + 50 * n == decoded);
            match binary_count {
                Some(n) if n > max_t => 0,
                Some(n) => mesh_cost(3 * n, n),
                // ASCII, read as decoded; read whole first when its head shows no facet.
                None => {
                    let t = (decoded / 50).min(max_t);
                    let whole = if head.windows(5).any(|w| w == b"facet") {
                        0
                    } else {
                        decoded
                    };
                    mesh_cost(3 * t, t).saturating_add(whole)
                }
            }
        }
        Format::Ply => match super::ply::header_counts(head) {
            Some((v, f)) if v <= max_v && f <= max_t => {
                mesh_cost(v, f).saturating_add(v.saturating_mul(PER_COLOUR))
            }
            Some(_) => 0,
            None => at_most(decoded / 8, decoded / 8),
        },
        // Vertex and face lines share the bytes: 8 bytes a line at least.
        Format::Obj => mesh_cost(decoded / 8, 0).min(mesh_cost(max_v, max_t)),
        // Read whole, then its accessors.
        Format::Gltf | Format::Glb => {
            // A document with images may decode textures up to their limit. Whether it has
            // any is read from its JSON when the head holds all of it (a GLB's JSON chunk comes
            // first and states its length); otherwise it is counted as having some.
            let json_end = match format {
                Format::Glb if head.len() >= 20 => {
                    20 + u64::from(u32::from_le_bytes(
                        head[12..16].try_into().expect("4 bytes"),
                    ))
                }
                _ => decoded,
            };
            let whole_json = json_end <= head.len() as u64;
            let images = memchr::memmem::find(head, b"\"images\"").is_some();
            let textures = if images || !whole_json {
                texture_limit(opts)
            } else {
                0
            };
            gltf_cost(decoded, textures, opts)
        }
    };
    fixed(bytes)
}

/// The bytes of textures a parse with `opts` may decode: none unless it reads them.
fn texture_limit(opts: &LoadOptions) -> u64 {
    if opts.textures {
        opts.max_texture_bytes
    } else {
        0
    }
}

/// A glTF of `decoded` bytes (the costliest format per byte): its bytes held, at most a vertex
/// a 12 bytes and a triangle a 6 with their attributes, and `textures` bytes of images.
fn gltf_cost(decoded: u64, textures: u64, opts: &LoadOptions) -> u64 {
    let v = (decoded / 12).min(opts.max_vertices() as u64);
    let t = (decoded / 6).min(opts.max_triangles as u64);
    decoded
        .saturating_add(mesh_cost(v, t))
        .saturating_add(v.saturating_mul(PER_COLOUR))
        .saturating_add(t.saturating_mul(PER_MATERIAL_ID + PER_CORNER_UVS))
        .saturating_add(textures)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testkit::gz;

    fn stl(n: u32) -> Vec<u8> {
        let mut b = vec![0u8; 80];
        b.extend_from_slice(&n.to_le_bytes());
        b.resize(84 + 50 * n as usize, 0);
        b
    }

    #[test]
    fn binary_stl_costs_its_header_count() {
        let opts = LoadOptions::default();
        let e = estimate(&stl(1000), None, &opts);
        assert_eq!(
            e.bytes,
            fixed_part(84 + 50 * 1000) + 1000 * (3 * PER_VERTEX + PER_TRIANGLE)
        );
        assert_eq!(e.decoded, 84 + 50 * 1000);
        // The same from a gzip: its header decoded, its size from the trailer.
        let e2 = estimate(&gz(&stl(1000)), None, &opts);
        assert_eq!(e2, e);
    }

    #[test]
    fn obj_and_ply_costs() {
        let opts = LoadOptions::default();
        let obj = b"v 0 0 0\n".repeat(10_000);
        let e = estimate(&gz(&obj), Some(Format::Obj), &opts);
        assert_eq!(e.decoded, 80_000);
        assert_eq!(e.bytes, fixed_part(80_000) + 10_000 * PER_VERTEX);
        let ply = b"ply\nformat ascii 1.0\nelement vertex 7\nproperty float x\nproperty float y\nproperty float z\nelement face 5\nproperty list uchar int vertex_indices\nend_header\n";
        let e = estimate(ply, None, &opts);
        assert_eq!(
            e.bytes,
            fixed_part(ply.len() as u64) + 7 * (PER_VERTEX + PER_COLOUR) + 5 * PER_TRIANGLE
        );
    }

    #[test]
    fn the_fixed_part_grows_with_the_file_up_to_its_bound() {
        assert_eq!(fixed_part(0), 2 << 20);
        assert_eq!(fixed_part(1 << 20), 5 << 20);
        assert_eq!(fixed_part(u64::MAX), FIXED);
        assert_eq!(FIXED, 26 << 20);
    }

    #[test]
    fn gzip_trailer_size() {
        assert_eq!(gzip_size(&gz(&[1u8; 12345])), Some(12345));
        assert_eq!(gzip_size(b"plain text, long enough"), None);
    }

    /// Fox.glb (one 1024² texture): without `textures` it is parsed with its materials but no
    /// image, and its estimate leaves the texture limit out.
    #[test]
    fn a_parse_without_textures_decodes_none_and_counts_none() {
        let fox = std::fs::read(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/Fox.glb"))
            .expect("tests/data/Fox.glb");
        let with = LoadOptions::default();
        let without = LoadOptions {
            textures: false,
            ..LoadOptions::default()
        };
        let a = super::super::load_bytes(&fox, None, &with).expect("Fox.glb");
        let b = super::super::load_bytes(&fox, None, &without).expect("Fox.glb");
        let (a, b) = (a.attributes(), b.attributes());
        assert_eq!(a.images.len(), 1);
        assert!(a.materials.iter().any(|m| m.texture.is_some()));
        assert!(b.images.is_empty());
        assert!(b.materials.iter().all(|m| m.texture.is_none()));
        let names = |x: &crate::mesh::Attributes| {
            x.materials
                .iter()
                .map(|m| (m.name.clone(), m.base_color))
                .collect::<Vec<_>>()
        };
        assert_eq!(names(a), names(b));
        let (ea, eb) = (estimate(&fox, None, &with), estimate(&fox, None, &without));
        assert_eq!(ea.bytes - eb.bytes, with.max_texture_bytes);
        assert_eq!(ea.decoded, eb.decoded);
    }
}
