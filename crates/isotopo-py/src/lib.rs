//! `isotopo._native`: the library's entry points for numpy arrays and files.
//!
//! The public API is the Python package (`python/isotopo/__init__.py`): it checks arguments,
//! converts the types isotopo does not store (bool, int64, non-native byte order), draws the
//! progress bar and wraps the reports. Each function here takes a volume, a dict of options
//! and a progress callable, runs one library job with the GIL released, and returns the
//! job's JSON report as a string (the command line's, same keys).

mod array;
mod progress;

use std::path::PathBuf;

use numpy::ndarray::{Array3, ShapeBuilder};
use numpy::IntoPyArray;
use pyo3::exceptions::{
    PyFileNotFoundError, PyKeyboardInterrupt, PyMemoryError, PyOSError, PyPermissionError,
    PyRuntimeError, PyValueError,
};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use isotopo::grid::Axis;
use isotopo::loops::Metric;
use isotopo::progress::Progress;
use isotopo::simplify::Mode;
use isotopo::topology::{Connectivity, Inside, SurfaceOptions};
use isotopo::volume::{Affine, FormatHeader, Samples, Scaling, VolumeInfo};
use isotopo::{AnalyzeOptions, SimplifyOptions, Source};

use array::{ArrayReader, ArrayView};
use progress::PyProgress;

/// Runs `job` with the GIL released, turning its error (and a panic) into a Python exception.
fn run<T: Send>(
    py: Python<'_>,
    progress: &PyProgress,
    job: impl FnOnce() -> isotopo::Result<T> + Send,
) -> PyResult<T> {
    let result = py.detach(|| {
        std::panic::catch_unwind(std::panic::AssertUnwindSafe(job)).unwrap_or_else(|p| {
            let what = p
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_default();
            Err(isotopo::Error::Internal(format!("panic: {what}")))
        })
    });
    result.map_err(|e| to_python(e, progress))
}

/// The exception for a library error: the command line's message, the type the issue of
/// Python users expects (`ValueError` for values, `OSError` for files).
fn to_python(e: isotopo::Error, progress: &PyProgress) -> PyErr {
    use isotopo::Error as E;
    let msg = e.to_string();
    match e {
        E::Cancelled => progress
            .take_error()
            .unwrap_or_else(|| PyKeyboardInterrupt::new_err("cancelled")),
        E::Usage(_) => PyValueError::new_err(msg),
        E::Input { ref path, .. } if path.as_os_str() == "<memory>" => PyValueError::new_err(msg),
        E::Input { .. } => PyOSError::new_err(msg),
        E::Io { ref source, .. } | E::Scratch { ref source, .. } => match source.kind() {
            std::io::ErrorKind::NotFound => PyFileNotFoundError::new_err(msg),
            std::io::ErrorKind::PermissionDenied => PyPermissionError::new_err(msg),
            _ => PyOSError::new_err(msg),
        },
        E::Memory { .. } => PyMemoryError::new_err(msg),
        E::Internal(_) => PyRuntimeError::new_err(format!(
            "internal error (a bug in isotopo; please report it with the volume): {msg}"
        )),
    }
}

/// One option from the dict the Python layer passes (every key is always present).
fn opt<'py, T: FromPyObjectOwned<'py>>(opts: &Bound<'py, PyDict>, key: &str) -> PyResult<T> {
    match opts.get_item(key)? {
        Some(v) => v.extract::<T>().map_err(|e| {
            let e: PyErr = e.into();
            PyValueError::new_err(format!("option {key}: {e}"))
        }),
        None => Err(PyValueError::new_err(format!("missing option {key}"))),
    }
}

fn surface(opts: &Bound<'_, PyDict>) -> PyResult<SurfaceOptions> {
    let inside = match opt::<String>(opts, "inside")?.as_str() {
        "above" => Inside::Above,
        "below" => Inside::Below,
        other => {
            return Err(PyValueError::new_err(format!(
                "inside must be \"above\" or \"below\", not {other:?}"
            )))
        }
    };
    let connectivity = match opt::<i64>(opts, "connectivity")? {
        6 => Connectivity::Six,
        26 => Connectivity::TwentySix,
        other => {
            return Err(PyValueError::new_err(format!(
                "connectivity must be 6 or 26, not {other}"
            )))
        }
    };
    Ok(SurfaceOptions {
        iso: opt(opts, "iso")?,
        inside,
        connectivity,
    })
}

fn axis(opts: &Bound<'_, PyDict>) -> PyResult<Axis> {
    match opt::<String>(opts, "axis")?.as_str() {
        "x" => Ok(Axis::X),
        "y" => Ok(Axis::Y),
        "z" => Ok(Axis::Z),
        other => Err(PyValueError::new_err(format!(
            "axis must be \"x\", \"y\" or \"z\", not {other:?}"
        ))),
    }
}

/// The grid of an array: its dims and type, unit spacing unless `spacing` (mm) is given.
fn array_info(view: &ArrayView, spacing: Option<[f64; 3]>) -> PyResult<VolumeInfo> {
    let mut info = VolumeInfo::synthetic(view.dims(), view.dtype());
    if let Some(s) = spacing {
        if s.iter().any(|x| !(x.is_finite() && *x > 0.0)) {
            return Err(PyValueError::new_err(format!(
                "voxel sizes must be positive, got spacing {s:?}"
            )));
        }
        let identity = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        info.affine = Affine::from_parts(identity, s, [0.0; 3]);
    }
    if view.dims().contains(&0) {
        return Err(PyValueError::new_err(format!(
            "the volume is empty: shape {:?}",
            view.dims()
        )));
    }
    Ok(info)
}

/// Runs `job` on `volume` (with the geometry of `opts`), reporting to `progress`, with the GIL
/// released.
fn run_job<T: Send>(
    py: Python<'_>,
    volume: &Bound<'_, PyAny>,
    opts: &Bound<'_, PyDict>,
    progress: Option<Py<PyAny>>,
    job: impl FnOnce(Source, &dyn Progress) -> isotopo::Result<T> + Send,
) -> PyResult<T> {
    let source = source(volume, opts)?;
    let progress = PyProgress::new(progress);
    let p = &progress;
    run(py, p, move || job(source, p))
}

/// The volume `array` as a source for one job, with the geometry of `opts`: `affine` (the
/// three top rows, from a loaded file) or else `spacing`.
fn source(array: &Bound<'_, PyAny>, opts: &Bound<'_, PyDict>) -> PyResult<Source> {
    let view = ArrayView::of(array)?;
    let mut info = array_info(&view, opt(opts, "spacing")?)?;
    if let Some(m) = opt::<Option<[[f64; 4]; 3]>>(opts, "affine")? {
        info.affine = Affine { m };
    }
    Ok(Source::Reader(Box::new(ArrayReader::new(view, info))))
}

/// Where the HTML report goes (`opts["html"]`, checked now, before the job), a second view of
/// the volume for its meshes, and its title (`opts["title"]`).
fn html_target(
    volume: &Bound<'_, PyAny>,
    opts: &Bound<'_, PyDict>,
) -> PyResult<Option<(PathBuf, Source, String)>> {
    let Some(path) = opt::<Option<PathBuf>>(opts, "html")? else {
        return Ok(None);
    };
    let second = source(volume, opts)?;
    let view = ArrayView::of(volume)?;
    let info = array_info(&view, None)?;
    isotopo::volume::check_output_path(&path, &info)
        .map_err(|e| to_python(e, &PyProgress::new(None)))?;
    let title = opt::<Option<String>>(opts, "title")?.unwrap_or_else(|| {
        let [x, y, z] = info.dims;
        format!("array {x} × {y} × {z}")
    });
    Ok(Some((path, second, title)))
}

/// b0, b1, b2, chi and the surfaces of the solid (the `genus --json` report).
#[pyfunction]
#[pyo3(signature = (volume, opts, progress=None))]
fn genus(
    py: Python<'_>,
    volume: &Bound<'_, PyAny>,
    opts: &Bound<'_, PyDict>,
    progress: Option<Py<PyAny>>,
) -> PyResult<String> {
    let surface = surface(opts)?;
    run_job(py, volume, opts, progress, |source, p| {
        let t = isotopo::genus(source, &surface, p)?;
        Ok(t.to_json(&surface).to_string())
    })
}

/// Every handle with its Reeb loop and cross loop (the `analyze --json` report).
#[pyfunction]
#[pyo3(signature = (volume, opts, progress=None))]
fn analyze(
    py: Python<'_>,
    volume: &Bound<'_, PyAny>,
    opts: &Bound<'_, PyDict>,
    progress: Option<Py<PyAny>>,
) -> PyResult<String> {
    let lengths = match opt::<String>(opts, "lengths")?.as_str() {
        "edges" => isotopo::jobs::Lengths::Edges,
        "mm" => isotopo::jobs::Lengths::Millimetres,
        "both" => isotopo::jobs::Lengths::Both,
        other => {
            return Err(PyValueError::new_err(format!(
                "lengths must be \"edges\", \"mm\" or \"both\", not {other:?}"
            )))
        }
    };
    let a = AnalyzeOptions {
        surface: surface(opts)?,
        axis: axis(opts)?,
        max_slices: opt(opts, "max_slices")?,
        tau: opt(opts, "tau")?,
        tau_mm: None,
        lengths,
    };
    // The HTML report reads the volume once more, through a second view of the array.
    let html = html_target(volume, opts)?;
    let third = match html {
        Some(_) => Some(source(volume, opts)?),
        None => None,
    };
    run_job(py, volume, opts, progress, |source, p| {
        // Streamed: the report's text is all that is held, not the handles it comes from.
        let mut done = isotopo::analyze_streamed(source, &a, p)?;
        if let (Some((path, second, title)), Some(third)) = (html, third) {
            let rows = isotopo::html::analysis_rows(&mut done)?;
            let topology = isotopo::genus(third, &a.surface, p)?;
            let mut report =
                isotopo::html::HtmlReport::analysis(&done, &a, rows).with_topology(&topology);
            report.title = title;
            let o = isotopo::html::HtmlOptions::default();
            isotopo::html::write_analysis(&path, &report, second, &a.surface, &o)?;
        }
        let mut text = Vec::new();
        done.write_json(&a, false, &mut text)?;
        String::from_utf8(text).map_err(|e| isotopo::Error::Internal(e.to_string()))
    })
}

/// Simplifies `volume` into `out` (the Python layer's fresh copy of it, same dims and type):
/// the `simplify --report` JSON.
#[pyfunction]
#[pyo3(signature = (volume, out, opts, progress=None))]
fn simplify(
    py: Python<'_>,
    volume: &Bound<'_, PyAny>,
    out: &Bound<'_, PyAny>,
    opts: &Bound<'_, PyDict>,
    progress: Option<Py<PyAny>>,
) -> PyResult<String> {
    let mode = match (opt(opts, "fill_only")?, opt(opts, "cut_only")?) {
        (false, false) => Mode::Both,
        (true, false) => Mode::FillOnly,
        (false, true) => Mode::CutOnly,
        (true, true) => {
            return Err(PyValueError::new_err(
                "fill_only and cut_only exclude each other: one, or neither (both closures)",
            ))
        }
    };
    let metric = match opt::<String>(opts, "metric")?.as_str() {
        "edges" => Metric::Edges,
        "mm" => Metric::Millimetres,
        other => {
            return Err(PyValueError::new_err(format!(
                "metric must be \"edges\" or \"mm\", not {other:?}"
            )))
        }
    };
    let s = SimplifyOptions {
        surface: surface(opts)?,
        axis: axis(opts)?,
        tau: opt(opts, "tau")?,
        metric,
        mode,
        max_ratio: opt(opts, "max_ratio")?,
        max_slices: opt(opts, "max_slices")?,
        well_composed: opt(opts, "well_composed")?,
        min_component: opt(opts, "min_component")?,
        largest: opt(opts, "largest")?,
        min_cavity: opt(opts, "min_cavity")?,
        fill_cavities: opt(opts, "fill_cavities")?,
        keep_handles: opt(opts, "keep_handles")?,
    };
    let target = ArrayView::of(out)?;
    let html = html_target(volume, opts)?;
    run_job(py, volume, opts, progress, |source, p| {
        let mut done = isotopo::simplify(source, &s, p)?;
        if let Some((path, _, title)) = html {
            let mut report = isotopo::html::HtmlReport::simplified(&done, &s);
            report.title = title;
            let o = isotopo::html::HtmlOptions::default();
            isotopo::html::write_simplified(&path, &report, &mut done, &s.surface, &o)?;
        }
        done.edit_with(
            |z, slice| {
                target.read(z, slice);
                Ok(())
            },
            |z, slice| {
                target.write(z, slice);
                Ok(())
            },
        )?;
        Ok(done.report(&s).to_string())
    })
}

/// A file's header: what `save(..., like=...)` writes back.
#[pyclass(frozen, module = "isotopo._native")]
struct Header {
    info: VolumeInfo,
}

#[pymethods]
impl Header {
    /// The file it was read from.
    #[getter]
    fn path(&self) -> PathBuf {
        self.info.path.clone()
    }
    /// The file's format (`nifti`, `nrrd`, `mgh`, `metaimage`, `npy`, `raw`, `tiff`).
    #[getter]
    fn format(&self) -> String {
        format!("{:?}", self.info.format).to_lowercase()
    }
    /// The stored sample type (`int16`, `float32`, …).
    #[getter]
    fn dtype(&self) -> &'static str {
        self.info.dtype.name()
    }
    /// Samples along x, y, z.
    #[getter]
    fn dims(&self) -> [usize; 3] {
        self.info.dims
    }
    /// Voxel index -> world millimetres (RAS+, as nibabel), a 4×4 matrix as rows.
    #[getter]
    fn affine(&self) -> [[f64; 4]; 4] {
        let m = self.info.affine.m;
        [m[0], m[1], m[2], [0.0, 0.0, 0.0, 1.0]]
    }
    /// Voxel size in millimetres along x, y, z.
    #[getter]
    fn spacing(&self) -> [f64; 3] {
        self.info.spacing()
    }
    /// `(slope, intercept)`: value = stored sample·slope + intercept.
    #[getter]
    fn scaling(&self) -> (f64, f64) {
        (self.info.scaling.slope, self.info.scaling.inter)
    }
    fn __repr__(&self) -> String {
        format!(
            "<isotopo header of {}: {} {}×{}×{} {}>",
            self.info.path.display(),
            self.format(),
            self.info.dims[0],
            self.info.dims[1],
            self.info.dims[2],
            self.info.dtype.name()
        )
    }
}

/// How to read a headerless raw file (and the spacing of NumPy and TIFF files, which carry
/// none): the dict `{dims, dtype, endian, offset, spacing}`, each key optional.
fn read_options(raw: Option<&Bound<'_, PyDict>>) -> PyResult<isotopo::volume::ReadOptions> {
    let mut r = isotopo::volume::ReadOptions::default();
    let Some(raw) = raw else { return Ok(r) };
    let get = |key: &str| raw.get_item(key).ok().flatten().filter(|v| !v.is_none());
    if let Some(v) = get("dims") {
        r.raw_dims = Some(v.extract()?);
    }
    if let Some(v) = get("dtype") {
        let name: String = v.extract()?;
        r.raw_type = Some(isotopo::volume::DType::parse(&name).ok_or_else(|| {
            PyValueError::new_err(format!("unknown raw sample type {name:?}; use uint8, int8, uint16, int16, uint32, int32, float32 or float64"))
        })?);
    }
    if let Some(v) = get("endian") {
        r.raw_endian = Some(match v.extract::<String>()?.as_str() {
            "little" => isotopo::volume::Endian::Little,
            "big" => isotopo::volume::Endian::Big,
            other => {
                return Err(PyValueError::new_err(format!(
                    "endian must be \"little\" or \"big\", not {other:?}"
                )))
            }
        });
    }
    if let Some(v) = get("offset") {
        r.raw_offset = v.extract()?;
    }
    if let Some(v) = get("spacing") {
        r.raw_spacing = Some(v.extract()?);
    }
    Ok(r)
}

/// Reads a volume file: `(array, header)`, the array indexed `[x, y, z]` in Fortran order, in
/// the stored type, or in values (float32, float64 for 32-bit samples) when the header scales.
#[pyfunction]
#[pyo3(signature = (path, raw=None))]
fn load(
    py: Python<'_>,
    path: PathBuf,
    raw: Option<&Bound<'_, PyDict>>,
) -> PyResult<(Py<PyAny>, Header)> {
    let read = read_options(raw)?;
    let progress = PyProgress::new(None);
    let p = &progress;
    let volume = run(py, p, move || {
        let mut reader = isotopo::volume::open(&path, &read)?;
        // The slices, then the array they are copied into.
        let nz = reader.info().nz();
        // Scaled values become float32 (float64 from 32-bit integers): up to 8 bytes a sample.
        let copy = match reader.info().scaling.is_identity() {
            true => 1,
            false => 8usize.div_ceil(reader.info().dtype.size()),
        };
        isotopo::volume::reserve_slices(reader.info(), (1 + copy) * nz, "loading into an array")?;
        let mut slices = Vec::with_capacity(nz);
        for _ in 0..reader.info().nz() {
            p.check()?;
            let mut s = Samples::new(reader.info().dtype);
            reader.read_slice(&mut s)?;
            slices.push(s);
        }
        Ok(isotopo::volume::InMemoryVolume::new(
            reader.info().clone(),
            slices,
        ))
    })?;
    let info = volume.info.clone();
    let array = to_numpy(py, volume)?;
    Ok((array, Header { info }))
}

/// The volume's samples as a Fortran-order numpy array (values when the header scales).
fn to_numpy(py: Python<'_>, volume: isotopo::volume::InMemoryVolume) -> PyResult<Py<PyAny>> {
    let dims = volume.info.dims;
    let shape = (dims[0], dims[1], dims[2]).f();
    let scaling = volume.info.scaling;
    let err = |e: numpy::ndarray::ShapeError| PyRuntimeError::new_err(e.to_string());
    if !scaling.is_identity() {
        let wide = matches!(
            volume.info.dtype,
            isotopo::volume::DType::U32 | isotopo::volume::DType::I32
        );
        let values = volume
            .slices
            .iter()
            .flat_map(|s| (0..s.len()).map(|i| scaling.apply(s.get_f64(i))));
        return Ok(if wide {
            let v: Vec<f64> = values.collect();
            Array3::from_shape_vec(shape, v)
                .map_err(err)?
                .into_pyarray(py)
                .into_any()
                .unbind()
        } else {
            let v: Vec<f32> = values.map(|x| x as f32).collect();
            Array3::from_shape_vec(shape, v)
                .map_err(err)?
                .into_pyarray(py)
                .into_any()
                .unbind()
        });
    }
    macro_rules! stored {
        ($($variant:ident),*) => {
            match volume.info.dtype {
                $(isotopo::volume::DType::$variant => {
                    let v: Vec<_> = volume.slices.into_iter().flat_map(|s| match s {
                        Samples::$variant(v) => v,
                        _ => Vec::new(),
                    }).collect();
                    Array3::from_shape_vec(shape, v).map_err(err)?.into_pyarray(py).into_any().unbind()
                })*
            }
        };
    }
    Ok(stored!(U8, I8, U16, I16, U32, I32, F32, F64))
}

/// Writes `array` to `path` (format from the extension), atomically, never over the file
/// `like` was read from. With `like` and the same grid, type and no scaling, its header is
/// kept byte for byte; otherwise its geometry (affine) is. `affine` replaces the geometry.
#[pyfunction]
#[pyo3(signature = (path, array, like=None, affine=None))]
fn save(
    py: Python<'_>,
    path: PathBuf,
    array: &Bound<'_, PyAny>,
    like: Option<&Bound<'_, Header>>,
    affine: Option<[[f64; 4]; 4]>,
) -> PyResult<()> {
    let view = ArrayView::of(array)?;
    let mut info = match like {
        Some(h) => h.get().info.clone(),
        None => array_info(&view, None)?,
    };
    // A refused path (over the input or its data file, or in no directory) is a file error.
    isotopo::volume::check_output_path(&path, &info)
        .map_err(|e| PyOSError::new_err(e.to_string()))?;
    let same = info.dims == view.dims() && info.dtype == view.dtype();
    if !(same && info.scaling.is_identity()) {
        info.header = FormatHeader::None;
        info.dims = view.dims();
        info.dtype = view.dtype();
        info.scaling = Scaling::IDENTITY;
    }
    if let Some(a) = affine {
        if a[3] != [0.0, 0.0, 0.0, 1.0] || a.iter().flatten().any(|x| !x.is_finite()) {
            return Err(PyValueError::new_err(
                "affine must be a finite 4×4 matrix whose last row is 0, 0, 0, 1",
            ));
        }
        info.affine = Affine {
            m: [a[0], a[1], a[2]],
        };
        info.header = FormatHeader::None;
    }
    let progress = &PyProgress::new(None);
    run(py, progress, move || {
        let mut reader = ArrayReader::new(view, info);
        isotopo::volume::convert(&mut reader, &path, progress)
    })
}

/// Panics inside a job, as a bug in the library would: the tests check that it arrives as a
/// `RuntimeError`, not as an abort of the interpreter.
#[pyfunction]
fn _panic_for_tests(py: Python<'_>) -> PyResult<()> {
    let progress = PyProgress::new(None);
    run(py, &progress, || -> isotopo::Result<()> {
        panic!("a deliberate panic")
    })
}

/// Sets the process's memory limit (see `isotopo::memory`): bytes, a size as the command line
/// takes it ("2G", "50%"), or None for the default.
#[pyfunction]
#[pyo3(signature = (limit=None))]
fn set_memory_limit(limit: Option<&Bound<'_, PyAny>>) -> PyResult<()> {
    let bytes = match limit {
        None => None,
        Some(v) if v.is_none() => None,
        Some(v) => Some(match v.extract::<String>() {
            Ok(text) => isotopo::memory::parse_size(&text).map_err(PyValueError::new_err)?,
            Err(_) => match v.extract::<u64>() {
                Ok(n) if n > 0 => n,
                _ => {
                    return Err(PyValueError::new_err(format!(
                        "the memory limit must be a positive number of bytes, a size such as \"2G\" or \"50%\", or None; got {v}"
                    )))
                }
            },
        }),
    };
    isotopo::memory::set_limit(bytes);
    Ok(())
}

/// The memory limit in force, in bytes.
#[pyfunction]
fn memory_limit() -> u64 {
    isotopo::memory::limit()
}

/// The native half of the `isotopo` package.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_class::<Header>()?;
    m.add_function(wrap_pyfunction!(genus, m)?)?;
    m.add_function(wrap_pyfunction!(analyze, m)?)?;
    m.add_function(wrap_pyfunction!(simplify, m)?)?;
    m.add_function(wrap_pyfunction!(load, m)?)?;
    m.add_function(wrap_pyfunction!(save, m)?)?;
    m.add_function(wrap_pyfunction!(set_memory_limit, m)?)?;
    m.add_function(wrap_pyfunction!(memory_limit, m)?)?;
    m.add_function(wrap_pyfunction!(_panic_for_tests, m)?)?;
    Ok(())
}
