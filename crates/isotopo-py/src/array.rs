//! numpy arrays as isotopo volumes, without copying them whole.
//!
//! A numpy array indexed `[x, y, z]` (nibabel's order) is read z-slice by z-slice, the way the
//! library streams files, whatever its memory order: C order, Fortran order or a strided view.
//!
//! ```text
//!   byte offset of [x, y, z] = x·strides[0] + y·strides[1] + z·strides[2]
//!   z-slice z = the nx·ny samples [.., .., z], x fastest (a contiguous run in Fortran order)
//! ```

use numpy::{PyArrayDescrMethods, PyUntypedArray, PyUntypedArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;

use isotopo::volume::{DType, Sample, Samples, SliceReader, VolumeInfo};
use isotopo::with_samples;

/// A view of a 3-D numpy array's samples: pointer, strides, dims and type. It does not own the
/// array: the caller keeps the array alive (and unchanged) for as long as the view is used.
#[derive(Clone, Copy)]
pub struct ArrayView {
    data: *mut u8,
    strides: [isize; 3],
    dims: [usize; 3],
    dtype: DType,
}

// SAFETY: the view only carries the address of samples owned by a numpy array that the calling
// Python function holds a reference to for the whole call, GIL released or not.
unsafe impl Send for ArrayView {}
unsafe impl Sync for ArrayView {}

/// The numpy type names isotopo reads (bool arrays are viewed as uint8 by the Python layer).
const TYPES: &str = "bool, uint8, int8, uint16, int16, uint32, int32, float32 or float64";

impl ArrayView {
    /// Views `array`, which must be a 3-D numpy array of a supported type in native byte order.
    pub fn of(array: &Bound<'_, PyAny>) -> PyResult<ArrayView> {
        let py = array.py();
        let a = array.cast::<PyUntypedArray>().map_err(|_| {
            PyTypeError::new_err(format!(
                "expected a numpy array, got {}",
                array
                    .get_type()
                    .name()
                    .map(|n| n.to_string())
                    .unwrap_or_default()
            ))
        })?;
        if a.ndim() != 3 {
            return Err(PyValueError::new_err(format!(
                "expected a 3-D volume indexed [x, y, z], got an array of shape {:?}",
                a.shape()
            )));
        }
        let dt = a.dtype();
        let dtype = [
            (numpy::dtype::<u8>(py), DType::U8),
            (numpy::dtype::<i8>(py), DType::I8),
            (numpy::dtype::<u16>(py), DType::U16),
            (numpy::dtype::<i16>(py), DType::I16),
            (numpy::dtype::<u32>(py), DType::U32),
            (numpy::dtype::<i32>(py), DType::I32),
            (numpy::dtype::<f32>(py), DType::F32),
            (numpy::dtype::<f64>(py), DType::F64),
        ]
        .into_iter()
        .find(|(d, _)| d.is_equiv_to(&dt))
        .map(|(_, t)| t)
        .ok_or_else(|| {
            PyTypeError::new_err(format!(
                "unsupported sample type {dt}; isotopo reads {TYPES} (in native byte order)"
            ))
        })?;
        let shape = a.shape();
        let strides = a.strides();
        Ok(ArrayView {
            // SAFETY: a valid numpy array object; only its data pointer is read.
            data: unsafe { (*a.as_array_ptr()).fields.data as *mut u8 },
            strides: [strides[0], strides[1], strides[2]],
            dims: [shape[0], shape[1], shape[2]],
            dtype,
        })
    }

    /// Samples along x, y, z.
    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }

    /// The sample type.
    pub fn dtype(&self) -> DType {
        self.dtype
    }

    /// Byte address of sample `[0, y, z]`.
    fn row(&self, y: usize, z: usize) -> *mut u8 {
        let offset = y as isize * self.strides[1] + z as isize * self.strides[2];
        self.data.wrapping_offset(offset)
    }

    /// Copies z-slice `z` into `out` (x fastest), replacing its content.
    pub fn read(&self, z: usize, out: &mut Samples) {
        if out.dtype() != self.dtype {
            *out = Samples::new(self.dtype);
        }
        with_samples!(out, v => self.gather(z, v))
    }

    fn gather<T: Sample>(&self, z: usize, out: &mut Vec<T>) {
        let [nx, ny, _] = self.dims;
        out.clear();
        out.reserve(nx * ny);
        for y in 0..ny {
            let row = self.row(y, z);
            if let Some(run) = self.contiguous::<T>(row) {
                // SAFETY: the row's nx samples are adjacent and aligned (checked), inside the array.
                out.extend_from_slice(unsafe { std::slice::from_raw_parts(run, nx) });
                continue;
            }
            for x in 0..nx {
                let p = row.wrapping_offset(x as isize * self.strides[0]) as *const T;
                // SAFETY: [x, y, z] is inside the array (x < nx, y < ny, z < nz), numpy
                // strides address it; read_unaligned since numpy allows unaligned arrays.
                out.push(unsafe { p.read_unaligned() });
            }
        }
    }

    /// The row starting at `row` as an aligned run of adjacent samples (x fastest in memory,
    /// Fortran order), which copies as one block; `None` otherwise.
    fn contiguous<T: Sample>(&self, row: *mut u8) -> Option<*const T> {
        let adjacent = self.strides[0] == std::mem::size_of::<T>() as isize;
        let aligned = (row as usize).is_multiple_of(std::mem::align_of::<T>());
        (adjacent && aligned).then_some(row as *const T)
    }

    /// Writes `slice` (x fastest) to z-slice `z`. Only for arrays the caller made writable and
    /// owns (the Python layer's fresh output array).
    pub fn write(&self, z: usize, slice: &Samples) {
        with_samples!(slice, v => self.scatter(z, v))
    }

    fn scatter<T: Sample>(&self, z: usize, samples: &[T]) {
        let [nx, ny, _] = self.dims;
        for y in 0..ny {
            let row = self.row(y, z);
            let samples = &samples[y * nx..(y + 1) * nx];
            if let Some(run) = self.contiguous::<T>(row) {
                // SAFETY: as in `gather`; the array is the caller's own writable copy.
                unsafe { std::slice::from_raw_parts_mut(run as *mut T, nx) }
                    .copy_from_slice(samples);
                continue;
            }
            for (x, &v) in samples.iter().enumerate() {
                let p = row.wrapping_offset(x as isize * self.strides[0]) as *mut T;
                // SAFETY: as in `gather`; the array is the caller's own writable copy.
                unsafe { p.write_unaligned(v) };
            }
        }
    }
}

/// An array streamed to the library as a volume.
pub struct ArrayReader {
    view: ArrayView,
    info: VolumeInfo,
    position: usize,
}

impl ArrayReader {
    /// Reads `view` as a volume described by `info` (dims and type must be the view's).
    pub fn new(view: ArrayView, info: VolumeInfo) -> ArrayReader {
        ArrayReader {
            view,
            info,
            position: 0,
        }
    }
}

impl SliceReader for ArrayReader {
    fn info(&self) -> &VolumeInfo {
        &self.info
    }

    fn read_slice(&mut self, out: &mut Samples) -> isotopo::Result<()> {
        if self.position >= self.view.dims[2] {
            return Err(isotopo::Error::Internal(
                "read past the last slice of a numpy array".into(),
            ));
        }
        self.view.read(self.position, out);
        self.position += 1;
        Ok(())
    }

    fn position(&self) -> usize {
        self.position
    }

    fn rewind(&mut self) -> isotopo::Result<()> {
        self.position = 0;
        Ok(())
    }
}
