//! `distance` against an independent brute-force oracle in exact rationals, and
//! `geom::lattice` (shared with `sdf`) against the same oracle.
//!
//! The oracle minimises |p − q|² over the triangle's parameter domain q = v0 + s·e1 + u·e2
//! (s, u ≥ 0, s + u ≤ 1): the least of the vertices, each edge's clamped projection, and the
//! interior stationary point of the 2×2 normal equations (Cramer's rule) when it lies in the
//! domain, every one an exact fraction of big integers (its own arithmetic below, no 256-bit
//! products of `lattice`'s). A convex quadratic's minimum over a triangle is at the stationary
//! point or on the boundary, so the least candidate is the distance.

use std::cmp::Ordering;

use super::voxelize;
use crate::cancel::Control;
use crate::engine::cpu::CpuEngine;
use crate::engine::geom::lattice;
use crate::engine::{Engine, GridMesh, Method};
use crate::grid::{Grid, GridSpec};
use crate::volume::BitVolume;

// ---- A small signed big integer: sign and magnitude in 32-bit limbs. ----

#[derive(Clone, Debug, PartialEq, Eq)]
struct Big {
    neg: bool,
    mag: Vec<u32>,
}

fn trim(mut m: Vec<u32>) -> Vec<u32> {
    while m.last() == Some(&0) {
        m.pop();
    }
    m
}

fn mag_cmp(a: &[u32], b: &[u32]) -> Ordering {
    a.len()
        .cmp(&b.len())
        .then_with(|| a.iter().rev().cmp(b.iter().rev()))
}

fn mag_add(a: &[u32], b: &[u32]) -> Vec<u32> {
    let mut out = Vec::with_capacity(a.len().max(b.len()) + 1);
    let mut carry = 0u64;
    for i in 0..a.len().max(b.len()) {
        let s = *a.get(i).unwrap_or(&0) as u64 + *b.get(i).unwrap_or(&0) as u64 + carry;
        out.push(s as u32);
        carry = s >> 32;
    }
    out.push(carry as u32);
    trim(out)
}

/// a − b for a ≥ b.
fn mag_sub(a: &[u32], b: &[u32]) -> Vec<u32> {
    let mut out = Vec::with_capacity(a.len());
    let mut borrow = 0i64;
    for i in 0..a.len() {
        let mut d = a[i] as i64 - *b.get(i).unwrap_or(&0) as i64 - borrow;
        borrow = (d < 0) as i64;
        if d < 0 {
            d += 1 << 32;
        }
        out.push(d as u32);
    }
    assert_eq!(borrow, 0);
    trim(out)
}

impl Big {
    fn from(v: i128) -> Big {
        let mut m = v.unsigned_abs();
        let mut mag = Vec::new();
        while m != 0 {
            mag.push(m as u32);
            m >>= 32;
        }
        Big { neg: v < 0, mag }
    }
    fn add(&self, o: &Big) -> Big {
        if self.neg == o.neg {
            return Big {
                neg: self.neg,
                mag: mag_add(&self.mag, &o.mag),
            };
        }
        match mag_cmp(&self.mag, &o.mag) {
            Ordering::Equal => Big::from(0),
            Ordering::Greater => Big {
                neg: self.neg,
                mag: mag_sub(&self.mag, &o.mag),
            },
            Ordering::Less => Big {
                neg: o.neg,
                mag: mag_sub(&o.mag, &self.mag),
            },
        }
    }
    fn sub(&self, o: &Big) -> Big {
        let mut n = o.clone();
        n.neg = !n.neg && !n.mag.is_empty();
        self.add(&n)
    }
    fn mul(&self, o: &Big) -> Big {
        let mut out = vec![0u32; self.mag.len() + o.mag.len() + 1];
        for (i, &a) in self.mag.iter().enumerate() {
            let mut carry = 0u64;
            for (j, &b) in o.mag.iter().enumerate() {
                let s = out[i + j] as u64 + a as u64 * b as u64 + carry;
                out[i + j] = s as u32;
                carry = s >> 32;
            }
            let mut k = i + o.mag.len();
            while carry != 0 {
                let s = out[k] as u64 + carry;
                out[k] = s as u32;
                carry = s >> 32;
                k += 1;
            }
        }
        let mag = trim(out);
        Big {
            neg: (self.neg != o.neg) && !mag.is_empty(),
            mag,
        }
    }
    fn is_neg(&self) -> bool {
        self.neg && !self.mag.is_empty()
    }
    fn cmp(&self, o: &Big) -> Ordering {
        match (self.is_neg(), o.is_neg()) {
            (false, true) => Ordering::Greater,
            (true, false) => Ordering::Less,
            (false, false) => mag_cmp(&self.mag, &o.mag),
            (true, true) => mag_cmp(&o.mag, &self.mag),
        }
    }
    /// The value in f64 from its top 96 bits (relative error below 2⁻⁵²).
    fn to_f64(&self) -> f64 {
        let n = self.mag.len();
        if n == 0 {
            return 0.0;
        }
        let k = n.saturating_sub(3);
        let mut top = 0u128;
        for i in (k..n).rev() {
            top = top << 32 | self.mag[i] as u128;
        }
        let v = top as f64 * 2f64.powi(32 * k as i32);
        if self.neg { -v } else { v }
    }
}

fn big(v: i128) -> Big {
    Big::from(v)
}

/// Σ aᵢ·bᵢ.
fn bdot(a: &[Big; 3], b: &[Big; 3]) -> Big {
    a[0].mul(&b[0]).add(&a[1].mul(&b[1])).add(&a[2].mul(&b[2]))
}

/// The exact squared distance from p to the triangle, as (numerator, denominator > 0).
fn oracle_d2(p: [i64; 3], tri: &[[i32; 3]; 3]) -> (Big, Big) {
    let v: [[Big; 3]; 3] = tri.map(|q| q.map(|c| big(c as i128)));
    let pb = p.map(|c| big(c as i128));
    let diff = |a: &[Big; 3], b: &[Big; 3]| [0, 1, 2].map(|i| a[i].sub(&b[i]));
    let mut best: Option<(Big, Big)> = None;
    let mut offer = |num: Big, den: Big| {
        let better = match &best {
            None => true,
            Some((bn, bd)) => num.mul(bd).cmp(&bn.mul(&den)) == Ordering::Less,
        };
        if better {
            best = Some((num, den));
        }
    };
    // Vertices.
    for q in &v {
        let w = diff(&pb, q);
        offer(bdot(&w, &w), big(1));
    }
    // Edges: q = a + λ(b − a), λ = (w·d)/(d·d) when strictly inside (0, 1); the ends are the
    // vertices. p − q = (dd·w − wd·d)/dd.
    for i in 0..3 {
        let (a, b) = (&v[i], &v[(i + 1) % 3]);
        let d = diff(b, a);
        let dd = bdot(&d, &d);
        if dd.mag.is_empty() {
            continue;
        }
        let w = diff(&pb, a);
        let wd = bdot(&w, &d);
        if wd.is_neg() || wd.mag.is_empty() || wd.cmp(&dd) != Ordering::Less {
            continue;
        }
        let r = [0, 1, 2].map(|k| dd.mul(&w[k]).sub(&wd.mul(&d[k])));
        offer(bdot(&r, &r), dd.mul(&dd));
    }
    // Interior: [A B; B C] [s u]ᵀ = [w·e1, w·e2]ᵀ.
    let (e1, e2) = (diff(&v[1], &v[0]), diff(&v[2], &v[0]));
    let w = diff(&pb, &v[0]);
    let (a, b, c) = (bdot(&e1, &e1), bdot(&e1, &e2), bdot(&e2, &e2));
    let (r1, r2) = (bdot(&w, &e1), bdot(&w, &e2));
    let mut det = a.mul(&c).sub(&b.mul(&b));
    let mut s = c.mul(&r1).sub(&b.mul(&r2));
    let mut u = a.mul(&r2).sub(&b.mul(&r1));
    if !det.mag.is_empty() {
        if det.is_neg() {
            det = big(0).sub(&det);
            s = big(0).sub(&s);
            u = big(0).sub(&u);
        }
        if !s.is_neg() && !u.is_neg() && s.add(&u).cmp(&det) != Ordering::Greater {
            // p − q = (det·w − s·e1 − u·e2)/det.
            let r = [0, 1, 2].map(|k| det.mul(&w[k]).sub(&s.mul(&e1[k])).sub(&u.mul(&e2[k])));
            offer(bdot(&r, &r), det.mul(&det));
        }
    }
    best.unwrap()
}

/// dist(p, T) against t, by the oracle.
fn oracle_cmp(d2: &(Big, Big), t: i64) -> Ordering {
    d2.0.cmp(&big(t as i128 * t as i128).mul(&d2.1))
}

/// The oracle's exact distance when it is an integer (a tie candidate).
fn exact_integer_distance(d2: &(Big, Big)) -> Option<i64> {
    let f = (d2.0.to_f64() / d2.1.to_f64()).sqrt().round() as i64;
    (-1..=1)
        .map(|k| f + k)
        .find(|&t| t >= 0 && oracle_cmp(d2, t) == Ordering::Equal)
}

// ---- Random input. ----

struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        // splitmix64
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }
    fn int(&mut self, lo: i64, hi: i64) -> i64 {
        lo + self.below((hi - lo + 1) as u64) as i64
    }
}

/// An integer vector of length exactly `t` (a Pythagorean quadruple), chosen at random among a
/// few found.
fn vector_of_length(rng: &mut Rng, t: i64) -> [i64; 3] {
    let mut found = vec![[t, 0, 0], [0, t, 0], [0, 0, t]];
    for _ in 0..400 {
        let a = rng.int(-t, t);
        let b = rng.int(-t, t);
        let r = t * t - a * a - b * b;
        if r < 0 {
            continue;
        }
        let c = (r as f64).sqrt().round() as i64;
        if c * c == r {
            found.push([a, b, if rng.below(2) == 0 { c } else { -c }]);
        }
    }
    found[rng.below(found.len() as u64) as usize]
}

fn cross(a: [i64; 3], b: [i64; 3]) -> [i64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn dot(a: [i64; 3], b: [i64; 3]) -> i64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn add_scaled(p: [i64; 3], k: i64, d: [i64; 3]) -> [i64; 3] {
    [p[0] + k * d[0], p[1] + k * d[1], p[2] + k * d[2]]
}

fn tri32(v: [[i64; 3]; 3]) -> [[i32; 3]; 3] {
    v.map(|p| p.map(|c| i32::try_from(c).unwrap()))
}

/// A triangle exactly `t` from `c`: its closest point f = c + o (|o| = t) is a vertex, an
/// edge's interior point or a face's interior point, and the rest of it lies in the half-space
/// (q − f)·o ≥ 0, so every point is at least t from c.
fn tie_triangle(rng: &mut Rng, c: [i64; 3], t: i64) -> [[i32; 3]; 3] {
    let o = vector_of_length(rng, t.max(1));
    let o = if t == 0 { [0, 0, 0] } else { o };
    let f = add_scaled(c, 1, o);
    // Two independent integer vectors perpendicular to o (any two when o = 0).
    let cands = [
        [o[1], -o[0], 0],
        [o[2], 0, -o[0]],
        [0, o[2], -o[1]],
        [1, 0, 0],
        [0, 1, 0],
    ];
    let perp: Vec<[i64; 3]> = cands
        .iter()
        .copied()
        .filter(|&u| u != [0; 3] && dot(u, o) == 0)
        .collect();
    let (u1, u2) = (
        perp[0],
        perp[1..]
            .iter()
            .copied()
            .find(|&u| cross(perp[0], u) != [0; 3]),
    );
    let u2 = u2.unwrap_or_else(|| cross(o, u1));
    let k = rng.int(1, 3);
    let away = |rng: &mut Rng| {
        // A random vector with (·)·o ≥ 0.
        let d = [0, 1, 2].map(|_| rng.int(-300, 300));
        if dot(d, o) < 0 { d.map(|x| -x) } else { d }
    };
    let v = match rng.below(3) {
        // Face: f the centroid of a triangle in o's perpendicular plane.
        0 => [
            add_scaled(add_scaled(f, -k, u1), -k, u2),
            add_scaled(add_scaled(f, 2 * k, u1), -k, u2),
            add_scaled(add_scaled(f, -k, u1), 2 * k, u2),
        ],
        // Edge: f the midpoint of an edge perpendicular to o, the third vertex away.
        1 => {
            let third = add_scaled(away(rng), 1, f);
            [add_scaled(f, -k, u1), add_scaled(f, k, u1), third]
        }
        // Vertex.
        _ => {
            let (a, b) = (away(rng), away(rng));
            [f, add_scaled(f, 1, a), add_scaled(f, 1, b)]
        }
    };
    tri32(v)
}

/// A random triangle near a box of `span` lattice units: ordinary, far larger than a voxel,
/// far smaller, or degenerate.
fn random_triangle(rng: &mut Rng, span: [i64; 3]) -> [[i32; 3]; 3] {
    let point = |rng: &mut Rng, m: i64| [0, 1, 2].map(|a| rng.int(-m, span[a] + m));
    let v0 = point(rng, 512);
    let v = match rng.below(8) {
        0 | 1 | 2 => [v0, point(rng, 512), point(rng, 512)],
        // Far larger than the grid.
        3 => [point(rng, 40_000), point(rng, 40_000), point(rng, 40_000)],
        // Far smaller than a voxel.
        4 => {
            let s = |rng: &mut Rng| [0, 1, 2].map(|_| rng.int(-6, 6));
            [v0, add_scaled(v0, 1, s(rng)), add_scaled(v0, 1, s(rng))]
        }
        // A segment (a repeated vertex, or three collinear points).
        5 => {
            let d = [0, 1, 2].map(|_| rng.int(-900, 900));
            let k = rng.int(-2, 3);
            [v0, add_scaled(v0, 1, d), add_scaled(v0, k, d)]
        }
        // A point.
        6 => [v0, v0, v0],
        // A sliver: nearly collinear.
        _ => {
            let d = [0, 1, 2].map(|_| rng.int(-900, 900));
            [
                v0,
                add_scaled(v0, 1, d),
                add_scaled(add_scaled(v0, 2, d), 1, [1, 0, 0]),
            ]
        }
    };
    tri32(v)
}

fn unit_grid(dims: [u32; 3]) -> Grid {
    Grid {
        origin: [0.0; 3],
        voxel_size: 1.0,
        dims,
    }
}

fn centre(i: u32) -> i64 {
    i as i64 * 256 + 128
}

/// The oracle's volume: every voxel whose centre is within t of some triangle. Triangles whose
/// bounding box is farther than t from the centre (exact integers) cannot be, and are skipped.
/// Also returns how many voxels are exactly at t from their nearest triangle.
fn oracle_volume(mesh: &GridMesh, t: i64) -> (BitVolume, u64) {
    let mut vol = BitVolume::new(mesh.grid);
    let [nx, ny, nz] = mesh.grid.dims;
    let boxes: Vec<[(i64, i64); 3]> = mesh
        .triangles
        .iter()
        .map(|tr| {
            [0, 1, 2].map(|a| {
                let c = tr.map(|v| v[a] as i64);
                (c[0].min(c[1]).min(c[2]), c[0].max(c[1]).max(c[2]))
            })
        })
        .collect();
    let mut ties = 0;
    for x in 0..nx {
        for y in 0..ny {
            for z in 0..nz {
                let p = [centre(x), centre(y), centre(z)];
                let mut best = Ordering::Greater;
                for (tr, b) in mesh.triangles.iter().zip(&boxes) {
                    let g2: i128 = (0..3)
                        .map(|a| {
                            let g = (b[a].0 - p[a]).max(p[a] - b[a].1).max(0) as i128;
                            g * g
                        })
                        .sum();
                    if g2 > t as i128 * t as i128 {
                        continue;
                    }
                    best = best.min(oracle_cmp(&oracle_d2(p, tr), t));
                    if best == Ordering::Less {
                        break;
                    }
                }
                if best != Ordering::Greater {
                    vol.set(x, y, z, true);
                }
                ties += (best == Ordering::Equal) as u64;
            }
        }
    }
    (vol, ties)
}

fn first_difference(got: &BitVolume, want: &BitVolume) -> Option<String> {
    let [nx, ny, nz] = want.grid().dims;
    for x in 0..nx {
        for y in 0..ny {
            for z in 0..nz {
                if got.get(x, y, z) != want.get(x, y, z) {
                    return Some(format!(
                        "voxel ({x}, {y}, {z}): got {}, oracle {}",
                        got.get(x, y, z),
                        want.get(x, y, z)
                    ));
                }
            }
        }
    }
    None
}

const THICKNESSES: [i64; 9] = [0, 1, 77, 128, 222, 256, 301, 512, 1000];

// ---- geom::lattice against the oracle. ----

#[test]
fn lattice_compare_and_distance_agree_with_the_oracle() {
    let mut rng = Rng(1);
    let mut ties = 0;
    for case in 0..6000 {
        // Coordinates at several scales, up to the lattice's limit.
        let m = [1 << 10, 1 << 16, 1 << 22, crate::engine::MAX_FIXED][case % 4];
        let tri = if case % 5 == 4 {
            let s = m.min(1 << 20);
            random_triangle(&mut rng, [s, s, s])
        } else {
            let pt = |rng: &mut Rng| [0, 1, 2].map(|_| rng.int(-m, m));
            let v0 = pt(&mut rng);
            match case % 7 {
                0 => [v0, v0, pt(&mut rng)],
                1 => [v0; 3],
                _ => [v0, pt(&mut rng), pt(&mut rng)],
            }
            .map(|p| p.map(|c| c as i32))
        };
        let p = [0, 1, 2].map(|_| rng.int(-m, m));
        let d2 = oracle_d2(p, &tri);
        // distance2: relative error below 2⁻⁵⁰ (and 2⁻⁴⁹ with the oracle's own conversion).
        let exact = d2.0.to_f64() / d2.1.to_f64();
        let got = lattice::distance2(p, &tri);
        assert!(
            (got - exact).abs() <= exact * 2f64.powi(-49),
            "{tri:?} {p:?}: distance2 {got} vs {exact}"
        );
        // compare at thresholds around the distance (and an exact tie when it is an integer).
        let r = exact.sqrt();
        if r <= (1u64 << 32) as f64 {
            let f = r.floor() as i64;
            for t in [f - 1, f, f + 1, f + 2] {
                if (0..=1 << 32).contains(&t) {
                    assert_eq!(
                        lattice::compare(p, &tri, t),
                        oracle_cmp(&d2, t),
                        "{tri:?} {p:?} t = {t}"
                    );
                }
            }
            if exact_integer_distance(&d2).is_some() {
                ties += 1;
            }
        }
    }
    // Constructed ties: exactly t from a point, through a vertex, an edge or a face.
    for case in 0..3000 {
        let t = [1, 3, 7, 128, 222, 255, 1000, 8192][case % 8];
        let c = [0, 1, 2].map(|_| rng.int(-1 << 20, 1 << 20));
        let tri = tie_triangle(&mut rng, c, t);
        let d2 = oracle_d2(c, &tri);
        assert_eq!(oracle_cmp(&d2, t), Ordering::Equal, "{tri:?} {c:?} {t}");
        assert_eq!(
            lattice::compare(c, &tri, t),
            Ordering::Equal,
            "{tri:?} {c:?} {t}"
        );
        assert_eq!(lattice::compare(c, &tri, t - 1), Ordering::Greater);
        assert_eq!(lattice::compare(c, &tri, t + 1), Ordering::Less);
        ties += 1;
    }
    assert!(ties >= 3000);
}

/// The oracle itself on cases worked by hand.
#[test]
fn the_oracle_knows_simple_cases() {
    let t = [[0, 0, 0], [8, 0, 0], [0, 8, 0]];
    let d = |p: [i64; 3], tri: &[[i32; 3]; 3]| {
        let (n, m) = oracle_d2(p, tri);
        n.to_f64() / m.to_f64()
    };
    assert_eq!(d([1, 1, 5], &t), 25.0);
    assert_eq!(d([6, 6, 0], &t), 8.0);
    assert_eq!(d([-3, -4, 0], &t), 25.0);
    assert_eq!(d([4, -2, 1], &t), 5.0);
    assert_eq!(d([5, 3, 4], &[[0, 0, 0], [10, 0, 0], [5, 0, 0]]), 25.0);
    assert_eq!(d([2, 2, 5], &[[2, 2, 2]; 3]), 9.0);
    // (1,1,1) over the face x + y + z = 6's centroid (2,2,2), distance √3 · 1 → 3 (squared).
    assert_eq!(d([3, 3, 3], &[[6, 0, 0], [0, 6, 0], [0, 0, 6]]), 3.0);
}

// ---- The volume against the oracle. ----

fn random_mesh(rng: &mut Rng, dims: [u32; 3], n: usize, t: i64) -> GridMesh {
    let span = dims.map(|d| d as i64 * 256);
    let mut triangles: Vec<[[i32; 3]; 3]> = (0..n).map(|_| random_triangle(rng, span)).collect();
    // Ties: triangles exactly t from some voxel centres.
    for _ in 0..n / 2 + 1 {
        let c = [0, 1, 2].map(|a| centre(rng.below(dims[a] as u64) as u32));
        triangles.push(tie_triangle(rng, c, t));
    }
    GridMesh {
        grid: unit_grid(dims),
        triangles,
    }
}

#[test]
fn random_meshes_equal_the_oracle() {
    let mut rng = Rng(7);
    let mut ties = 0;
    for seed in 0..36 {
        let t = THICKNESSES[seed % THICKNESSES.len()];
        let dims = [0, 1, 2].map(|_| 1 + rng.below(10) as u32);
        let mesh = random_mesh(&mut rng, dims, 1 + seed % 9, t);
        let got = voxelize(&mesh, t, &Control::none()).unwrap();
        let (want, tied) = oracle_volume(&mesh, t);
        ties += tied;
        if let Some(d) = first_difference(&got, &want) {
            panic!("seed {seed}, t = {t}, dims {dims:?}: {d}");
        }
        // The trait's default is this implementation.
        assert_eq!(
            CpuEngine.distance_with(&mesh, t, &Control::none()).unwrap(),
            got
        );
    }
    assert!(ties > 20, "only {ties} voxels exactly at t");
}

fn spot() -> crate::mesh::Mesh {
    let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/spot.obj");
    crate::mesh::load_file(&p, usize::MAX).unwrap()
}

fn fitted(m: &crate::mesh::Mesh, n: u32) -> GridMesh {
    let (lo, hi) = m.bounds();
    let g = Grid::fit(
        lo,
        hi,
        GridSpec::Resolution { n, cubic: false },
        1,
        Default::default(),
    )
    .unwrap();
    GridMesh::new(m, &g).unwrap()
}

/// A real mesh (spot, and the shared meshes' open teapot when present) against the oracle.
#[test]
fn real_meshes_equal_the_oracle() {
    let mut meshes = vec![("spot", fitted(&spot(), 14))];
    let shared = std::env::var_os("VOXD_SHARED_MESHES").map_or_else(
        || std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/meshes"),
        std::path::PathBuf::from,
    );
    match crate::mesh::load_file(&shared.join("teapot.obj"), usize::MAX) {
        Ok(m) => meshes.push(("teapot", fitted(&m, 12))),
        Err(e) => eprintln!("NOTICE: no shared teapot ({e}); testing spot alone"),
    }
    for (name, mesh) in &meshes {
        for t in [222, 700] {
            let got = voxelize(mesh, t, &Control::none()).unwrap();
            let (want, _) = oracle_volume(mesh, t);
            assert!(want.count_ones() > 0);
            if let Some(d) = first_difference(&got, &want) {
                panic!("{name}, t = {t}: {d}");
            }
        }
    }
}

/// With t ≥ s·√3/2, every voxel of `surface` is set: a triangle touching a voxel's closed box
/// is within half its diagonal of the centre.
#[test]
fn the_default_thickness_holds_the_surface() {
    let mut rng = Rng(3);
    let mut meshes: Vec<GridMesh> = (0..40)
        .map(|s| {
            let dims = [0, 1, 2].map(|_| 1 + rng.below(14) as u32);
            random_mesh(&mut rng, dims, 1 + s % 12, 0)
        })
        .collect();
    meshes.push(fitted(&spot(), 64));
    for (i, mesh) in meshes.iter().enumerate() {
        let surface = CpuEngine.voxelize(mesh, Method::Surface).unwrap();
        for t in [crate::engine::distance::DEFAULT_LATTICE, 300] {
            let d = voxelize(mesh, t, &Control::none()).unwrap();
            let mut missing = surface.clone();
            missing.subtract(&d);
            assert_eq!(missing.count_ones(), 0, "mesh {i}, t = {t}");
        }
        // And 221 (below s·√3/2) is not enough in general: not asserted per mesh.
    }
    // A voxel whose box a triangle touches only at its corner: at 221 the corner is farther.
    let corner = [
        [256, 256, 256],
        [256 + 300, 256, 256],
        [256, 256 + 300, 256 + 40],
    ];
    let mesh = GridMesh {
        grid: unit_grid([2, 2, 2]),
        triangles: vec![corner],
    };
    assert!(
        CpuEngine
            .voxelize(&mesh, Method::Surface)
            .unwrap()
            .get(0, 0, 0)
    );
    assert!(voxelize(&mesh, 222, &Control::none()).unwrap().get(0, 0, 0));
    assert!(!voxelize(&mesh, 221, &Control::none()).unwrap().get(0, 0, 0));
}

#[test]
fn cancellation_stops_it() {
    let mesh = fitted(&spot(), 32);
    let ctl = Control::new();
    ctl.cancel();
    assert!(voxelize(&mesh, 222, &ctl).is_err());
    let ctl = Control::new();
    voxelize(&mesh, 222, &ctl).unwrap();
    assert_eq!(ctl.progress(), 1.0);
}
