//! The one random generator of the integration tests: seeded, deterministic and dependency-free,
//! so a failing seed reproduces. Property tests (`props`) draw their cases with proptest and
//! their voxels from a seed with this. Not for `src/`'s unit tests (another crate).

/// xorshift64*.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Rng {
        Rng(seed.wrapping_mul(0x9E3779B97F4A7C15) | 1)
    }
    pub fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545F4914F6CDD1D)
    }
    pub fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
    /// A coordinate in [lo, hi] on the half-voxel lattice (on voxel faces and column centres).
    pub fn half(&mut self, lo: f64, hi: f64) -> f64 {
        let n = ((hi - lo) * 2.0) as u64;
        lo + self.below(n + 1) as f64 / 2.0
    }
}
