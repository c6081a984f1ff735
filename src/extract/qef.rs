//! The quadratic error function of dual contouring (Ju et al. 2002; the solve after Lindstrom
//! 2000 and Schaefer & Warren): for planes `n_i · x = n_i · p_i`, the point minimising
//! `Σ (n_i · (x − p_i))²`, found about the mass point `m` (the mean of the `p_i`) with the
//! symmetric eigen-decomposition of `AᵀA` and its small eigenvalues truncated: directions the
//! planes do not pin (a flat patch pins one, an edge two, a corner three) keep the mass point's
//! coordinate, so a rank-deficient cell's vertex is the point of its feature nearest `m`.

#![allow(clippy::needless_range_loop)] // 3×3 matrix code reads best by index.

/// Eigenvalues of `AᵀA` below this fraction of the largest are dropped (singular values of
/// `A` below √0.003 ≈ 0.055 of the largest). Two planes at an angle θ give the eigenvalues
/// 1 ± cos θ, whose ratio is tan²(θ/2): planes within 6.3° of each other count as one. (It was
/// 0.02, 16°: a cell holding a face and a shallow tessellation crease of a faceted part then
/// placed its vertex between the two planes, a few hundredths of a voxel off both, and tilted
/// the face's triangles by degrees; rocker-arm at 384 voxels, with the box rule of
/// [`Qef::solve_in`]: dihedral error mean 3.2° → 1.9°, edges over 5° 7 → 4 of 47.)
pub const TRUNCATE: f64 = 0.003;

/// A QEF's sums: `AᵀA` (upper triangle xx, xy, xz, yy, yz, zz), `Aᵀb`, and the points' sum and
/// count for the mass point.
#[derive(Clone, Copy, Debug, Default)]
pub struct Qef {
    ata: [f64; 6],
    atb: [f64; 3],
    mass: [f64; 3],
    points: u32,
    planes: u32,
}

impl Qef {
    /// Adds the plane through `p` with unit normal `n` (a zero `n` adds `p` to the mass point
    /// only).
    pub fn add(&mut self, p: [f64; 3], n: [f64; 3]) {
        for a in 0..3 {
            self.mass[a] += p[a];
        }
        self.points += 1;
        if n == [0.0; 3] {
            return;
        }
        let d = n[0] * p[0] + n[1] * p[1] + n[2] * p[2];
        let [x, y, z] = n;
        for (s, v) in self
            .ata
            .iter_mut()
            .zip([x * x, x * y, x * z, y * y, y * z, z * z])
        {
            *s += v;
        }
        for a in 0..3 {
            self.atb[a] += n[a] * d;
        }
        self.planes += 1;
    }

    /// The mean of the points added.
    pub fn mass_point(&self) -> [f64; 3] {
        let n = f64::from(self.points.max(1));
        self.mass.map(|s| s / n)
    }

    /// The minimiser about the mass point, with [`TRUNCATE`]'s rank rule.
    pub fn solve(&self) -> [f64; 3] {
        let m = self.mass_point();
        if self.planes == 0 {
            return m;
        }
        let (a, r) = self.about(m);
        step(a, r, m, [false; 3])
    }

    /// The minimiser within the box `[lo, hi]` (`lo ≤ hi` on every axis, the mass point inside
    /// it): [`Qef::solve`]'s point when it is inside; else, of the minimisers on the box's
    /// faces, edges and corners (each with the box's coordinates fixed on its axes, the others
    /// solved with the same rank rule about the mass point's) that lie in the box, the one with
    /// the least error (ties: the first, faces before edges before corners, in axis order,
    /// low side first). So a vertex whose feature leaves the cell stays on the feature's planes
    /// where the cell meets them, rather than being pulled off them towards the mass point.
    pub fn solve_in(&self, lo: [f64; 3], hi: [f64; 3]) -> [f64; 3] {
        let m = self.mass_point();
        if self.planes == 0 {
            return m;
        }
        let (a, r) = self.about(m);
        let inside = |x: &[f64; 3]| (0..3).all(|k| x[k] >= lo[k] && x[k] <= hi[k]);
        let x = step(a, r, m, [false; 3]);
        if inside(&x) {
            return x;
        }
        // The error about the mass point, less its constant: yᵀ(AᵀA)y − 2yᵀr, y = x − m.
        let error = |x: &[f64; 3]| {
            let y = [0, 1, 2].map(|k| x[k] - m[k]);
            let ay = [0, 1, 2].map(|i| (0..3).map(|j| a[i][j] * y[j]).sum::<f64>());
            (0..3)
                .map(|k| y[k] * ay[k] - 2.0 * y[k] * r[k])
                .sum::<f64>()
        };
        let mut best: Option<([f64; 3], f64)> = None;
        // Fixed axes by count (1, 2, 3), each axis at lo or hi.
        for fixed in 1..=3u32 {
            for axes in 0u32..8 {
                if axes.count_ones() != fixed {
                    continue;
                }
                for sides in 0u32..8 {
                    if sides & !axes != 0 {
                        continue;
                    }
                    let mut start = m;
                    let mut held = [false; 3];
                    for k in 0..3 {
                        if axes >> k & 1 == 1 {
                            held[k] = true;
                            start[k] = if sides >> k & 1 == 1 { hi[k] } else { lo[k] };
                        }
                    }
                    // r at the start point: Aᵀb − AᵀA·start = r − AᵀA·(start − m).
                    let d = [0, 1, 2].map(|k| start[k] - m[k]);
                    let rs = [0, 1, 2].map(|i| r[i] - (0..3).map(|j| a[i][j] * d[j]).sum::<f64>());
                    let x = step(a, rs, start, held);
                    if !inside(&x) {
                        continue;
                    }
                    let e = error(&x);
                    if best.is_none_or(|(_, b)| e < b) {
                        best = Some((x, e));
                    }
                }
            }
        }
        // A corner is always in the box: some candidate is.
        best.map_or(m, |(x, _)| x)
    }

    /// `AᵀA` as a matrix and `Aᵀb − AᵀA·m`: the residual's pull from `m`.
    fn about(&self, m: [f64; 3]) -> ([[f64; 3]; 3], [f64; 3]) {
        let [xx, xy, xz, yy, yz, zz] = self.ata;
        let a = [[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]];
        let r = [0, 1, 2].map(|i| self.atb[i] - (0..3).map(|j| a[i][j] * m[j]).sum::<f64>());
        (a, r)
    }
}

/// `start` moved to the minimiser over the axes not `held` (their rows and columns of `a`
/// kept, the others zeroed), `r` the residual's pull at `start`, with [`TRUNCATE`]'s rank rule
/// on the kept part (a direction it drops keeps `start`'s coordinate).
fn step(mut a: [[f64; 3]; 3], mut r: [f64; 3], start: [f64; 3], held: [bool; 3]) -> [f64; 3] {
    for i in 0..3 {
        for j in 0..3 {
            if held[i] || held[j] {
                a[i][j] = 0.0;
            }
        }
        if held[i] {
            r[i] = 0.0;
        }
    }
    let (vals, vecs) = eigen(a);
    let max = vals.iter().cloned().fold(0.0, f64::max);
    let mut x = start;
    for k in 0..3 {
        if vals[k] > TRUNCATE * max && vals[k] > 0.0 {
            let v = [vecs[0][k], vecs[1][k], vecs[2][k]];
            let c = (v[0] * r[0] + v[1] * r[1] + v[2] * r[2]) / vals[k];
            for i in 0..3 {
                if !held[i] {
                    x[i] += c * v[i];
                }
            }
        }
    }
    x
}

/// Eigenvalues and eigenvectors (columns) of a symmetric 3×3 matrix by cyclic Jacobi rotations
/// (converges quadratically; a few sweeps reach f64 round-off).
pub fn eigen(mut a: [[f64; 3]; 3]) -> ([f64; 3], [[f64; 3]; 3]) {
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for _ in 0..16 {
        let off = a[0][1].powi(2) + a[0][2].powi(2) + a[1][2].powi(2);
        let diag = a[0][0].powi(2) + a[1][1].powi(2) + a[2][2].powi(2);
        if off <= 1e-30 * diag || off == 0.0 {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if a[p][q] == 0.0 {
                continue;
            }
            // The rotation that zeroes a[p][q] (Golub & Van Loan's symmetric Schur step).
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let t = if theta == 0.0 { 1.0 } else { t };
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            for k in 0..3 {
                let (akp, akq) = (a[k][p], a[k][q]);
                a[k][p] = c * akp - s * akq;
                a[k][q] = s * akp + c * akq;
            }
            for k in 0..3 {
                let (apk, aqk) = (a[p][k], a[q][k]);
                a[p][k] = c * apk - s * aqk;
                a[q][k] = s * apk + c * aqk;
            }
            for row in &mut v {
                let (vp, vq) = (row[p], row[q]);
                row[p] = c * vp - s * vq;
                row[q] = s * vp + c * vq;
            }
        }
    }
    ([a[0][0], a[1][1], a[2][2]], v)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mul(a: [[f64; 3]; 3], x: [f64; 3]) -> [f64; 3] {
        [0, 1, 2].map(|i| (0..3).map(|j| a[i][j] * x[j]).sum())
    }

    #[test]
    fn eigen_decomposes_symmetric_matrices() {
        let mut s = 0x2545_f491_4f6c_dd1du64;
        let mut r = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        for _ in 0..200 {
            let (p, q, w, u, v, z) = (r(), r(), r(), r(), r(), r());
            let a = [[p, q, w], [q, u, v], [w, v, z]];
            let (vals, vecs) = eigen(a);
            for k in 0..3 {
                let e = [vecs[0][k], vecs[1][k], vecs[2][k]];
                let av = mul(a, e);
                for i in 0..3 {
                    assert!((av[i] - vals[k] * e[i]).abs() < 1e-12, "{a:?}");
                }
            }
        }
    }

    /// A corner pins the point; an edge leaves it free along the edge (the mass point's
    /// coordinate there); a plane leaves two directions free.
    #[test]
    fn corners_edges_and_planes() {
        let c = [0.3, 0.7, 0.2];
        let mut q = Qef::default();
        q.add([0.3, 0.0, 0.0], [1.0, 0.0, 0.0]);
        q.add([0.0, 0.7, 1.0], [0.0, 1.0, 0.0]);
        q.add([1.0, 1.0, 0.2], [0.0, 0.0, 1.0]);
        let x = q.solve();
        assert!((0..3).all(|a| (x[a] - c[a]).abs() < 1e-12), "{x:?}");
        // Two planes at 90° meeting on the line y = 0.7, z = 0.2; points spread along x.
        let mut q = Qef::default();
        q.add([0.0, 0.7, 0.9], [0.0, 1.0, 0.0]);
        q.add([1.0, 0.1, 0.2], [0.0, 0.0, 1.0]);
        let x = q.solve();
        assert!((x[0] - 0.5).abs() < 1e-12 && (x[1] - 0.7).abs() < 1e-12);
        assert!((x[2] - 0.2).abs() < 1e-12, "{x:?}");
        // Nearly parallel planes (2° apart) are one: the mass point moved only along their
        // mean normal (x by sin 1° of the move, y not at all), not to their far-off line.
        let t = 2f64.to_radians();
        let mut q = Qef::default();
        q.add([0.0, 0.0, 0.5], [0.0, 0.0, 1.0]);
        q.add([1.0, 1.0, 0.5], [t.sin(), 0.0, t.cos()]);
        let x = q.solve();
        assert!(
            (x[0] - 0.5).abs() < 1e-3 && (x[1] - 0.5).abs() < 1e-12,
            "{x:?}"
        );
        assert!((x[2] - 0.5).abs() < 0.02, "{x:?}");
        // Without the truncation the minimiser would be on their line x = 1, z = 0.5.
        assert!((x[0] - 0.5).abs() < (x[2] - 0.5).abs(), "{x:?}");
        // No planes: the mass point.
        let mut q = Qef::default();
        q.add([0.0, 0.0, 0.0], [0.0; 3]);
        q.add([1.0, 0.0, 0.0], [0.0; 3]);
        assert_eq!(q.solve(), [0.5, 0.0, 0.0]);
    }

    /// A corner outside the box: the box rule keeps the vertex on the two planes that cross
    /// the box (the old rule, back along the segment to the mass point, left both).
    #[test]
    fn a_corner_outside_the_box_keeps_the_planes_that_cross_it() {
        let mut q = Qef::default();
        q.add([1.2, 0.0, 0.0], [1.0, 0.0, 0.0]);
        q.add([0.0, 0.3, 1.0], [0.0, 1.0, 0.0]);
        q.add([1.0, 1.0, 0.4], [0.0, 0.0, 1.0]);
        assert!((q.solve()[0] - 1.2).abs() < 1e-12);
        let x = q.solve_in([0.0; 3], [1.0; 3]);
        let want = [1.0, 0.3, 0.4];
        assert!((0..3).all(|a| (x[a] - want[a]).abs() < 1e-12), "{x:?}");
        // Inside: the free minimiser, bit for bit.
        assert_eq!(q.solve_in([0.0; 3], [2.0; 3]), q.solve());
    }

    /// Against brute force: with three or more planes far from parallel (no eigenvalue
    /// truncated), `solve_in` is inside the box and no point of a 41³ lattice of the box (its
    /// corners, edge midpoints and face centres among them) has less error.
    #[test]
    fn the_box_minimiser_is_the_least_error_point_of_the_box() {
        let mut rng = crate::testkit::Rng::new(0x9e37_79b9_7f4a_7c15);
        let mut r = || rng.unit();
        let mut outside = 0;
        for case in 0..300 {
            let lo = [r() - 0.5, r() - 0.5, r() - 0.5];
            let hi = [0, 1, 2].map(|k| lo[k] + 0.2 + r());
            let mut q = Qef::default();
            let mut planes = vec![];
            let count = 3 + case % 4;
            while planes.len() < count {
                let n = [r() - 0.5, r() - 0.5, r() - 0.5];
                let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
                if l < 0.1 {
                    continue;
                }
                let n = n.map(|c| c / l);
                // Points spread about the box (corners often outside it).
                let p = [0, 1, 2].map(|k| lo[k] - 0.6 + (hi[k] - lo[k] + 1.2) * r());
                planes.push((p, n));
            }
            for &(p, n) in &planes {
                q.add(p, n);
            }
            let (vals, _) = eigen(q.about(q.mass_point()).0);
            let max = vals.iter().cloned().fold(0.0, f64::max);
            if vals.iter().any(|&v| v < 0.05 * max) {
                continue; // near-parallel planes: the rank rule applies, not brute force.
            }
            let err = |x: [f64; 3]| {
                planes
                    .iter()
                    .map(|(p, n)| {
                        let d: f64 = (0..3).map(|k| n[k] * (x[k] - p[k])).sum();
                        d * d
                    })
                    .sum::<f64>()
            };
            let x = q.solve_in(lo, hi);
            assert!(
                (0..3).all(|k| x[k] >= lo[k] && x[k] <= hi[k]),
                "{case}: {x:?}"
            );
            let free = q.solve();
            if (0..3).any(|k| free[k] < lo[k] || free[k] > hi[k]) {
                outside += 1;
            }
            let e = err(x);
            let n = 40;
            for i in 0..=n {
                for j in 0..=n {
                    for k in 0..=n {
                        let t = [i, j, k].map(|v| f64::from(v) / f64::from(n));
                        let y = [0, 1, 2].map(|a| lo[a] + t[a] * (hi[a] - lo[a]));
                        assert!(e <= err(y) + 1e-9, "{case}: {x:?} {e} > {y:?} {}", err(y));
                    }
                }
            }
        }
        // The cases that test the box rule (the free minimiser outside the box).
        assert!(outside > 100, "{outside}");
    }
}
