//! What a loader keeps besides the geometry, for colour and material voxels (issue 34): vertex
//! colours and each triangle's material, with the material table.
//!
//! * **Vertex colours**: RGBA in [0, 1] per position, as the file stores them: glTF's
//!   `COLOR_0` (linear, by the glTF specification; RGB without alpha is alpha 1; normalized
//!   integers divided by their maximum), PLY's `red`/`green`/`blue`[/`alpha`] (bytes / 255 or
//!   floats as written).
//! * **Materials**: one id per triangle into the table, an id per glTF material in the
//!   document's order (a primitive without a material gets glTF's default material, added
//!   at the end of the table when used); each material's name and base colour factor
//!   (`baseColorFactor`, linear RGBA, default white).
//!
//! * **Textures**: a material's base colour texture ([`TextureRef`]: image and sampler), the
//!   decoded images (`texture.rs`), and the texture coordinates ([`Uv`]), in the UV set the
//!   material's texture reads, with the texture's `KHR_texture_transform` applied (zeros where
//!   the material has no texture): one per position for glTF (its vertices are split where
//!   their coordinates differ), one per triangle corner for OBJ (its `vt` are indexed apart).
//!
//! The loaders that do not read an attribute leave it out; nothing here is invented.

use super::MeshError;
pub use super::texture::{Image, TextureRef};

/// A mesh's colour and material attributes (all empty for a file without them).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Attributes {
    /// One RGBA per position.
    pub colors: Option<Vec<[f32; 4]>>,
    /// Are `colors` sRGB-encoded (PLY's and OBJ's, by their tools' convention: MeshLab and
    /// Blender write display values) rather than linear (glTF's, by its specification)?
    /// Colour voxels decode them to linear light before they interpolate.
    pub colors_srgb: bool,
    /// One id per triangle, into `materials`.
    pub material: Option<Vec<u16>>,
    pub materials: Vec<Material>,
    /// The texture coordinates (see the module docs), when some material has a texture.
    pub uv: Option<Uv>,
    /// The images the materials' textures read.
    pub images: Vec<Image>,
}

/// Texture coordinates, as the file gives them.
#[derive(Clone, Debug, PartialEq)]
pub enum Uv {
    /// Each triangle's at its corners (OBJ: `vt` indices apart from the positions').
    Corners(Vec<[[f32; 2]; 3]>),
    /// Each vertex's, shared by the triangles using it (glTF: one per position); a sixth of
    /// the corners' memory on a closed mesh.
    Vertices(Vec<[f32; 2]>),
}

impl Uv {
    /// The coordinates at the corners of triangle `t`, whose vertices are `tri`.
    #[inline]
    pub fn corners(&self, t: usize, tri: [u32; 3]) -> [[f32; 2]; 3] {
        match self {
            Uv::Corners(c) => c[t],
            Uv::Vertices(v) => tri.map(|i| v[i as usize]),
        }
    }
}

/// A material of the table.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// Its name in the file (glTF `name`; `material N` when it has none).
    pub name: String,
    /// Linear RGBA in [0, 1].
    pub base_color: [f32; 4],
    /// The base colour texture (multiplied by `base_color`, as glTF does).
    pub texture: Option<TextureRef>,
}

/// A triangle without a material while a loader gathers the table.
pub(super) const NO_MATERIAL: u16 = u16::MAX;

impl Attributes {
    /// Sets the material table and each triangle's id, where [`NO_MATERIAL`] is the file's
    /// default material (glTF's, or OBJ faces before any `usemtl`): added after `table`,
    /// named "default", white, when a triangle uses it.
    pub(super) fn set_materials(&mut self, mut table: Vec<Material>, mut ids: Vec<u16>) {
        if ids.contains(&NO_MATERIAL) {
            let default = table.len() as u16;
            table.push(Material {
                name: "default".into(),
                base_color: [1.0; 4],
                texture: None,
            });
            for m in &mut ids {
                if *m == NO_MATERIAL {
                    *m = default;
                }
            }
        }
        self.materials = table;
        self.material = Some(ids);
    }

    /// Does the mesh carry any attribute?
    pub fn is_empty(&self) -> bool {
        self.colors.is_none() && self.material.is_none()
    }

    /// Checks the attributes against a mesh of `positions` vertices and `triangles` triangles:
    /// one colour per vertex, one material per triangle, every id in the table, colours finite
    /// and in [0, 1].
    pub fn check(&self, positions: usize, triangles: usize) -> Result<(), MeshError> {
        let bad = |detail: String| {
            Err(MeshError::Malformed {
                format: "mesh attributes",
                detail,
            })
        };
        if let Some(c) = &self.colors {
            if c.len() != positions {
                return bad(format!(
                    "{} vertex colours for {positions} vertices",
                    c.len()
                ));
            }
            if let Some(i) = c
                .iter()
                .position(|c| c.iter().any(|v| !(0.0..=1.0).contains(v)))
            {
                return bad(format!(
                    "vertex {i}'s colour {:?} is not within [0, 1]",
                    c[i]
                ));
            }
        }
        if let Some(m) = &self.material {
            if m.len() != triangles {
                return bad(format!(
                    "{} material ids for {triangles} triangles",
                    m.len()
                ));
            }
            if let Some(t) = m
                .iter()
                .position(|&id| usize::from(id) >= self.materials.len())
            {
                return bad(format!(
                    "triangle {t}'s material {} is not in the table of {}",
                    m[t],
                    self.materials.len()
                ));
            }
        }
        match &self.uv {
            Some(Uv::Corners(uv)) if uv.len() != triangles => {
                return bad(format!(
                    "{} texture coordinate triples for {triangles} triangles",
                    uv.len()
                ));
            }
            Some(Uv::Vertices(uv)) if uv.len() != positions => {
                return bad(format!(
                    "{} texture coordinates for {positions} vertices",
                    uv.len()
                ));
            }
            _ => {}
        }
        if let Some((i, _)) = self
            .materials
            .iter()
            .enumerate()
            .find(|(_, m)| m.texture.is_some_and(|t| t.image >= self.images.len()))
        {
            return bad(format!(
                "material {i}'s texture reads image {}, not among the {} images",
                self.materials[i].texture.unwrap().image,
                self.images.len()
            ));
        }
        if self.materials.iter().any(|m| m.texture.is_some()) && self.uv.is_none() {
            return bad("a material has a texture but the mesh has no texture coordinates".into());
        }
        Ok(())
    }

    /// A one-line summary for `voxd info`: "vertex colours, 3 materials (body, eyes, ...)" or
    /// "none".
    pub fn describe(&self) -> String {
        let mut parts = vec![];
        if self.colors.is_some() {
            parts.push("vertex colours".to_string());
        }
        if self.material.is_some() {
            // The first eight (a file may have thousands).
            let mut names: Vec<String> = self
                .materials
                .iter()
                .take(8)
                .map(|m| {
                    let c = m.base_color;
                    let tex = match m.texture {
                        Some(t) => {
                            let i = &self.images[t.image];
                            format!(" texture {}x{}", i.width, i.height)
                        }
                        None => String::new(),
                    };
                    format!(
                        "{} [{:.3} {:.3} {:.3} {:.3}]{tex}",
                        m.name, c[0], c[1], c[2], c[3]
                    )
                })
                .collect();
            if self.materials.len() > 8 {
                names.push("…".into());
            }
            parts.push(format!(
                "{} material{}: {}",
                self.materials.len(),
                if self.materials.len() == 1 { "" } else { "s" },
                names.join(", ")
            ));
        }
        if parts.is_empty() {
            "none".into()
        } else {
            parts.join("; ")
        }
    }
}
