//! A mesh's edges grouped by their lower end, without sorting all of them, each with how its
//! triangles use it: what the diagnosis counts (boundary, non-manifold and unoriented edges) and
//! what the winding fill's caps close (the edges whose directed uses do not cancel) are both
//! read off these.

use rayon::prelude::*;

/// One undirected edge `lo`–`hi` (`lo < hi`) and how its triangles use it: `uses` times in all,
/// `net` = the uses from `lo` to `hi` minus those from `hi` to `lo`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct EdgeUses {
    pub lo: u32,
    pub hi: u32,
    pub uses: usize,
    pub net: i64,
}

/// Goes through the edges of `triangles` (each triangle's three, on vertex ids `id(i)` below
/// `n`; an edge whose two ends are one vertex is no edge), calling `visit(&mut acc, edge)` once
/// per undirected edge in order of (lower end, higher end). The range of lower ends is split
/// into `parts` parts (`None`: one per thread, one for a small mesh), each with an accumulator
/// from `init`, returned in order. Each part goes through all triangles twice (counting the
/// sizes of its lower ends' groups, then placing each use in its group as the higher end and a
/// bit for its direction), then sorts each group (a few uses, about six on a closed mesh), so
/// nothing of the size of all edges is sorted.
pub(crate) fn edge_groups<A: Send>(
    triangles: &[[u32; 3]],
    id: impl Fn(u32) -> u32 + Copy + Sync,
    n: usize,
    parts: Option<usize>,
    init: impl Fn() -> A + Sync,
    visit: impl Fn(&mut A, EdgeUses) + Sync,
) -> Vec<A> {
    let parts = parts.unwrap_or_else(|| threads_for(triangles.len())).max(1);
    let per = n.div_ceil(parts).max(1);
    (0..parts)
        .into_par_iter()
        .map(|k| {
            let (first, end) = ((k * per).min(n), ((k + 1) * per).min(n));
            let mut start = vec![0usize; end - first + 1];
            edges_from(triangles, id, first..end, |lo, _, _| start[lo + 1] += 1);
            for i in 1..start.len() {
                start[i] += start[i - 1];
            }
            // Placing a use moves its group's start up by one: once all are placed, a group
            // starts where the one before it did and ends where its own start is. A use is
            // the higher end and a bit set when it runs from the higher end, so that sorting a
            // group puts an edge's uses together.
            let mut placed = vec![0u64; start[end - first]];
            edges_from(triangles, id, first..end, |lo, p, q| {
                placed[start[lo]] = (u64::from(p.max(q)) << 1) | u64::from(p > q);
                start[lo] += 1;
            });
            let mut acc = init();
            let mut from = 0;
            for (lo, &to) in (first as u32..).zip(&start[..end - first]) {
                let group = &mut placed[from..to];
                from = to;
                sort_group(group);
                for run in group.chunk_by(|a, b| a >> 1 == b >> 1) {
                    let back = run.iter().filter(|&&u| u & 1 == 1).count();
                    let edge = EdgeUses {
                        lo,
                        hi: (run[0] >> 1) as u32,
                        uses: run.len(),
                        net: run.len() as i64 - 2 * back as i64,
                    };
                    visit(&mut acc, edge);
                }
            }
            acc
        })
        .collect()
}

/// The threads a pass over `items` positions or triangles is split among: one below 64 Ki
/// items, since each part goes through all of them, so splitting a small mesh among threads
/// that are busy with other meshes (a service's small jobs) only multiplies the work.
pub(crate) fn threads_for(items: usize) -> usize {
    if items < 1 << 16 {
        1
    } else {
        rayon::current_num_threads()
    }
}

/// Sorts a group: by insertion up to 16 entries.
fn sort_group(group: &mut [u64]) {
    if group.len() <= 16 {
        for i in 1..group.len() {
            let mut j = i;
            while j > 0 && group[j - 1] > group[j] {
                group.swap(j - 1, j);
                j -= 1;
            }
        }
    } else {
        group.sort_unstable();
    }
}

/// Calls `f(lower end - lower.start, p, q)` for every edge p → q whose lower end is in `lower`.
#[inline]
fn edges_from(
    triangles: &[[u32; 3]],
    id: impl Fn(u32) -> u32,
    lower: std::ops::Range<usize>,
    mut f: impl FnMut(usize, u32, u32),
) {
    for t in triangles {
        let m = t.map(&id);
        for (p, q) in [(m[0], m[1]), (m[1], m[2]), (m[2], m[0])] {
            let lo = p.min(q) as usize;
            if p != q && lower.contains(&lo) {
                f(lo - lower.start, p, q);
            }
        }
    }
}
