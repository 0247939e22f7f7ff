//! FreeSurfer MGH (`.mgh`) and MGZ (`.mgz`, gzipped): a 284-byte big-endian header, the samples,
//! then an optional trailer (scan parameters, tags) that is kept and written back.

use super::stream::{AtomicOutput, DataLocation, SampleWriter, StreamReader};
use super::{
    Affine, Compression, DType, Endian, Format, FormatHeader, Samples, Scaling, SliceWriter,
    VolumeInfo,
};
use crate::error::{Error, Result};
use flate2::read::MultiGzDecoder;
use std::io::Read;
use std::path::Path;

const HEADER: usize = 284;

#[derive(Clone, Debug)]
pub struct MghHeader {
    pub bytes: Vec<u8>,
    /// What follows the samples (filled in once the samples have been read).
    pub tail: Vec<u8>,
}

fn be_i32(b: &[u8], o: usize) -> i32 {
    i32::from_be_bytes(b[o..o + 4].try_into().unwrap())
}
fn be_f32(b: &[u8], o: usize) -> f64 {
    f32::from_be_bytes(b[o..o + 4].try_into().unwrap()) as f64
}

fn dtype_from_code(c: i32) -> Option<DType> {
    Some(match c {
        0 => DType::U8,
        1 => DType::I32,
        3 => DType::F32,
        4 => DType::I16,
        _ => return None,
    })
}

fn code_from_dtype(t: DType) -> Option<i32> {
    Some(match t {
        DType::U8 => 0,
        DType::I32 => 1,
        DType::F32 => 3,
        DType::I16 => 4,
        _ => return None,
    })
}

fn affine_of(b: &[u8], dims: [usize; 3]) -> Affine {
    let good_ras = i16::from_be_bytes(b[28..30].try_into().unwrap()) != 0;
    let (delta, mdc, c_ras) = if good_ras {
        let delta = [be_f32(b, 30), be_f32(b, 34), be_f32(b, 38)];
        // Stored row by row: x_r x_a x_s, y_r y_a y_s, z_r z_a z_s (the direction of each axis).
        let mdc: [[f64; 3]; 3] =
            std::array::from_fn(|axis| std::array::from_fn(|w| be_f32(b, 42 + 12 * axis + 4 * w)));
        let c_ras = [be_f32(b, 78), be_f32(b, 82), be_f32(b, 86)];
        (delta, mdc, c_ras)
    } else {
        // FreeSurfer's default: coronal (LIA), 1 mm, centred.
        (
            [1.0; 3],
            [[-1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]],
            [0.0; 3],
        )
    };
    let mut a = Affine::IDENTITY;
    for c in 0..3 {
        for r in 0..3 {
            a.m[r][c] = mdc[c][r] * delta[c];
        }
    }
    for r in 0..3 {
        let centre: f64 = (0..3).map(|c| a.m[r][c] * dims[c] as f64 / 2.0).sum();
        a.m[r][3] = c_ras[r] - centre;
    }
    a
}

pub(crate) fn open(path: &Path) -> Result<StreamReader> {
    let gz = path
        .to_string_lossy()
        .to_ascii_lowercase()
        .ends_with(".mgz");
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, "opening", e))?;
    let mut input: Box<dyn Read> = if gz {
        Box::new(MultiGzDecoder::new(std::io::BufReader::new(file)))
    } else {
        Box::new(std::io::BufReader::new(file))
    };
    let mut b = vec![0u8; HEADER];
    if let Err(e) = input.read_exact(&mut b) {
        return Err(if e.kind() == std::io::ErrorKind::UnexpectedEof {
            Error::input(
                path,
                "a file shorter than the 284-byte MGH header",
                "an MGH/MGZ volume",
            )
        } else if gz {
            Error::input(
                path,
                format!("corrupt gzip data ({e})"),
                "a gzip-compressed MGH volume (.mgz)",
            )
        } else {
            Error::io(path, "reading", e)
        });
    }
    let version = be_i32(&b, 0);
    if version != 1 {
        return Err(Error::input(
            path,
            format!("MGH version {version}"),
            "MGH version 1",
        ));
    }
    let raw_dims = [be_i32(&b, 4), be_i32(&b, 8), be_i32(&b, 12)];
    if raw_dims.iter().any(|&d| d < 1) {
        return Err(Error::input(
            path,
            format!("dimensions {raw_dims:?}"),
            "positive dimensions",
        ));
    }
    let frames = be_i32(&b, 16);
    if frames != 1 {
        return Err(Error::input(
            path,
            format!("{frames} frames"),
            "a single-frame volume",
        ));
    }
    let code = be_i32(&b, 20);
    let dtype = dtype_from_code(code).ok_or_else(|| {
        Error::input(
            path,
            format!("unsupported MGH type code {code}"),
            "MGH types 0 (uchar), 1 (int), 3 (float) or 4 (short)",
        )
    })?;
    let dims = raw_dims.map(|d| d as usize);
    let info = VolumeInfo {
        path: path.to_path_buf(),
        format: Format::Mgh,
        dims,
        dtype,
        affine: affine_of(&b, dims),
        scaling: Scaling::IDENTITY,
        endian: Endian::Big,
        compression: if gz {
            Compression::Gzip
        } else {
            Compression::None
        },
        header: FormatHeader::Mgh(MghHeader {
            bytes: b,
            tail: Vec::new(),
        }),
    };
    let loc = DataLocation {
        path: path.to_path_buf(),
        offset: if gz { 0 } else { HEADER as u64 },
        compression: info.compression,
        skip: if gz { HEADER as u64 } else { 0 },
        from_end: false,
        endian: Endian::Big,
        exact_size: false,
        read_trailer: true,
    };
    StreamReader::new(info, loc)
}

fn new_header(source: &VolumeInfo, code: i32) -> Vec<u8> {
    let mut b = vec![0u8; HEADER];
    let put_i = |b: &mut Vec<u8>, o: usize, v: i32| b[o..o + 4].copy_from_slice(&v.to_be_bytes());
    let put_f =
        |b: &mut Vec<u8>, o: usize, v: f64| b[o..o + 4].copy_from_slice(&(v as f32).to_be_bytes());
    put_i(&mut b, 0, 1);
    for i in 0..3 {
        put_i(&mut b, 4 + 4 * i, source.dims[i] as i32);
    }
    put_i(&mut b, 16, 1);
    put_i(&mut b, 20, code);
    b[28..30].copy_from_slice(&1i16.to_be_bytes());
    let spacing = source.affine.spacing();
    let dir = source.affine.direction();
    for i in 0..3 {
        put_f(&mut b, 30 + 4 * i, spacing[i]);
    }
    for axis in 0..3 {
        for w in 0..3 {
            put_f(&mut b, 42 + 12 * axis + 4 * w, dir[w][axis]);
        }
    }
    let centre = source.affine.apply(source.dims.map(|d| d as f64 / 2.0));
    for i in 0..3 {
        put_f(&mut b, 78 + 4 * i, centre[i]);
    }
    b
}

pub(crate) struct MghWriter {
    samples: SampleWriter,
}

pub(crate) fn create(
    path: &Path,
    compression: Compression,
    source: &VolumeInfo,
) -> Result<MghWriter> {
    let code = code_from_dtype(source.dtype).ok_or_else(|| {
        Error::usage(format!(
            "{}: MGH cannot store {} samples (only uint8, int16, int32, float32); write .nii.gz or .nrrd instead",
            path.display(),
            source.dtype
        ))
    })?;
    let header = match &source.header {
        FormatHeader::Mgh(h) => h.bytes.clone(),
        _ => new_header(source, code),
    };
    let mut out = AtomicOutput::create(path, compression)?;
    out.write_all(&header)?;
    Ok(MghWriter {
        samples: SampleWriter::new(out, Endian::Big, source),
    })
}

impl SliceWriter for MghWriter {
    fn write_slice(&mut self, slice: &Samples) -> Result<()> {
        self.samples.write_slice(slice)
    }
    fn finish(mut self: Box<Self>, source: &VolumeInfo) -> Result<()> {
        if let FormatHeader::Mgh(h) = &source.header {
            if !h.tail.is_empty() {
                self.samples.out.write_all(&h.tail)?;
            }
        }
        self.samples.out.commit()
    }
}
