//! The unit tests' random numbers: xorshift64 (shifts 13, 7, 17), the same sequence from the
//! same seed on every machine, so a test's measured counts stay put.

/// A xorshift64 generator; its state is the seed (not 0).
pub(crate) struct Rng(pub(crate) u64);

impl Rng {
    /// The next state.
    pub(crate) fn next_u64(&mut self) -> u64 {
        let s = &mut self.0;
        *s ^= *s << 13;
        *s ^= *s >> 7;
        *s ^= *s << 17;
        *s
    }

    /// A number below `n` (the next state modulo `n`).
    pub(crate) fn below(&mut self, n: u64) -> u64 {
        self.next_u64() % n
    }

    /// A number in [0, 1), from the state's top 53 bits.
    pub(crate) fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Uniform noise in [0, 1) (24 bits a sample), each sample summed with its six neighbours and
/// thresholded at 3.5 (iso 0): a sponge of a few dozen handles on a 20³ grid.
pub(crate) fn sponge(n: usize, seed: u64) -> crate::volume::InMemoryVolume {
    let mut rng = Rng(seed);
    let noise: Vec<f32> = (0..n * n * n)
        .map(|_| (rng.next_u64() >> 40) as f32 / (1u64 << 24) as f32)
        .collect();
    crate::volume::InMemoryVolume::from_fn([n; 3], |x, y, z| {
        let at = |x: usize, y: usize, z: usize| noise[(z * n + y) * n + x];
        let (lo, hi) = (
            |v: usize| v.saturating_sub(1),
            |v: usize| (v + 1).min(n - 1),
        );
        at(x, y, z)
            + at(lo(x), y, z)
            + at(hi(x), y, z)
            + at(x, lo(y), z)
            + at(x, hi(y), z)
            + at(x, y, lo(z))
            + at(x, y, hi(z))
            - 3.5
    })
}
