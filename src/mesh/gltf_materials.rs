//! glTF materials for colour voxels: each material's name, `baseColorFactor` and
//! `baseColorTexture` (image, sampler, UV set, `KHR_texture_transform`), and the texture
//! coordinates of a primitive's triangles. Images come from buffer views or `data:` URIs only,
//! never from files (a texture by any other URI is dropped with a warning: the material keeps
//! its factor). Each image is decoded once, however many textures read it, within the mesh's
//! texture limit (`max_texture_bytes`, all its images together), while the loader reads the
//! geometry ([`decode`]).

use std::borrow::Cow;

use base64::Engine as _;
use gltf::texture::{MagFilter, WrappingMode};

use super::texture::{self, Filter, Image, TextureRef, Wrap};
use super::{Material, MeshError, malformed};

/// How one material reads its texture coordinates: the UV set and the affine map of
/// `KHR_texture_transform` (u' = m[0]·u + m[1]·v + m[2], v' = m[3]·u + m[4]·v + m[5]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct UvSpec {
    pub set: u32,
    pub m: [f64; 6],
}

impl UvSpec {
    pub fn apply(&self, uv: [f32; 2]) -> [f32; 2] {
        let (u, v) = (f64::from(uv[0]), f64::from(uv[1]));
        let m = &self.m;
        [
            (m[0] * u + m[1] * v + m[2]) as f32,
            (m[3] * u + m[4] * v + m[5]) as f32,
        ]
    }
}

/// An image a texture reads, still encoded: its bytes (borrowed from a buffer, or decoded from
/// a `data:` URI) and its name in errors.
pub(super) struct Encoded<'b> {
    bytes: Cow<'b, [u8]>,
    what: String,
}

/// A document's materials, the images their textures read (to decode, in order: a
/// [`TextureRef`]'s `image` is an index into them), and each one's texture coordinates.
pub(super) type Materials<'b> = (Vec<Material>, Vec<Encoded<'b>>, Vec<Option<UvSpec>>);

/// The document's materials in order, the images their textures read (not decoded yet:
/// [`decode`]), and each material's [`UvSpec`] (`None`: no texture).
pub(super) fn materials<'b>(
    doc: &gltf::Document,
    buffers: &'b [Cow<'_, [u8]>],
    textures: bool,
) -> Result<Materials<'b>, MeshError> {
    let mut images: Vec<Encoded<'b>> = vec![];
    // glTF image index -> index into `images`.
    let mut decoded: Vec<Option<usize>> = vec![None; doc.images().len()];
    let mut table = vec![];
    let mut specs = vec![];
    for m in doc.materials() {
        let pbr = m.pbr_metallic_roughness();
        let mut tex = None;
        let mut spec = None;
        // Without `textures` (no colour asked for) the images are not decoded.
        if let Some(info) = pbr.base_color_texture().filter(|_| textures) {
            let t = info.texture();
            let src = t.source();
            let slot = src.index();
            let image = match decoded[slot] {
                Some(i) => Some(i),
                None => match image_bytes(&src, buffers)? {
                    None => None,
                    Some(bytes) => {
                        images.push(Encoded {
                            bytes,
                            what: format!("glTF image {slot}"),
                        });
                        decoded[slot] = Some(images.len() - 1);
                        decoded[slot]
                    }
                },
            };
            if let Some(image) = image {
                let s = t.sampler();
                let wrap = |w: WrappingMode| match w {
                    WrappingMode::ClampToEdge => Wrap::ClampToEdge,
                    WrappingMode::MirroredRepeat => Wrap::MirroredRepeat,
                    WrappingMode::Repeat => Wrap::Repeat,
                };
                tex = Some(TextureRef {
                    image,
                    wrap: [wrap(s.wrap_s()), wrap(s.wrap_t())],
                    filter: match s.mag_filter() {
                        Some(MagFilter::Nearest) => Filter::Nearest,
                        _ => Filter::Linear,
                    },
                });
                let mut set = info.tex_coord();
                let mut mat = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
                if let Some(tt) = info.texture_transform() {
                    let [ox, oy] = tt.offset().map(f64::from);
                    let [sx, sy] = tt.scale().map(f64::from);
                    let (sin, cos) = f64::from(tt.rotation()).sin_cos();
                    // translation · rotation · scale, the extension's order.
                    mat = [cos * sx, sin * sy, ox, -sin * sx, cos * sy, oy];
                    if let Some(c) = tt.tex_coord() {
                        set = c;
                    }
                }
                spec = Some(UvSpec { set, m: mat });
            }
        }
        table.push(Material {
            name: m.name().map_or_else(
                || format!("material {}", m.index().unwrap_or(0)),
                str::to_string,
            ),
            base_color: pbr.base_color_factor(),
            texture: tex,
        });
        specs.push(spec);
    }
    Ok((table, images, specs))
}

/// The images [`materials`] found, decoded in order within `budget` bytes (4 a texel, all of
/// them together).
pub(super) fn decode(images: &[Encoded<'_>], mut budget: u64) -> Result<Vec<Image>, MeshError> {
    let mut out = Vec::with_capacity(images.len());
    for e in images {
        texture::decode_into(&mut out, &mut budget, &e.bytes, &e.what)?;
    }
    Ok(out)
}

/// The encoded bytes of an image in a buffer view or a `data:` URI; `None` (with a warning)
/// for any other URI.
fn image_bytes<'b>(
    img: &gltf::Image,
    buffers: &'b [Cow<'_, [u8]>],
) -> Result<Option<Cow<'b, [u8]>>, MeshError> {
    match img.source() {
        gltf::image::Source::View { view, .. } => {
            let buf = &buffers[view.buffer().index()];
            let end = view.offset().checked_add(view.length());
            match end.and_then(|end| buf.get(view.offset()..end)) {
                Some(b) => Ok(Some(Cow::Borrowed(b))),
                None => Err(malformed(
                    "glTF",
                    format!(
                        "image {}'s buffer view lies outside its buffer",
                        img.index()
                    ),
                )),
            }
        }
        gltf::image::Source::Uri { uri, .. } => match uri.strip_prefix("data:") {
            Some(rest) => {
                let (_, payload) = rest.split_once(";base64,").ok_or_else(|| {
                    malformed("glTF", "only base64 data URIs are supported for images")
                })?;
                base64::engine::general_purpose::STANDARD
                    .decode(payload.trim())
                    .map(|b| Some(Cow::Owned(b)))
                    .map_err(|e| {
                        malformed("glTF", format!("bad base64 in an image's data URI: {e}"))
                    })
            }
            None => {
                tracing::warn!(
                    image = img.index(),
                    "a glTF image in an external file is not read (only GLB buffers and data URIs): its texture is left out"
                );
                Ok(None)
            }
        },
    }
}
