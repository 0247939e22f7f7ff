//! The volume as the later stages see it: inside bits per plane in a window of planes (the rest
//! in a scratch file), in the frame of the sweep axis, and the fractions along crossing edges
//! for lengths in millimetres. Everything above (the surface graph, the sweep, the loops, the
//! closures) reads and edits the volume through [`MaskVolume`].

mod fractions;
mod planes;
pub(crate) mod simple;

pub use fractions::EdgeFractions;
pub use planes::{window_for, Axis, Frame, MaskVolume, DEFAULT_WINDOW_BYTES, MIN_WINDOW};

/// An `n`³ mask for tests, each sample inside with chance `percent` / 100 (one number of
/// `rng` a sample, x fastest).
#[cfg(test)]
pub(crate) fn random_mask(rng: &mut crate::test_rng::Rng, n: usize, percent: u64) -> MaskVolume {
    let mut vol = MaskVolume::new([n; 3], Frame::identity());
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                vol.set(x, y, z, rng.below(100) < percent);
            }
        }
    }
    vol
}

/// The sample `d` away from `q`.
#[inline]
pub(crate) fn shift(q: [i64; 3], d: [i64; 3]) -> [i64; 3] {
    [q[0] + d[0], q[1] + d[1], q[2] + d[2]]
}

/// The samples of a small box `lo ..= hi`, numbered x fastest, for searches that keep a flag or
/// a mark per sample of the box (an array, not a hash set of positions).
#[derive(Clone, Copy, Debug)]
pub(crate) struct BoxCells {
    lo: [i64; 3],
    size: [usize; 3],
}

impl BoxCells {
    pub(crate) fn new(lo: [i64; 3], hi: [i64; 3]) -> BoxCells {
        let size = std::array::from_fn(|k| (hi[k] - lo[k] + 1).max(0) as usize);
        BoxCells { lo, size }
    }

    /// How many samples the box holds.
    pub(crate) fn len(&self) -> usize {
        self.size.iter().product()
    }

    /// The number of sample `q`, `None` outside the box.
    pub(crate) fn index(&self, q: [i64; 3]) -> Option<usize> {
        let r: [i64; 3] = std::array::from_fn(|k| q[k] - self.lo[k]);
        (0..3)
            .all(|k| r[k] >= 0 && (r[k] as usize) < self.size[k])
            .then(|| (r[2] as usize * self.size[1] + r[1] as usize) * self.size[0] + r[0] as usize)
    }

    /// How far apart in the numbering two samples `d` apart are.
    pub(crate) fn offset(&self, d: [i64; 3]) -> i64 {
        let size = self.size.map(|n| n as i64);
        (d[2] * size[1] + d[1]) * size[0] + d[0]
    }

    /// Whether sample number `c` lies on the box's outer layer.
    pub(crate) fn on_shell(&self, c: usize) -> bool {
        let r = [
            c % self.size[0],
            c / self.size[0] % self.size[1],
            c / (self.size[0] * self.size[1]),
        ];
        (0..3).any(|k| r[k] == 0 || r[k] + 1 == self.size[k])
    }

    /// The sample numbered `c`.
    pub(crate) fn sample(&self, c: usize) -> [i64; 3] {
        let (x, y, z) = (
            c % self.size[0],
            c / self.size[0] % self.size[1],
            c / (self.size[0] * self.size[1]),
        );
        [
            self.lo[0] + x as i64,
            self.lo[1] + y as i64,
            self.lo[2] + z as i64,
        ]
    }
}
