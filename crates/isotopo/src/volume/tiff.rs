//! Multi-page TIFF stacks: one grayscale page per z-slice (tifffile's and ImageJ's stacks).
//! Voxel size comes from ImageJ metadata when present (`spacing=` and the resolution tags), else
//! from `--raw-spacing`, else 1.

use super::{
    check_dims, Affine, Compression, DType, Endian, Format, FormatHeader, ReadOptions, Samples,
    Scaling, SliceReader, SliceWriter, VolumeInfo,
};
use crate::error::{Error, Result};
use std::fs::File;
use std::io::BufReader;
use std::path::Path;
use tiff::decoder::{Decoder, DecodingResult, Limits};
use tiff::tags::Tag;

type Dec = Decoder<BufReader<File>>;

/// The decoder's limits for a file of `len` bytes: what its tags and strips can describe. A
/// page, and the values of a tag (the decoder allocates for their count before reading them),
/// are bounded by what deflate can expand the file to (at most 1,032 to 1; at least 64 MiB),
/// compressed strips by the file itself, so a corrupt header is an error, not an allocation of
/// terabytes.
fn limits(len: u64) -> Limits {
    const DEFLATE_MAX_RATIO: u64 = 1032;
    let bytes = usize::try_from(len).unwrap_or(usize::MAX);
    let mut l = Limits::default();
    l.decoding_buffer_size = usize::try_from(len.saturating_mul(DEFLATE_MAX_RATIO))
        .unwrap_or(usize::MAX)
        .max(1 << 26);
    l.ifd_value_size = bytes;
    l.intermediate_buffer_size = bytes;
    l
}

fn decoder(path: &Path) -> Result<Dec> {
    let f = File::open(path).map_err(|e| Error::io(path, "opening", e))?;
    let len = f
        .metadata()
        .map_err(|e| Error::io(path, "opening", e))?
        .len();
    Decoder::new(BufReader::new(f))
        .map(|d| d.with_limits(limits(len)))
        .map_err(|e| {
            Error::input(
                path,
                format!("an unreadable TIFF ({e})"),
                "a TIFF stack of grayscale pages",
            )
        })
}

fn tiff_err(path: &Path, page: usize, e: tiff::TiffError) -> Error {
    let why = match e {
        tiff::TiffError::LimitsExceeded => {
            "a tag or page larger than the file can hold: a corrupt header".to_string()
        }
        e => e.to_string(),
    };
    Error::input(
        path,
        format!("page {} cannot be decoded ({why})", page + 1),
        "a TIFF stack of grayscale pages",
    )
}

fn page_dtype(path: &Path, page: usize, d: &mut Dec) -> Result<(u32, u32, DType)> {
    let (w, h) = d.dimensions().map_err(|e| tiff_err(path, page, e))?;
    let ct = d.colortype().map_err(|e| tiff_err(path, page, e))?;
    let bits = match ct {
        tiff::ColorType::Gray(b) => b,
        other => {
            return Err(Error::input(
                path,
                format!("page {} has colour type {other:?}", page + 1),
                "grayscale pages (one sample per pixel)",
            ));
        }
    };
    let format = d
        .find_tag_unsigned::<u16>(Tag::SampleFormat)
        .ok()
        .flatten()
        .unwrap_or(1);
    let t = match (format, bits) {
        (1, 8) => DType::U8,
        (2, 8) => DType::I8,
        (1, 16) => DType::U16,
        (2, 16) => DType::I16,
        (1, 32) => DType::U32,
        (2, 32) => DType::I32,
        (3, 32) => DType::F32,
        (3, 64) => DType::F64,
        _ => {
            return Err(Error::input(
                path,
                format!(
                    "page {} has {bits}-bit samples of format {format}",
                    page + 1
                ),
                "8-, 16- or 32-bit integer or 32/64-bit float samples",
            ))
        }
    };
    Ok((w, h, t))
}

/// ImageJ's voxel size: x and y from the resolution tags, z from `spacing=` in the description.
fn imagej_spacing(d: &mut Dec) -> Option<[f64; 3]> {
    let desc = match d.get_tag(Tag::ImageDescription).ok()? {
        tiff::decoder::ifd::Value::Ascii(s) => s,
        _ => return None,
    };
    if !desc.starts_with("ImageJ=") {
        return None;
    }
    let z = desc
        .lines()
        .find_map(|l| l.strip_prefix("spacing="))
        .and_then(|v| v.trim().parse::<f64>().ok())?;
    let mut res = |tag| match d.get_tag(tag).ok()? {
        tiff::decoder::ifd::Value::Rational(n, den) if n > 0 => Some(den as f64 / n as f64),
        _ => None,
    };
    Some([
        res(Tag::XResolution).unwrap_or(1.0),
        res(Tag::YResolution).unwrap_or(1.0),
        z,
    ])
}

pub(crate) struct TiffReader {
    info: VolumeInfo,
    decoder: Dec,
    position: usize,
}

pub(crate) fn open(path: &Path, options: &ReadOptions) -> Result<TiffReader> {
    let mut d = decoder(path)?;
    let (w, h, dtype) = page_dtype(path, 0, &mut d)?;
    let spacing = options
        .raw_spacing
        .or_else(|| imagej_spacing(&mut d))
        .unwrap_or([1.0; 3]);
    let mut pages = 1usize;
    while d.more_images() {
        d.next_image().map_err(|e| tiff_err(path, pages, e))?;
        let (w2, h2, t2) = page_dtype(path, pages, &mut d)?;
        if (w2, h2, t2) != (w, h, dtype) {
            return Err(Error::input(
                path,
                format!("page {} is {w2}×{h2} {t2}", pages + 1),
                format!("every page {w}×{h} {dtype} like the first"),
            ));
        }
        pages += 1;
    }
    let dims = [w as usize, h as usize, pages];
    check_dims(path, dims, dtype)?;
    let info = VolumeInfo {
        path: path.to_path_buf(),
        format: Format::Tiff,
        dims,
        dtype,
        affine: Affine::from_spacing(spacing, [0.0; 3]),
        scaling: Scaling::IDENTITY,
        endian: Endian::Little,
        compression: Compression::None,
        header: FormatHeader::Tiff,
    };
    Ok(TiffReader {
        info,
        decoder: decoder(path)?,
        position: 0,
    })
}

impl SliceReader for TiffReader {
    fn info(&self) -> &VolumeInfo {
        &self.info
    }

    fn read_slice(&mut self, out: &mut Samples) -> Result<()> {
        let path = &self.info.path;
        if self.position > 0 {
            self.decoder
                .next_image()
                .map_err(|e| tiff_err(path, self.position, e))?;
        }
        let img = self
            .decoder
            .read_image()
            .map_err(|e| tiff_err(path, self.position, e))?;
        let s = match img {
            DecodingResult::U8(v) => Samples::U8(v),
            DecodingResult::I8(v) => Samples::I8(v),
            DecodingResult::U16(v) => Samples::U16(v),
            DecodingResult::I16(v) => Samples::I16(v),
            DecodingResult::U32(v) => Samples::U32(v),
            DecodingResult::I32(v) => Samples::I32(v),
            DecodingResult::F32(v) => Samples::F32(v),
            DecodingResult::F64(v) => Samples::F64(v),
            DecodingResult::U64(_) | DecodingResult::I64(_) => {
                return Err(Error::input(
                    path,
                    "64-bit integer samples",
                    "at most 32-bit integer samples",
                ));
            }
        };
        if s.dtype() != self.info.dtype || s.len() != self.info.slice_len() {
            return Err(Error::input(
                path,
                format!(
                    "page {} decodes to {} {} samples",
                    self.position + 1,
                    s.len(),
                    s.dtype()
                ),
                format!(
                    "{} {} samples per page",
                    self.info.slice_len(),
                    self.info.dtype
                ),
            ));
        }
        *out = s;
        self.position += 1;
        Ok(())
    }

    fn position(&self) -> usize {
        self.position
    }

    fn rewind(&mut self) -> Result<()> {
        self.decoder = decoder(&self.info.path)?;
        self.position = 0;
        Ok(())
    }
}

pub(crate) struct TiffWriter {
    path: std::path::PathBuf,
    /// The file that becomes the output; the encoder writes through its own handle to it.
    tmp: super::stream::Staged,
    encoder: tiff::encoder::TiffEncoder<File>,
    dims: [usize; 3],
}

pub(crate) fn create(path: &Path, source: &VolumeInfo) -> Result<TiffWriter> {
    let tmp = super::stream::Staged::beside(path)?;
    let handle = tmp
        .file()
        .try_clone()
        .map_err(|e| Error::io(path, "creating", e))?;
    let encoder = tiff::encoder::TiffEncoder::new(handle)
        .map_err(|e| Error::io(path, "writing", std::io::Error::other(e.to_string())))?;
    Ok(TiffWriter {
        path: path.to_path_buf(),
        tmp,
        encoder,
        dims: source.dims,
    })
}

impl SliceWriter for TiffWriter {
    fn write_slice(&mut self, slice: &Samples) -> Result<()> {
        use tiff::encoder::colortype as ct;
        let (w, h) = (self.dims[0] as u32, self.dims[1] as u32);
        let e = &mut self.encoder;
        let r = match slice {
            Samples::U8(v) => e.write_image::<ct::Gray8>(w, h, v),
            Samples::I8(v) => e.write_image::<ct::GrayI8>(w, h, v),
            Samples::U16(v) => e.write_image::<ct::Gray16>(w, h, v),
            Samples::I16(v) => e.write_image::<ct::GrayI16>(w, h, v),
            Samples::U32(v) => e.write_image::<ct::Gray32>(w, h, v),
            Samples::I32(v) => e.write_image::<ct::GrayI32>(w, h, v),
            Samples::F32(v) => e.write_image::<ct::Gray32Float>(w, h, v),
            Samples::F64(v) => e.write_image::<ct::Gray64Float>(w, h, v),
        };
        r.map_err(|e| Error::io(&self.path, "writing", std::io::Error::other(e.to_string())))
    }

    fn finish(self: Box<Self>, _source: &VolumeInfo) -> Result<()> {
        // The encoder writes unbuffered: every page is in the file already.
        drop(self.encoder);
        self.tmp.persist(&self.path)
    }
}
