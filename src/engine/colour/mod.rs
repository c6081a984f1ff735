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

/// Bytes of a [`Piece`] (the memory estimate's, `app::cost::colour_job`).
pub const PIECE_BYTES: u64 = std::mem::size_of::<Piece>() as u64;

/// Triangles a batch: the pieces of two batches are held at once (`app::cost::colour_job`).
pub const BATCH: usize = 1 << 15;

/// Everything the colour at a point of a triangle needs.
struct Shader<'m> {
    mesh: &'m Mesh,
    a: &'m Attributes,
    /// The vertex colours in linear light.
    colors: Option<std::borrow::Cow<'m, [[f32; 4]]>>,
}

/// What one triangle's colour needs, gathered once for all its pieces ([`Shader::prepare`]).
struct TriShade<'m> {
    /// The colour without the texture at corners 0, 1 and 2 (it is linear over the triangle:
    /// the base colour times the interpolated vertex colour).
    plain: [[f64; 4]; 3],
    /// Whether `plain` differs between the corners (vertex colours): else it is `plain[0]`
    /// everywhere.
    varying: bool,
    /// The texture: the image, its sampler, the texture coordinates of the corners.
    texture: Option<(&'m Image, crate::mesh::texture::TextureRef, [[f64; 2]; 3])>,
}

/// `v0 + (v1 − v0)·b0 + (v2 − v0)·b1`: the value at weights `b` of something linear over a
/// triangle, from its corners.
#[inline(always)]
fn interpolate<const N: usize>(c: &[[f64; N]; 3], b: [f64; 2]) -> [f64; N] {
    std::array::from_fn(|k| c[0][k] + (c[1][k] - c[0][k]) * b[0] + (c[2][k] - c[0][k]) * b[1])
}

impl<'m> Shader<'m> {
    /// Triangle `t`'s [`TriShade`].
    fn prepare(&self, t: usize) -> TriShade<'m> {
        let base = match &self.a.material {
            Some(m) => self.a.materials[usize::from(m[t])]
                .base_color
                .map(f64::from),
            None => [1.0; 4],
        };
        let (plain, varying) = match &self.colors {
            Some(vc) => {
                let tri = self.mesh.triangles()[t];
                let plain: [[f64; 4]; 3] = std::array::from_fn(|i| {
                    std::array::from_fn(|k| base[k] * f64::from(vc[tri[i] as usize][k]))
                });
                let varying = plain[1] != plain[0] || plain[2] != plain[0];
                (plain, varying)
            }
            None => ([base; 3], false),
        };
        let texture = (|| {
            let a: &'m Attributes = self.a;
            let m = a.material.as_ref()?[t];
            let tex = a.materials[usize::from(m)].texture?;
            let uv = a.uv.as_ref()?.corners(t, self.mesh.triangles()[t]);
            Some((&a.images[tex.image], tex, uv.map(|c| c.map(f64::from))))
        })();
        TriShade {
            plain,
            varying,
            texture,
        }
    }

    /// The integral of the colour over `piece` (of a triangle shaded by `sh`) and its area, in
    /// world units.
    fn integrate(sh: &TriShade, piece: &[Vertex], s2: f64) -> (f64, [f64; 4]) {
        let Some((img, tex, uv)) = &sh.texture else {
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
            let c = interpolate(&sh.plain, b);
            let area = a2 / 2.0 * s2;
            return (area, c.map(|v| v * area));
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
            let uvs = fan.map(|v| interpolate(uv, v.b));
            let samples = ((uvs[1][0] - uvs[0][0]) * (uvs[2][1] - uvs[0][1])
                - (uvs[2][0] - uvs[0][0]) * (uvs[1][1] - uvs[0][1]))
                .abs()
                / 2.0
                * texels
                * SAMPLES_PER_TEXEL;
            // No more than SAMPLES_PER_VOXEL_FACE a voxel face's area of surface: a voxel's
            // colour averages all its parts' samples.
            let samples = samples.min((SAMPLES_PER_VOXEL_FACE * area / s2).max(1.0));
            // The least level with 4^level ≥ samples, up to MAX_LEVEL (powers of 4 are exact).
            let (mut level, mut four_to) = (0, 1.0);
            while level < MAX_LEVEL && four_to < samples {
                level += 1;
                four_to *= 4.0;
            }
            let n = 1u32 << level;
            let per = area / f64::from(n * n);
            // The samples of a fan triangle are summed in f32 (at most 4^MAX_LEVEL of values
            // in [0, 1]: a relative error under 2^-15), the fan triangles in f64.
            let mut part = [0.0f32; 4];
            if sh.varying {
                let plains = fan.map(|v| interpolate(&sh.plain, v.b));
                sub_centroids(n, |s, r| {
                    let [u, v] = interpolate(&uvs, [s, r]);
                    let c = interpolate(&plains, [s, r]);
                    let texel = img.sample(u, v, tex);
                    for k in 0..4 {
                        part[k] += (c[k] as f32) * texel[k];
                    }
                });
                for k in 0..4 {
                    sum[k] += per * f64::from(part[k]);
                }
            } else {
                sub_centroids(n, |s, r| {
                    let [u, v] = interpolate(&uvs, [s, r]);
                    let texel = img.sample(u, v, tex);
                    for k in 0..4 {
                        part[k] += texel[k];
                    }
                });
                for k in 0..4 {
                    sum[k] += per * sh.plain[0][k] * f64::from(part[k]);
                }
            }
            total += area;
        }
        (total, sum)
    }
}

/// Calls `f(s, r)` with the centroids of the n² equal sub-triangles of the triangle with corners
/// (0, 0), (1, 0), (0, 1) cut n times along each edge (n a power of two).
fn sub_centroids(n: u32, mut f: impl FnMut(f64, f64)) {
    // n is a power of two, so multiplying by 1/n is dividing by n, exactly.
    debug_assert!(n.is_power_of_two());
    let inv = 1.0 / f64::from(n);
    for i in 0..n {
        let (a1, a2) = (
            (f64::from(i) + 1.0 / 3.0) * inv,
            (f64::from(i) + 2.0 / 3.0) * inv,
        );
        for j in 0..n - i {
            f(a1, (f64::from(j) + 1.0 / 3.0) * inv);
            if i + j + 1 < n {
                f(a2, (f64::from(j) + 2.0 / 3.0) * inv);
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
    // Each run of triangles' pieces in triangle order, the runs in order (rayon's collect keeps
    // it): a voxel's sums are taken in triangle order, the same on every run whatever the
    // threads did.
    let cut = |range: std::ops::Range<usize>| -> Vec<Vec<Piece>> {
        range
            .into_par_iter()
            .with_min_len(16)
            .fold(
                || (Vec::new(), Clipper::default()),
                |(mut out, mut clipper), t| {
                    let tri = mesh.triangle(t).map(to_grid);
                    let sh = shader.prepare(t);
                    clipper.pieces(&tri, dims, |v, piece| {
                        let (area, rgba) = Shader::integrate(&sh, piece, s2);
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
            .collect()
    };
    let material = a.material.as_deref().filter(|_| want.material);
    let add = |acc: &mut HashMap<u64, Acc, _>,
               mats: &mut HashMap<(u64, u16), f64, _>,
               runs: Vec<Vec<Piece>>| {
        for p in runs.iter().flatten() {
            let e = acc.entry(p.key).or_default();
            e.area += p.area;
            for k in 0..4 {
                e.rgba[k] += p.rgba[k];
            }
            if let Some(m) = material {
                *mats.entry((p.key, m[p.tri as usize])).or_default() += p.area;
            }
        }
    };
    // Batch b's pieces are added while batch b + 1 is cut (the adding is serial).
    let mut pending: Option<Vec<Vec<Piece>>> = None;
    for start in (0..n).step_by(BATCH) {
        ctl.check()?;
        let end = (start + BATCH).min(n);
        let (_, runs) = rayon::join(
            || {
                if let Some(runs) = pending.take() {
                    add(&mut acc, &mut mats, runs);
                }
            },
            || cut(start..end),
        );
        pending = Some(runs);
        counter.add((end - start) as u64);
    }
    if let Some(runs) = pending.take() {
        add(&mut acc, &mut mats, runs);
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
