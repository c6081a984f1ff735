//! The one helper module of `src/`'s unit tests: a seeded random generator, scratch
//! directories and gzip. Compiled only under `cfg(test)`.
//!
//! Not here: the integration tests' helpers (`tests/common/`, another crate, which has its own
//! generator of the same algorithm), nor fixtures of one subsystem (meshes, stores), which stay
//! beside the tests that use them.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// xorshift64*: small, dependency-free and deterministic, so a failing seed reproduces. The seed
/// is the state as given (not mixed), which keeps the streams the tests were written against.
/// [`Rng::plain`] gives the plain xorshift64 (13, 7, 17) instead, for the lane kernels' tests:
/// their tolerances sit close to the rounding of the cases that stream draws (another stream
/// finds a case past them), so it is kept exactly rather than changed with this module.
pub(crate) struct Rng {
    state: u64,
    star: bool,
}

impl Rng {
    /// A generator from `seed`, which must not be zero (xorshift's one fixed point).
    pub(crate) fn new(seed: u64) -> Rng {
        assert_ne!(seed, 0, "xorshift never leaves the zero state");
        Rng {
            state: seed,
            star: true,
        }
    }

    /// The plain xorshift64 from `seed` (see the type's note on why it is kept).
    pub(crate) fn plain(seed: u64) -> Rng {
        Rng {
            star: false,
            ..Rng::new(seed)
        }
    }

    pub(crate) fn next_u64(&mut self) -> u64 {
        let x = &mut self.state;
        if self.star {
            *x ^= *x >> 12;
            *x ^= *x << 25;
            *x ^= *x >> 27;
            x.wrapping_mul(0x2545_F491_4F6C_DD1D)
        } else {
            *x ^= *x << 13;
            *x ^= *x >> 7;
            *x ^= *x << 17;
            *x
        }
    }

    /// Uniform in [0, 1), from the top 53 bits.
    pub(crate) fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Below `n` (modulo bias is irrelevant at test sizes).
    pub(crate) fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }

    pub(crate) fn pick<T: Copy>(&mut self, of: &[T]) -> T {
        of[self.below(of.len())]
    }

    /// Uniform in [lo, hi).
    pub(crate) fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }

    /// A point of the cube [lo, hi)³.
    pub(crate) fn point(&mut self, lo: f64, hi: f64) -> [f64; 3] {
        [0, 1, 2].map(|_| self.range(lo, hi))
    }

    /// A uniformly random unit vector (rejection from the unit ball, away from its centre).
    pub(crate) fn direction(&mut self) -> [f64; 3] {
        loop {
            let v = self.point(-1.0, 1.0);
            let l = v.iter().map(|c| c * c).sum::<f64>().sqrt();
            if l > 0.1 && l <= 1.0 {
                return v.map(|c| c / l);
            }
        }
    }
}

/// A bit volume on `grid` with each voxel set with probability `p` (drawn x, then y, then z).
pub(crate) fn random_bit_volume(
    rng: &mut Rng,
    grid: crate::grid::Grid,
    p: f64,
) -> crate::volume::BitVolume {
    let mut b = crate::volume::BitVolume::new(grid);
    let d = grid.dims;
    for x in 0..d[0] {
        for y in 0..d[1] {
            for z in 0..d[2] {
                if rng.unit() < p {
                    b.set(x, y, z, true);
                }
            }
        }
    }
    b
}

/// A directory of its own under the system's temporary directory, removed with everything in
/// it when dropped. Unique per process and per call (tests run in parallel threads of one
/// process, and the same name may be asked twice), created empty.
pub(crate) struct Scratch(PathBuf);

impl Scratch {
    /// `name` only makes a leftover directory recognisable (a test killed before its drop).
    pub(crate) fn new(name: &str) -> Scratch {
        static NEXT: AtomicU64 = AtomicU64::new(0);
        let n = NEXT.fetch_add(1, Ordering::Relaxed);
        let dir = std::env::temp_dir().join(format!("voxd-{name}-{}-{n}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        Scratch(dir)
    }

    pub(crate) fn path(&self) -> &Path {
        &self.0
    }
}

impl std::ops::Deref for Scratch {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<Path> for Scratch {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

#[test]
fn scratch_directories_are_distinct_and_removed() {
    let (a, b) = (Scratch::new("kit"), Scratch::new("kit"));
    assert_ne!(a.path(), b.path());
    assert!(a.is_dir() && b.is_dir());
    std::fs::write(a.join("f"), b"x").unwrap();
    let at = a.path().to_path_buf();
    drop(a);
    assert!(!at.exists());
}

#[test]
fn the_generator_keeps_its_stream() {
    // The first draws of seed 1, so a change of algorithm (which would silently change every
    // seeded test's cases) is seen here.
    let mut r = Rng::new(1);
    assert_eq!(
        [r.next_u64(), r.next_u64()],
        [5_180_492_295_206_395_165, 12_380_297_144_915_551_517]
    );
    let mut p = Rng::plain(1);
    assert_eq!(
        [p.next_u64(), p.next_u64()],
        [1_082_269_761, 1_152_992_998_833_853_505]
    );
    let u = Rng::new(7).unit();
    assert!((0.0..1.0).contains(&u));
}

/// `b` gzipped (one member, fast compression).
pub(crate) fn gz(b: &[u8]) -> Vec<u8> {
    use std::io::Write;
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    e.write_all(b).unwrap();
    e.finish().unwrap()
}

/// The unit octahedron (vertices ±1 on each axis), its triangles counter-clockwise seen from
/// outside.
pub(crate) fn octahedron() -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let p = vec![
        [1.0, 0.0, 0.0],
        [-1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, -1.0, 0.0],
        [0.0, 0.0, 1.0],
        [0.0, 0.0, -1.0],
    ];
    let t = vec![
        [0, 2, 4],
        [2, 1, 4],
        [1, 3, 4],
        [3, 0, 4],
        [2, 0, 5],
        [1, 2, 5],
        [3, 1, 5],
        [0, 3, 5],
    ];
    (p, t)
}
