//! A bounding-volume hierarchy over triangles: a binary tree, built by median splits of the
//! triangles' centroids along the longest axis of their box, whose every node holds a bounding
//! sphere (every point of its triangles lies within `radius` of `centre`, the area-weighted
//! centroid), its total area, and a per-node [`Summary`] that the user of the tree chooses.
//! The winding fill's hierarchy ([`crate::engine::winding::WindingTree`]) is this tree with the
//! multipole expansion of its triangles' dipole field as the summary; a nearest-triangle query
//! (a distance field) needs no summary at all (`()`).
//!
//! Not here: any traversal. A query walks [`Bvh::nodes`] from the root (index 0), skipping a
//! node whose sphere is far enough and opening the others: inner nodes through `first` and
//! `right`, leaves through their range of [`Bvh::tris`].

use rayon::prelude::*;

use super::{area_normal, norm, sub};

/// Leaves hold at most this many triangles.
pub(crate) const LEAF: usize = 8;

/// A node of the hierarchy.
#[derive(Clone, Debug)]
pub(crate) struct Node<S> {
    /// Area-weighted centroid of the node's triangles (the expansion point).
    pub(crate) centre: [f64; 3],
    /// Every point of every triangle of the node lies within this distance of `centre`.
    pub(crate) radius: f64,
    /// Σ triangle areas.
    pub(crate) area: f64,
    /// Leaf: triangle range; inner node: `first` is the left child, `count` 0 and `right` the
    /// right child. A leaf's `right` is the user's (the winding tree numbers its lane leaves
    /// there).
    pub(crate) first: u32,
    pub(crate) count: u32,
    pub(crate) right: u32,
    /// What the user of the tree keeps per node ([`Summary`]).
    pub(crate) summary: S,
}

/// What a node carries besides its bounds, computed as the tree is built: a leaf's from its
/// triangles, an inner node's from its children's. `Moments` is what the build keeps per node
/// to combine them (dropped once the tree is built).
pub(crate) trait Summary: Sized {
    type Moments;
    /// A leaf's summary over `tris`, about the leaf's `centre`.
    fn leaf(tris: &[[[f64; 3]; 3]], centre: [f64; 3]) -> (Self, Self::Moments);
    /// The parent's summary from its two children's, about the parent's `centre`.
    fn combine(
        children: [(&Node<Self>, &Self::Moments); 2],
        centre: [f64; 3],
    ) -> (Self, Self::Moments);
}

/// No summary: the bounds alone (for nearest-triangle queries).
impl Summary for () {
    type Moments = ();
    fn leaf(_: &[[[f64; 3]; 3]], _: [f64; 3]) -> ((), ()) {
        ((), ())
    }
    fn combine(_: [(&Node<()>, &()); 2], _: [f64; 3]) -> ((), ()) {
        ((), ())
    }
}

/// The hierarchy over a triangle set.
pub(crate) struct Bvh<S> {
    /// The root first (when there are triangles); no nodes for no triangles.
    pub(crate) nodes: Vec<Node<S>>,
    /// Triangles in leaf order.
    pub(crate) tris: Vec<[[f64; 3]; 3]>,
    /// Their areas.
    pub(crate) areas: Vec<f64>,
}

impl<S: Summary> Bvh<S> {
    pub(crate) fn new(positions: &[[f64; 3]], triangles: &[[u32; 3]]) -> Bvh<S> {
        let mut tris: Vec<[[f64; 3]; 3]> = triangles
            .par_iter()
            .map(|t| t.map(|i| positions[i as usize]))
            .collect();
        let mut nodes = Vec::with_capacity(2 * tris.len() / LEAF + 2);
        if !tris.is_empty() {
            build(&mut nodes, &mut Vec::new(), &mut tris, 0);
        }
        let areas: Vec<f64> = tris.iter().map(|t| norm(area_normal(t))).collect();
        Bvh { nodes, tris, areas }
    }
}

/// Builds the subtree over `tris` (their first index `offset`; it reorders them) into `nodes`,
/// with each node's moments at the same index of `moments`; returns its root's index.
pub(crate) fn build<S: Summary>(
    nodes: &mut Vec<Node<S>>,
    moments: &mut Vec<S::Moments>,
    tris: &mut [[[f64; 3]; 3]],
    offset: u32,
) -> u32 {
    let index = nodes.len() as u32;
    if tris.len() <= LEAF {
        let (node, m) = leaf(tris, offset);
        nodes.push(node);
        moments.push(m);
        return index;
    }
    // Median split of the centroids along the longest axis of their box.
    let cen = |t: &[[f64; 3]; 3]| [0, 1, 2].map(|a| (t[0][a] + t[1][a] + t[2][a]) / 3.0);
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for t in tris.iter() {
        let c = cen(t);
        for a in 0..3 {
            lo[a] = lo[a].min(c[a]);
            hi[a] = hi[a].max(c[a]);
        }
    }
    let axis = (0..3)
        .max_by(|&a, &b| (hi[a] - lo[a]).total_cmp(&(hi[b] - lo[b])))
        .unwrap_or(0);
    let mid = tris.len() / 2;
    tris.select_nth_unstable_by(mid, |a, b| cen(a)[axis].total_cmp(&cen(b)[axis]));
    // Placeholders, filled below.
    let (node, m) = leaf(&[], 0);
    nodes.push(node);
    moments.push(m);
    let (left, right) = tris.split_at_mut(mid);
    let l = build(nodes, moments, left, offset);
    let r = build(nodes, moments, right, offset + mid as u32);
    let (li, ri) = (l as usize, r as usize);
    let (node, m) = combine(
        [(&nodes[li], &moments[li]), (&nodes[ri], &moments[ri])],
        l,
        r,
    );
    nodes[index as usize] = node;
    moments[index as usize] = m;
    index
}

/// The leaf over `tris`, whose first index is `offset`.
#[allow(clippy::needless_range_loop)] // index notation, as the summaries' formulas
fn leaf<S: Summary>(tris: &[[[f64; 3]; 3]], offset: u32) -> (Node<S>, S::Moments) {
    let mut area = 0.0;
    let mut weighted = [0.0; 3];
    let mut mean = [0.0; 3];
    for t in tris {
        let an = area_normal(t);
        let a = norm(an);
        area += a;
        for k in 0..3 {
            let c = (t[0][k] + t[1][k] + t[2][k]) / 3.0;
            weighted[k] += a * c;
            mean[k] += c / tris.len() as f64;
        }
    }
    let centre = if area > 0.0 {
        weighted.map(|w| w / area)
    } else {
        mean
    };
    let mut radius: f64 = 0.0;
    for t in tris {
        for v in t.map(|v| sub(v, centre)) {
            radius = radius.max(norm(v));
        }
    }
    let (summary, moments) = S::leaf(tris, centre);
    let node = Node {
        centre,
        radius,
        area,
        first: offset,
        count: tris.len() as u32,
        right: 0,
        summary,
    };
    (node, moments)
}

/// The parent of two nodes (indices `li` and `ri`): its centre the area-weighted mean of
/// theirs, its sphere around both of theirs.
fn combine<S: Summary>(
    children: [(&Node<S>, &S::Moments); 2],
    li: u32,
    ri: u32,
) -> (Node<S>, S::Moments) {
    let [(l, _), (r, _)] = children;
    let area = l.area + r.area;
    let centre = if area > 0.0 {
        [0, 1, 2].map(|k| (l.centre[k] * l.area + r.centre[k] * r.area) / area)
    } else {
        [0, 1, 2].map(|k| 0.5 * (l.centre[k] + r.centre[k]))
    };
    let mut radius: f64 = 0.0;
    for (ch, _) in children {
        let d = sub(ch.centre, centre);
        radius = radius.max(norm(d) + ch.radius);
    }
    let (summary, moments) = S::combine(children, centre);
    let node = Node {
        centre,
        radius,
        area,
        first: li,
        count: 0,
        right: ri,
        summary,
    };
    (node, moments)
}
