//! Counter-based randomness: every value is a hash of (seed, stream, index), so any block of the
//! scan can be generated on any thread in any order and the output is the same.

#[inline]
pub fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

#[inline]
pub fn hash3(seed: u64, a: i64, b: i64) -> u64 {
    mix(seed ^ mix(a as u64 ^ mix(b as u64)))
}

/// A small sequential generator seeded from a hash.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Rng {
        Rng(mix(seed))
    }
    #[inline]
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        mix(self.0)
    }
    /// Uniform in [0, 1).
    #[inline]
    pub fn f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
    /// Roughly normal noise, mean 0, sd 1: the sum of two uniforms from one 64-bit draw
    /// (a triangular distribution; plenty for sensor noise).
    #[inline]
    pub fn normal(&mut self) -> f64 {
        let h = self.next_u64();
        let a = (h >> 32) as f64 * (1.0 / 4_294_967_296.0);
        let b = (h & 0xFFFF_FFFF) as f64 * (1.0 / 4_294_967_296.0);
        (a + b - 1.0) * 2.449
    }
}

/// Uniform in [0,1) from a hash.
#[inline]
pub fn unit(h: u64) -> f64 {
    (h >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// The i-th independent uniform in [0,1) drawn from hash `h`.
#[inline]
pub fn sub(h: u64, i: u64) -> f64 {
    unit(mix(h ^ i.wrapping_mul(0xA24B_AED4_963E_E407)))
}
