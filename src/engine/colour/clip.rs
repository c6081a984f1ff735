//! A triangle cut exactly into the parts inside each voxel (obj2voxel's `blend` does the same):
//! the triangle, in grid coordinates (voxel (i, j, k) is [i, i+1) × [j, j+1) × [k, k+1)), is
//! split at the planes x = i + 1 into slabs, each slab at y = j + 1, each of those at z = k + 1
//! (Sutherland–Hodgman against one plane at a time, both sides kept). A piece's vertices carry
//! the barycentric weights of the triangle's corners, so anything linear over the triangle
//! (vertex colours, texture coordinates) is known at them. A point on a plane belongs to both
//! sides; the piece it makes on one side has zero area and is dropped by the caller.

/// A vertex of a piece: grid coordinates and the weights of the triangle's corners 1 and 2
/// (corner 0's is 1 − b[0] − b[1]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Vertex {
    pub p: [f64; 3],
    pub b: [f64; 2],
}

fn lerp(a: &Vertex, b: &Vertex, t: f64) -> Vertex {
    Vertex {
        p: std::array::from_fn(|k| a.p[k] + (b.p[k] - a.p[k]) * t),
        b: std::array::from_fn(|k| a.b[k] + (b.b[k] - a.b[k]) * t),
    }
}

/// Splits the polygon `poly` at the plane `p[axis] = c` into `below` (≤ c) and `above` (≥ c).
fn split(poly: &[Vertex], axis: usize, c: f64, below: &mut Vec<Vertex>, above: &mut Vec<Vertex>) {
    below.clear();
    above.clear();
    for (i, a) in poly.iter().enumerate() {
        let b = &poly[(i + 1) % poly.len()];
        let (da, db) = (a.p[axis] - c, b.p[axis] - c);
        if da <= 0.0 {
            below.push(*a);
        }
        if da >= 0.0 {
            above.push(*a);
        }
        if (da < 0.0 && db > 0.0) || (da > 0.0 && db < 0.0) {
            let x = lerp(a, b, da / (da - db));
            below.push(x);
            above.push(x);
        }
    }
}

/// Twice the area of a planar polygon (the length of its Newell normal).
pub fn double_area(poly: &[Vertex]) -> f64 {
    let mut n = [0.0f64; 3];
    let o = poly[0].p;
    for w in poly[1..].windows(2) {
        let a: [f64; 3] = std::array::from_fn(|k| w[0].p[k] - o[k]);
        let b: [f64; 3] = std::array::from_fn(|k| w[1].p[k] - o[k]);
        n[0] += a[1] * b[2] - a[2] * b[1];
        n[1] += a[2] * b[0] - a[0] * b[2];
        n[2] += a[0] * b[1] - a[1] * b[0];
    }
    (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt()
}

/// Calls `f(voxel, piece)` for each part of triangle `tri` (grid coordinates) inside a voxel of
/// a grid of `dims`, in (x, y, z) order; parts outside the grid are left out. Pieces may have
/// zero area (a triangle along a voxel face, a corner touching one).
pub fn pieces(tri: &[[f64; 3]; 3], dims: [u32; 3], f: impl FnMut([u32; 3], &[Vertex])) {
    Clipper::default().pieces(tri, dims, f);
}

/// [`pieces`] with its polygons' buffers kept from one triangle to the next (one per thread:
/// allocating them for each triangle was a tenth of the colour pass).
#[derive(Default)]
pub struct Clipper {
    bufs: [Vec<Vertex>; 7],
}

impl Clipper {
    /// [`pieces`].
    pub fn pieces(
        &mut self,
        tri: &[[f64; 3]; 3],
        dims: [u32; 3],
        mut f: impl FnMut([u32; 3], &[Vertex]),
    ) {
        let lo: [f64; 3] = std::array::from_fn(|k| tri[0][k].min(tri[1][k]).min(tri[2][k]));
        let hi: [f64; 3] = std::array::from_fn(|k| tri[0][k].max(tri[1][k]).max(tri[2][k]));
        let mut first = [0i64; 3];
        let mut last = [0i64; 3];
        for k in 0..3 {
            first[k] = lo[k].floor().max(0.0) as i64;
            last[k] = (hi[k].floor() as i64).min(i64::from(dims[k]) - 1);
            if hi[k] < 0.0 || first[k] > last[k] {
                return;
            }
        }
        let corner = |p: [f64; 3], b: [f64; 2]| Vertex { p, b };
        let poly = [
            corner(tri[0], [0.0, 0.0]),
            corner(tri[1], [1.0, 0.0]),
            corner(tri[2], [0.0, 1.0]),
        ];
        // Wholly inside one voxel (every coordinate in [first, first + 1)): the triangle is its
        // one piece, as the cuts below would leave it.
        if (0..3).all(|k| {
            first[k] == last[k] && lo[k] >= first[k] as f64 && hi[k] < (first[k] + 1) as f64
        }) {
            f(first.map(|c| c as u32), &poly);
            return;
        }
        let [rest_x, b0, a0, b1, a1, b2, a2] = &mut self.bufs;
        rest_x.clear();
        rest_x.extend(poly);
        // Cut away what lies below the grid's first plane on each axis.
        for k in 0..3 {
            if lo[k] < first[k] as f64 {
                split(rest_x, k, first[k] as f64, b0, a0);
                std::mem::swap(rest_x, a0);
                if rest_x.len() < 3 {
                    return;
                }
            }
        }
        // The last plane on an axis lies past the triangle unless the grid ends first: what is
        // left is then all below it, and is taken as it is (the cut would copy it).
        let past: [bool; 3] = std::array::from_fn(|k| hi[k] < (last[k] + 1) as f64);
        let cut = |rest: &mut Vec<Vertex>,
                   axis: usize,
                   c: i64,
                   below: &mut Vec<Vertex>,
                   above: &mut Vec<Vertex>| {
            if c == last[axis] && past[axis] {
                std::mem::swap(rest, below);
                rest.clear();
            } else {
                split(rest, axis, (c + 1) as f64, below, above);
                std::mem::swap(rest, above);
            }
        };
        for i in first[0]..=last[0] {
            cut(rest_x, 0, i, b0, a0);
            if b0.len() >= 3 {
                let rest_y = &mut *b0;
                for j in first[1]..=last[1] {
                    cut(rest_y, 1, j, b1, a1);
                    if b1.len() >= 3 {
                        let rest_z = &mut *b1;
                        for k in first[2]..=last[2] {
                            cut(rest_z, 2, k, b2, a2);
                            if b2.len() >= 3 {
                                f([i as u32, j as u32, k as u32], b2);
                            }
                            if rest_z.len() < 3 {
                                break;
                            }
                        }
                    }
                    if rest_y.len() < 3 {
                        break;
                    }
                }
            }
            if rest_x.len() < 3 {
                break;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The area of the triangle's part inside box [lo, hi], by Monte Carlo-free exact means:
    /// the pieces summed must give the triangle's area, and each piece lies in its voxel.
    #[test]
    fn pieces_tile_the_triangle_and_stay_in_their_voxels() {
        let mut seed = 7u64;
        let mut rnd = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        for case in 0..300 {
            let scale = [0.3, 2.0, 9.0][case % 3];
            let tri: [[f64; 3]; 3] =
                std::array::from_fn(|_| std::array::from_fn(|_| 1.0 + rnd() * scale));
            let dims = [16u32; 3];
            let whole = double_area(&[
                Vertex {
                    p: tri[0],
                    b: [0.0; 2],
                },
                Vertex {
                    p: tri[1],
                    b: [0.0; 2],
                },
                Vertex {
                    p: tri[2],
                    b: [0.0; 2],
                },
            ]);
            let mut sum = 0.0;
            let mut seen = std::collections::HashSet::new();
            pieces(&tri, dims, |v, piece| {
                assert!(seen.insert(v), "voxel {v:?} twice");
                for q in piece {
                    for (c, lo) in q.p.iter().zip(v) {
                        assert!(*c >= lo as f64 - 1e-9 && *c <= lo as f64 + 1.0 + 1e-9);
                    }
                    // The weights give the point back.
                    let w = [1.0 - q.b[0] - q.b[1], q.b[0], q.b[1]];
                    for (k, c) in q.p.iter().enumerate() {
                        let p = w[0] * tri[0][k] + w[1] * tri[1][k] + w[2] * tri[2][k];
                        assert!((p - c).abs() < 1e-9);
                    }
                }
                sum += double_area(piece);
            });
            assert!(
                (sum - whole).abs() <= 1e-9 * whole.max(1.0),
                "{sum} vs {whole}"
            );
        }
    }

    #[test]
    fn parts_outside_the_grid_are_left_out() {
        // A unit right triangle in z = 0.5 spanning x, y in [-1, 1]: only its quarter in
        // voxel (0, 0, 0) is inside a 1³ grid.
        let tri = [[-1.0, -1.0, 0.5], [1.0, -1.0, 0.5], [-1.0, 1.0, 0.5]];
        let mut got = vec![];
        pieces(&tri, [1, 1, 1], |v, p| got.push((v, double_area(p) / 2.0)));
        // The part of the triangle x + y <= 0 inside [0, 1]²: empty but the corner (0, 0).
        assert!(got.iter().all(|(v, a)| *v == [0, 0, 0] && a.abs() < 1e-12));
        let tri = [[-1.0, -1.0, 0.5], [3.0, -1.0, 0.5], [-1.0, 3.0, 0.5]];
        let mut got = vec![];
        pieces(&tri, [1, 1, 1], |v, p| got.push((v, double_area(p) / 2.0)));
        // x + y <= 2 covers [0, 1]² whole.
        assert_eq!(got.len(), 1);
        assert!((got[0].1 - 1.0).abs() < 1e-12);
    }
}
