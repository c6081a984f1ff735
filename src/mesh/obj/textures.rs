//! An OBJ's material table with its textures: each `usemtl` name's colour and `map_Kd` image
//! from the libraries ([`super::mtl`]), the images decoded once each within the mesh's texture
//! limit, and each triangle's texture coordinates at its corners.
//!
//! OBJ's texture coordinates have v up (the image's bottom-left corner is (0, 0)); voxd's
//! textures take glTF's, v down, so a corner's coordinates are `(u', 1 − v')` where
//! `(u', v') = s·vt + o` (the `map_Kd` options `-s`, `-o`). A texture is left out, with a warning,
//! when its file is missing or the OBJ has no `vt` lines; a file that is not a readable PNG or
//! JPEG, or one over the limit, refuses the mesh (as a glTF's image does).

use std::collections::HashMap;

use super::mtl::{self, MapKd};
use super::parser::NO_UV;
use crate::mesh::texture::{self, Filter, Image, TextureRef, Wrap};
use crate::mesh::{LoadOptions, Material, MeshError};

/// The material table for the `usemtl` names `names`, each material's `map_Kd` (where its
/// texture was read), and the images.
pub(super) type Table = (Vec<Material>, Vec<Option<MapKd>>, Vec<Image>);

pub(super) fn table(
    names: &[Vec<u8>],
    libs: &[Vec<u8>],
    opts: &LoadOptions,
    texcoords: &[[f32; 2]],
) -> Result<Table, MeshError> {
    let defs = mtl::materials(libs, &opts.external);
    let mut images: Vec<Image> = vec![];
    let mut by_path: HashMap<String, Option<usize>> = HashMap::new();
    let mut budget = opts.max_texture_bytes;
    let mut table = Vec::with_capacity(names.len());
    let mut maps = Vec::with_capacity(names.len());
    for n in names {
        let name = String::from_utf8_lossy(n).into_owned();
        let def = defs.get(&name);
        let mut texture = None;
        let mut map = None;
        // Without `opts.textures` (no colour asked for) no `map_Kd` is read.
        if let Some(m) = def.and_then(|d| d.map.as_ref()).filter(|_| opts.textures) {
            if texcoords.is_empty() {
                tracing::warn!(material = %name, texture = %m.path, "texture left out: the OBJ has no texture coordinates (vt)");
            } else {
                let slot = match by_path.get(&m.path) {
                    Some(&slot) => slot,
                    None => {
                        let slot = match mtl::read(&opts.external, &m.path, opts.max_texture_bytes)
                        {
                            Ok(bytes) => Some(texture::decode_into(
                                &mut images,
                                &mut budget,
                                &bytes,
                                &format!("texture {}", m.path),
                            )?),
                            Err(e) => {
                                tracing::warn!(material = %name, texture = %m.path, "texture not read: {e}");
                                None
                            }
                        };
                        by_path.insert(m.path.clone(), slot);
                        slot
                    }
                };
                if let Some(image) = slot {
                    let wrap = if m.clamp {
                        Wrap::ClampToEdge
                    } else {
                        Wrap::Repeat
                    };
                    texture = Some(TextureRef {
                        image,
                        wrap: [wrap; 2],
                        filter: Filter::Linear,
                    });
                    map = Some(m.clone());
                }
            }
        }
        table.push(Material {
            name,
            base_color: def.map_or([1.0; 4], |d| d.colour),
            texture,
        });
        maps.push(map);
    }
    Ok((table, maps, images))
}

/// Each triangle's corners' texture coordinates (glTF's convention, with its material's
/// `map_Kd` options applied), zeros for a triangle whose material has no texture or a corner
/// without coordinates. `material`: each triangle's index into `maps` (the default material,
/// past its end, has none); `corners`: each triangle's indices into `texcoords`.
pub(super) fn corner_uvs(
    material: &[u16],
    corners: &[[u32; 3]],
    texcoords: &[[f32; 2]],
    maps: &[Option<MapKd>],
) -> Vec<[[f32; 2]; 3]> {
    material
        .iter()
        .zip(corners)
        .map(
            |(&m, c)| match maps.get(usize::from(m)).and_then(Option::as_ref) {
                None => [[0.0; 2]; 3],
                Some(map) => c.map(|i| {
                    if i == NO_UV {
                        return [0.0; 2];
                    }
                    let [u, v] = texcoords[i as usize];
                    [
                        map.scale[0] * u + map.offset[0],
                        1.0 - (map.scale[1] * v + map.offset[1]),
                    ]
                }),
            },
        )
        .collect()
}
