//! Headerless raw samples, x fastest. Dimensions and type come from `--raw-dims`/`--raw-type`, or
//! from a file name in the common `name_NXxNYxNZ_type.raw` pattern (`tooth_103x94x161_uint8.raw`).

use super::stream::{AtomicOutput, DataLocation, SampleWriter, StreamReader};
use super::{
    Affine, Compression, DType, Endian, Format, FormatHeader, ReadOptions, Scaling, VolumeInfo,
};
use crate::error::{Error, Result};
use std::path::Path;

/// Dimensions and type named in a file name: `..._103x94x161_uint8.raw`.
pub fn dims_from_name(path: &Path) -> (Option<[usize; 3]>, Option<DType>) {
    let name = path
        .file_name()
        .unwrap_or_default()
        .to_string_lossy()
        .to_string();
    let stem = name.split('.').next().unwrap_or("");
    let mut dims = None;
    let mut dtype = None;
    for token in stem.split(['_', '-']) {
        let parts: Vec<&str> = token.split('x').collect();
        if parts.len() == 3 {
            if let (Ok(a), Ok(b), Ok(c)) = (parts[0].parse(), parts[1].parse(), parts[2].parse()) {
                dims = Some([a, b, c]);
            }
        }
        if let Some(t) = DType::parse(token) {
            if token.len() > 2 {
                dtype = Some(t);
            }
        }
    }
    (dims, dtype)
}

pub(crate) fn open(path: &Path, options: &ReadOptions) -> Result<StreamReader> {
    let (name_dims, name_type) = dims_from_name(path);
    let dims = options.raw_dims.or(name_dims).ok_or_else(|| {
        Error::usage(format!(
            "{}: a headerless raw file needs --raw-dims NX,NY,NZ and --raw-type T (or a name like vol_256x256x128_uint8.raw)",
            path.display()
        ))
    })?;
    let dtype = options.raw_type.or(name_type).ok_or_else(|| {
        Error::usage(format!(
            "{}: a headerless raw file needs --raw-type (uint8, int8, uint16, int16, uint32, int32, float32, float64)",
            path.display()
        ))
    })?;
    let endian = options.raw_endian.unwrap_or(Endian::Little);
    let gz = path.to_string_lossy().to_ascii_lowercase().ends_with(".gz");
    let compression = if gz {
        Compression::Gzip
    } else {
        Compression::None
    };
    let info = VolumeInfo {
        path: path.to_path_buf(),
        format: Format::Raw,
        dims,
        dtype,
        affine: Affine::from_spacing(options.raw_spacing.unwrap_or([1.0; 3]), [0.0; 3]),
        scaling: Scaling::IDENTITY,
        endian,
        compression,
        header: FormatHeader::None,
    };
    let loc = DataLocation {
        path: path.to_path_buf(),
        offset: if gz { 0 } else { options.raw_offset },
        compression,
        skip: if gz { options.raw_offset } else { 0 },
        from_end: false,
        endian,
        exact_size: true,
        read_trailer: false,
    };
    StreamReader::new(info, loc)
}

pub(crate) fn create(
    path: &Path,
    compression: Compression,
    source: &VolumeInfo,
) -> Result<SampleWriter> {
    let endian = if source.format == Format::Raw {
        source.endian
    } else {
        Endian::Little
    };
    Ok(SampleWriter::new(
        AtomicOutput::create(path, compression)?,
        endian,
        source,
    ))
}
