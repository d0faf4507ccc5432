//! The one small deterministic random generator of the crate: SplitMix64 (Steele, Lea and
//! Flood 2014). Everything random here must be reproducible from a seed (the dataset, the
//! eigensolvers' start blocks, training's shuffles, synthetic test strikes, the scrape noise);
//! none of it needs cryptographic quality, and every draw is a few integer operations with no
//! allocation, so the audio thread may use it too.

/// A SplitMix64 stream; `Clone` forks it.
#[derive(Clone, Debug)]
pub struct SplitMix64(u64);

impl SplitMix64 {
    /// The increment of the state (the golden ratio in 64 bits).
    const GAMMA: u64 = 0x9E37_79B9_7F4A_7C15;

    /// A stream whose state starts at `state` (the first draw mixes `state + GAMMA`).
    pub const fn new(state: u64) -> Self {
        SplitMix64(state)
    }

    /// The next 64 random bits.
    #[inline]
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(Self::GAMMA);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `[0, 1)`, 53 bits.
    #[inline]
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in `[lo, hi)`.
    #[inline]
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }

    /// Uniform integer in `0..n` (`n > 0`; the modulo bias is below `n / 2^64`).
    #[inline]
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }

    /// Uniform integer in `lo..=hi`.
    #[inline]
    pub fn int(&mut self, lo: usize, hi: usize) -> usize {
        lo + self.below(hi - lo + 1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The reference sequence of SplitMix64 from state 0 (Vigna's `splitmix64.c`), and draws
    /// that stay in range with the mean of a uniform (0.5 within 5 sigma of 10^4 draws).
    #[test]
    fn matches_the_reference_and_is_uniform() {
        let mut r = SplitMix64::new(0);
        assert_eq!(r.next_u64(), 0xE220_A839_7B1D_CDAF);
        assert_eq!(r.next_u64(), 0x6E78_9E6A_A1B9_65F4);
        let mut sum = 0.0;
        for _ in 0..10_000 {
            let u = r.unit();
            assert!((0.0..1.0).contains(&u));
            sum += u;
            assert!(r.int(3, 5) >= 3 && r.int(3, 5) <= 5);
        }
        let sigma = (1.0f64 / 12.0 / 10_000.0).sqrt();
        assert!((sum / 10_000.0 - 0.5).abs() < 5.0 * sigma);
    }
}
