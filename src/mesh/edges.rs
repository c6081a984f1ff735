//! A mesh's edges grouped by their lower end, without sorting all of them: what the diagnosis
//! counts (boundary and non-manifold edges) and what the winding fill's caps close (the edges
//! whose directed uses do not cancel) are both read off these groups.

use rayon::prelude::*;

/// Goes through the edges of `triangles` (each triangle's three, on vertex ids `id(i)` below
/// `n`; an edge whose two ends are one vertex is no edge) grouped by their lower end: for every
/// lower end `lo` in order, `visit(&mut acc, lo, group)` gets the entries `entry(p, q)` of the
/// edges p → q (as a triangle uses them) with `min(p, q) = lo`, in no particular order. The
/// range of lower ends is split into `parts` parts, each with an accumulator from `init`,
/// returned in order; each part goes through all triangles twice (counting its groups' sizes,
/// then placing the entries), so nothing of the size of all edges is sorted.
pub(crate) fn edge_groups<E, A>(
    triangles: &[[u32; 3]],
    id: impl Fn(u32) -> u32 + Copy + Sync,
    n: usize,
    parts: usize,
    entry: impl Fn(u32, u32) -> E + Sync,
    init: impl Fn() -> A + Sync,
    visit: impl Fn(&mut A, u32, &mut [E]) + Sync,
) -> Vec<A>
where
    E: Copy + Default + Send,
    A: Send,
{
    let parts = parts.max(1);
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
            // Placing an edge moves its group's start up by one: once all are placed, a
            // group starts where the one before it did and ends where its own start is.
            let mut placed = vec![E::default(); start[end - first]];
            edges_from(triangles, id, first..end, |lo, p, q| {
                placed[start[lo]] = entry(p, q);
                start[lo] += 1;
            });
            let mut acc = init();
            let mut from = 0;
            for (lo, &to) in (first as u32..).zip(&start[..end - first]) {
                visit(&mut acc, lo, &mut placed[from..to]);
                from = to;
            }
            acc
        })
        .collect()
}

/// Sorts a group: a few entries each (about six on a closed mesh), by insertion up to 16.
pub(crate) fn sort_group<E: Ord + Copy>(group: &mut [E]) {
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
