//! The quadratic error function of dual contouring (Ju et al. 2002; the solve after Lindstrom
//! 2000 and Schaefer & Warren): for planes `n_i · x = n_i · p_i`, the point minimising
//! `Σ (n_i · (x − p_i))²`, found about the mass point `m` (the mean of the `p_i`) with the
//! symmetric eigen-decomposition of `AᵀA` and its small eigenvalues truncated: directions the
//! planes do not pin (a flat patch pins one, an edge two, a corner three) keep the mass point's
//! coordinate, so a rank-deficient cell's vertex is the point of its feature nearest `m`.

#![allow(clippy::needless_range_loop)] // 3×3 matrix code reads best by index.

/// Eigenvalues of `AᵀA` below this fraction of the largest are dropped (singular values of
/// `A` below √0.02 ≈ 0.14 of the largest: planes within about 8° of each other count as one).
pub const TRUNCATE: f64 = 0.02;

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
        let [xx, xy, xz, yy, yz, zz] = self.ata;
        let a = [[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]];
        // r = Aᵀb − AᵀA m: the residual's pull from the mass point.
        let r = [0, 1, 2].map(|i| self.atb[i] - (0..3).map(|j| a[i][j] * m[j]).sum::<f64>());
        let (vals, vecs) = eigen(a);
        let max = vals.iter().cloned().fold(0.0, f64::max);
        let mut x = m;
        for k in 0..3 {
            if vals[k] > TRUNCATE * max && vals[k] > 0.0 {
                let v = [vecs[0][k], vecs[1][k], vecs[2][k]];
                let c = (v[0] * r[0] + v[1] * r[1] + v[2] * r[2]) / vals[k];
                for i in 0..3 {
                    x[i] += c * v[i];
                }
            }
        }
        x
    }
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
}
