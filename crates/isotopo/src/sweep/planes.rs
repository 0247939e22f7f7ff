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

use crate::error::Result;
use crate::progress::Progress;
use crate::topology::cases::Connectivity;
use crate::topology::genus::GenusReport;
use crate::topology::{PlaneMask, SurfaceOptions};
use crate::volume::{Samples, SliceReader};

/// The sweep direction.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Axis {
    X,
    Y,
    Z,
}

impl Axis {
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
    pub uvw: [usize; 3],
    pub offset: [i64; 3],
}

impl Frame {
    pub fn identity() -> Frame {
        Frame {
            uvw: [0, 1, 2],
            offset: [0; 3],
        }
    }

    pub fn for_axis(axis: Axis) -> Frame {
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
#[derive(Clone, Debug)]
pub struct MaskVolume {
    /// Extent along (u, v, w).
    pub dims: [usize; 3],
    pub planes: Vec<PlaneMask>,
    /// Where these coordinates sit in the original volume.
    pub frame: Frame,
    empty: PlaneMask,
}

impl MaskVolume {
    /// An all-outside volume.
    pub fn new(dims: [usize; 3], frame: Frame) -> MaskVolume {
        MaskVolume {
            dims,
            planes: (0..dims[2])
                .map(|_| PlaneMask::empty(dims[0], dims[1]))
                .collect(),
            frame,
            empty: PlaneMask::empty(dims[0], dims[1]),
        }
    }

    /// Classifies a whole volume and arranges its planes for a sweep along `axis`.
    pub fn from_reader(
        reader: &mut dyn SliceReader,
        opts: &SurfaceOptions,
        axis: Axis,
        progress: &dyn Progress,
    ) -> Result<MaskVolume> {
        let info = reader.info().clone();
        let [nx, ny, nz] = info.dims;
        let classifier = opts.classifier(&info);
        let uvw = axis.uvw();
        let dims = [info.dims[uvw[0]], info.dims[uvw[1]], info.dims[uvw[2]]];
        let mut vol = MaskVolume::new(dims, Frame::for_axis(axis));
        let mut slice = Samples::new(info.dtype);
        let mut plane = PlaneMask::empty(nx, ny);
        progress.start("classify", nz as u64);
        for z in 0..nz {
            reader.read_slice(&mut slice)?;
            plane.fill(&slice, &classifier);
            if axis == Axis::Z {
                vol.planes[z] = plane.clone();
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
        }
        progress.finish();
        Ok(vol)
    }

    /// Plane `w`, with the all-outside padding planes at -1 and `dims[2]`.
    #[inline]
    pub fn plane(&self, w: i64) -> &PlaneMask {
        if w < 0 || w >= self.dims[2] as i64 {
            &self.empty
        } else {
            &self.planes[w as usize]
        }
    }

    #[inline]
    pub fn get(&self, u: i64, v: i64, w: i64) -> bool {
        self.plane(w).get(u as isize, v as isize)
    }

    #[inline]
    pub fn set(&mut self, u: usize, v: usize, w: usize, inside: bool) {
        self.planes[w].set(u, v, inside)
    }

    /// Number of inside samples.
    pub fn count(&self) -> u64 {
        self.planes.iter().map(|p| p.count()).sum()
    }

    /// A copy rotated so that the sweep runs along this volume's u axis: (u', v', w') = (v, w, u).
    pub fn rotated(&self) -> MaskVolume {
        let [nu, nv, nw] = self.dims;
        let mut out = MaskVolume::new([nv, nw, nu], self.frame.rotated([0, 0, 0]));
        for w in 0..nw {
            let p = &self.planes[w];
            for v in 0..nv {
                for u in 0..nu {
                    if p.get(u as isize, v as isize) {
                        out.planes[u].set(v, w, true);
                    }
                }
            }
        }
        out
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
            let cur = SliceSurfels::build(self.plane(s), self.plane(s + 1), s as i32, conn);
            let base = tracker.add_slice(&cur, &[], prev.as_ref().map(|(p, b)| (p, *b)), conn)?;
            prev = Some((cur, base));
        }
        tracker.report(
            self.dims,
            &crate::volume::Affine::from_spacing([1.0; 3], [0.0; 3]),
        )
    }
}
