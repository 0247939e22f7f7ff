//! Inside/outside classification of samples, packed one bit per sample.
//!
//! A [`PlaneMask`] holds one z-plane, padded by one outside sample on every side so that cubes
//! at the border see outside corners and every isosurface is closed:
//!
//! ```text
//!   padded column  0   1   2  ...  nx   nx+1
//!   sample x      -1   0   1  ... nx-1   nx      (x = -1 and x = nx are padding, always 0)
//! ```
//!
//! Rows likewise run over y = -1 ..= ny. The planes z = -1 and z = nz are all outside.

use crate::volume::{Sample, Samples, Scaling};
use crate::with_samples;

/// Which side of the isovalue is inside (DESIGN.md §1). Ties and NaN are always outside.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum Inside {
    /// `v > iso` (CT, probability maps; the default).
    Above,
    /// `v < iso` (signed distance fields).
    Below,
}

/// Decides inside/outside for raw samples of a volume.
#[derive(Clone, Copy, Debug)]
pub struct Classifier {
    pub iso: f64,
    pub inside: Inside,
    pub scaling: Scaling,
}

impl Classifier {
    #[inline]
    pub fn inside_value(&self, value: f64) -> bool {
        match self.inside {
            Inside::Above => value > self.iso,
            Inside::Below => value < self.iso,
        }
    }

    /// Whether a raw stored sample is inside (after the header's scaling).
    #[inline]
    pub fn inside_raw(&self, raw: f64) -> bool {
        self.inside_value(self.scaling.apply(raw))
    }
}

/// One padded z-plane of inside bits.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PlaneMask {
    pub nx: usize,
    pub ny: usize,
    /// u64 words per padded row.
    pub words: usize,
    pub bits: Vec<u64>,
}

impl PlaneMask {
    /// An all-outside plane (also the padding planes z = -1 and z = nz).
    pub fn empty(nx: usize, ny: usize) -> PlaneMask {
        let words = (nx + 2).div_ceil(64);
        PlaneMask {
            nx,
            ny,
            words,
            bits: vec![0; words * (ny + 2)],
        }
    }

    /// Padded row `j` (sample y = j - 1).
    #[inline]
    pub fn row(&self, j: usize) -> &[u64] {
        &self.bits[j * self.words..(j + 1) * self.words]
    }

    /// Inside bit at padded column `i`, padded row `j`.
    #[inline]
    pub fn get_padded(&self, i: usize, j: usize) -> bool {
        (self.bits[j * self.words + i / 64] >> (i % 64)) & 1 == 1
    }

    /// Inside bit of sample (x, y); outside beyond the volume.
    #[inline]
    pub fn get(&self, x: isize, y: isize) -> bool {
        if x < 0 || y < 0 || x >= self.nx as isize || y >= self.ny as isize {
            return false;
        }
        self.get_padded(x as usize + 1, y as usize + 1)
    }

    #[inline]
    pub fn set(&mut self, x: usize, y: usize, inside: bool) {
        let (i, j) = (x + 1, y + 1);
        let w = &mut self.bits[j * self.words + i / 64];
        if inside {
            *w |= 1 << (i % 64);
        } else {
            *w &= !(1 << (i % 64));
        }
    }

    pub fn count(&self) -> u64 {
        self.bits.iter().map(|w| w.count_ones() as u64).sum()
    }

    pub fn is_empty(&self) -> bool {
        self.bits.iter().all(|&w| w == 0)
    }

    /// Classifies one z-slice of raw samples (`nx·ny`, x fastest) into this plane.
    pub fn fill(&mut self, samples: &Samples, c: &Classifier) {
        debug_assert_eq!(samples.len(), self.nx * self.ny);
        self.bits.iter_mut().for_each(|w| *w = 0);
        with_samples!(samples, v => fill_rows(self, v, c));
    }
}

fn fill_rows<T: Sample>(plane: &mut PlaneMask, v: &[T], c: &Classifier) {
    let (nx, words) = (plane.nx, plane.words);
    let identity = c.scaling.is_identity();
    let mut flags = vec![0u8; nx];
    for y in 0..plane.ny {
        let row = &v[y * nx..(y + 1) * nx];
        if identity {
            let iso = c.iso;
            match c.inside {
                Inside::Above => flags
                    .iter_mut()
                    .zip(row)
                    .for_each(|(f, &s)| *f = (s.to_f64() > iso) as u8),
                Inside::Below => flags
                    .iter_mut()
                    .zip(row)
                    .for_each(|(f, &s)| *f = (s.to_f64() < iso) as u8),
            }
        } else {
            flags
                .iter_mut()
                .zip(row)
                .for_each(|(f, &s)| *f = c.inside_raw(s.to_f64()) as u8);
        }
        let out = &mut plane.bits[(y + 1) * words..(y + 2) * words];
        // Padded column i = x + 1.
        for (x, &f) in flags.iter().enumerate() {
            let i = x + 1;
            out[i / 64] |= (f as u64) << (i % 64);
        }
    }
}
