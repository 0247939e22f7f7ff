//! A volume held in memory: a slice source whose window is the whole volume. Used for small
//! volumes, synthetic shapes in tests, and mini-volumes built by the sweep.

use super::{DType, Samples, SliceReader, VolumeInfo};
use crate::error::{Error, Result};

/// A whole volume in memory, one [`Samples`] buffer per z-slice; as a [`SliceReader`] it hands
/// out copies of its slices in order.
#[derive(Clone, Debug)]
pub struct InMemoryVolume {
    /// Description of the volume: dims, sample type, geometry, scaling, source file.
    pub info: VolumeInfo,
    /// One entry per z-slice, `nx·ny` samples each, `x` fastest.
    pub slices: Vec<Samples>,
    position: usize,
}

impl InMemoryVolume {
    /// A volume from its description and its `nz` slices (`nx·ny` samples each, of type
    /// `info.dtype`), positioned at slice 0.
    pub fn new(info: VolumeInfo, slices: Vec<Samples>) -> InMemoryVolume {
        debug_assert_eq!(slices.len(), info.nz());
        InMemoryVolume {
            info,
            slices,
            position: 0,
        }
    }

    /// A float32 volume with samples `f(x, y, z)` (synthetic shapes).
    pub fn from_fn(dims: [usize; 3], f: impl Fn(usize, usize, usize) -> f32) -> InMemoryVolume {
        let [nx, ny, nz] = dims;
        let slices = (0..nz)
            .map(|z| {
                let mut v = Vec::with_capacity(nx * ny);
                for y in 0..ny {
                    for x in 0..nx {
                        v.push(f(x, y, z));
                    }
                }
                Samples::F32(v)
            })
            .collect();
        InMemoryVolume::new(VolumeInfo::synthetic(dims, DType::F32), slices)
    }

    /// A uint8 volume: 1 where `inside(x, y, z)`, else 0 (use isovalue 0.5).
    pub fn from_mask(
        dims: [usize; 3],
        inside: impl Fn(usize, usize, usize) -> bool,
    ) -> InMemoryVolume {
        let [nx, ny, nz] = dims;
        let slices = (0..nz)
            .map(|z| {
                let mut v = Vec::with_capacity(nx * ny);
                for y in 0..ny {
                    for x in 0..nx {
                        v.push(inside(x, y, z) as u8);
                    }
                }
                Samples::U8(v)
            })
            .collect();
        InMemoryVolume::new(VolumeInfo::synthetic(dims, DType::U8), slices)
    }

    /// Reads every slice of `reader`.
    pub fn from_reader(reader: &mut dyn SliceReader) -> Result<InMemoryVolume> {
        let nz = reader.info().nz();
        super::reserve_slices(reader.info(), nz, "the whole volume in memory")?;
        let mut slices = Vec::with_capacity(nz);
        for _ in 0..nz {
            let mut s = Samples::new(reader.info().dtype);
            reader.read_slice(&mut s)?;
            slices.push(s);
        }
        Ok(InMemoryVolume::new(reader.info().clone(), slices))
    }

    /// Samples along x, y, z (`info.dims`).
    pub fn dims(&self) -> [usize; 3] {
        self.info.dims
    }

    /// Raw sample at `(x, y, z)`.
    pub fn get(&self, x: usize, y: usize, z: usize) -> f64 {
        self.slices[z].get_f64(y * self.info.dims[0] + x)
    }

    /// Sets the raw sample at `(x, y, z)` to `v`, which must be representable in the volume's
    /// type (it is cast, not checked).
    pub fn set(&mut self, x: usize, y: usize, z: usize, v: f64) {
        let nx = self.info.dims[0];
        self.slices[z].set_f64(y * nx + x, v)
    }
}

impl SliceReader for InMemoryVolume {
    fn info(&self) -> &VolumeInfo {
        &self.info
    }

    fn read_slice(&mut self, out: &mut Samples) -> Result<()> {
        let s = self.slices.get(self.position).ok_or_else(|| {
            Error::Internal("read past the last slice of an in-memory volume".into())
        })?;
        out.clone_from(s);
        self.position += 1;
        Ok(())
    }

    fn position(&self) -> usize {
        self.position
    }

    fn rewind(&mut self) -> Result<()> {
        self.position = 0;
        Ok(())
    }
}
