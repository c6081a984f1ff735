//! Colour and material voxels (issue 34; `docs/methods.md`, "Colour and material"): the
//! attribute channels of a bit volume computed from its mesh's colours and materials.
//!
//! * **Surface voxels** (a voxel that a part of some triangle of positive area lies in): the
//!   area-weighted average, over the parts of the triangles inside the voxel (cut exactly:
//!   `clip.rs`), of the surface colour. The colour at a point of a triangle is, in linear light,
//!   its material's base colour × the interpolated vertex colour × the base colour texture
//!   sampled at its interpolated texture coordinates through the texture's sampler (each factor
//!   1 where the mesh has none). Without a texture that colour is linear over a part, so its
//!   average is the value at the part's centroid (exact). With one, each part is fanned into
//!   triangles and each of those cut into 4^k equal sub-triangles sampled at their centroids,
//!   the least k with 4^k ≥ 4 × the triangle's area in texels or 16 × its area in voxel faces
//!   (s²), whichever is less (at least 1), and k at most [`MAX_LEVEL`]: four samples a texel,
//!   up to 16 a voxel face of surface (a voxel's colour averages the samples of all its parts;
//!   past that a sample stands for more than a quarter texel). On a checkerboard of
//!   4-texel squares 2.7 texels a voxel the voxels' colours are within 0.011 (linear) of the
//!   exact mean of the bilinear interpolant; with one sample a texel they were 0.063 off,
//!   with sixteen 0.003 (`tests/service/colour.rs`).
//!   Material: the id with the largest total area in the voxel; ties by the lowest id.
//! * **Other set voxels** (the inside of a solid, a distance voxel no triangle passes through):
//!   the value of the nearest surface voxel, found by propagation (`propagate.rs`), so the cost
//!   stays linear in the voxels.
//! * **Stored** as channels of the bits ([`Attributed`]): `rgba` (sRGB bytes, alpha linear,
//!   the average rounded once) and `material` (u16 ids into the mesh's material table).

pub mod carry;
mod clip;
mod propagate;

use std::collections::HashMap;

use rayon::prelude::*;

use crate::cancel::{Canceled, Control};
use crate::grid::Grid;
use crate::mesh::texture::{Image, linear_to_srgb, srgb_to_linear};
use crate::mesh::{Attributes, Mesh};
use crate::volume::{Attributed, BitVolume, ChannelValues};

pub use clip::{Clipper, Vertex, double_area, pieces};

/// Most subdivision levels of a textured fan triangle (4^4 = 256 samples).
pub const MAX_LEVEL: u32 = 4;
/// Texture samples a texel of a fan triangle's area, up to [`MAX_LEVEL`] and
/// [`SAMPLES_PER_VOXEL_FACE`].
pub const SAMPLES_PER_TEXEL: f64 = 4.0;
/// Texture samples at most a voxel face's area (s²) of a fan triangle (at least one).
pub const SAMPLES_PER_VOXEL_FACE: f64 = 16.0;
pub use crate::volume::channels::{MATERIAL, RGBA};

/// Which channels to compute.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Want {
    pub colour: bool,
    pub material: bool,
}

impl Want {
    pub fn any(self) -> bool {
        self.colour || self.material
    }
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ColourError {
    #[error(
        "the mesh has no colour: no vertex colours and no materials (color=true needs one of them)"
    )]
    NoColour,
    #[error("the mesh has no materials (material=true needs glTF materials or OBJ usemtl names)")]
    NoMaterials,
    #[error(transparent)]
    Canceled(Canceled),
}

impl From<Canceled> for ColourError {
    fn from(c: Canceled) -> Self {
        ColourError::Canceled(c)
    }
}

/// Checks that `attributes` can give what `want` asks for.
pub fn check(attributes: &Attributes, want: Want) -> Result<(), ColourError> {
    if want.colour && attributes.colors.is_none() && attributes.material.is_none() {
        return Err(ColourError::NoColour);
    }
    if want.material && attributes.material.is_none() {
        return Err(ColourError::NoMaterials);
    }
    Ok(())
}

/// The surface voxels ([`surface`]): sorted keys (`(x·Y + y)·Z + z`, the order of set voxels
/// in a bit volume) with their average linear colour and their material.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Surface {
    pub keys: Vec<u64>,
    pub rgba: Vec<[f32; 4]>,
    pub material: Vec<u16>,
}

/// The key of voxel v on a grid of `dims`.
pub fn key(v: [u32; 3], dims: [u32; 3]) -> u64 {
    (u64::from(v[0]) * u64::from(dims[1]) + u64::from(v[1])) * u64::from(dims[2]) + u64::from(v[2])
}

/// One part of a triangle in a voxel.
struct Piece {
    key: u64,
    tri: u32,
    area: f64,
    rgba: [f64; 4],
}

#[derive(Default)]
struct Acc {
    area: f64,
    rgba: [f64; 4],
}

/// Triangles a batch: the pieces of one batch are held at once.
const BATCH: usize = 1 << 15;

/// Everything the colour at a point of a triangle needs.
struct Shader<'m> {
    mesh: &'m Mesh,
    a: &'m Attributes,
    /// The vertex colours in linear light.
    colors: Option<std::borrow::Cow<'m, [[f32; 4]]>>,
}

impl Shader<'_> {
    /// Linear RGBA at barycentric weights `b` (of corners 1 and 2) of triangle `t`, without
    /// the texture.
    fn plain(&self, t: usize, b: [f64; 2]) -> [f64; 4] {
        let mut c = [1.0f64; 4];
        if let Some(m) = &self.a.material {
            let base = self.a.materials[usize::from(m[t])].base_color;
            c = base.map(f64::from);
        }
        if let Some(vc) = &self.colors {
            let tri = self.mesh.triangles()[t];
            let w = [1.0 - b[0] - b[1], b[0], b[1]];
            for (k, ck) in c.iter_mut().enumerate() {
                let v: f64 = (0..3)
                    .map(|i| w[i] * f64::from(vc[tri[i] as usize][k]))
                    .sum();
                *ck *= v;
            }
        }
        c
    }

    /// The texture of triangle `t`'s material, with the image.
    fn texture(
        &self,
        t: usize,
    ) -> Option<(&Image, crate::mesh::texture::TextureRef, &[[f32; 2]; 3])> {
        let m = self.a.material.as_ref()?[t];
        let tex = self.a.materials[usize::from(m)].texture?;
        Some((&self.a.images[tex.image], tex, &self.a.uv.as_ref()?[t]))
    }

    /// The integral of the colour over `piece` (of triangle `t`) and its area, in world units.
    fn integrate(&self, t: usize, piece: &[Vertex], s2: f64) -> (f64, [f64; 4]) {
        let Some((img, tex, uv)) = self.texture(t) else {
            let a2 = double_area(piece);
            // The area-weighted centroid of the fan's triangles.
            let o = piece[0].b;
            let mut cb = [0.0f64; 2];
            for w in piece[1..].windows(2) {
                let fan = [piece[0], w[0], w[1]];
                let a = double_area(&fan);
                for k in 0..2 {
                    cb[k] += a * (o[k] + w[0].b[k] + w[1].b[k]) / 3.0;
                }
            }
            let b = if a2 > 0.0 {
                [cb[0] / a2, cb[1] / a2]
            } else {
                o
            };
            let c = self.plain(t, b);
            let area = a2 / 2.0 * s2;
            return (area, c.map(|v| v * area));
        };
        let uv_at = |b: [f64; 2]| -> [f64; 2] {
            let w = [1.0 - b[0] - b[1], b[0], b[1]];
            std::array::from_fn(|k| (0..3).map(|i| w[i] * f64::from(uv[i][k])).sum())
        };
        let texels = f64::from(img.width) * f64::from(img.height);
        let mut total = 0.0;
        let mut sum = [0.0f64; 4];
        for w in piece[1..].windows(2) {
            let fan = [piece[0], w[0], w[1]];
            let area = double_area(&fan) / 2.0 * s2;
            if area <= 0.0 {
                continue;
            }
            let uvs = fan.map(|v| uv_at(v.b));
            let samples = ((uvs[1][0] - uvs[0][0]) * (uvs[2][1] - uvs[0][1])
                - (uvs[2][0] - uvs[0][0]) * (uvs[1][1] - uvs[0][1]))
                .abs()
                / 2.0
                * texels
                * SAMPLES_PER_TEXEL;
            // No more than SAMPLES_PER_VOXEL_FACE a voxel face's area of surface: a voxel's
            // colour averages all its parts' samples.
            let samples = samples.min((SAMPLES_PER_VOXEL_FACE * area / s2).max(1.0));
            let mut level = 0;
            while level < MAX_LEVEL && 4f64.powi(level as i32) < samples {
                level += 1;
            }
            let n = 1u32 << level;
            let per = area / f64::from(n * n);
            sub_centroids(n, |s, r| {
                // The point at (s, r) of the fan triangle, in the triangle's weights.
                let b: [f64; 2] = std::array::from_fn(|k| {
                    fan[0].b[k] + (fan[1].b[k] - fan[0].b[k]) * s + (fan[2].b[k] - fan[0].b[k]) * r
                });
                let [u, v] = uv_at(b);
                let texel = img.sample(u, v, &tex);
                let c = self.plain(t, b);
                for k in 0..4 {
                    sum[k] += per * c[k] * f64::from(texel[k]);
                }
            });
            total += area;
        }
        (total, sum)
    }
}

/// Calls `f(s, r)` with the centroids of the n² equal sub-triangles of the triangle with corners
/// (0, 0), (1, 0), (0, 1) cut n times along each edge.
fn sub_centroids(n: u32, mut f: impl FnMut(f64, f64)) {
    let nf = f64::from(n);
    for i in 0..n {
        for j in 0..n - i {
            f(
                (f64::from(i) + 1.0 / 3.0) / nf,
                (f64::from(j) + 1.0 / 3.0) / nf,
            );
            if i + j + 1 < n {
                f(
                    (f64::from(i) + 2.0 / 3.0) / nf,
                    (f64::from(j) + 2.0 / 3.0) / nf,
                );
            }
        }
    }
}

/// The surface voxels of `mesh` on `grid` with the attributes `want` asks for (see the module
/// docs), checking `ctl` between batches of triangles. Blocking; parallel.
pub fn surface(
    mesh: &Mesh,
    grid: &Grid,
    want: Want,
    ctl: &Control,
) -> Result<Surface, ColourError> {
    let a = mesh.attributes();
    check(a, want)?;
    let colors = a.colors.as_deref().map(|c| {
        if a.colors_srgb {
            std::borrow::Cow::Owned(
                c.iter()
                    .map(|v| {
                        let lin = |x: f32| srgb_to_linear(f64::from(x)) as f32;
                        [lin(v[0]), lin(v[1]), lin(v[2]), v[3]]
                    })
                    .collect(),
            )
        } else {
            std::borrow::Cow::Borrowed(c)
        }
    });
    let shader = Shader { mesh, a, colors };
    let dims = grid.dims;
    let s2 = grid.voxel_size * grid.voxel_size;
    let to_grid = |p: [f64; 3]| grid.index_of(p);
    let mut acc: HashMap<u64, Acc, foldhash::fast::FixedState> =
        HashMap::with_hasher(foldhash::fast::FixedState::default());
    let mut mats: HashMap<(u64, u16), f64, foldhash::fast::FixedState> =
        HashMap::with_hasher(foldhash::fast::FixedState::default());
    let n = mesh.triangles().len();
    let counter = ctl.counter(n as u64);
    for start in (0..n).step_by(BATCH) {
        ctl.check()?;
        let end = (start + BATCH).min(n);
        let mut batch: Vec<Piece> = (start..end)
            .into_par_iter()
            .with_min_len(256)
            .fold(
                || (Vec::new(), Clipper::default()),
                |(mut out, mut clipper), t| {
                    let tri = mesh.triangle(t).map(to_grid);
                    clipper.pieces(&tri, dims, |v, piece| {
                        let (area, rgba) = shader.integrate(t, piece, s2);
                        if area > 0.0 {
                            out.push(Piece {
                                key: key(v, dims),
                                tri: t as u32,
                                area,
                                rgba,
                            });
                        }
                    });
                    (out, clipper)
                },
            )
            .map(|(out, _)| out)
            .reduce(Vec::new, |mut a, mut b| {
                a.append(&mut b);
                a
            });
        // In triangle order within a voxel, whatever the threads did: the sums are then the
        // same on every run.
        batch.par_sort_unstable_by_key(|p| (p.key, p.tri));
        for p in &batch {
            let e = acc.entry(p.key).or_default();
            e.area += p.area;
            for k in 0..4 {
                e.rgba[k] += p.rgba[k];
            }
            if want.material {
                let id = a.material.as_ref().expect("checked")[p.tri as usize];
                *mats.entry((p.key, id)).or_default() += p.area;
            }
        }
        counter.add((end - start) as u64);
    }
    let mut keys: Vec<u64> = acc.keys().copied().collect();
    keys.par_sort_unstable();
    let rgba = if want.colour {
        keys.iter()
            .map(|k| {
                let e = &acc[k];
                e.rgba.map(|v| (v / e.area) as f32)
            })
            .collect()
    } else {
        vec![]
    };
    let material = if want.material {
        let mut best: HashMap<u64, (f64, u16), foldhash::fast::FixedState> =
            HashMap::with_hasher(foldhash::fast::FixedState::default());
        for (&(k, id), &area) in &mats {
            let e = best.entry(k).or_insert((area, id));
            if area > e.0 || (area == e.0 && id < e.1) {
                *e = (area, id);
            }
        }
        keys.iter().map(|k| best[k].1).collect()
    } else {
        vec![]
    };
    Ok(Surface {
        keys,
        rgba,
        material,
    })
}

/// A linear RGBA as stored: sRGB bytes, alpha linear, each rounded once.
pub fn to_rgba8(c: [f32; 4]) -> [u8; 4] {
    let byte = |v: f64| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
    [
        byte(linear_to_srgb(f64::from(c[0]).clamp(0.0, 1.0))),
        byte(linear_to_srgb(f64::from(c[1]).clamp(0.0, 1.0))),
        byte(linear_to_srgb(f64::from(c[2]).clamp(0.0, 1.0))),
        byte(f64::from(c[3])),
    ]
}

/// `bits` with the channels `want` asks for, from `mesh` on `bits`' grid (see the module
/// docs). Blocking; checks `ctl`.
pub fn attribute(
    mesh: &Mesh,
    bits: BitVolume,
    want: Want,
    ctl: &Control,
) -> Result<Attributed, ColourError> {
    let grid = *bits.grid();
    let t0 = std::time::Instant::now();
    let s = surface(mesh, &grid, want, &ctl.stage(0.0, 0.7))?;
    let t1 = std::time::Instant::now();
    let source = propagate::nearest(&bits, &s.keys, &ctl.stage(0.7, 1.0))?;
    tracing::debug!(
        surface_s = (t1 - t0).as_secs_f64(),
        propagate_s = t1.elapsed().as_secs_f64(),
        surface_voxels = s.keys.len(),
        "colour"
    );
    let mut out = Attributed::new(bits);
    // `source` indexes the surface voxels; without any (a volume no triangle crosses with
    // positive area) every value is zero.
    let pick = |r: usize| source[r] as usize;
    if want.colour {
        // Each surface voxel's bytes once (the sRGB curve is not cheap), then by source.
        let bytes: Vec<[u8; 4]> = s.rgba.par_iter().map(|&c| to_rgba8(c)).collect();
        let v = (0..source.len())
            .into_par_iter()
            .with_min_len(4096)
            .map(|r| {
                if s.keys.is_empty() {
                    [0; 4]
                } else {
                    bytes[pick(r)]
                }
            })
            .collect();
        out.add(RGBA, ChannelValues::Rgba8(v))
            .expect("one per voxel");
    }
    if want.material {
        let v = (0..source.len())
            .map(|r| {
                if s.keys.is_empty() {
                    0
                } else {
                    s.material[pick(r)]
                }
            })
            .collect();
        out.add(MATERIAL, ChannelValues::U16(v))
            .expect("one per voxel");
    }
    Ok(out)
}

#[cfg(test)]
mod tests;
