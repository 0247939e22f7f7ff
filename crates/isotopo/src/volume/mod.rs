//! Volumes on disk: the model (dims, type, geometry, the format's own header), readers that stream
//! z-slices in order, and writers that stream them back out atomically.
//!
//! Every format is read the same way: [`open`] parses and checks the header, then
//! [`SliceReader::read_slice`] hands out one z-slice at a time (`nx·ny` samples, `x` fastest).
//! Compressed data is decompressed as a stream, so memory holds one slice, not the volume.
//!
//! ```no_run
//! use isotopo::volume::{open, ReadOptions, Samples};
//! let mut reader = open("head.nii.gz".as_ref(), &ReadOptions::default())?;
//! let [nx, ny, nz] = reader.info().dims;
//! let mut slice = Samples::new(reader.info().dtype);
//! for _z in 0..nz {
//!     reader.read_slice(&mut slice)?;
//!     assert_eq!(slice.len(), nx * ny);
//! }
//! # Ok::<(), isotopo::Error>(())
//! ```

mod dtype;
pub mod geometry;
pub mod memory;
mod metaimage;
mod mgh;
mod nifti;
mod npy;
mod nrrd;
mod raw;
pub mod stats;
mod stream;
mod tiff;

pub(crate) use dtype::with_dtype;
pub use dtype::{DType, Endian, Sample, Samples, Threshold};
pub use geometry::{Affine, BBox};
pub use memory::InMemoryVolume;
pub use stream::{check_output_path, AtomicOutput};

use crate::error::{Error, Result};
use std::path::{Path, PathBuf};

/// The file formats isotopo knows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// NIfTI-1 or NIfTI-2, `.nii` or `.nii.gz`.
    Nifti,
    /// NRRD, attached (`.nrrd`) or detached (`.nhdr` + data file).
    Nrrd,
    /// FreeSurfer MGH (`.mgh`) or gzipped MGZ (`.mgz`).
    Mgh,
    /// MetaImage, attached (`.mha`) or detached (`.mhd` + data file).
    MetaImage,
    /// NumPy `.npy`, indexed `[x, y, z]`.
    Npy,
    /// Headerless samples, described by `--raw-dims`, `--raw-type`, …
    Raw,
    /// Multi-page TIFF, one page per z-slice.
    Tiff,
}

impl Format {
    /// The format's usual name, for messages and reports (`NIfTI`, `NRRD`, `MGH`, …).
    pub fn name(self) -> &'static str {
        match self {
            Format::Nifti => "NIfTI",
            Format::Nrrd => "NRRD",
            Format::Mgh => "MGH",
            Format::MetaImage => "MetaImage",
            Format::Npy => "NumPy",
            Format::Raw => "raw",
            Format::Tiff => "TIFF",
        }
    }

    /// The format an output path asks for, from its extension.
    pub fn from_path(path: &Path) -> Option<(Format, Compression)> {
        let name = path.file_name()?.to_string_lossy().to_ascii_lowercase();
        let (stem, gz) = match name.strip_suffix(".gz") {
            Some(s) => (s.to_string(), true),
            None => (name.clone(), false),
        };
        let comp = if gz {
            Compression::Gzip
        } else {
            Compression::None
        };
        let ext = stem.rsplit('.').next().unwrap_or("");
        if !stem.contains('.') {
            return None;
        }
        Some(match ext {
            "nii" => (Format::Nifti, comp),
            "nrrd" | "nhdr" if !gz => (Format::Nrrd, comp),
            "mgh" if !gz => (Format::Mgh, Compression::None),
            "mgz" if !gz => (Format::Mgh, Compression::Gzip),
            "mha" | "mhd" if !gz => (Format::MetaImage, comp),
            "npy" if !gz => (Format::Npy, comp),
            "raw" | "bin" | "img" | "dat" => (Format::Raw, comp),
            "tif" | "tiff" if !gz => (Format::Tiff, comp),
            _ => return None,
        })
    }
}

/// How a stream of samples is compressed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Compression {
    /// Uncompressed.
    None,
    /// gzip (`.gz`, NRRD `gzip`, MGZ).
    Gzip,
    /// zlib (MetaImage `CompressedData = True`).
    Zlib,
}

/// Intensity scaling stored in the header (NIfTI `scl_slope`/`scl_inter`): value = raw·slope + inter.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scaling {
    /// Rescale slope: value = raw·slope + inter.
    pub slope: f64,
    /// Rescale intercept, in value units: value = raw·slope + inter.
    pub inter: f64,
}

impl Scaling {
    /// Slope 1, intercept 0: values are the raw samples.
    pub const IDENTITY: Scaling = Scaling {
        slope: 1.0,
        inter: 0.0,
    };

    /// True when the scaling leaves raw samples unchanged (slope exactly 1, intercept exactly 0).
    pub fn is_identity(&self) -> bool {
        self.slope == 1.0 && self.inter == 0.0
    }

    /// The value of a raw stored sample: `raw·slope + inter`.
    #[inline]
    pub fn apply(&self, raw: f64) -> f64 {
        raw * self.slope + self.inter
    }
}

/// Everything known about a volume before reading its samples.
#[derive(Clone, Debug)]
pub struct VolumeInfo {
    /// The file the user named.
    pub path: PathBuf,
    /// Format of the file ([`Format::Raw`] for synthetic volumes).
    pub format: Format,
    /// Samples along x, y, z. `x` varies fastest in memory and in every stream.
    pub dims: [usize; 3],
    /// Stored sample type.
    pub dtype: DType,
    /// Voxel index `(i, j, k)` → world millimetres. World is RAS+ (NIfTI, FreeSurfer, nibabel);
    /// LPS formats (NRRD with an LPS space, MetaImage) are converted on read and back on write.
    pub affine: Affine,
    /// Scaling applied to raw samples to get values (identity for most formats).
    pub scaling: Scaling,
    /// Byte order of the stored samples.
    pub endian: Endian,
    /// Compression of the stored samples.
    pub compression: Compression,
    /// The format's own header, kept so that writing back to the same format is faithful.
    pub header: FormatHeader,
}

impl VolumeInfo {
    /// Samples along x (`dims[0]`).
    pub fn nx(&self) -> usize {
        self.dims[0]
    }
    /// Samples along y (`dims[1]`).
    pub fn ny(&self) -> usize {
        self.dims[1]
    }
    /// Samples along z (`dims[2]`): the number of z-slices.
    pub fn nz(&self) -> usize {
        self.dims[2]
    }
    /// Samples in one z-slice.
    pub fn slice_len(&self) -> usize {
        self.dims[0] * self.dims[1]
    }
    /// Samples in the whole volume: `nx·ny·nz`.
    pub fn voxel_count(&self) -> u64 {
        self.dims.iter().map(|&d| d as u64).product()
    }
    /// Voxel spacing in millimetres along i, j, k (lengths of the affine's columns).
    pub fn spacing(&self) -> [f64; 3] {
        self.affine.spacing()
    }

    /// A volume description that is not tied to any file (for synthetic and in-memory volumes).
    pub fn synthetic(dims: [usize; 3], dtype: DType) -> VolumeInfo {
        VolumeInfo {
            path: PathBuf::from("<memory>"),
            format: Format::Raw,
            dims,
            dtype,
            affine: Affine::IDENTITY,
            scaling: Scaling::IDENTITY,
            endian: Endian::Little,
            compression: Compression::None,
            header: FormatHeader::None,
        }
    }
}

/// Header bytes and fields each format keeps for a faithful write-back.
#[derive(Clone, Debug)]
pub enum FormatHeader {
    /// No header: headerless raw files and synthetic or in-memory volumes.
    None,
    /// NIfTI-1/2: the file's bytes before the samples (header, extension flag, extensions).
    Nifti(nifti::NiftiHeader),
    /// NRRD: the magic line, every other header line verbatim, and the detached data file if any.
    Nrrd(nrrd::NrrdHeader),
    /// MGH/MGZ: the 284 header bytes, and the trailer that follows the samples.
    Mgh(mgh::MghHeader),
    /// MetaImage: the `Key = Value` fields in file order, and the detached data file if any.
    MetaImage(metaimage::MetaHeader),
    /// NumPy: no fields beyond those of [`VolumeInfo`].
    Npy,
    /// TIFF: no fields beyond those of [`VolumeInfo`].
    Tiff,
}

/// How to interpret files that do not describe themselves (headerless raw), and overrides.
#[derive(Clone, Debug, Default)]
pub struct ReadOptions {
    /// `--raw-dims NX,NY,NZ`.
    pub raw_dims: Option<[usize; 3]>,
    /// `--raw-type T`.
    pub raw_type: Option<DType>,
    /// `--raw-endian little|big`; little by default.
    pub raw_endian: Option<Endian>,
    /// `--raw-spacing SX,SY,SZ` in millimetres; also applies to NumPy and TIFF, which carry none.
    pub raw_spacing: Option<[f64; 3]>,
    /// Bytes to skip at the start of a raw file (`--raw-offset`).
    pub raw_offset: u64,
}

/// Streams the z-slices of a volume, in order.
pub trait SliceReader: Send {
    /// What is known about the volume. Complete once every slice has been read (an MGH trailer
    /// is kept in its [`FormatHeader`] only then).
    fn info(&self) -> &VolumeInfo;
    /// Reads the next z-slice (`nx·ny` samples, `x` fastest) into `out`, replacing its content.
    fn read_slice(&mut self, out: &mut Samples) -> Result<()>;
    /// Index of the slice the next `read_slice` returns.
    fn position(&self) -> usize;
    /// Starts again from slice 0 (re-opening the file).
    fn rewind(&mut self) -> Result<()>;
}

/// Largest number of samples isotopo accepts in one volume (2^40, about 8 TB of float64):
/// anything larger is a corrupt header, refused before allocating.
pub const MAX_VOXELS: u64 = 1 << 40;
/// Largest accepted extent along one axis (the surface graph packs coordinates in 20 bits).
pub const MAX_DIM: usize = 1_000_000;

/// Checks dims read from a header before anything is allocated for them.
pub(crate) fn check_dims(path: &Path, dims: [usize; 3], dtype: DType) -> Result<()> {
    if dims.contains(&0) {
        return Err(Error::input(
            path,
            format!(
                "dimensions {}×{}×{} contain a zero",
                dims[0], dims[1], dims[2]
            ),
            "at least one sample along each axis",
        ));
    }
    let total = dims
        .iter()
        .try_fold(1u64, |acc, &d| acc.checked_mul(d as u64));
    match total {
        Some(t) if t <= MAX_VOXELS && dims.iter().all(|&d| d <= MAX_DIM) => {}
        _ => {
            return Err(Error::input(
                path,
                format!(
                    "absurd dimensions {}×{}×{} ({} samples)",
                    dims[0], dims[1], dims[2], dtype
                ),
                format!("at most {MAX_DIM} samples per axis and {MAX_VOXELS} in all"),
            ))
        }
    }
    Ok(())
}

/// A data file named in a detached header (`.nhdr`, `.mhd`), resolved against the header's folder
/// unless absolute; `expected` says where it should be when it does not exist.
pub(crate) fn data_file_beside(header: &Path, name: &str, expected: &str) -> Result<PathBuf> {
    let p = Path::new(name);
    let full = if p.is_absolute() {
        p.to_path_buf()
    } else {
        header.parent().unwrap_or(Path::new(".")).join(p)
    };
    if !full.exists() {
        return Err(Error::input(
            header,
            format!("data file {} does not exist", full.display()),
            expected,
        ));
    }
    Ok(full)
}

/// Opens a volume for streaming. The format comes from the extension, else from the file's first
/// bytes; headerless files need `options.raw_dims` and `options.raw_type`.
pub fn open(path: &Path, options: &ReadOptions) -> Result<Box<dyn SliceReader>> {
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, "opening", e))?;
    if meta.is_dir() {
        return Err(Error::input(path, "a directory", "a volume file"));
    }
    let format = match Format::from_path(path) {
        Some((f, _)) => f,
        None if options.raw_dims.is_some() => Format::Raw,
        None => sniff(path)?,
    };
    let reader: Box<dyn SliceReader> = match format {
        Format::Nifti => Box::new(nifti::open(path)?),
        Format::Nrrd => Box::new(nrrd::open(path)?),
        Format::Mgh => Box::new(mgh::open(path)?),
        Format::MetaImage => Box::new(metaimage::open(path)?),
        Format::Npy => npy::open(path, options)?,
        Format::Raw => Box::new(raw::open(path, options)?),
        Format::Tiff => Box::new(tiff::open(path, options)?),
    };
    // A slice, and its bytes as read, are what every reader holds.
    reserve_slices(reader.info(), 2, "reading")?;
    Ok(reader)
}

/// Checks the memory limit ([`crate::memory::reserve`]) before `count` slices of `info`'s
/// samples are held at once, for `why` (the stage that holds them).
pub fn reserve_slices(info: &VolumeInfo, count: usize, why: &str) -> Result<()> {
    let [nx, ny, _] = info.dims;
    let bytes = (info.slice_len() as u64)
        .saturating_mul(info.dtype.size() as u64)
        .saturating_mul(count as u64);
    crate::memory::reserve(
        &format!("{count} slices of {nx}×{ny} {} samples ({why})", info.dtype),
        bytes,
    )
}

/// Guesses the format of a file with an unknown extension from its first bytes.
fn sniff(path: &Path) -> Result<Format> {
    use std::io::Read;
    let mut head = [0u8; 8];
    let mut f = std::fs::File::open(path).map_err(|e| Error::io(path, "opening", e))?;
    let n = f
        .read(&mut head)
        .map_err(|e| Error::io(path, "reading", e))?;
    let head = &head[..n];
    if head.starts_with(b"NRRD") {
        return Ok(Format::Nrrd);
    }
    if head.starts_with(b"\x93NUMPY") {
        return Ok(Format::Npy);
    }
    if head.starts_with(b"II*\0") || head.starts_with(b"MM\0*") {
        return Ok(Format::Tiff);
    }
    if n >= 4 {
        let s = u32::from_le_bytes(head[..4].try_into().unwrap());
        if s == 348 || s == 540 || s.swap_bytes() == 348 || s.swap_bytes() == 540 {
            return Ok(Format::Nifti);
        }
    }
    if head.starts_with(b"ObjectType") || head.starts_with(b"NDims") {
        return Ok(Format::MetaImage);
    }
    Err(Error::input(
        path,
        "a file whose format is not recognised from its name or its first bytes",
        "one of .nii .nii.gz .nrrd .nhdr .mgh .mgz .mha .mhd .npy .tif, or a raw file with --raw-dims and --raw-type",
    ))
}

/// Writes z-slices, in order, to a new file that appears only when [`SliceWriter::finish`] succeeds.
pub trait SliceWriter {
    /// Writes the next z-slice: `nx·ny` samples, `x` fastest, of the volume's sample type.
    fn write_slice(&mut self, slice: &Samples) -> Result<()>;
    /// Completes the file and moves it into place. `source` is the final description of the
    /// volume (after reading it completely: MGH keeps its trailer there).
    fn finish(self: Box<Self>, source: &VolumeInfo) -> Result<()>;
}

/// Creates a writer for `path`. The format follows the extension; the header is the source's own
/// when the format is the same, so NIfTI stays NIfTI with its extensions, NRRD keeps its fields…
/// Refuses to overwrite the input.
pub fn create(path: &Path, source: &VolumeInfo) -> Result<Box<dyn SliceWriter>> {
    check_output_path(path, source)?;
    let (format, comp) = Format::from_path(path).ok_or_else(|| {
        Error::usage(format!(
            "{}: cannot tell the output format from the extension; use .nii, .nii.gz, .nrrd, .nhdr, .mgh, .mgz, .mha, .mhd, .npy, .raw or .tif",
            path.display()
        ))
    })?;
    Ok(match format {
        Format::Nifti => Box::new(nifti::create(path, comp, source)?),
        Format::Nrrd => Box::new(nrrd::create(path, source)?),
        Format::Mgh => Box::new(mgh::create(path, comp, source)?),
        Format::MetaImage => Box::new(metaimage::create(path, source)?),
        Format::Npy => Box::new(npy::create(path, source)?),
        Format::Raw => Box::new(raw::create(path, comp, source)?),
        Format::Tiff => Box::new(tiff::create(path, source)?),
    })
}

/// Copies every slice of `reader` to a new file at `out` (format from its extension). Stops
/// with [`Error::Cancelled`] when `progress` says so; nothing is written then.
pub fn convert(
    reader: &mut dyn SliceReader,
    out: &Path,
    progress: &dyn crate::progress::Progress,
) -> Result<()> {
    let mut writer = create(out, reader.info())?;
    let mut slice = Samples::new(reader.info().dtype);
    progress.start("convert", reader.info().nz() as u64);
    for _ in 0..reader.info().nz() {
        crate::progress::between_steps(progress, "conversion")?;
        reader.read_slice(&mut slice)?;
        writer.write_slice(&slice)?;
        progress.advance(1);
    }
    progress.finish();
    let info = reader.info().clone();
    writer.finish(&info)
}

/// Reads a whole volume into memory (small volumes, tests).
pub fn read_all(path: &Path, options: &ReadOptions) -> Result<InMemoryVolume> {
    let mut reader = open(path, options)?;
    InMemoryVolume::from_reader(reader.as_mut())
}
