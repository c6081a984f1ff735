//! `.binvox` (Patrick Min's format): a text header (`#binvox 1`, `dim D D D`, `translate x y z`,
//! `scale s`, `data`) then (value, count ≤ 255) byte pairs. Voxels run with y fastest, then z,
//! then x: index `x·D·D + z·D + y`. `scale` is the edge length of the whole cube, so the format is
//! cubic: a grid that is not is padded with empty voxels on its high sides up to the longest axis.

use super::{CodecError, malformed};
use crate::grid::Grid;
use crate::volume::{BitVolume, Volume};

/// Can `.binvox` hold `v`? (Its row of the format table: bit volumes only.)
pub fn check(v: &Volume) -> Result<(), CodecError> {
    super::VolumeFormat::Binvox.check(v)
}

pub fn encode(v: &Volume) -> Result<Vec<u8>, CodecError> {
    check(v)?;
    let mut out = vec![];
    write(v, &mut out).expect("writing to memory");
    Ok(out)
}

/// Streams the `.binvox` of `v` to `out` in pieces of at most 64 KiB (the padded cube of a
/// long, thin grid is far larger than the grid). `InvalidInput` for a density volume (see
/// [`check`]).
pub fn write(v: &Volume, out: &mut impl std::io::Write) -> std::io::Result<()> {
    let Some(b) = v.bits() else {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "binvox stores one bit per voxel",
        ));
    };
    let g = b.grid();
    let n = *g.dims.iter().max().unwrap();
    out.write_all(
        format!(
            "#binvox 1\ndim {n} {n} {n}\ntranslate {} {} {}\nscale {}\ndata\n",
            g.origin[0],
            g.origin[1],
            g.origin[2],
            n as f64 * g.voxel_size
        )
        .as_bytes(),
    )?;
    let mut rle = Rle {
        buf: Vec::with_capacity(PIECE + 2),
        run: None,
    };
    let [dx, dy, dz] = g.dims;
    for x in 0..n {
        for z in 0..n {
            if x >= dx || z >= dz {
                // Padding: a whole column of empty voxels at once (the padded cube of a long,
                // thin grid is mostly this).
                rle.push(0, n as u64, out)?;
                continue;
            }
            for y in 0..dy {
                rle.push(b.get(x, y, z) as u8, 1, out)?;
            }
            rle.push(0, (n - dy) as u64, out)?;
        }
    }
    if let Some((v, c)) = rle.run {
        rle.buf.extend_from_slice(&[v, c]);
    }
    out.write_all(&rle.buf)
}

/// Bytes of output held before they are written.
const PIECE: usize = 64 << 10;

/// The run-length encoder: the open run and the pairs not yet written.
struct Rle {
    buf: Vec<u8>,
    run: Option<(u8, u8)>,
}

impl Rle {
    /// Appends `count` voxels of `val`.
    fn push(
        &mut self,
        val: u8,
        mut count: u64,
        out: &mut impl std::io::Write,
    ) -> std::io::Result<()> {
        while count > 0 {
            match &mut self.run {
                Some((v, c)) if *v == val && *c < 255 => {
                    let add = count.min(255 - *c as u64);
                    *c += add as u8;
                    count -= add;
                }
                _ => {
                    let add = count.min(255);
                    if let Some((v, c)) = self.run.replace((val, add as u8)) {
                        self.buf.extend_from_slice(&[v, c]);
                        if self.buf.len() >= PIECE {
                            out.write_all(&self.buf)?;
                            self.buf.clear();
                        }
                    }
                    count -= add;
                }
            }
        }
        Ok(())
    }
}

pub fn decode(bytes: &[u8]) -> Result<BitVolume, CodecError> {
    decode_limited(bytes, u64::MAX)
}

/// [`decode`], refusing grids of more than `max_voxels` voxels before allocating them.
pub fn decode_limited(bytes: &[u8], max_voxels: u64) -> Result<BitVolume, CodecError> {
    let mut pos = 0;
    let mut line = || -> Result<String, CodecError> {
        let end = bytes[pos..]
            .iter()
            .position(|&c| c == b'\n')
            .ok_or_else(|| malformed("binvox", "truncated header"))?;
        let l = String::from_utf8_lossy(&bytes[pos..pos + end])
            .trim()
            .to_string();
        pos += end + 1;
        Ok(l)
    };
    if !line()?.starts_with("#binvox") {
        return Err(malformed("binvox", "not a .binvox file (no #binvox line)"));
    }
    let (mut dims, mut translate, mut scale) = (None, [0.0; 3], 1.0);
    loop {
        let l = line()?;
        let t: Vec<&str> = l.split_whitespace().collect();
        match t.as_slice() {
            ["data"] => break,
            ["dim", a, b, c] => {
                let d: Result<Vec<u32>, _> = [a, b, c].iter().map(|s| s.parse::<u32>()).collect();
                dims = Some(d.map_err(|_| malformed("binvox", format!("bad dim line {l:?}")))?);
            }
            ["translate", a, b, c] => {
                for (o, s) in translate.iter_mut().zip([a, b, c]) {
                    *o = s
                        .parse()
                        .map_err(|_| malformed("binvox", format!("bad translate line {l:?}")))?;
                }
            }
            ["scale", s] => {
                scale = s
                    .parse()
                    .map_err(|_| malformed("binvox", format!("bad scale line {l:?}")))?
            }
            _ => return Err(malformed("binvox", format!("unknown header line {l:?}"))),
        }
    }
    let d = dims.ok_or_else(|| malformed("binvox", "no dim line"))?;
    let (d, h, w) = (d[0], d[1], d[2]);
    // Saturating: three u32 axes can multiply past u64 (a wrapped product would pass the bound).
    let total = Grid::count([d, h, w]);
    if total == 0 || total > (1u64 << 36) {
        return Err(malformed("binvox", "dims out of range"));
    }
    let n = d.max(h).max(w);
    let vs = scale / n as f64;
    if !(vs.is_finite() && vs > 0.0) || translate.iter().any(|t: &f64| !t.is_finite()) {
        return Err(malformed("binvox", "bad scale or translate"));
    }
    // Index order x·(w·h) + z·w + y: the first dim is x, the second z, the third y.
    let grid = Grid {
        origin: translate,
        voxel_size: vs,
        dims: [d, w, h],
    };
    let data = &bytes[pos..];
    // The runs must cover the grid exactly; checked before the volume is allocated, so a header
    // naming a huge grid over a few bytes of data costs nothing.
    if !data.len().is_multiple_of(2) {
        return Err(malformed("binvox", "odd number of data bytes"));
    }
    let covered: u64 = data.chunks_exact(2).map(|p| p[1] as u64).sum();
    if covered > total {
        return Err(malformed(
            "binvox",
            "run-length data runs past the end of the grid",
        ));
    }
    if covered < total {
        return Err(malformed(
            "binvox",
            format!("truncated: data covers {covered} of {total} voxels"),
        ));
    }
    if total > max_voxels {
        return Err(malformed(
            "binvox",
            format!("the grid has {total} voxels, over the limit of {max_voxels}"),
        ));
    }
    let mut v = BitVolume::new(grid);
    let mut i = 0u64;
    for pair in data.chunks_exact(2) {
        let [val, count] = pair else { unreachable!() };
        if *val != 0 {
            for j in i..i + *count as u64 {
                let (x, rest) = (
                    (j / (w as u64 * h as u64)) as u32,
                    j % (w as u64 * h as u64),
                );
                let (z, y) = ((rest / w as u64) as u32, (rest % w as u64) as u32);
                v.set(x, y, z, true);
            }
        }
        i += *count as u64;
    }
    Ok(v)
}
