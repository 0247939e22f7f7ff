//! Inside masks as a stack of planes perpendicular to the sweep axis, and the frame that maps
//! sweep coordinates back to the volume's.
//!
//! The sweep always runs along its own third axis `w`; sweeping a volume along x or y is
//! sweeping a rotated copy. The rotations are cyclic, so they keep handedness (outward normals
//! stay outward):
//!
//! ```text
//!   --axis z:  (u, v, w) = (x, y, z)
//!   --axis x:  (u, v, w) = (y, z, x)
//!   --axis y:  (u, v, w) = (z, x, y)
//! ```

use crate::error::{Error, Result};
use crate::progress::Progress;
use crate::topology::cases::Connectivity;
use crate::topology::genus::GenusReport;
use crate::topology::{PlaneMask, SurfaceOptions};
use crate::volume::{Samples, SliceReader};
use std::borrow::Cow;
use std::sync::OnceLock;

/// The sweep direction.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Axis {
    /// Slices are planes of constant x.
    X,
    /// Slices are planes of constant y.
    Y,
    /// Slices are planes of constant z (the default: the order samples are stored in).
    Z,
}

impl Axis {
    /// "x", "y" or "z".
    pub fn name(self) -> &'static str {
        match self {
            Axis::X => "x",
            Axis::Y => "y",
            Axis::Z => "z",
        }
    }

    /// Index in (x, y, z) of the sweep's (u, v, w) axes.
    pub fn uvw(self) -> [usize; 3] {
        match self {
            Axis::Z => [0, 1, 2],
            Axis::X => [1, 2, 0],
            Axis::Y => [2, 0, 1],
        }
    }
}

/// Maps coordinates of a (possibly rotated, cropped) mask volume to the original volume's:
/// `original[uvw[k]] = offset[uvw[k]] + local[k]`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Frame {
    pub(crate) uvw: [usize; 3],
    /// Added to original coordinates after the permutation (the padding).
    pub offset: [i64; 3],
}

impl Frame {
    /// Local coordinates are original ones (sweep along z, no offset).
    pub fn identity() -> Frame {
        Frame {
            uvw: [0, 1, 2],
            offset: [0; 3],
        }
    }

    pub(crate) fn for_axis(axis: Axis) -> Frame {
        Frame {
            uvw: axis.uvw(),
            offset: [0; 3],
        }
    }

    /// A point (integer or half-integer grid position) in original coordinates.
    #[inline]
    pub fn to_original(&self, p: [f64; 3]) -> [f64; 3] {
        let mut o = [0.0; 3];
        for k in 0..3 {
            o[self.uvw[k]] = self.offset[self.uvw[k]] as f64 + p[k];
        }
        o
    }

    /// An original-coordinate box in local coordinates (lowest and highest corners).
    pub fn to_local_box(&self, b: &crate::volume::BBox) -> ([i64; 3], [i64; 3]) {
        let local = |o: [i64; 3]| -> [i64; 3] {
            std::array::from_fn(|k| o[self.uvw[k]] - self.offset[self.uvw[k]])
        };
        let (a, c) = (local(b.min), local(b.max));
        (
            std::array::from_fn(|k| a[k].min(c[k])),
            std::array::from_fn(|k| a[k].max(c[k])),
        )
    }

    /// Local integer coordinates to original ones.
    #[inline]
    pub fn to_original_i(&self, p: [i64; 3]) -> [i64; 3] {
        let mut o = [0; 3];
        for k in 0..3 {
            o[self.uvw[k]] = self.offset[self.uvw[k]] + p[k];
        }
        o
    }

    /// The frame of a copy rotated so that its sweep runs along this frame's u axis, cropped so
    /// that its local (0, 0, 0) is this frame's local `origin`.
    pub fn rotated(&self, origin: [i64; 3]) -> Frame {
        // New (u', v', w') = old (v, w, u); the new origin is the old local `origin`.
        Frame {
            uvw: [self.uvw[1], self.uvw[2], self.uvw[0]],
            offset: self.to_original_i(origin),
        }
    }
}

/// Inside bits of a whole volume, one padded [`PlaneMask`] per plane along the sweep axis.
///
/// Out of core, only a window of planes is in memory: the others wait in a scratch file and
/// are read back when something asks for them (a loop round a long handle reaches far below
/// the sweep), until the next [`MaskVolume::keep_window`] lets them go again (edited ones
/// written back first).
///
/// ```text
///   plane   0 1 2 3 4 5 6 7 8 9 ...          . on disk only
///           . . . # . . # # # # . . .         # in memory: the window below the sweep,
///                 ^ a long handle's cycle       and whatever a search read back
/// ```
#[derive(Debug)]
pub struct MaskVolume {
    /// Extent along (u, v, w).
    pub dims: [usize; 3],
    planes: Vec<OnceLock<PlaneMask>>,
    /// Planes changed since they were last written to the scratch file.
    dirty: Vec<bool>,
    store: Option<PlaneStore>,
    /// Out of core: planes kept in memory below the sweep (see [`MaskVolume::follow_sweep`]).
    window: usize,
    /// Where these coordinates sit in the original volume.
    pub frame: Frame,
    empty: PlaneMask,
    /// Where the surface crosses the grid edges, when the volume was read with them (for lengths
    /// in millimetres; see [`MaskVolume::from_reader_with_fractions`]).
    pub fractions: Option<crate::grid::EdgeFractions>,
}

/// The scratch file behind an out-of-core [`MaskVolume`]: plane `w` at `w · plane_bytes`, its
/// words little-endian. Deleted when dropped (an unnamed temporary file).
#[derive(Debug)]
struct PlaneStore {
    file: std::fs::File,
    plane_bytes: u64,
}

/// The scratch file could not be made or written: say where it goes and how to move it.
fn scratch_error(what: &str, bytes: u64, e: std::io::Error) -> Error {
    let of = format!("the planes out of memory ({} MB)", bytes.div_ceil(1 << 20));
    Error::scratch(
        what,
        &of,
        e,
        "set TMPDIR to a writable folder with room, or --max-slices 0 to keep the whole volume \
         in memory",
    )
}

impl PlaneStore {
    fn create(plane_bytes: usize, planes: usize) -> Result<PlaneStore> {
        let bytes = (plane_bytes * planes) as u64;
        let file = tempfile::tempfile()
            .and_then(|f| f.set_len(bytes).map(|_| f))
            .map_err(|e| scratch_error("create", bytes, e))?;
        Ok(PlaneStore {
            file,
            plane_bytes: plane_bytes as u64,
        })
    }

    /// Writes `words` at word offset `at` of plane `w`.
    fn write(&self, w: usize, at: usize, words: &[u64]) -> Result<()> {
        use std::os::unix::fs::FileExt;
        let bytes: Vec<u8> = words.iter().flat_map(|x| x.to_le_bytes()).collect();
        self.file
            .write_all_at(&bytes, w as u64 * self.plane_bytes + at as u64 * 8)
            .map_err(|e| scratch_error("write", bytes.len() as u64, e))
    }

    fn read(&self, w: usize, into: &mut PlaneMask) {
        use std::os::unix::fs::FileExt;
        let mut bytes = vec![0u8; self.plane_bytes as usize];
        // The file was sized and written by this process; a failure here is the machine's.
        self.file
            .read_exact_at(&mut bytes, w as u64 * self.plane_bytes)
            .unwrap_or_else(|e| panic!("cannot read back the scratch file: {e}"));
        for (x, b) in into.bits.iter_mut().zip(bytes.chunks_exact(8)) {
            *x = u64::from_le_bytes(b.try_into().expect("8 bytes"));
        }
    }
}

/// Memory the planes of an out-of-core volume may take by default.
pub const DEFAULT_WINDOW_BYTES: usize = 16 << 20;

/// Fewest planes a window holds (a sweep step needs two, a rewind a few more).
pub const MIN_WINDOW: usize = 8;

/// Planes in memory at a time when classifying a volume: `max_slices` if given (0: all), else
/// as many as [`DEFAULT_WINDOW_BYTES`] holds.
pub fn window_for(dims: [usize; 3], max_slices: Option<usize>) -> usize {
    let plane = PlaneMask::empty(dims[0], dims[1]).bits.len() * 8;
    let w = match max_slices {
        Some(0) => dims[2],
        Some(n) => n,
        None => DEFAULT_WINDOW_BYTES / plane.max(1),
    };
    w.max(MIN_WINDOW).min(dims[2].max(1))
}

impl MaskVolume {
    /// An all-outside volume, in memory.
    pub fn new(dims: [usize; 3], frame: Frame) -> MaskVolume {
        MaskVolume {
            dims,
            planes: (0..dims[2])
                .map(|_| OnceLock::from(PlaneMask::empty(dims[0], dims[1])))
                .collect(),
            dirty: vec![false; dims[2]],
            store: None,
            window: dims[2],
            frame,
            empty: PlaneMask::empty(dims[0], dims[1]),
            fractions: None,
        }
    }

    /// An all-outside volume kept in a scratch file, none of its planes in memory yet.
    fn on_disk(dims: [usize; 3], frame: Frame, window: usize) -> Result<MaskVolume> {
        let empty = PlaneMask::empty(dims[0], dims[1]);
        Ok(MaskVolume {
            dims,
            planes: (0..dims[2]).map(|_| OnceLock::new()).collect(),
            dirty: vec![false; dims[2]],
            store: Some(PlaneStore::create(empty.bits.len() * 8, dims[2])?),
            window,
            frame,
            empty,
            fractions: None,
        })
    }

    /// Classifies a whole volume and arranges its planes for a sweep along `axis`. With
    /// `max_slices` (0: no limit) below the number of planes, or by default when the planes
    /// would take more than [`DEFAULT_WINDOW_BYTES`], the volume is kept out of core.
    pub fn from_reader(
        reader: &mut dyn SliceReader,
        opts: &SurfaceOptions,
        axis: Axis,
        max_slices: Option<usize>,
        progress: &dyn Progress,
    ) -> Result<MaskVolume> {
        MaskVolume::classify(reader, opts, axis, max_slices, false, progress)
    }

    /// [`MaskVolume::from_reader`], also recording where the surface crosses each grid edge
    /// (two bytes per crossing edge, and its key), for lengths in millimetres along the interpolated surface.
    pub fn from_reader_with_fractions(
        reader: &mut dyn SliceReader,
        opts: &SurfaceOptions,
        axis: Axis,
        max_slices: Option<usize>,
        progress: &dyn Progress,
    ) -> Result<MaskVolume> {
        MaskVolume::classify(reader, opts, axis, max_slices, true, progress)
    }

    fn classify(
        reader: &mut dyn SliceReader,
        opts: &SurfaceOptions,
        axis: Axis,
        max_slices: Option<usize>,
        with_fractions: bool,
        progress: &dyn Progress,
    ) -> Result<MaskVolume> {
        let info = reader.info().clone();
        let [nx, ny, nz] = info.dims;
        let classifier = opts.classifier(&info);
        let uvw = axis.uvw();
        let dims = [info.dims[uvw[0]], info.dims[uvw[1]], info.dims[uvw[2]]];
        let window = window_for(dims, max_slices);
        let out_of_core = window < dims[2];
        let plane_bytes = PlaneMask::empty(dims[0], dims[1]).bits.len() as u64 * 8;
        crate::memory::reserve(
            &format!(
                "{window} planes of {}×{} inside bits (the planes kept in memory; fewer with --max-slices)",
                dims[0], dims[1]
            ),
            plane_bytes * window as u64,
        )?;
        let mut vol = if out_of_core {
            MaskVolume::on_disk(dims, Frame::for_axis(axis), window)?
        } else {
            MaskVolume::new(dims, Frame::for_axis(axis))
        };
        let mut slice = Samples::new(info.dtype);
        let mut plane = PlaneMask::empty(nx, ny);
        let mut fractions = with_fractions.then(|| crate::grid::EdgeFractions::new(info.dims));
        let mut below: Option<(Samples, PlaneMask)> = None;
        // Out of core along x or y: each input slice gives a line to every plane; gather a
        // chunk of them (within the default budget) and update each plane once per chunk.
        let chunk = (DEFAULT_WINDOW_BYTES / (plane.bits.len() * 8).max(1)).max(MIN_WINDOW);
        let mut pending: Vec<PlaneMask> = Vec::new();
        progress.start("classify", nz as u64);
        for z in 0..nz {
            reader.read_slice(&mut slice)?;
            plane.fill(&slice, &classifier);
            if let Some(f) = &mut fractions {
                f.add_plane(
                    z,
                    &slice,
                    &plane,
                    below.as_ref().map(|(s, m)| (s, m)),
                    &classifier,
                );
                below = Some((slice.clone(), plane.clone()));
            }
            if axis == Axis::Z {
                match &vol.store {
                    Some(store) => store.write(z, 0, &plane.bits)?,
                    None => vol.planes[z] = OnceLock::from(plane.clone()),
                }
            } else if out_of_core {
                pending.push(plane.clone());
                if pending.len() == chunk || z + 1 == nz {
                    vol.write_chunk(&pending, z + 1 - pending.len(), uvw)?;
                    pending.clear();
                }
            } else {
                for y in 0..ny {
                    for x in 0..nx {
                        if plane.get(x as isize, y as isize) {
                            let p = [x, y, z];
                            vol.set(p[uvw[0]], p[uvw[1]], p[uvw[2]], true);
                        }
                    }
                }
            }
            progress.advance(1);
            crate::progress::between_steps(progress, "classification of the samples")?;
        }
        progress.finish();
        vol.fractions = fractions;
        Ok(vol)
    }

    /// Out of core, sweeping along x or y: input planes `z0 ..` each give one line of samples to
    /// every sweep plane (a row along x, a column along y); reads each plane, sets them, writes
    /// it back.
    fn write_chunk(&mut self, inputs: &[PlaneMask], z0: usize, uvw: [usize; 3]) -> Result<()> {
        let nw = self.dims[2];
        // The input axis (x or y) that runs along each line.
        let free = if uvw[2] == 0 { 1 } else { 0 };
        let mut plane = self.empty.clone();
        let store = self.store.as_ref().expect("out of core");
        for w in 0..nw {
            store.read(w, &mut plane);
            for (k, input) in inputs.iter().enumerate() {
                let n = if free == 0 { input.nx } else { input.ny };
                for t in 0..n {
                    let mut p = [0usize; 3];
                    p[uvw[2]] = w;
                    p[free] = t;
                    p[2] = z0 + k;
                    if input.get(p[0] as isize, p[1] as isize) {
                        plane.set(p[uvw[0]], p[uvw[1]], true);
                    }
                }
            }
            store.write(w, 0, &plane.bits)?;
        }
        Ok(())
    }

    /// Plane `w`, with the all-outside padding planes at -1 and `dims[2]` (read back from the
    /// scratch file if it is out of memory).
    #[inline]
    pub fn plane(&self, w: i64) -> &PlaneMask {
        if w < 0 || w >= self.dims[2] as i64 {
            return &self.empty;
        }
        self.planes[w as usize].get_or_init(|| self.load(w as usize))
    }

    #[cold]
    fn load(&self, w: usize) -> PlaneMask {
        let mut p = self.empty.clone();
        if let Some(store) = &self.store {
            store.read(w, &mut p);
        }
        p
    }

    /// Plane `w` without keeping it in memory: for passes over every plane.
    pub fn plane_once(&self, w: i64) -> Cow<'_, PlaneMask> {
        if w < 0 || w >= self.dims[2] as i64 {
            return Cow::Borrowed(&self.empty);
        }
        match self.planes[w as usize].get() {
            Some(p) => Cow::Borrowed(p),
            None => Cow::Owned(self.load(w as usize)),
        }
    }

    /// Whether the sample `q` (local u, v, w) is in the volume, not in the padding round it.
    #[inline]
    pub fn contains(&self, q: [i64; 3]) -> bool {
        (0..3).all(|k| q[k] >= 0 && q[k] < self.dims[k] as i64)
    }

    #[inline]
    /// Whether the sample at local (u, v, w) is inside; outside the volume (the padding), false.
    pub fn get(&self, u: i64, v: i64, w: i64) -> bool {
        self.plane(w).get(u as isize, v as isize)
    }

    /// The 3 × 3 × 3 samples round `q`, which must lie in the volume, as bits: bit
    /// `9 (dz + 1) + 3 (dy + 1) + dx + 1` for the sample at `q + (dx, dy, dz)` (nine row reads
    /// where 27 `get`s each found their plane and word).
    pub fn block(&self, q: [i64; 3]) -> u32 {
        debug_assert!(self.contains(q));
        let mut bits = 0u32;
        for dz in 0..3 {
            let plane = self.plane(q[2] + dz - 1);
            for dy in 0..3 {
                // Padded row q.y + dy, padded columns q.x ..= q.x + 2 (samples x - 1 ..= x + 1).
                let row = plane.row((q[1] + dy) as usize);
                let (i, s) = (q[0] as usize / 64, q[0] as usize % 64);
                let mut three = row[i] >> s;
                if s > 61 {
                    three |= row[i + 1] << (64 - s);
                }
                bits |= ((three & 7) as u32) << (9 * dz + 3 * dy);
            }
        }
        bits
    }

    #[inline]
    /// Sets the sample at local (u, v, w) inside or outside.
    pub fn set(&mut self, u: usize, v: usize, w: usize, inside: bool) {
        self.plane(w as i64);
        self.dirty[w] = self.store.is_some();
        self.planes[w]
            .get_mut()
            .expect("loaded above")
            .set(u, v, inside)
    }

    /// Planes the window holds (all of them in memory).
    pub fn window(&self) -> usize {
        self.window
    }

    /// Is the volume out of core?
    pub fn out_of_core(&self) -> bool {
        self.store.is_some()
    }

    /// Planes in memory now.
    pub fn planes_in_memory(&self) -> usize {
        self.planes.iter().filter(|p| p.get().is_some()).count()
    }

    /// Out of core: lets go of every plane outside `lo ..= hi` (writing edited ones back).
    pub fn keep_window(&mut self, lo: i64, hi: i64) -> Result<()> {
        let Some(store) = &self.store else {
            return Ok(());
        };
        for w in 0..self.dims[2] {
            if (lo..=hi).contains(&(w as i64)) {
                continue;
            }
            if self.dirty[w] {
                if let Some(p) = self.planes[w].get() {
                    store.write(w, 0, &p.bits)?;
                }
                self.dirty[w] = false;
            }
            self.planes[w].take();
        }
        Ok(())
    }

    /// Out of core, with the sweep about to process slice `next` (planes `next` and `next + 1`):
    /// keeps the window of planes just below it, lets go of the rest.
    pub fn follow_sweep(&mut self, next: i64) -> Result<()> {
        let hi = next + 1;
        self.keep_window(hi + 1 - self.window as i64, hi)
    }

    /// Number of inside samples.
    pub fn count(&self) -> u64 {
        (0..self.dims[2] as i64)
            .map(|w| self.plane_once(w).count())
            .sum()
    }
}

impl MaskVolume {
    /// Betti numbers of the solid and genus of its surfaces (the genus pass run on the bits,
    /// without areas).
    pub fn genus(&self, conn: Connectivity) -> Result<GenusReport> {
        use crate::topology::genus::SurfaceTracker;
        use crate::topology::slice::SliceSurfels;
        let mut tracker = SurfaceTracker::default();
        let mut prev: Option<(SliceSurfels, u32)> = None;
        for s in -1..self.dims[2] as i64 {
            let cur =
                SliceSurfels::build(&self.plane_once(s), &self.plane_once(s + 1), s as i32, conn);
            let base = tracker.add_slice(&cur, &[], prev.as_ref().map(|(p, b)| (p, *b)), conn)?;
            prev = Some((cur, base));
        }
        tracker.report(
            self.dims,
            &crate::volume::Affine::from_spacing([1.0; 3], [0.0; 3]),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_box_goes_back_to_local_coordinates() {
        for axis in [Axis::X, Axis::Y, Axis::Z] {
            let mut frame = Frame::for_axis(axis);
            frame.offset = [3, -2, 7];
            let (p, q) = ([1, 5, -1], [4, 2, 9]);
            let mut b = crate::volume::BBox::EMPTY;
            b.include(frame.to_original_i(p));
            b.include(frame.to_original_i(q));
            assert_eq!(frame.to_local_box(&b), ([1, 2, -1], [4, 5, 9]), "{axis:?}");
        }
    }

    /// The volume holds its samples from 0 to its extent less one on each axis; a sample one
    /// beyond any face is padding.
    #[test]
    fn a_volume_contains_its_samples_and_not_the_padding() {
        let vol = MaskVolume::new([3, 4, 5], Frame::identity());
        for k in 0..3 {
            let n = vol.dims[k] as i64;
            for (at, held) in [(-1, false), (0, true), (n - 1, true), (n, false)] {
                let mut q = [1, 1, 1];
                q[k] = at;
                assert_eq!(vol.contains(q), held, "{q:?}");
            }
        }
    }
}
