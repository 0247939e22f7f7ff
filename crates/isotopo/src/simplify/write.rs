//! Writing the result: the samples that changed side, the values written for them, and the
//! edited volume streamed to a new file.

use super::Edit;
use crate::error::{Error, Result};
use crate::grid::MaskVolume;
use crate::progress::Progress;
use crate::surface::search::FastMap;
use crate::topology::Classifier;
use crate::volume::{DType, Samples, SliceReader, VolumeInfo};
use std::path::Path;

/// The samples that end on the other side (`original`: each flipped sample's first side),
/// in original coordinates, plane by plane (out of core, each plane read once).
pub(super) fn final_edits(vol: &mut MaskVolume, original: &FastMap<[i64; 3], bool>) -> Vec<Edit> {
    let mut edits: Vec<Edit> = changed_sides(vol, original)
        .into_iter()
        .map(|(q, inside)| (vol.frame.to_original_i(q), inside))
        .collect();
    edits.sort_by_key(|(p, _)| [p[2], p[1], p[0]]);
    edits
}

/// The samples of `original` (each flipped sample's first side) now on the other side, with
/// their side now, in local coordinates by plane, row and column (each plane read once).
pub(super) fn changed_sides(
    vol: &mut MaskVolume,
    original: &FastMap<[i64; 3], bool>,
) -> Vec<([i64; 3], bool)> {
    let mut flipped: Vec<([i64; 3], bool)> = original.iter().map(|(&q, &was)| (q, was)).collect();
    flipped.sort_unstable_by_key(|(q, _)| [q[2], q[1], q[0]]);
    let mut changed = Vec::new();
    for same_plane in flipped.chunk_by(|a, b| a.0[2] == b.0[2]) {
        let plane = vol.plane_once(same_plane[0].0[2]);
        for &(q, was) in same_plane {
            if plane.get(q[0] as isize, q[1] as isize) != was {
                changed.push((q, !was));
            }
        }
    }
    changed
}

/// Stored values written for inside and outside samples: the representable values nearest the
/// isovalue strictly on each side (never the isovalue itself, which meshers disagree on: isotopo
/// counts it outside, VTK inside); for floating-point samples, a relative margin of 2^-10 keeps
/// the new surface from sitting exactly on the samples.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct WallValues {
    /// Written for samples set inside (`None`: no such value in the type).
    pub inside: Option<f64>,
    /// Written for samples set outside.
    pub outside: Option<f64>,
}

impl WallValues {
    /// The values for samples of type `dtype` classified by `classifier`.
    pub fn new(dtype: DType, classifier: &Classifier) -> WallValues {
        // The isovalue in stored units.
        let raw_iso = classifier.raw_iso();
        let (lo, hi) = dtype.range();
        let ok = |raw: f64, inside: bool| -> bool {
            raw.is_finite()
                && raw >= lo
                && raw <= hi
                && round_trip(dtype, raw) == raw
                && classifier.inside_raw(raw) == inside
                && !classifier.on_iso_raw(raw)
        };
        let pick = |inside: bool| -> Option<f64> {
            let mut candidates: Vec<f64> = Vec::new();
            if dtype.is_float() {
                let eps = raw_iso.abs().max(1.0) / 1024.0;
                for k in [1.0, 2.0, 4.0] {
                    candidates.push(round_trip(dtype, raw_iso + k * eps));
                    candidates.push(round_trip(dtype, raw_iso - k * eps));
                }
            } else {
                let f = raw_iso.floor();
                for k in -2..=3 {
                    candidates.push((f + k as f64).clamp(lo, hi));
                }
            }
            candidates
                .into_iter()
                .filter(|&r| ok(r, inside))
                .min_by(|a, b| (a - raw_iso).abs().total_cmp(&(b - raw_iso).abs()))
        };
        WallValues {
            inside: pick(true),
            outside: pick(false),
        }
    }
}

/// The nearest value of the type (for floats; integers are passed through).
fn round_trip(dtype: DType, v: f64) -> f64 {
    match dtype {
        DType::F32 => v as f32 as f64,
        _ => v,
    }
}

/// What writing changed besides the listed edits.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct Written {
    /// Samples exactly at the isovalue (isotopo counts them outside, VTK inside), besides
    /// those edited.
    pub samples_at_iso: u64,
    /// Whether they were moved to the outside value (floating-point samples, well-composed
    /// output; see [`SimplifyOptions::well_composed`](super::SimplifyOptions::well_composed)).
    pub at_iso_moved: bool,
    /// The largest change of a sample's value, edits included (after the header's scaling).
    pub largest_move: f64,
}

/// Edits slices in order: the listed edits set to the wall values, the samples at the isovalue
/// counted and, with `move_at_iso`, moved to the outside value.
pub(crate) struct SliceEditor<'a> {
    edits: &'a [Edit],
    next: usize,
    values: &'a WallValues,
    classifier: Classifier,
    move_at_iso: bool,
    /// What has been changed so far.
    pub written: Written,
}

impl<'a> SliceEditor<'a> {
    /// An editor for `edits` (sorted by z, then y, then x).
    pub fn new(
        edits: &'a [Edit],
        values: &'a WallValues,
        classifier: Classifier,
        move_at_iso: bool,
    ) -> SliceEditor<'a> {
        SliceEditor {
            edits,
            next: 0,
            values,
            classifier,
            move_at_iso,
            written: Written::default(),
        }
    }

    /// Edits slice `z` (`nx` samples per row), the slices being given in order.
    pub fn apply(&mut self, z: usize, nx: usize, slice: &mut Samples) -> Result<()> {
        let mut edited: Vec<usize> = Vec::new();
        while self.next < self.edits.len() && self.edits[self.next].0[2] == z as i64 {
            let ([x, y, _], inside) = self.edits[self.next];
            let i = y as usize * nx + x as usize;
            let v = self.value(inside, slice)?;
            self.set(slice, i, v);
            edited.push(i);
            self.next += 1;
        }
        let outside = if self.move_at_iso {
            Some(self.value(false, slice)?)
        } else {
            None
        };
        for i in 0..slice.len() {
            if self.classifier.on_iso_raw(slice.get_f64(i)) && edited.binary_search(&i).is_err() {
                self.written.samples_at_iso += 1;
                if let Some(v) = outside {
                    self.set(slice, i, v);
                    self.written.at_iso_moved = true;
                }
            }
        }
        Ok(())
    }

    /// Sets sample `i` to the stored value `raw`, keeping the largest move.
    fn set(&mut self, slice: &mut Samples, i: usize, raw: f64) {
        let scaling = self.classifier.scaling;
        let moved = (scaling.apply(raw) - scaling.apply(slice.get_f64(i))).abs();
        if moved.is_finite() {
            self.written.largest_move = self.written.largest_move.max(moved);
        }
        slice.set_f64(i, raw);
    }

    fn value(&self, inside: bool, slice: &Samples) -> Result<f64> {
        if inside {
            self.values.inside
        } else {
            self.values.outside
        }
        .ok_or_else(|| {
            Error::Internal(format!(
                "no {} value representable in {}",
                if inside { "inside" } else { "outside" },
                slice.dtype()
            ))
        })
    }
}

/// Streams `reader` to a new file `out`, edited by `editor`; returns what it changed.
pub(crate) fn write_edited(
    reader: &mut dyn SliceReader,
    out: &Path,
    mut editor: SliceEditor,
    progress: &dyn Progress,
) -> Result<Written> {
    reader.rewind()?;
    let info: VolumeInfo = reader.info().clone();
    let [nx, _, nz] = info.dims;
    let mut writer = crate::volume::create(out, &info)?;
    let mut slice = Samples::new(info.dtype);
    progress.start("write", nz as u64);
    for z in 0..nz {
        reader.read_slice(&mut slice)?;
        editor.apply(z, nx, &mut slice)?;
        writer.write_slice(&slice)?;
        progress.advance(1);
        crate::progress::between_steps(progress, "writing of the output")?;
    }
    progress.finish();
    let info = reader.info().clone();
    writer.finish(&info)?;
    Ok(editor.written)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::topology::Inside;
    use crate::volume::Scaling;

    /// The wall values are stored values of the type, strictly on their side, never on the
    /// isovalue, and the nearest such: no integer between them and the isovalue; for floats
    /// within the first margin (2^-10 of the isovalue, at least 2^-10).
    #[test]
    fn wall_values_are_the_nearest_on_each_side() {
        let scalings = [
            Scaling::IDENTITY,
            Scaling {
                slope: 2.0,
                inter: -1024.0,
            },
        ];
        let mut checked = 0;
        for dtype in DType::ALL {
            for scaling in scalings {
                for iso in [0.5, 0.0, 1.0, 127.5, -3.0, 0.1, 1000.25, -1023.0] {
                    for inside in [Inside::Above, Inside::Below] {
                        let c = Classifier {
                            iso,
                            inside,
                            scaling,
                        };
                        let w = WallValues::new(dtype, &c);
                        for (value, side) in [(w.inside, true), (w.outside, false)] {
                            let what = format!("{dtype} {scaling:?} iso {iso} {inside:?} {side}");
                            check(dtype, &c, value, side, &what);
                            checked += 1;
                        }
                    }
                }
            }
        }
        assert_eq!(checked, 8 * 2 * 8 * 2 * 2);
    }

    fn check(dtype: DType, c: &Classifier, value: Option<f64>, side: bool, what: &str) {
        let raw_iso = c.raw_iso();
        let (lo, hi) = dtype.range();
        let Some(v) = value else {
            // Only when the whole range of the type is on the other side.
            let ends = [lo, hi];
            assert!(
                ends.iter()
                    .all(|&e| c.inside_raw(e) != side || c.on_iso_raw(e)),
                "{what}"
            );
            return;
        };
        assert!(v >= lo && v <= hi, "{what}: {v} outside the type");
        assert_eq!(c.inside_raw(v), side, "{what}: {v} on the wrong side");
        assert!(!c.on_iso_raw(v), "{what}: {v} on the isovalue");
        if dtype.is_float() {
            if dtype == DType::F32 {
                assert_eq!(v as f32 as f64, v, "{what}: {v} is not a float32");
            }
            let eps = raw_iso.abs().max(1.0) / 1024.0;
            assert!(
                (v - raw_iso).abs() <= 1.01 * eps,
                "{what}: {v} is not the nearest"
            );
        } else {
            assert_eq!(v.fract(), 0.0, "{what}: {v} is not an integer");
            let closer = v - (v - raw_iso).signum();
            let valid = closer >= lo && closer <= hi && c.inside_raw(closer) == side;
            assert!(
                !valid || c.on_iso_raw(closer),
                "{what}: {closer} is nearer than {v}"
            );
        }
    }
}
