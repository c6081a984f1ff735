//! The hierarchies the winding fill reads: [`WindingTree`], Barill et al.'s hierarchy over a
//! triangle set (the [`bvh`] of [`crate::engine::geom`] with, per node, the second-order
//! expansion of its triangles' dipole field), its plain evaluation at a point, and [`Trees`],
//! the four hierarchies of one fill (over the caps and the mesh, and over the boundary chain on
//! each one's positions).
//!
//! Not here: the interval and Taylor bounds over balls ([`super::bounds`]), the traversals of
//! eight balls at once ([`super::traverse`]), the boundary chain's own tree ([`super::edges`]).

use std::f64::consts::PI;

use super::BETA;
use super::caps::chain_boundary;
use super::edges::EdgeTree;
use super::lanes::{self, Far, LANES};
use super::traverse::spread_lanes;
use crate::engine::geom::bvh::{self, Bvh, LEAF};
use crate::engine::geom::{area_normal, dist2_to_triangle, dot, norm, sub};
use crate::engine::snap::snapped_world;
use crate::grid::Grid;
use crate::mesh::Mesh;

const _: () = assert!(LEAF <= LANES, "a leaf's triangles fit the lanes");

/// A node of the hierarchy, with its expansion.
pub(super) type Node = bvh::Node<Far>;

/// The hierarchies the certification reads: over the caps and over the mesh, and over the
/// boundary chain on each one's positions.
pub(super) struct Trees {
    pub(super) caps: WindingTree,
    pub(super) mesh: WindingTree,
    pub(super) cap_edges: EdgeTree,
    pub(super) mesh_edges: EdgeTree,
}

impl Trees {
    /// `closed` and `caps` from [`super::caps::closed_by_caps`].
    pub(super) fn new(mesh: &Mesh, closed: &Mesh, caps: &[[u32; 3]], grid: &Grid) -> Trees {
        // The caps exactly as the crossing count sees them: on the 1/256-voxel lattice.
        let cap_positions: Vec<[f64; 3]> = closed
            .positions()
            .iter()
            .map(|&p| snapped_world(grid, p))
            .collect();
        // Degenerate caps (fans over collinear edges; many where the mesh has degenerate
        // triangles) subtend nothing and their boundaries add nothing to the Biot–Savart field
        // (a closed path along a line), so neither the tree nor the bound needs them. The
        // crossing count has none either: they cover no column.
        let live = |p: &[[f64; 3]]| -> Vec<[u32; 3]> {
            caps.iter()
                .filter(|t| norm(area_normal(&t.map(|i| p[i as usize]))) > 0.0)
                .copied()
                .collect()
        };
        let snapped_caps = live(&cap_positions);
        let (cap_tree, mesh_tree) = rayon::join(
            || WindingTree::new(&cap_positions, &snapped_caps),
            || WindingTree::new(mesh.positions(), mesh.triangles()),
        );
        let segments = |p: &[[f64; 3]], caps: &[[u32; 3]]| {
            let segs = chain_boundary(caps)
                .iter()
                .map(|e| e.map(|i| p[i as usize]))
                .collect();
            EdgeTree::new(segs)
        };
        Trees {
            caps: cap_tree,
            mesh: mesh_tree,
            cap_edges: segments(&cap_positions, &snapped_caps),
            mesh_edges: segments(closed.positions(), &live(closed.positions())),
        }
    }
}

/// Barill et al.'s hierarchy over a triangle set.
pub struct WindingTree {
    pub(super) nodes: Vec<Node>,
    /// Triangles in leaf order.
    pub(super) tris: Vec<[[f64; 3]; 3]>,
    /// Their areas.
    pub(super) areas: Vec<f64>,
    /// Each leaf's triangles lane by lane (a leaf node's `right`).
    pub(super) leaves: Vec<lanes::Leaf>,
}

/// A node's moments about its centre, kept while the tree is built (a parent's are its
/// children's, moved).
#[derive(Clone, Debug, Default)]
pub(crate) struct Moments {
    /// Σ area·normal.
    n1: [f64; 3],
    /// Σ_t (area·normal)_i (centroid − centre)_j.
    m: [[f64; 3]; 3],
    /// Σ_t normal_i ∫_t (x − centre)_j (x − centre)_k dA, (j, k) in order xx yy zz xy xz yz.
    c: [[f64; 6]; 3],
}

/// A node's moments folded for evaluation ([`lanes::Far`]).
#[allow(clippy::needless_range_loop)] // index notation of the moment formulas
fn folded(moments: &Moments) -> Far {
    let Moments { n1, m, c } = moments;
    let n1 = *n1;
    let mut far = Far {
        n1,
        tr: m[0][0] + m[1][1] + m[2][2],
        ..Far::default()
    };
    for (e, &(i, j)) in SYM.iter().enumerate() {
        let sym = if i == j { m[i][i] } else { m[i][j] + m[j][i] };
        far.m[e] = 3.0 * sym;
    }
    for i in 0..3 {
        let full = sym_full(&c[i]);
        for k in 0..3 {
            far.w[k] += 1.5 * (2.0 * full[i][k]);
        }
        far.w[i] += 1.5 * (full[0][0] + full[1][1] + full[2][2]);
        for e in 0..6 {
            far.c[i][e] = 7.5 * if e < 3 { c[i][e] } else { 2.0 * c[i][e] };
        }
    }
    far
}

const SYM: [(usize, usize); 6] = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)];

/// The expansion as the tree's node summary: a leaf's moments from its triangles, a parent's
/// from its children's, moved ([`bvh::Summary`]).
impl bvh::Summary for Far {
    type Moments = Moments;

    #[allow(clippy::needless_range_loop)] // index notation of the moment formulas
    fn leaf(tris: &[[[f64; 3]; 3]], centre: [f64; 3]) -> (Far, Moments) {
        let mut n1 = [0.0; 3];
        for t in tris {
            let an = area_normal(t);
            for k in 0..3 {
                n1[k] += an[k];
            }
        }
        let mut m = [[0.0; 3]; 3];
        let mut c = [[0.0; 6]; 3];
        for t in tris {
            let an = area_normal(t);
            let y = t.map(|v| sub(v, centre));
            let s = [0, 1, 2].map(|k| y[0][k] + y[1][k] + y[2][k]);
            for i in 0..3 {
                for j in 0..3 {
                    m[i][j] += an[i] * s[j] / 3.0;
                }
                // n_i ∫ y_j y_k dA = (area·n)_i / 12 · (Σ_v y_v,j y_v,k + s_j s_k).
                for (e, &(j, k)) in SYM.iter().enumerate() {
                    let second: f64 = y.iter().map(|v| v[j] * v[k]).sum::<f64>() + s[j] * s[k];
                    c[i][e] += an[i] * second / 12.0;
                }
            }
        }
        let moments = Moments { n1, m, c };
        (folded(&moments), moments)
    }

    /// The moments moved to the parent's centre (d = child centre − centre):
    /// M += n1 ⊗ d, C_ijk += d_j M_ik + d_k M_ij + d_j d_k n1_i.
    #[allow(clippy::needless_range_loop)] // index notation of the moment formulas
    fn combine(children: [(&Node, &Moments); 2], centre: [f64; 3]) -> (Far, Moments) {
        let mut out = Moments::default();
        for (ch, chm) in children {
            let d = sub(ch.centre, centre);
            for i in 0..3 {
                out.n1[i] += chm.n1[i];
                for j in 0..3 {
                    out.m[i][j] += chm.m[i][j] + chm.n1[i] * d[j];
                }
                for (e, &(j, k)) in SYM.iter().enumerate() {
                    out.c[i][e] += chm.c[i][e]
                        + d[j] * chm.m[i][k]
                        + d[k] * chm.m[i][j]
                        + d[j] * d[k] * chm.n1[i];
                }
            }
        }
        (folded(&out), out)
    }
}

/// 4π × the node's expanded winding number at q, with r = centre − q and d2 = |r|².
#[allow(clippy::needless_range_loop)] // index notation of the moment formulas
#[inline]
pub(super) fn far_field(n: &Node, r: [f64; 3], d2: f64) -> f64 {
    lanes::far_one(&n.summary, r, d2)
}

fn sym_full(c: &[f64; 6]) -> [[f64; 3]; 3] {
    [[c[0], c[3], c[4]], [c[3], c[1], c[5]], [c[4], c[5], c[2]]]
}

impl WindingTree {
    pub fn new(positions: &[[f64; 3]], triangles: &[[u32; 3]]) -> WindingTree {
        let Bvh {
            mut nodes,
            tris,
            areas,
        } = Bvh::<Far>::new(positions, triangles);
        let mut leaves = Vec::new();
        for n in nodes.iter_mut().filter(|n| n.count > 0) {
            n.right = leaves.len() as u32;
            let range = n.first as usize..(n.first + n.count) as usize;
            leaves.push(lanes::Leaf::new(&tris[range.clone()], &areas[range]));
        }
        WindingTree {
            nodes,
            tris,
            areas,
            leaves,
        }
    }

    /// The generalised winding number at q, exact near q and expanded far from it.
    pub fn winding_number(&self, q: [f64; 3]) -> f64 {
        self.evaluate(q, -1.0).expect("no plane check")
    }

    /// [`Self::winding_number`] at eight points, from one traversal ([`spread_lanes`] over
    /// balls of radius 0, which opens and expands each point's nodes as `winding_number` does).
    pub(super) fn winding_numbers(&self, qs: &[[f64; 3]; LANES]) -> [f64; LANES] {
        let at = spread_lanes(
            self,
            qs,
            0.0,
            f64::NEG_INFINITY,
            &[f64::INFINITY; LANES],
            0.0,
            &[false; LANES],
        );
        std::array::from_fn(|i| match at[i] {
            Some(t) => t.value / (4.0 * PI),
            // Only where a distance came out NaN: the plain traversal.
            None => self.winding_number(qs[i]),
        })
    }

    /// [`Self::winding_number`], or `None` when q lies within `eps` of a triangle summed exactly
    /// (where the sign of its solid angle is a tie to break by other means).
    pub fn winding_number_off_planes(&self, q: [f64; 3], eps: f64) -> Option<f64> {
        self.evaluate(q, eps)
    }

    fn evaluate(&self, q: [f64; 3], eps: f64) -> Option<f64> {
        if self.nodes.is_empty() {
            return Some(0.0);
        }
        let mut sum = 0.0;
        let mut stack = [0u32; 64];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let n = &self.nodes[stack[top] as usize];
            let r = sub(n.centre, q);
            let d2 = dot(r, r);
            if d2 > (BETA * n.radius).powi(2) {
                sum += far_field(n, r, d2);
            } else if n.count > 0 {
                let (angles, dist2) = lanes::leaf(&self.leaves[n.right as usize], q);
                for j in 0..n.count as usize {
                    if eps >= 0.0 && dist2[j] <= eps * eps {
                        return None;
                    }
                    sum += angles[j];
                }
            } else {
                stack[top] = n.first;
                stack[top + 1] = n.right;
                top += 2;
            }
        }
        Some(sum / (4.0 * PI))
    }

    /// Σ exact solid angles at q of the triangles `near` (with twice their areas), or `None`
    /// when one lies within `gap` of q.
    pub(super) fn near_sum(&self, near: &[(u32, f64)], q: [f64; 3], gap: f64) -> Option<f64> {
        let mut sum = 0.0;
        for &(i, twice_area) in near {
            let t = &self.tris[i as usize];
            let [a, b, c] = t.map(|v| sub(v, q));
            let (det, den) = lanes::det_den(a, b, c);
            // det = twice the area × the signed distance from q to the triangle's plane, which
            // is at most the distance to the triangle: beyond twice gap (a factor 2 for
            // rounding), no tie. A NaN is a tie, as in `spread`.
            if det.abs() <= 2.0 * gap * twice_area || det.is_nan() {
                let d2 = dist2_to_triangle(q, t);
                if d2 <= gap * gap || d2.is_nan() {
                    return None;
                }
            }
            sum += 2.0 * lanes::atan2(det, den);
        }
        Some(sum)
    }

    /// Pushes the children of inner node `n`, the nearer to q on top (a triangle touching the
    /// query's ball is found soonest); a leaf's triangles are handled by the caller.
    #[inline]
    pub(super) fn open(&self, n: &Node, stack: &mut [u32; 64], top: &mut usize, q: [f64; 3]) {
        let (a, b) = (n.first, n.right);
        let dist2 = |i: u32| {
            let v = sub(self.nodes[i as usize].centre, q);
            dot(v, v)
        };
        let (near, far) = if dist2(a) <= dist2(b) { (a, b) } else { (b, a) };
        stack[*top] = far;
        stack[*top + 1] = near;
        *top += 2;
    }
}
