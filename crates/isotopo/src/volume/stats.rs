//! Value statistics for `isotopo info`: range, quantiles, a histogram, NaN/Inf counts and a
//! suggested isovalue (Otsu's threshold).

use super::{DType, Sample, Samples, Scaling, SliceReader};
use crate::error::Result;
use crate::progress::Progress;
use crate::with_samples;

/// Statistics of a volume's values (after the header's intensity scaling).
#[derive(Clone, Debug, serde::Serialize)]
pub struct Stats {
    /// Samples in the volume (`nx·ny·nz`), finite or not.
    pub samples: u64,
    /// Samples whose value is NaN.
    pub nan: u64,
    /// Samples whose value is +∞.
    pub pos_inf: u64,
    /// Samples whose value is −∞.
    pub neg_inf: u64,
    /// Smallest finite value (NaN when there is none).
    pub min: f64,
    /// Largest finite value (NaN when there is none).
    pub max: f64,
    /// Mean of the finite values (NaN when there is none).
    pub mean: f64,
    /// `(fraction, value)` pairs: 0.01, 0.05, 0.25, 0.5, 0.75, 0.95, 0.99.
    pub quantiles: Vec<(f64, f64)>,
    /// Whether quantiles are exact (8/16-bit integers) or to within one of 4096 bins.
    pub exact: bool,
    /// Otsu's threshold between the two main populations of values.
    pub otsu: f64,
    /// Histogram over `[min, max]`: bin edges (`counts.len() + 1` of them) and counts.
    pub edges: Vec<f64>,
    /// Finite values in each histogram bin, bin `k` covering `edges[k]` to `edges[k + 1]`.
    pub counts: Vec<u64>,
}

const FINE_BINS: usize = 4096;
const SHOWN_BINS: usize = 32;
const QUANTILES: [f64; 7] = [0.01, 0.05, 0.25, 0.5, 0.75, 0.95, 0.99];

/// Counts of values on a fine grid: exact per raw value for 8/16-bit integers, else 4096 bins.
struct Fine {
    lo: f64,
    width: f64,
    counts: Vec<u64>,
}

impl Fine {
    fn value_of(&self, i: usize) -> f64 {
        self.lo + self.width * i as f64
    }
}

/// Count, sum and range of the finite values seen so far, and counts of the others.
struct Totals {
    nan: u64,
    pos_inf: u64,
    neg_inf: u64,
    n: u64,
    min: f64,
    max: f64,
    sum: f64,
}

impl Totals {
    fn new() -> Totals {
        Totals {
            nan: 0,
            pos_inf: 0,
            neg_inf: 0,
            n: 0,
            min: f64::INFINITY,
            max: f64::NEG_INFINITY,
            sum: 0.0,
        }
    }

    /// One value, whatever it is.
    #[inline]
    fn add(&mut self, x: f64) {
        if x.is_nan() {
            self.nan += 1;
        } else if x == f64::INFINITY {
            self.pos_inf += 1;
        } else if x == f64::NEG_INFINITY {
            self.neg_inf += 1;
        } else {
            self.n += 1;
            self.sum += x;
            self.min = self.min.min(x);
            self.max = self.max.max(x);
        }
    }

    /// `count` copies of the value `v` (exact histograms).
    fn add_copies(&mut self, v: f64, count: u64) {
        self.n += count;
        self.sum += v * count as f64;
        self.min = self.min.min(v);
        self.max = self.max.max(v);
    }
}

/// Exact integer histograms are indexed by raw value: the first raw value and how many there are
/// (none for other types).
fn raw_range(dtype: DType) -> (i64, usize) {
    match dtype {
        DType::U8 => (0i64, 256usize),
        DType::I8 => (-128, 256),
        DType::U16 => (0, 65536),
        DType::I16 => (-32768, 65536),
        _ => (0, 0),
    }
}

/// The one pass over 8/16-bit integers: how many samples have each raw value.
fn count_raw(
    reader: &mut dyn SliceReader,
    slice: &mut Samples,
    (raw_lo, raw_n): (i64, usize),
    progress: &dyn Progress,
) -> Result<Vec<u64>> {
    let mut raw_counts = vec![0u64; raw_n];
    for _ in 0..reader.info().nz() {
        reader.read_slice(slice)?;
        with_samples!(&*slice, v => {
            for &x in v.iter() {
                raw_counts[(x.to_f64() as i64 - raw_lo) as usize] += 1;
            }
        });
        progress.advance(1);
    }
    Ok(raw_counts)
}

/// The exact histogram in value order, adding its values to `totals`.
fn exact_fine(raw_counts: Vec<u64>, raw_lo: i64, scaling: Scaling, totals: &mut Totals) -> Fine {
    for (i, &c) in raw_counts.iter().enumerate() {
        if c > 0 {
            totals.add_copies(scaling.apply((i as i64 + raw_lo) as f64), c);
        }
    }
    // Values in raw order; a negative slope reverses them.
    let raw_n = raw_counts.len();
    let mut counts = raw_counts;
    let (lo, width) = if scaling.slope < 0.0 {
        counts.reverse();
        (
            scaling.apply((raw_lo + raw_n as i64 - 1) as f64),
            -scaling.slope,
        )
    } else {
        (scaling.apply(raw_lo as f64), scaling.slope)
    };
    Fine { lo, width, counts }
}

/// First pass over other types: the totals of the (scaled) values.
fn scan_values(
    reader: &mut dyn SliceReader,
    slice: &mut Samples,
    scaling: Scaling,
    totals: &mut Totals,
    progress: &dyn Progress,
) -> Result<()> {
    for _ in 0..reader.info().nz() {
        reader.read_slice(slice)?;
        with_samples!(&*slice, v => {
            for &x in v.iter() {
                totals.add(scaling.apply(x.to_f64()));
            }
        });
        progress.advance(1);
    }
    Ok(())
}

/// Second pass over other types: the finite values in 4096 bins over `[min, max]`.
fn binned_fine(
    reader: &mut dyn SliceReader,
    slice: &mut Samples,
    scaling: Scaling,
    (min, max): (f64, f64),
    progress: &dyn Progress,
) -> Result<Fine> {
    let width = if max > min {
        (max - min) / FINE_BINS as f64
    } else {
        1.0
    };
    let mut counts = vec![0u64; FINE_BINS];
    reader.rewind()?;
    for _ in 0..reader.info().nz() {
        reader.read_slice(slice)?;
        with_samples!(&*slice, v => {
            for &x in v.iter() {
                let x = scaling.apply(x.to_f64());
                if x.is_finite() {
                    let b = (((x - min) / width) as usize).min(FINE_BINS - 1);
                    counts[b] += 1;
                }
            }
        });
        progress.advance(1);
    }
    Ok(Fine {
        lo: min + width / 2.0,
        width,
        counts,
    })
}

/// Statistics of every value of a volume, read from `reader` positioned at slice 0: one pass for
/// 8/16-bit integers (exact), two for other types (rewinding the reader in between).
pub fn compute(reader: &mut dyn SliceReader, progress: &dyn Progress) -> Result<Stats> {
    let info = reader.info().clone();
    let scaling = info.scaling;
    let exact = matches!(info.dtype, DType::U8 | DType::I8 | DType::U16 | DType::I16);
    let mut slice = Samples::new(info.dtype);
    let mut t = Totals::new();
    progress.start("statistics", info.nz() as u64 * if exact { 1 } else { 2 });
    let fine = if exact {
        let raw = raw_range(info.dtype);
        let raw_counts = count_raw(reader, &mut slice, raw, progress)?;
        exact_fine(raw_counts, raw.0, scaling, &mut t)
    } else {
        scan_values(reader, &mut slice, scaling, &mut t, progress)?;
        binned_fine(reader, &mut slice, scaling, (t.min, t.max), progress)?
    };
    progress.finish();
    let n = t.n;
    let quantiles = QUANTILES
        .iter()
        .map(|&q| (q, quantile(&fine, n, q)))
        .collect();
    let otsu = otsu(&fine);
    let (edges, counts) = coarse(&fine, t.min, t.max);
    Ok(Stats {
        samples: info.voxel_count(),
        nan: t.nan,
        pos_inf: t.pos_inf,
        neg_inf: t.neg_inf,
        min: if n > 0 { t.min } else { f64::NAN },
        max: if n > 0 { t.max } else { f64::NAN },
        mean: if n > 0 { t.sum / n as f64 } else { f64::NAN },
        quantiles,
        exact,
        otsu,
        edges,
        counts,
    })
}

fn quantile(f: &Fine, n: u64, q: f64) -> f64 {
    if n == 0 {
        return f64::NAN;
    }
    let target = ((q * n as f64).ceil() as u64).clamp(1, n);
    let mut acc = 0;
    for (i, &c) in f.counts.iter().enumerate() {
        acc += c;
        if acc >= target {
            return f.value_of(i);
        }
    }
    f.value_of(f.counts.len() - 1)
}

/// Otsu's method: the threshold that maximises the variance between the values below and above.
fn otsu(f: &Fine) -> f64 {
    let total: u64 = f.counts.iter().sum();
    if total == 0 {
        return f64::NAN;
    }
    let sum_all: f64 = f
        .counts
        .iter()
        .enumerate()
        .map(|(i, &c)| c as f64 * f.value_of(i))
        .sum();
    let (mut w0, mut sum0) = (0.0f64, 0.0f64);
    let (mut best, mut best_t) = (-1.0f64, f.value_of(0));
    let last = f.counts.iter().rposition(|&c| c > 0).unwrap_or(0);
    for (i, &c) in f.counts.iter().enumerate().take(last) {
        w0 += c as f64;
        sum0 += c as f64 * f.value_of(i);
        if c == 0 || w0 == 0.0 {
            continue;
        }
        let w1 = total as f64 - w0;
        if w1 <= 0.0 {
            break;
        }
        let m0 = sum0 / w0;
        let m1 = (sum_all - sum0) / w1;
        let between = w0 * w1 * (m0 - m1) * (m0 - m1);
        if between > best {
            best = between;
            // Threshold halfway to the next occupied value.
            let next = (i + 1..f.counts.len())
                .find(|&j| f.counts[j] > 0)
                .unwrap_or(i + 1);
            best_t = (f.value_of(i) + f.value_of(next)) / 2.0;
        }
    }
    best_t
}

fn coarse(f: &Fine, min: f64, max: f64) -> (Vec<f64>, Vec<u64>) {
    if !(min.is_finite() && max.is_finite()) {
        return (vec![], vec![]);
    }
    let span = if max > min { max - min } else { 1.0 };
    let bins = SHOWN_BINS;
    let edges: Vec<f64> = (0..=bins)
        .map(|i| min + span * i as f64 / bins as f64)
        .collect();
    let mut counts = vec![0u64; bins];
    for (i, &c) in f.counts.iter().enumerate() {
        if c == 0 {
            continue;
        }
        let b = (((f.value_of(i) - min) / span * bins as f64) as usize).min(bins - 1);
        counts[b] += c;
    }
    (edges, counts)
}
