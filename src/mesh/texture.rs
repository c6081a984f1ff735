//! Base colour textures for colour voxels (issue 34): PNG and JPEG images decoded by image-rs
//! within a byte budget, and their sampling as glTF defines it.
//!
//! * **Decoding**: the image's dimensions are read from its header first; one whose RGBA8 texels
//!   would take more than the budget left (`max_texture_bytes`, shared by all the mesh's
//!   images) is refused before any texel is decoded (4 bytes a texel counted, whatever the
//!   image holds). Texels are kept as 8-bit sRGB: RGB (3 bytes a texel, alpha 255) for images
//!   without alpha, RGBA (4 bytes) for the others, as the files hold them.
//! * **Coordinates**: glTF's: (0, 0) is the image's top-left corner, u to the right, v down;
//!   texel (i, j)'s centre is at ((i + ½)/W, (j + ½)/H).
//! * **Wrapping** per axis (glTF sampler `wrapS`/`wrapT`): repeat (the default), mirrored repeat,
//!   clamp to edge, applied to texel indices.
//! * **Filtering** (the sampler's `magFilter`): linear (the default, bilinear between the four
//!   nearest texel centres) or nearest (the texel the point lies in).
//! * **Colour space**: texels are sRGB-encoded, so they are decoded to linear light (the sRGB
//!   transfer function of IEC 61966-2-1) before they are filtered; alpha is linear.

use super::MeshError;

/// A decoded image: `width × height` sRGB texels, row by row from the top, 8 bits a channel:
/// RGB (alpha 255) or RGBA.
#[derive(Clone, PartialEq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    /// Bytes a texel: 3 (RGB) or 4 (RGBA).
    channels: usize,
    bytes: Vec<u8>,
}

impl Image {
    /// An image of `width × height` RGBA texels (`texels.len()` must be their number).
    pub fn from_rgba(width: u32, height: u32, texels: Vec<[u8; 4]>) -> Image {
        assert_eq!(texels.len(), width as usize * height as usize);
        Image {
            width,
            height,
            channels: 4,
            bytes: texels.into_iter().flatten().collect(),
        }
    }

    /// Texel `i` (row-major) as RGBA bytes.
    #[inline(always)]
    pub fn rgba_at(&self, i: usize) -> [u8; 4] {
        if self.channels == 3 {
            unpack::<3>(&self.bytes[3 * i..])
        } else {
            unpack::<4>(&self.bytes[4 * i..])
        }
    }

    /// All texels as RGBA bytes, row by row.
    pub fn to_rgba(&self) -> Vec<[u8; 4]> {
        (0..self.width as usize * self.height as usize)
            .map(|i| self.rgba_at(i))
            .collect()
    }
}

/// The texel at the front of `b`, packed in `C` bytes (3: RGB, alpha 255; 4: RGBA), as RGBA.
#[inline(always)]
fn unpack<const C: usize>(b: &[u8]) -> [u8; 4] {
    if C == 3 {
        [b[0], b[1], b[2], 255]
    } else {
        [b[0], b[1], b[2], b[3]]
    }
}

impl std::fmt::Debug for Image {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Image({}x{})", self.width, self.height)
    }
}

/// How texel indices outside the image are brought back in (glTF's sampler wrap modes).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Wrap {
    #[default]
    Repeat,
    MirroredRepeat,
    ClampToEdge,
}

/// The filter between texels (glTF's `magFilter`; voxels average over areas larger than a
/// texel only through the sampling of `engine::colour`, so there is no minification filter:
/// mipmaps, as `minFilter` may ask, blended a texture atlas's islands and were less accurate on
/// `Fox.glb`, docs/methods.md, "Colour and material").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Filter {
    #[default]
    Linear,
    Nearest,
}

/// A material's base colour texture: the image, its sampler. The texture coordinates (with a
/// `KHR_texture_transform` applied) are the mesh's, per triangle corner.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TextureRef {
    pub image: usize,
    pub wrap: [Wrap; 2],
    pub filter: Filter,
}

/// sRGB-encoded byte to linear light, for each of the 256 values.
pub fn srgb_to_linear_table() -> &'static [f32; 256] {
    static TABLE: std::sync::OnceLock<[f32; 256]> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| std::array::from_fn(|i| srgb_to_linear(i as f64 / 255.0) as f32))
}

/// The sRGB transfer function's inverse (IEC 61966-2-1), on [0, 1].
pub fn srgb_to_linear(c: f64) -> f64 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// The sRGB transfer function (IEC 61966-2-1), on [0, 1].
pub fn linear_to_srgb(c: f64) -> f64 {
    if c <= 0.0031308 {
        c * 12.92
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// Decodes `bytes` ([`decode`]) within what is left of a mesh's texture budget, takes the
/// image's texels from it and adds the image to `images`: its index there.
pub fn decode_into(
    images: &mut Vec<Image>,
    budget: &mut u64,
    bytes: &[u8],
    what: &str,
) -> Result<usize, MeshError> {
    let img = decode(bytes, *budget, what)?;
    *budget -= u64::from(img.width) * u64::from(img.height) * 4;
    images.push(img);
    Ok(images.len() - 1)
}

/// Decodes a PNG or JPEG image (recognised by its bytes) whose texels fit in `budget` bytes (4 a
/// texel), refusing a larger one before decoding it. `what` names it in errors ("image 2").
pub fn decode(bytes: &[u8], budget: u64, what: &str) -> Result<Image, MeshError> {
    let bad = |detail: String| MeshError::Malformed {
        format: "texture",
        detail: format!("{what}: {detail}"),
    };
    let format = image::guess_format(bytes).map_err(|_| bad("not a PNG or JPEG image".into()))?;
    if !matches!(format, image::ImageFormat::Png | image::ImageFormat::Jpeg) {
        return Err(bad(format!(
            "{format:?} images are not read; use PNG or JPEG"
        )));
    }
    let reader = image::ImageReader::with_format(std::io::Cursor::new(bytes), format);
    let (w, h) = reader
        .into_dimensions()
        .map_err(|e| bad(format!("unreadable header: {e}")))?;
    let need = u64::from(w) * u64::from(h) * 4;
    if need > budget {
        return Err(MeshError::Malformed {
            format: "texture",
            detail: format!(
                "{what} is {w}x{h}, {need} bytes decoded, over the {budget} bytes left of the limit on a mesh's decoded textures"
            ),
        });
    }
    // A second reader, built with the limit from the header's size: the PNG decoder sizes its
    // own buffers by the limits it is built with (`set_limits` afterwards would not reach
    // them), so the header is read twice.
    let mut reader = image::ImageReader::with_format(std::io::Cursor::new(bytes), format);
    let mut limits = image::Limits::default();
    limits.max_alloc = Some(need.saturating_mul(2).max(1 << 20));
    reader.limits(limits);
    let decoder = reader
        .into_decoder()
        .map_err(|e| bad(format!("unreadable header: {e}")))?;
    use image::ImageDecoder;
    let (width, height) = decoder.dimensions();
    let channels = match decoder.color_type() {
        image::ColorType::L8 => 1,
        image::ColorType::La8 => 2,
        image::ColorType::Rgb8 => 3,
        image::ColorType::Rgba8 => 4,
        _ => 0,
    };
    let (bytes, channels) = if channels > 0 {
        // 8-bit images are decoded into the texels' own array and widened there, in place,
        // grey to RGB, grey and alpha to RGBA; RGB stays RGB (the decoder's array, its RGBA
        // copy and the texels were three arrays of fresh pages, 176 MB for a 4096² RGB
        // texture: a quarter of a coloured voxelization's time went to the kernel clearing
        // them; then one RGBA array, 64 MB; now 48 MB).
        let n = width as usize * height as usize;
        let wide = if channels % 2 == 1 { 3 } else { 4 };
        let mut bytes = vec![0u8; n * wide];
        decoder
            .read_image(&mut bytes[..n * channels])
            .map_err(|e| bad(format!("{e}")))?;
        if channels < wide {
            widen(&mut bytes, channels, wide);
        }
        (bytes, wide)
    } else {
        // 16-bit and float images: through the library's conversion.
        let rgba = image::DynamicImage::from_decoder(decoder)
            .map_err(|e| bad(format!("{e}")))?
            .into_rgba8()
            .into_raw();
        (rgba, 4)
    };
    Ok(Image {
        width,
        height,
        channels,
        bytes,
    })
}

/// Widens the texels packed at the front of `buf` with `channels` bytes each (grey: 1, grey
/// and alpha: 2) to `wide` bytes each (RGB: 3, RGBA: 4) in place, as the `image` crate's
/// conversions do: grey to three equal components. Back to front: texel i's bytes are read
/// before anything at or after `channels · i` is written.
fn widen(buf: &mut [u8], channels: usize, wide: usize) {
    let n = buf.len() / wide;
    for i in (0..n).rev() {
        let s = &buf[channels * i..channels * (i + 1)];
        let c = match *s {
            [g] => [g, g, g, 255],
            [g, a] => [g, g, g, a],
            [r, g, b] => [r, g, b, 255],
            [r, g, b, a] => [r, g, b, a],
            _ => unreachable!("one to four channels"),
        };
        buf[wide * i..wide * (i + 1)].copy_from_slice(&c[..wide]);
    }
}

/// Byte i / 255 for each of the 256 bytes (alpha is linear).
const UNIT: [f32; 256] = {
    let mut t = [0.0f32; 256];
    let mut i = 0;
    while i < 256 {
        t[i] = i as f32 / 255.0;
        i += 1;
    }
    t
};

/// A texel's sRGB bytes in linear light (alpha as it is).
fn linear(c: [u8; 4]) -> [f32; 4] {
    linear_by(srgb_to_linear_table(), c)
}

/// [`linear`] with the table at hand.
#[inline(always)]
fn linear_by(lin: &[f32; 256], c: [u8; 4]) -> [f32; 4] {
    [
        lin[c[0] as usize],
        lin[c[1] as usize],
        lin[c[2] as usize],
        UNIT[c[3] as usize],
    ]
}

fn wrap(i: i64, n: u32, mode: Wrap) -> u32 {
    let n = i64::from(n);
    (match mode {
        Wrap::Repeat => i.rem_euclid(n),
        Wrap::ClampToEdge => i.clamp(0, n - 1),
        Wrap::MirroredRepeat => {
            let m = i.rem_euclid(2 * n);
            if m < n { m } else { 2 * n - 1 - m }
        }
    }) as u32
}

impl Image {
    fn texel(&self, i: i64, j: i64, t: &TextureRef) -> [f32; 4] {
        let x = wrap(i, self.width, t.wrap[0]);
        let y = wrap(j, self.height, t.wrap[1]);
        linear(self.rgba_at(y as usize * self.width as usize + x as usize))
    }

    /// The linear RGBA at texture coordinates (u, v) through `t`'s sampler. Coordinates that
    /// are not finite read texel (0, 0).
    #[inline(always)]
    pub fn sample(&self, u: f64, v: f64, t: &TextureRef) -> [f32; 4] {
        if t.filter == Filter::Linear {
            // Between four texel centres inside the image (nearly every sample): nothing to
            // wrap, and u, v in (0, 1), where every wrap mode leaves them as they are, so the
            // result is `sample_any`'s, without its floors and remainders.
            let (w, h) = (f64::from(self.width), f64::from(self.height));
            let (x, y) = (u * w - 0.5, v * h - 0.5);
            if x >= 0.0 && y >= 0.0 && x < w - 1.0 && y < h - 1.0 {
                let (i, j) = (x as usize, y as usize);
                let (fx, fy) = ((x - i as f64) as f32, (y - j as f64) as f32);
                return self.bilinear_inside(i, j, fx, fy);
            }
        }
        self.sample_any(u, v, t)
    }

    /// Bilinear between texels (i, j), (i + 1, j), (i, j + 1) and (i + 1, j + 1), all inside
    /// the image, at fractions `fx`, `fy`.
    #[inline(always)]
    fn bilinear_inside(&self, i: usize, j: usize, fx: f32, fy: f32) -> [f32; 4] {
        if self.channels == 3 {
            self.bilinear_packed::<3>(i, j, fx, fy)
        } else {
            self.bilinear_packed::<4>(i, j, fx, fy)
        }
    }

    /// [`Image::bilinear_inside`] for `C` bytes a texel.
    #[inline(always)]
    fn bilinear_packed<const C: usize>(&self, i: usize, j: usize, fx: f32, fy: f32) -> [f32; 4] {
        let w = self.width as usize;
        let at = C * (j * w + i);
        let lin = srgb_to_linear_table();
        let (top, bottom) = (
            &self.bytes[at..at + 2 * C],
            &self.bytes[at + C * w..at + C * w + 2 * C],
        );
        bilinear(
            [
                linear_by(lin, unpack::<C>(top)),
                linear_by(lin, unpack::<C>(&top[C..])),
                linear_by(lin, unpack::<C>(bottom)),
                linear_by(lin, unpack::<C>(&bottom[C..])),
            ],
            fx,
            fy,
        )
    }

    /// [`Image::sample`] anywhere (out of line: `sample`'s common case is inlined alone).
    #[inline(never)]
    fn sample_any(&self, u: f64, v: f64, t: &TextureRef) -> [f32; 4] {
        let (u, v) = if u.is_finite() && v.is_finite() {
            (u, v)
        } else {
            (0.0, 0.0)
        };
        // In texel units; far coordinates are brought near 0 first (wrapping is periodic in
        // the image size, or clamped) so the float stays exact enough.
        let fold = |c: f64, n: u32, m: Wrap| match m {
            Wrap::Repeat => c.rem_euclid(1.0) * f64::from(n),
            Wrap::MirroredRepeat => c.rem_euclid(2.0) * f64::from(n),
            Wrap::ClampToEdge => c.clamp(-1.0, 2.0) * f64::from(n),
        };
        let x = fold(u, self.width, t.wrap[0]);
        let y = fold(v, self.height, t.wrap[1]);
        match t.filter {
            Filter::Nearest => self.texel(x.floor() as i64, y.floor() as i64, t),
            Filter::Linear => {
                let (x, y) = (x - 0.5, y - 0.5);
                let (x0, y0) = (x.floor(), y.floor());
                let (fx, fy) = ((x - x0) as f32, (y - y0) as f32);
                let (i, j) = (x0 as i64, y0 as i64);
                let (w, h) = (i64::from(self.width), i64::from(self.height));
                if i >= 0 && j >= 0 && i + 1 < w && j + 1 < h {
                    // All four inside: no wrapping (what `texel` would give, without its
                    // divisions).
                    return self.bilinear_inside(i as usize, j as usize, fx, fy);
                }
                let corners = [(i, j), (i + 1, j), (i, j + 1), (i + 1, j + 1)]
                    .map(|(i, j)| self.texel(i, j, t));
                bilinear(corners, fx, fy)
            }
        }
    }
}

/// Bilinear interpolation between texels `[a, b, c, d]` (top left, top right, bottom left,
/// bottom right) at fractions `fx`, `fy`.
#[inline(always)]
fn bilinear([a, b, c, d]: [[f32; 4]; 4], fx: f32, fy: f32) -> [f32; 4] {
    std::array::from_fn(|k| {
        let top = a[k] + (b[k] - a[k]) * fx;
        let bottom = c[k] + (d[k] - c[k]) * fx;
        top + (bottom - top) * fy
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(w: u32, h: u32, f: impl Fn(u32, u32) -> [u8; 4]) -> Image {
        Image::from_rgba(
            w,
            h,
            (0..h)
                .flat_map(|y| (0..w).map(move |x| (x, y)))
                .map(|(x, y)| f(x, y))
                .collect(),
        )
    }

    #[test]
    fn srgb_bytes_survive_the_round_trip_through_linear() {
        for b in 0..=255u8 {
            let lin = srgb_to_linear_table()[b as usize] as f64;
            assert_eq!((linear_to_srgb(lin) * 255.0).round() as u8, b, "byte {b}");
        }
    }

    #[test]
    fn wrap_modes_and_filters() {
        // 2x1: left texel black, right white (alpha = the red byte, linear).
        let img = image(2, 1, |x, _| [255 * x as u8; 4]);
        let t = |wrap, filter| TextureRef {
            image: 0,
            wrap: [wrap; 2],
            filter,
        };
        let rep = t(Wrap::Repeat, Filter::Nearest);
        assert_eq!(img.sample(0.25, 0.5, &rep)[0], 0.0);
        assert_eq!(img.sample(0.75, 0.5, &rep)[0], 1.0);
        assert_eq!(img.sample(1.25, 7.5, &rep)[0], 0.0);
        assert_eq!(img.sample(-0.25, 0.5, &rep)[0], 1.0);
        let mir = t(Wrap::MirroredRepeat, Filter::Nearest);
        assert_eq!(img.sample(1.25, 0.5, &mir)[0], 1.0);
        assert_eq!(img.sample(-0.25, 0.5, &mir)[0], 0.0);
        let clamp = t(Wrap::ClampToEdge, Filter::Nearest);
        assert_eq!(img.sample(5.0, 0.5, &clamp)[0], 1.0);
        assert_eq!(img.sample(-5.0, 0.5, &clamp)[0], 0.0);
        // Bilinear: halfway between the texel centres (u = 0.5) is the mean, in linear light.
        let lin = t(Wrap::ClampToEdge, Filter::Linear);
        assert!((img.sample(0.5, 0.5, &lin)[3] - 0.5).abs() < 1e-6);
        assert!((img.sample(0.375, 0.5, &lin)[3] - 0.25).abs() < 1e-6);
        // Repeat blends the last texel with the first across the edge.
        let lrep = t(Wrap::Repeat, Filter::Linear);
        assert!((img.sample(0.0, 0.5, &lrep)[3] - 0.5).abs() < 1e-6);
        assert_eq!(
            img.sample(f64::NAN, 0.5, &lrep),
            img.sample(0.0, 0.0, &lrep)
        );
    }

    #[test]
    fn the_fast_path_gives_what_the_general_sampler_gives() {
        // Texels from a hash: neighbours differ, so a wrong texel or weight shows.
        let rgba = image(37, 23, |x, y| {
            let h = x.wrapping_mul(2654435761) ^ y.wrapping_mul(40503).rotate_left(7);
            h.to_le_bytes()
        });
        // The same texels packed as RGB (alpha 255), as an RGB file decodes.
        let opaque: Vec<[u8; 4]> = rgba
            .to_rgba()
            .iter()
            .map(|t| [t[0], t[1], t[2], 255])
            .collect();
        let rgb = Image {
            width: 37,
            height: 23,
            channels: 3,
            bytes: opaque.iter().flat_map(|t| [t[0], t[1], t[2]]).collect(),
        };
        assert_eq!(rgb.to_rgba(), opaque);
        let mut rng = crate::testkit::Rng::new(3);
        let mut rnd = || rng.unit();
        for (img, wrap) in [&rgba, &rgb].into_iter().flat_map(|img| {
            [Wrap::Repeat, Wrap::MirroredRepeat, Wrap::ClampToEdge].map(|w| (img, w))
        }) {
            let t = TextureRef {
                image: 0,
                wrap: [wrap; 2],
                filter: Filter::Linear,
            };
            for i in 0..4000 {
                // Inside, on texel centres and edges, and outside the image.
                let (u, v) = match i % 4 {
                    0 => (rnd(), rnd()),
                    1 => (((i % 37) as f64 + 0.5) / 37.0, (i % 23) as f64 / 23.0),
                    2 => (rnd() * 3.0 - 1.0, rnd() * 3.0 - 1.0),
                    _ => (0.5 / 37.0 + rnd() * 1e-12, 1.0 - 0.5 / 23.0 - rnd() * 1e-12),
                };
                assert_eq!(img.sample(u, v, &t), img.sample_any(u, v, &t), "{u} {v}");
            }
        }
    }

    #[test]
    fn decoding_is_bounded_before_it_starts() {
        let mut png = vec![];
        let img = image::RgbaImage::from_pixel(64, 32, image::Rgba([10, 20, 30, 255]));
        img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
            .unwrap();
        let got = decode(&png, 64 * 32 * 4, "image 0").unwrap();
        assert_eq!((got.width, got.height), (64, 32));
        assert!(got.to_rgba().iter().all(|t| *t == [10, 20, 30, 255]));
        let err = decode(&png, 64 * 32 * 4 - 1, "image 0").unwrap_err();
        assert!(err.to_string().contains("64x32"), "{err}");
        assert!(decode(b"GIF89a....", 1 << 20, "image 1").is_err());
        assert!(decode(&png[..40], 1 << 20, "image 1").is_err());
    }

    #[test]
    fn every_colour_type_decodes_to_the_libraries_rgba() {
        // Random texels of every 8-bit type (widened in place) and two 16-bit ones (the
        // library's conversion), as PNG, and 8-bit grey and RGB as JPEG: the texels must be the
        // `image` crate's own `into_rgba8` of the same file.
        let mut rng = crate::testkit::Rng::new(11);
        let (w, h) = (29, 17);
        let bytes: Vec<u8> = (0..w * h * 8).map(|_| rng.below(256) as u8).collect();
        let words: Vec<u16> = bytes
            .chunks_exact(2)
            .map(|c| u16::from_le_bytes([c[0], c[1]]))
            .collect();
        let n = (w * h) as usize;
        let images: Vec<image::DynamicImage> = vec![
            image::GrayImage::from_raw(w, h, bytes[..n].to_vec())
                .unwrap()
                .into(),
            image::GrayAlphaImage::from_raw(w, h, bytes[..2 * n].to_vec())
                .unwrap()
                .into(),
            image::RgbImage::from_raw(w, h, bytes[..3 * n].to_vec())
                .unwrap()
                .into(),
            image::RgbaImage::from_raw(w, h, bytes[..4 * n].to_vec())
                .unwrap()
                .into(),
            image::ImageBuffer::<image::Luma<u16>, _>::from_raw(w, h, words[..n].to_vec())
                .unwrap()
                .into(),
            image::ImageBuffer::<image::Rgb<u16>, _>::from_raw(w, h, words[..3 * n].to_vec())
                .unwrap()
                .into(),
        ];
        let mut files = vec![];
        for img in &images {
            let mut png = vec![];
            img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
                .unwrap();
            files.push(png);
        }
        for img in &images[..3] {
            if matches!(img, image::DynamicImage::ImageLumaA8(_)) {
                continue;
            }
            let mut jpg = vec![];
            img.write_to(
                &mut std::io::Cursor::new(&mut jpg),
                image::ImageFormat::Jpeg,
            )
            .unwrap();
            files.push(jpg);
        }
        assert_eq!(files.len(), 8);
        for (i, f) in files.iter().enumerate() {
            let want = image::load_from_memory(f).unwrap().into_rgba8();
            let got = decode(f, 1 << 20, "image").unwrap();
            assert_eq!((got.width, got.height), (w, h), "file {i}");
            let got: Vec<u8> = got.to_rgba().iter().flatten().copied().collect();
            assert_eq!(got, want.into_raw(), "file {i}");
        }
    }
}
