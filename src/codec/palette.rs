//! A palette of at most 255 colours for a coloured volume (MagicaVoxel's `.vox`), and each
//! voxel's entry.
//!
//! * **Few colours**: when the voxels have at most 255 distinct RGBA colours, those are the
//!   palette (in increasing RGBA order) and nothing is lost.
//! * **Otherwise**, median cut seeded k-means in CIELAB (with alpha as a fourth axis, 0–100
//!   like L*) over the distinct colours weighted by their voxels (over [`EXACT_POINTS`] of them,
//!   gathered in cells of 5 bits per RGB channel and 3 for alpha, each at the count-weighted
//!   mean colour of its colours, in Lab): median cut splits the cells' box with
//!   the largest weighted spread along its widest axis at the weighted median until there are
//!   255 boxes; their weighted means seed [`LLOYD`] rounds of k-means over the cells. Each voxel
//!   then takes the palette entry nearest to its exact colour in Lab (ΔE76, with alpha). Lab is
//!   the space in which distances approximate perceived differences, which is what the error
//!   report (mean and 99th-percentile ΔE76) measures; median cut alone leaves large boxes in
//!   sparse regions, which the k-means rounds pull towards the colours actually present.
//!
//! Deterministic: no randomness, no thread-dependent order.

use std::collections::HashMap;

use crate::mesh::texture::srgb_to_linear_table;

/// k-means rounds after median cut.
pub const LLOYD: usize = 8;
/// Palette entries (MagicaVoxel's index 0 is empty; 1..=255 are colours).
pub const ENTRIES: usize = 255;
/// Up to this many distinct colours, median cut and k-means work on the colours themselves
/// rather than on cells.
pub const EXACT_POINTS: usize = 1 << 14;

/// A colour in Lab with alpha on L*'s scale.
type Lab = [f64; 4];

/// An sRGB RGBA8 colour in Lab (D65) and alpha · 100 / 255.
pub fn lab(c: [u8; 4]) -> Lab {
    let t = srgb_to_linear_table();
    let (r, g, b) = (
        f64::from(t[c[0] as usize]),
        f64::from(t[c[1] as usize]),
        f64::from(t[c[2] as usize]),
    );
    let x = (0.4124564 * r + 0.3575761 * g + 0.1804375 * b) / 0.95047;
    let y = 0.2126729 * r + 0.7151522 * g + 0.0721750 * b;
    let z = (0.0193339 * r + 0.119192 * g + 0.9503041 * b) / 1.08883;
    let f = |t: f64| {
        if t > 216.0 / 24389.0 {
            t.cbrt()
        } else {
            (24389.0 / 27.0 * t + 16.0) / 116.0
        }
    };
    let (fx, fy, fz) = (f(x), f(y), f(z));
    [
        116.0 * fy - 16.0,
        500.0 * (fx - fy),
        200.0 * (fy - fz),
        f64::from(c[3]) * 100.0 / 255.0,
    ]
}

fn d2(a: &Lab, b: &Lab) -> f64 {
    (0..4).map(|k| (a[k] - b[k]) * (a[k] - b[k])).sum()
}

/// The palette and each voxel's index into it (0-based; `.vox` adds 1), with the error.
#[derive(Clone, Debug, PartialEq)]
pub struct Quantized {
    pub palette: Vec<[u8; 4]>,
    pub index: Vec<u8>,
    /// Mean and 99th percentile over the voxels of ΔE76 (with alpha) between a voxel's colour
    /// and its entry's.
    pub mean_de: f64,
    pub p99_de: f64,
}

/// A weighted point of the cells.
#[derive(Clone, Copy)]
struct Cell {
    lab: Lab,
    w: f64,
}

/// Quantizes `colours` (one per voxel) to at most [`ENTRIES`] entries (module docs).
pub fn quantize(colours: &[[u8; 4]]) -> Quantized {
    let mut counts: HashMap<u32, u32, foldhash::fast::FixedState> =
        HashMap::with_hasher(foldhash::fast::FixedState::default());
    for c in colours {
        *counts.entry(u32::from_be_bytes(*c)).or_default() += 1;
    }
    let mut distinct: Vec<(u32, u32)> = counts.into_iter().collect();
    distinct.sort_unstable();
    let palette: Vec<[u8; 4]> = if distinct.len() <= ENTRIES {
        distinct.iter().map(|&(c, _)| c.to_be_bytes()).collect()
    } else {
        entries(&distinct)
    };
    // Each distinct colour's nearest entry, by a search outward in L* order.
    let labs: Vec<Lab> = palette.iter().map(|&c| lab(c)).collect();
    let mut by_l: Vec<usize> = (0..labs.len()).collect();
    by_l.sort_by(|&a, &b| labs[a][0].total_cmp(&labs[b][0]).then(a.cmp(&b)));
    let ls: Vec<f64> = by_l.iter().map(|&i| labs[i][0]).collect();
    let nearest = |q: &Lab| -> (usize, f64) {
        let start = ls.partition_point(|&l| l < q[0]);
        let mut best = (usize::MAX, f64::INFINITY);
        let consider = |j: usize, best: &mut (usize, f64)| {
            let i = by_l[j];
            let d = d2(q, &labs[i]);
            if d < best.1 || (d == best.1 && i < best.0) {
                *best = (i, d);
            }
        };
        let (mut lo, mut hi) = (start, start);
        loop {
            let down = lo > 0 && (q[0] - ls[lo - 1]).powi(2) <= best.1;
            let up = hi < ls.len() && (ls[hi] - q[0]).powi(2) <= best.1;
            if !down && !up {
                break;
            }
            if up {
                consider(hi, &mut best);
                hi += 1;
            }
            if down {
                lo -= 1;
                consider(lo, &mut best);
            }
        }
        (best.0, best.1.sqrt())
    };
    let mut to_entry: HashMap<u32, (u8, f64), foldhash::fast::FixedState> =
        HashMap::with_hasher(foldhash::fast::FixedState::default());
    let mut errors: Vec<(f64, u32)> = Vec::with_capacity(distinct.len());
    for &(c, n) in &distinct {
        let (i, d) = nearest(&lab(c.to_be_bytes()));
        to_entry.insert(c, (i as u8, d));
        errors.push((d, n));
    }
    let index = colours
        .iter()
        .map(|c| to_entry[&u32::from_be_bytes(*c)].0)
        .collect();
    errors.sort_by(|a, b| a.0.total_cmp(&b.0));
    let total: u64 = errors.iter().map(|e| u64::from(e.1)).sum();
    let mean_de = if total == 0 {
        0.0
    } else {
        errors.iter().map(|e| e.0 * f64::from(e.1)).sum::<f64>() / total as f64
    };
    let mut p99_de = 0.0;
    let mut seen = 0u64;
    let rank = (total as f64 * 0.99).ceil() as u64;
    for e in &errors {
        seen += u64::from(e.1);
        if seen >= rank {
            p99_de = e.0;
            break;
        }
    }
    Quantized {
        palette,
        index,
        mean_de,
        p99_de,
    }
}

/// The entries for more than [`ENTRIES`] distinct colours: median cut, then k-means.
fn entries(distinct: &[(u32, u32)]) -> Vec<[u8; 4]> {
    // Few enough distinct colours are the points themselves; more are gathered in cells.
    if distinct.len() <= EXACT_POINTS {
        let pts: Vec<Cell> = distinct
            .iter()
            .map(|&(c, n)| Cell {
                lab: lab(c.to_be_bytes()),
                w: f64::from(n),
            })
            .collect();
        return refine(&pts);
    }
    // Cells of 5 bits per colour channel and 3 for alpha.
    let mut cells: HashMap<u32, (Lab, f64), foldhash::fast::FixedState> =
        HashMap::with_hasher(foldhash::fast::FixedState::default());
    for &(c, n) in distinct {
        let b = c.to_be_bytes();
        let key = u32::from(b[0] >> 3) << 13
            | u32::from(b[1] >> 3) << 8
            | u32::from(b[2] >> 3) << 3
            | u32::from(b[3] >> 5);
        let l = lab(b);
        let e = cells.entry(key).or_insert(([0.0; 4], 0.0));
        for (s, v) in e.0.iter_mut().zip(l) {
            *s += v * f64::from(n);
        }
        e.1 += f64::from(n);
    }
    let mut keys: Vec<u32> = cells.keys().copied().collect();
    keys.sort_unstable();
    let pts: Vec<Cell> = keys
        .iter()
        .map(|k| {
            let (s, w) = cells[k];
            Cell {
                lab: s.map(|v| v / w),
                w,
            }
        })
        .collect();
    refine(&pts)
}

/// Median cut of `pts` into [`ENTRIES`] boxes, [`LLOYD`] rounds of k-means, the entries.
fn refine(pts: &[Cell]) -> Vec<[u8; 4]> {
    let mut centres = median_cut(pts, ENTRIES);
    for _ in 0..LLOYD {
        let mut sums = vec![([0.0f64; 4], 0.0f64); centres.len()];
        for p in pts {
            let (mut best, mut bd) = (0, f64::INFINITY);
            for (i, c) in centres.iter().enumerate() {
                let d = d2(&p.lab, c);
                if d < bd {
                    best = i;
                    bd = d;
                }
            }
            for k in 0..4 {
                sums[best].0[k] += p.lab[k] * p.w;
            }
            sums[best].1 += p.w;
        }
        for (c, (s, w)) in centres.iter_mut().zip(&sums) {
            if *w > 0.0 {
                *c = s.map(|v| v / w);
            }
        }
    }
    let mut out: Vec<[u8; 4]> = centres.iter().map(from_lab).collect();
    out.sort_unstable();
    out.dedup();
    out
}

/// Median cut of weighted points into at most `n` boxes; their weighted means.
fn median_cut(pts: &[Cell], n: usize) -> Vec<Lab> {
    let mut boxes: Vec<Vec<Cell>> = vec![pts.to_vec()];
    let spread = |b: &[Cell]| -> (f64, usize) {
        let w: f64 = b.iter().map(|p| p.w).sum();
        let mut best = (0.0, 0);
        for k in 0..4 {
            let m = b.iter().map(|p| p.lab[k] * p.w).sum::<f64>() / w;
            let v = b.iter().map(|p| (p.lab[k] - m).powi(2) * p.w).sum::<f64>();
            if v > best.0 {
                best = (v, k);
            }
        }
        best
    };
    while boxes.len() < n {
        let (i, (v, axis)) = boxes
            .iter()
            .enumerate()
            .map(|(i, b)| (i, if b.len() > 1 { spread(b) } else { (0.0, 0) }))
            .max_by(|a, b| a.1.0.total_cmp(&b.1.0).then(b.0.cmp(&a.0)))
            .expect("a box");
        if v <= 0.0 {
            break;
        }
        let mut b = std::mem::take(&mut boxes[i]);
        b.sort_by(|p, q| p.lab[axis].total_cmp(&q.lab[axis]));
        let half: f64 = b.iter().map(|p| p.w).sum::<f64>() / 2.0;
        let mut acc = 0.0;
        let mut cut = 1;
        for (j, p) in b.iter().enumerate() {
            acc += p.w;
            if acc >= half {
                cut = (j + 1).clamp(1, b.len() - 1);
                break;
            }
        }
        let upper = b.split_off(cut);
        boxes[i] = b;
        boxes.push(upper);
    }
    boxes
        .iter()
        .map(|b| {
            let w: f64 = b.iter().map(|p| p.w).sum();
            std::array::from_fn(|k| b.iter().map(|p| p.lab[k] * p.w).sum::<f64>() / w)
        })
        .collect()
}

/// The sRGB RGBA8 colour nearest a Lab point (rounded per channel after the exact inverse).
fn from_lab(c: &Lab) -> [u8; 4] {
    let fy = (c[0] + 16.0) / 116.0;
    let fx = fy + c[1] / 500.0;
    let fz = fy - c[2] / 200.0;
    let inv = |f: f64| {
        if f.powi(3) > 216.0 / 24389.0 {
            f.powi(3)
        } else {
            (116.0 * f - 16.0) * 27.0 / 24389.0
        }
    };
    let (x, y, z) = (inv(fx) * 0.95047, inv(fy), inv(fz) * 1.08883);
    let r = 3.2404542 * x - 1.5371385 * y - 0.4985314 * z;
    let g = -0.969266 * x + 1.8760108 * y + 0.041556 * z;
    let b = 0.0556434 * x - 0.2040259 * y + 1.0572252 * z;
    let byte =
        |v: f64| (crate::mesh::texture::linear_to_srgb(v.clamp(0.0, 1.0)) * 255.0).round() as u8;
    [
        byte(r),
        byte(g),
        byte(b),
        (c[3] * 255.0 / 100.0).round().clamp(0.0, 255.0) as u8,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn few_colours_are_kept_exactly() {
        let c = vec![[10, 20, 30, 255], [200, 0, 0, 255], [10, 20, 30, 255]];
        let q = quantize(&c);
        assert_eq!(q.palette, vec![[10, 20, 30, 255], [200, 0, 0, 255]]);
        assert_eq!(q.index, vec![0, 1, 0]);
        assert_eq!((q.mean_de, q.p99_de), (0.0, 0.0));
    }

    #[test]
    fn lab_round_trips_and_many_colours_quantize_closely() {
        for c in [
            [0, 0, 0, 255],
            [255, 255, 255, 255],
            [12, 200, 77, 128],
            [255, 0, 0, 0],
        ] {
            assert_eq!(from_lab(&lab(c)), c);
        }
        // A smooth ramp of 4096 distinct colours: 255 entries leave a small error, and every
        // voxel's entry is the nearest one (brute force).
        let c: Vec<[u8; 4]> = (0..4096u32)
            .map(|i| [(i % 64 * 4) as u8, (i / 64 * 4) as u8, 128, 255])
            .collect();
        let q = quantize(&c);
        assert!(q.palette.len() <= ENTRIES);
        assert!(
            q.mean_de < 3.0 && q.p99_de < 6.0,
            "{} {}",
            q.mean_de,
            q.p99_de
        );
        let labs: Vec<Lab> = q.palette.iter().map(|&p| lab(p)).collect();
        for (v, &i) in c.iter().zip(&q.index) {
            let l = lab(*v);
            let best = labs.iter().map(|p| d2(&l, p)).fold(f64::INFINITY, f64::min);
            assert_eq!(d2(&l, &labs[i as usize]), best);
        }
    }
}
