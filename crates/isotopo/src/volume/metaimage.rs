//! MetaImage (`.mha` attached, `.mhd` + data file): ITK's text header. World coordinates in
//! MetaImage are LPS (ITK's convention) and are converted to RAS on read and back on write.

use super::stream::{AtomicOutput, DataLocation, SampleWriter, StreamReader};
use super::{
    data_file_beside, Affine, Compression, DType, Endian, Format, FormatHeader, Samples, Scaling,
    SliceWriter, VolumeInfo,
};
use crate::error::{Error, Result};
use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};

#[derive(Clone, Debug)]
pub struct MetaHeader {
    /// `Key = Value` fields in file order (ElementDataFile last).
    pub fields: Vec<(String, String)>,
    /// Detached data file, resolved against the header's directory.
    pub data_file: Option<PathBuf>,
}

const MAX_HEADER: u64 = 1 << 20;

fn meta_dtype(s: &str) -> Option<DType> {
    Some(match s {
        "MET_UCHAR" => DType::U8,
        "MET_CHAR" => DType::I8,
        "MET_USHORT" => DType::U16,
        "MET_SHORT" => DType::I16,
        "MET_UINT" => DType::U32,
        "MET_INT" => DType::I32,
        "MET_FLOAT" => DType::F32,
        "MET_DOUBLE" => DType::F64,
        _ => return None,
    })
}

fn meta_type_name(t: DType) -> &'static str {
    match t {
        DType::U8 => "MET_UCHAR",
        DType::I8 => "MET_CHAR",
        DType::U16 => "MET_USHORT",
        DType::I16 => "MET_SHORT",
        DType::U32 => "MET_UINT",
        DType::I32 => "MET_INT",
        DType::F32 => "MET_FLOAT",
        DType::F64 => "MET_DOUBLE",
    }
}

fn truthy(s: &str) -> bool {
    matches!(s.to_ascii_lowercase().as_str(), "true" | "1" | "yes")
}

/// Reads `Key = Value` lines up to ElementDataFile, the last field; also returns the header's
/// length in bytes (where attached data starts).
fn read_fields(path: &Path) -> Result<(Vec<(String, String)>, u64)> {
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, "opening", e))?;
    let mut rd = BufReader::new(file).take(MAX_HEADER);
    let mut fields: Vec<(String, String)> = Vec::new();
    let mut header_len = 0u64;
    loop {
        let mut raw = Vec::new();
        let n = rd
            .read_until(b'\n', &mut raw)
            .map_err(|e| Error::io(path, "reading", e))?;
        if n == 0 {
            return Err(Error::input(
                path,
                "a header without ElementDataFile",
                "a MetaImage header ending with ElementDataFile",
            ));
        }
        header_len += n as u64;
        let line = String::from_utf8_lossy(&raw).trim().to_string();
        if line.is_empty() {
            continue;
        }
        let (k, v) = line.split_once('=').ok_or_else(|| {
            Error::input(
                path,
                format!("header line {line:?}"),
                "\"Key = Value\" lines",
            )
        })?;
        let (k, v) = (k.trim().to_string(), v.trim().to_string());
        let last = k == "ElementDataFile";
        fields.push((k, v));
        if last {
            break;
        }
    }
    Ok((fields, header_len))
}

/// Looks up header fields; keys are case-insensitive, the first occurrence counts.
struct Fields<'a> {
    path: &'a Path,
    list: &'a [(String, String)],
}

impl<'a> Fields<'a> {
    fn get(&self, k: &str) -> Option<&'a str> {
        self.list
            .iter()
            .find(|(f, _)| f.eq_ignore_ascii_case(k))
            .map(|(_, v)| v.as_str())
    }

    /// The numbers of field `k`, if present.
    fn nums(&self, k: &str) -> Result<Option<Vec<f64>>> {
        match self.get(k) {
            None => Ok(None),
            Some(v) => v
                .split_whitespace()
                .map(|x| x.parse::<f64>())
                .collect::<std::result::Result<Vec<_>, _>>()
                .map(Some)
                .map_err(|_| {
                    Error::input(self.path, format!("{k} = {v}"), format!("numbers for {k}"))
                }),
        }
    }
}

/// NDims (3 when absent) and DimSize, with a single channel per element.
fn dims(f: &Fields) -> Result<(usize, [usize; 3])> {
    let path = f.path;
    let ndims = f
        .nums("NDims")?
        .and_then(|v| v.first().copied())
        .unwrap_or(3.0) as usize;
    if !(1..=3).contains(&ndims) {
        return Err(Error::input(
            path,
            format!("NDims = {ndims}"),
            "a 3-D image",
        ));
    }
    let size = f
        .nums("DimSize")?
        .ok_or_else(|| Error::input(path, "no DimSize", "DimSize = NX NY NZ"))?;
    if size.len() != ndims || size.iter().any(|&s| s < 0.0 || s.fract() != 0.0) {
        return Err(Error::input(
            path,
            format!("DimSize {size:?}"),
            format!("{ndims} non-negative integers"),
        ));
    }
    let mut dims = [1usize; 3];
    for (i, s) in size.iter().enumerate() {
        dims[i] = *s as usize;
    }
    if let Some(ch) = f.nums("ElementNumberOfChannels")? {
        if ch.first().copied().unwrap_or(1.0) != 1.0 {
            return Err(Error::input(
                path,
                format!("{} channels per element", ch[0]),
                "scalar samples (one channel)",
            ));
        }
    }
    Ok((ndims, dims))
}

fn sample_type(f: &Fields) -> Result<DType> {
    let et = f.get("ElementType").ok_or_else(|| {
        Error::input(
            f.path,
            "no ElementType",
            "ElementType = MET_SHORT (or another MET_ type)",
        )
    })?;
    meta_dtype(et).ok_or_else(|| {
        Error::input(f.path, format!("unsupported ElementType {et}"), "MET_UCHAR, MET_CHAR, MET_USHORT, MET_SHORT, MET_UINT, MET_INT, MET_FLOAT or MET_DOUBLE")
    })
}

/// Voxel-to-world map (RAS) from spacing, origin and direction matrix, each under any of the
/// names ITK accepts (every name is parsed, so a malformed alternative is an error too).
fn geometry(f: &Fields, ndims: usize) -> Result<Affine> {
    let spacing = f
        .nums("ElementSpacing")?
        .or(f.nums("ElementSize")?)
        .unwrap_or(vec![1.0; ndims]);
    let origin = f
        .nums("Offset")?
        .or(f.nums("Origin")?)
        .or(f.nums("Position")?)
        .unwrap_or(vec![0.0; ndims]);
    let matrix = f
        .nums("TransformMatrix")?
        .or(f.nums("Rotation")?)
        .or(f.nums("Orientation")?);
    let mut dir = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    if let Some(m) = matrix {
        if m.len() == ndims * ndims && ndims == 3 {
            // Row `axis` of TransformMatrix is the direction of that axis (ITK's reading).
            for axis in 0..3 {
                for w in 0..3 {
                    dir[w][axis] = m[axis * 3 + w];
                }
            }
        }
    }
    let sp: [f64; 3] = std::array::from_fn(|i| spacing.get(i).copied().unwrap_or(1.0));
    let or: [f64; 3] = std::array::from_fn(|i| origin.get(i).copied().unwrap_or(0.0));
    let affine = Affine::from_parts(dir, sp, or).flip_xy();
    if !affine.is_valid() {
        return Err(Error::input(
            f.path,
            "a degenerate ElementSpacing or TransformMatrix",
            "an invertible voxel-to-world map",
        ));
    }
    Ok(affine)
}

/// The file named by ElementDataFile, or `None` for LOCAL (data after the header).
fn data_file(f: &Fields) -> Result<Option<PathBuf>> {
    let df = f.get("ElementDataFile").unwrap_or("LOCAL");
    if df.eq_ignore_ascii_case("LOCAL") {
        return Ok(None);
    }
    if df.starts_with("LIST") || df.contains('%') || df.contains(' ') {
        return Err(Error::input(
            f.path,
            format!("ElementDataFile = {df} (several files)"),
            "LOCAL or a single data file",
        ));
    }
    data_file_beside(f.path, df, "the data file named by ElementDataFile").map(Some)
}

/// Where the samples start: after the header (LOCAL), else HeaderSize bytes into the data file
/// (-1: the samples end the file).
fn data_location(
    f: &Fields,
    header_len: u64,
    data_file: Option<&Path>,
    compressed: bool,
    endian: Endian,
) -> Result<DataLocation> {
    let header_size = f
        .nums("HeaderSize")?
        .and_then(|v| v.first().copied())
        .unwrap_or(0.0);
    let (offset, from_end) = match data_file {
        None => (header_len, false),
        Some(_) if header_size == -1.0 => (0, true),
        Some(_) => (header_size.max(0.0) as u64, false),
    };
    Ok(DataLocation {
        path: data_file.unwrap_or(f.path).to_path_buf(),
        offset,
        compression: compression(compressed),
        skip: 0,
        from_end: from_end && !compressed,
        endian,
        exact_size: data_file.is_some() && !compressed && header_size == 0.0,
        read_trailer: false,
    })
}

fn compression(compressed: bool) -> Compression {
    if compressed {
        Compression::Zlib
    } else {
        Compression::None
    }
}

pub(crate) fn open(path: &Path) -> Result<StreamReader> {
    let (fields, header_len) = read_fields(path)?;
    let f = Fields {
        path,
        list: &fields,
    };
    let (ndims, dims) = dims(&f)?;
    let dtype = sample_type(&f)?;
    let msb = f
        .get("ElementByteOrderMSB")
        .or_else(|| f.get("BinaryDataByteOrderMSB"))
        .map(truthy)
        .unwrap_or(false);
    let endian = if msb { Endian::Big } else { Endian::Little };
    let compressed = f.get("CompressedData").map(truthy).unwrap_or(false);
    let affine = geometry(&f, ndims)?;
    let data_file = data_file(&f)?;
    let loc = data_location(&f, header_len, data_file.as_deref(), compressed, endian)?;
    let info = VolumeInfo {
        path: path.to_path_buf(),
        format: Format::MetaImage,
        dims,
        dtype,
        affine,
        scaling: Scaling::IDENTITY,
        endian,
        compression: compression(compressed),
        header: FormatHeader::MetaImage(MetaHeader { fields, data_file }),
    };
    StreamReader::new(info, loc)
}

fn fmt3(v: [f64; 3]) -> String {
    format!("{} {} {}", v[0], v[1], v[2])
}

/// Header fields for `source`, keeping a MetaImage source's own fields where they still apply.
fn output_fields(source: &VolumeInfo, compressed: bool, data_file: &str) -> Vec<(String, String)> {
    let lps = source.affine.flip_xy();
    let dir = lps.direction();
    let matrix: Vec<String> = (0..3)
        .flat_map(|axis| (0..3).map(move |w| (axis, w)))
        .map(|(a, w)| format!("{}", dir[w][a]))
        .collect();
    let ours: Vec<(String, String)> = vec![
            ("ObjectType".into(), "Image".into()),
            ("NDims".into(), "3".into()),
            ("BinaryData".into(), "True".into()),
            (
                "BinaryDataByteOrderMSB".into(),
                if source.endian == Endian::Big
                    && matches!(source.header, FormatHeader::MetaImage(_))
                {
                    "True"
                } else {
                    "False"
                }
                .into(),
            ),
            (
                "CompressedData".into(),
                if compressed { "True" } else { "False" }.into(),
            ),
            ("TransformMatrix".into(), matrix.join(" ")),
            ("Offset".into(), fmt3(lps.origin())),
            ("ElementSpacing".into(), fmt3(lps.spacing())),
            (
                "DimSize".into(),
                format!("{} {} {}", source.dims[0], source.dims[1], source.dims[2]),
            ),
            ("ElementType".into(), meta_type_name(source.dtype).into()),
        ];
    let mut fields = match &source.header {
        FormatHeader::MetaImage(h) => h.fields.clone(),
        _ => Vec::new(),
    };
    let drop = [
        "ElementDataFile",
        "CompressedDataSize",
        "HeaderSize",
        "ElementByteOrderMSB",
        "Origin",
        "Position",
        "Rotation",
        "Orientation",
        "ElementSize",
    ];
    fields.retain(|(k, _)| !drop.iter().any(|d| d.eq_ignore_ascii_case(k)));
    for (k, v) in ours {
        match fields.iter_mut().find(|(f, _)| f.eq_ignore_ascii_case(&k)) {
            Some(slot) => slot.1 = v,
            None => fields.push((k, v)),
        }
    }
    fields.push(("ElementDataFile".into(), data_file.into()));
    fields
}

fn header_text(fields: &[(String, String)]) -> String {
    fields.iter().map(|(k, v)| format!("{k} = {v}\n")).collect()
}

pub(crate) struct MetaWriter {
    samples: SampleWriter,
    path: PathBuf,
    detached: bool,
    compressed: bool,
    endian: Endian,
    /// Attached + compressed: the samples' output is only a stage for the compressed data,
    /// appended after the header (which must state its size).
    staged: bool,
}

pub(crate) fn create(path: &Path, source: &VolumeInfo) -> Result<MetaWriter> {
    let detached = path
        .extension()
        .map(|e| e.eq_ignore_ascii_case("mhd"))
        .unwrap_or(false);
    let compressed = match &source.header {
        FormatHeader::MetaImage(_) => source.compression != Compression::None,
        _ => true,
    };
    let endian = match &source.header {
        FormatHeader::MetaImage(_) => source.endian,
        _ => Endian::Little,
    };
    let stem = path
        .file_stem()
        .unwrap_or_default()
        .to_string_lossy()
        .to_string();
    let (out, staged) = if detached {
        let data = path.with_file_name(format!(
            "{stem}.{}",
            if compressed { "zraw" } else { "raw" }
        ));
        super::check_output_path(&data, source)?;
        (
            AtomicOutput::create(
                &data,
                if compressed {
                    Compression::Zlib
                } else {
                    Compression::None
                },
            )?,
            false,
        )
    } else if compressed {
        (AtomicOutput::create(path, Compression::Zlib)?, true)
    } else {
        let mut out = AtomicOutput::create(path, Compression::None)?;
        out.write_all(header_text(&output_fields(source, false, "LOCAL")).as_bytes())?;
        (out, false)
    };
    Ok(MetaWriter {
        samples: SampleWriter::new(out, endian, source),
        path: path.to_path_buf(),
        detached,
        compressed,
        endian,
        staged,
    })
}

impl SliceWriter for MetaWriter {
    fn write_slice(&mut self, slice: &Samples) -> Result<()> {
        self.samples.write_slice(slice)
    }

    fn finish(self: Box<Self>, source: &VolumeInfo) -> Result<()> {
        let mut src = source.clone();
        src.endian = self.endian;
        if let FormatHeader::MetaImage(_) = src.header {
        } else {
            src.endian = Endian::Little;
        }
        if self.staged {
            // The header with the compressed size, then the staged data.
            let mut data = self.samples.out.into_bytes_written()?;
            let size = data
                .metadata()
                .map_err(|e| Error::io(&self.path, "writing", e))?
                .len();
            let mut fields = output_fields(&src, true, "LOCAL");
            fields.insert(
                fields.len() - 1,
                ("CompressedDataSize".into(), size.to_string()),
            );
            let mut out = AtomicOutput::create(&self.path, Compression::None)?;
            out.write_all(header_text(&fields).as_bytes())?;
            let mut buf = vec![0u8; 1 << 20];
            loop {
                let n = data
                    .read(&mut buf)
                    .map_err(|e| Error::io(&self.path, "writing", e))?;
                if n == 0 {
                    break;
                }
                out.write_all(&buf[..n])?;
            }
            return out.commit();
        }
        let data_path = self.samples.out.path().to_path_buf();
        self.samples.out.commit()?;
        if self.detached {
            let name = data_path
                .file_name()
                .unwrap_or_default()
                .to_string_lossy()
                .to_string();
            let mut fields = output_fields(&src, self.compressed, &name);
            if self.compressed {
                let size = std::fs::metadata(&data_path)
                    .map_err(|e| Error::io(&data_path, "reading", e))?
                    .len();
                fields.insert(
                    fields.len() - 1,
                    ("CompressedDataSize".into(), size.to_string()),
                );
            }
            let mut h = AtomicOutput::create(&self.path, Compression::None)?;
            h.write_all(header_text(&fields).as_bytes())?;
            h.commit()?;
        }
        Ok(())
    }
}
