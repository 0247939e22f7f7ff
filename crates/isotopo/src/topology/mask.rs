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

use crate::volume::{Sample, Samples, Scaling, Threshold};
use crate::with_samples;

/// Which side of the isovalue is inside (docs/ARCHITECTURE.md, conventions). Ties and NaN are always outside.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum Inside {
    /// `v > iso` (CT, probability maps; the default).
    Above,
    /// `v < iso` (signed distance fields).
    Below,
}

impl Inside {
    /// `above` or `below`, as the command line and the reports spell it.
    pub fn name(self) -> &'static str {
        match self {
            Inside::Above => "above",
            Inside::Below => "below",
        }
    }
}

/// Decides inside/outside for raw samples of a volume.
#[derive(Clone, Copy, Debug)]
pub struct Classifier {
    /// Isovalue, in value units (after `scaling`).
    pub iso: f64,
    /// Which side of the isovalue is inside.
    pub inside: Inside,
    /// The header's scaling from raw samples to values.
    pub scaling: Scaling,
}

impl Classifier {
    /// Whether a value (already scaled) is inside; NaN and values equal to `iso` are outside.
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

    /// Whether a raw stored sample lies exactly on the isovalue (after the header's scaling):
    /// isotopo counts it outside, VTK inside.
    #[inline]
    pub fn on_iso_raw(&self, raw: f64) -> bool {
        self.scaling.apply(raw) == self.iso
    }

    /// How many raw samples of a slice lie exactly on the isovalue ([`Classifier::on_iso_raw`]),
    /// in one loop per stored type.
    pub fn count_on_iso(&self, samples: &Samples) -> u64 {
        with_samples!(samples, v => count_on_iso(v, self))
    }

    /// The isovalue in stored units (before the header's scaling).
    pub fn raw_iso(&self) -> f64 {
        (self.iso - self.scaling.inter) / self.scaling.slope
    }
}

/// One padded z-plane of inside bits.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PlaneMask {
    /// Samples along x (without the padding).
    pub nx: usize,
    /// Samples along y (without the padding).
    pub ny: usize,
    /// u64 words per padded row.
    pub words: usize,
    /// `ny + 2` padded rows of `words` words each; padded column `i` is bit `i % 64` of word
    /// `i / 64` of its row.
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

    /// Sets the inside bit of sample (x, y), which must lie in the volume.
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

    /// Number of inside samples in the plane.
    pub fn count(&self) -> u64 {
        self.bits.iter().map(|w| w.count_ones() as u64).sum()
    }

    /// True when no sample of the plane is inside.
    pub fn is_empty(&self) -> bool {
        self.bits.iter().all(|&w| w == 0)
    }

    /// Classifies one z-slice of raw samples (`nx·ny`, x fastest) into this plane.
    pub fn fill(&mut self, samples: &Samples, c: &Classifier) {
        debug_assert_eq!(samples.len(), self.nx * self.ny);
        with_samples!(samples, v => fill_rows(self, v, c));
    }
}

fn count_on_iso<T: Sample>(v: &[T], c: &Classifier) -> u64 {
    if c.scaling.is_identity() {
        // Compared in the stored type, a loop the compiler vectorizes: no sample can equal an
        // isovalue that the type cannot hold.
        let t = T::from_f64(c.iso);
        if t.to_f64() != c.iso {
            return 0;
        }
        // Summed in 16-bit lanes, as many as the compared samples fill (in 64-bit lanes, a
        // 16-bit sample type's comparisons would be spread over four times as many), and the
        // lanes' totals in 64 bits: no chunk holds more than u16::MAX samples.
        v.chunks(u16::MAX as usize)
            .map(|chunk| chunk.iter().map(|&x| (x == t) as u16).sum::<u16>() as u64)
            .sum()
    } else {
        v.iter().filter(|x| c.on_iso_raw(x.to_f64())).count() as u64
    }
}

/// Gathers bit 0 of each of 8 bytes into one byte (byte k gives bit k).
#[inline]
fn gather8(bytes: &[u8]) -> u64 {
    let x = u64::from_le_bytes(bytes.try_into().unwrap());
    x.wrapping_mul(0x0102_0408_1020_4080) >> 56
}

fn fill_rows<T: Sample>(plane: &mut PlaneMask, v: &[T], c: &Classifier) {
    let (nx, words) = (plane.nx, plane.words);
    // One flag byte per sample (a loop the compiler vectorizes), then 8 flags per byte.
    let mut flags = vec![0u8; nx.div_ceil(64) * 64];
    let mut packed = vec![0u64; nx.div_ceil(64)];
    let threshold = if c.scaling.is_identity() {
        Some(match c.inside {
            Inside::Above => T::above(c.iso),
            Inside::Below => T::below(c.iso),
        })
    } else {
        None
    };
    for y in 0..plane.ny {
        let row = &v[y * nx..(y + 1) * nx];
        match threshold {
            Some(Threshold::Greater(t)) => flags
                .iter_mut()
                .zip(row)
                .for_each(|(f, &s)| *f = (s > t) as u8),
            Some(Threshold::Less(t)) => flags
                .iter_mut()
                .zip(row)
                .for_each(|(f, &s)| *f = (s < t) as u8),
            Some(Threshold::All) => flags[..nx].iter_mut().for_each(|f| *f = 1),
            Some(Threshold::Nothing) => flags[..nx].iter_mut().for_each(|f| *f = 0),
            None => flags
                .iter_mut()
                .zip(row)
                .for_each(|(f, &s)| *f = c.inside_raw(s.to_f64()) as u8),
        }
        for (k, p) in packed.iter_mut().enumerate() {
            let chunk = &flags[k * 64..k * 64 + 64];
            let mut w = 0u64;
            for b in 0..8 {
                w |= gather8(&chunk[b * 8..b * 8 + 8]) << (8 * b);
            }
            *p = w;
        }
        // Bits past nx are stale flags from the previous row: clear them.
        if nx % 64 != 0 {
            let last = packed.len() - 1;
            packed[last] &= (1u64 << (nx % 64)) - 1;
        }
        // Padded column i = x + 1: shift everything up by one bit.
        let out = &mut plane.bits[(y + 1) * words..(y + 2) * words];
        let mut carry = 0u64;
        for k in 0..words {
            let w = packed.get(k).copied().unwrap_or(0);
            out[k] = (w << 1) | carry;
            carry = w >> 63;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::DType;

    /// The vectorized per-type comparisons agree with `value > iso` and `value == iso` in f64
    /// for every type, isovalues on and between representable values, and both sides.
    #[test]
    fn fill_agrees_with_the_f64_rule() {
        let (nx, ny) = (131, 3);
        let mut rng = crate::test_rng::Rng(12345);
        let mut next = || rng.next_u64();
        for t in DType::ALL {
            let mut s = Samples::zeros(t, nx * ny);
            let (lo, hi) = t.range();
            for i in 0..nx * ny {
                let r = next();
                let v = match t {
                    DType::F32 => f32::from_bits(r as u32) as f64,
                    DType::F64 => f64::from_bits(r),
                    _ => lo + (r % ((hi - lo) as u64 + 1).max(1)) as f64,
                };
                s.set_f64(i, if i % 7 == 0 { 100.0 } else { v });
            }
            if let Samples::F32(v) = &mut s {
                v[1] = 0.1f32;
                v[2] = f32::NAN;
            }
            for iso in [
                100.0,
                99.5,
                0.1,
                -3.7,
                1e30,
                -1e30,
                lo - 10.0,
                hi + 10.0,
                0.0,
            ] {
                for inside in [Inside::Above, Inside::Below] {
                    for scaling in [
                        Scaling::IDENTITY,
                        Scaling {
                            slope: 2.0,
                            inter: -1.0,
                        },
                    ] {
                        let c = Classifier {
                            iso,
                            inside,
                            scaling,
                        };
                        let mut p = PlaneMask::empty(nx, ny);
                        p.fill(&s, &c);
                        let on_iso =
                            (0..nx * ny).filter(|&i| c.on_iso_raw(s.get_f64(i))).count() as u64;
                        assert_eq!(c.count_on_iso(&s), on_iso, "{t} iso {iso} {scaling:?}");
                        if iso == 100.0 && scaling.is_identity() {
                            assert!(on_iso > 0, "{t}: the samples set to 100 count");
                        }
                        for y in 0..ny {
                            for x in 0..nx {
                                let want = c.inside_raw(s.get_f64(y * nx + x));
                                assert_eq!(
                                    p.get(x as isize, y as isize),
                                    want,
                                    "{t} iso {iso} {inside:?} at {x},{y}"
                                );
                            }
                            assert!(!p.get_padded(0, y + 1) && !p.get_padded(nx + 1, y + 1));
                        }
                        assert_eq!(
                            p.row(0)
                                .iter()
                                .chain(p.row(ny + 1))
                                .map(|w| w.count_ones())
                                .sum::<u32>(),
                            0
                        );
                    }
                }
            }
        }
    }

    /// More samples at the isovalue than a 16-bit lane holds, in a slice of every type: each
    /// one counted.
    #[test]
    fn every_sample_at_the_isovalue_counts_in_a_large_slice() {
        let n = 3 * u16::MAX as usize + 5;
        let c = Classifier {
            iso: 7.0,
            inside: Inside::Above,
            scaling: Scaling::IDENTITY,
        };
        for t in DType::ALL {
            let mut s = Samples::zeros(t, n);
            for i in (0..n).filter(|i| i % 5 != 3) {
                s.set_f64(i, 7.0);
            }
            assert_eq!(c.count_on_iso(&s), (n - n / 5) as u64, "{t}");
        }
    }
}
