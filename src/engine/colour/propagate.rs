//! The nearest surface voxel of every set voxel, by propagation: a breadth-first walk from all
//! surface voxels at once through the set voxels, 26-connected, each voxel reached in a round
//! taking, among the sources of its neighbours reached in the round before, the one whose centre
//! is nearest to its own (Euclidean; ties by the lower source index). This is the propagation
//! of Danielsson's distance transform restricted to the volume: it finds the exact nearest
//! source except in rare configurations, where it finds one a fraction of a voxel farther, and it
//! never leaves the volume (the interior of a solid takes its colour from its own walls). The
//! cost is linear in the set voxels.

use crate::cancel::{Canceled, Control};
use crate::volume::BitVolume;

const NONE: u32 = u32::MAX;

struct Ranks<'b> {
    bits: &'b BitVolume,
    starts: Vec<u64>,
    dims: [u32; 3],
}

impl<'b> Ranks<'b> {
    fn new(bits: &'b BitVolume) -> Ranks<'b> {
        let wpc = bits.words_per_column();
        let mut starts = Vec::with_capacity(bits.words().len() / wpc.max(1) + 1);
        let mut n = 0u64;
        starts.push(0);
        for col in bits.words().chunks_exact(wpc) {
            n += col.iter().map(|w| u64::from(w.count_ones())).sum::<u64>();
            starts.push(n);
        }
        Ranks {
            bits,
            starts,
            dims: bits.dims(),
        }
    }

    fn len(&self) -> usize {
        *self.starts.last().expect("one entry") as usize
    }

    /// The rank of set voxel v, `None` when v is not set.
    fn rank(&self, v: [u32; 3]) -> Option<usize> {
        let col = self.bits.column(v[0], v[1]);
        let (w, b) = ((v[2] / 64) as usize, v[2] % 64);
        if col[w] >> b & 1 == 0 {
            return None;
        }
        let c = v[0] as usize * self.dims[1] as usize + v[1] as usize;
        let below: u64 = col[..w]
            .iter()
            .map(|x| u64::from(x.count_ones()))
            .sum::<u64>()
            + u64::from((col[w] & ((1u64 << b) - 1)).count_ones());
        Some((self.starts[c] + below) as usize)
    }
}

fn coords(k: u64, dims: [u32; 3]) -> [u32; 3] {
    let z = (k % u64::from(dims[2])) as u32;
    let c = k / u64::from(dims[2]);
    [
        (c / u64::from(dims[1])) as u32,
        (c % u64::from(dims[1])) as u32,
        z,
    ]
}

fn dist2(a: [u32; 3], b: [u32; 3]) -> u64 {
    (0..3)
        .map(|k| {
            let d = i64::from(a[k]) - i64::from(b[k]);
            (d * d) as u64
        })
        .sum()
}

/// For each set voxel of `bits` (by rank: the order of [`BitVolume::iter_ones`]), the index in
/// `sources` (sorted keys of [`super::key`]) of its nearest source as the module docs define
/// it; 0 for a set voxel no source reaches (and for every voxel when there are no sources).
pub fn nearest(bits: &BitVolume, sources: &[u64], ctl: &Control) -> Result<Vec<u32>, Canceled> {
    let r = Ranks::new(bits);
    let dims = r.dims;
    let n = r.len();
    let mut src = vec![NONE; n];
    let mut frontier: Vec<([u32; 3], u32)> = Vec::with_capacity(sources.len());
    let source_at: Vec<[u32; 3]> = sources.iter().map(|&k| coords(k, dims)).collect();
    for (i, &v) in source_at.iter().enumerate() {
        if let Some(rank) = r.rank(v) {
            src[rank] = i as u32;
        }
        frontier.push((v, i as u32));
    }
    let mut reached = frontier
        .iter()
        .filter(|(v, _)| r.rank(*v).is_some())
        .count();
    let mut proposal = vec![NONE; n];
    let mut proposed: Vec<(usize, [u32; 3])> = vec![];
    while !frontier.is_empty() && reached < n {
        ctl.check()?;
        for &(v, s) in &frontier {
            let at = source_at[s as usize];
            for dx in -1i64..=1 {
                for dy in -1i64..=1 {
                    for dz in -1i64..=1 {
                        let q = [
                            i64::from(v[0]) + dx,
                            i64::from(v[1]) + dy,
                            i64::from(v[2]) + dz,
                        ];
                        if (0..3).any(|k| q[k] < 0 || q[k] >= i64::from(dims[k])) {
                            continue;
                        }
                        let q = q.map(|c| c as u32);
                        let Some(rank) = r.rank(q) else { continue };
                        if src[rank] != NONE {
                            continue;
                        }
                        let cur = proposal[rank];
                        if cur == NONE {
                            proposal[rank] = s;
                            proposed.push((rank, q));
                        } else {
                            let (d, dc) = (dist2(q, at), dist2(q, source_at[cur as usize]));
                            if d < dc || (d == dc && s < cur) {
                                proposal[rank] = s;
                            }
                        }
                    }
                }
            }
        }
        frontier.clear();
        for &(rank, q) in &proposed {
            src[rank] = proposal[rank];
            proposal[rank] = NONE;
            frontier.push((q, src[rank]));
        }
        reached += proposed.len();
        proposed.clear();
        ctl.set(reached as f64 / n.max(1) as f64);
    }
    for s in &mut src {
        if *s == NONE {
            *s = 0;
        }
    }
    Ok(src)
}
