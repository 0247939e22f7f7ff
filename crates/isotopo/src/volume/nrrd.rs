//! NRRD (`.nrrd` attached, `.nhdr` detached): raw and gzip encodings, either byte order.
//!
//! Fields isotopo does not use (kinds, units, key/value pairs, comments) are kept and written
//! back unchanged.

use super::stream::{AtomicOutput, DataLocation, SampleWriter, StreamReader};
use super::{
    data_file_beside, Affine, Compression, DType, Endian, Format, FormatHeader, Samples, Scaling,
    SliceWriter, VolumeInfo,
};
use crate::error::{Error, Result};
use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};

#[derive(Clone, Debug)]
pub struct NrrdHeader {
    /// First line, e.g. `NRRD0004`.
    pub magic: String,
    /// Every header line after the magic, verbatim.
    pub lines: Vec<String>,
    /// Detached data file, resolved against the header's directory.
    pub data_file: Option<PathBuf>,
}

const MAX_HEADER: u64 = 1 << 20;

fn nrrd_dtype(s: &str) -> Option<DType> {
    Some(match s.trim() {
        "uchar" | "unsigned char" | "uint8" | "uint8_t" => DType::U8,
        "signed char" | "int8" | "int8_t" => DType::I8,
        "short" | "short int" | "signed short" | "signed short int" | "int16" | "int16_t" => {
            DType::I16
        }
        "ushort" | "unsigned short" | "unsigned short int" | "uint16" | "uint16_t" => DType::U16,
        "int" | "signed int" | "int32" | "int32_t" => DType::I32,
        "uint" | "unsigned int" | "uint32" | "uint32_t" => DType::U32,
        "float" => DType::F32,
        "double" => DType::F64,
        _ => return None,
    })
}

fn nrrd_type_name(t: DType) -> &'static str {
    match t {
        DType::U8 => "uint8",
        DType::I8 => "int8",
        DType::U16 => "uint16",
        DType::I16 => "int16",
        DType::U32 => "uint32",
        DType::I32 => "int32",
        DType::F32 => "float",
        DType::F64 => "double",
    }
}

/// Parses `(1,0,0)`-style vectors; `none` gives `None`.
fn parse_vectors(path: &Path, s: &str) -> Result<Vec<Option<Vec<f64>>>> {
    let mut out = Vec::new();
    let mut rest = s.trim();
    while !rest.is_empty() {
        if let Some(r) = rest.strip_prefix("none") {
            out.push(None);
            rest = r.trim_start();
            continue;
        }
        let open = rest.find('(');
        let close = rest.find(')');
        match (open, close) {
            (Some(0), Some(c)) => {
                let inner = &rest[1..c];
                let v: std::result::Result<Vec<f64>, _> =
                    inner.split(',').map(|x| x.trim().parse::<f64>()).collect();
                let v = v.map_err(|_| {
                    Error::input(path, format!("vector ({inner})"), "numbers like (1,0,0)")
                })?;
                out.push(Some(v));
                rest = rest[c + 1..].trim_start();
            }
            _ => {
                return Err(Error::input(
                    path,
                    format!("vector list \"{s}\""),
                    "vectors like (1,0,0) (0,1,0) (0,0,1)",
                ))
            }
        }
    }
    Ok(out)
}

fn parse_numbers<T: std::str::FromStr>(path: &Path, field: &str, s: &str) -> Result<Vec<T>> {
    s.split_whitespace()
        .map(|x| {
            x.parse::<T>().map_err(|_| {
                Error::input(
                    path,
                    format!("{field}: \"{s}\""),
                    format!("a list of numbers for \"{field}\""),
                )
            })
        })
        .collect()
}

/// The header as read: the magic line, the lines after it, their `field: value` pairs (field
/// names lower-cased) and the header's length in bytes (where attached data starts).
struct RawHeader {
    magic: String,
    lines: Vec<String>,
    fields: Vec<(String, String)>,
    len: u64,
}

impl RawHeader {
    /// The first value of `field`.
    fn get(&self, field: &str) -> Option<&str> {
        self.fields
            .iter()
            .find(|(f, _)| f == field)
            .map(|(_, v)| v.as_str())
    }

    /// The first value of `field`, else of its other spelling.
    fn get2(&self, field: &str, other: &str) -> Option<&str> {
        self.get(field).or_else(|| self.get(other))
    }
}

/// Reads the magic line and the header lines up to the blank line (or the end of a detached
/// header), at most [`MAX_HEADER`] bytes.
fn read_header(path: &Path) -> Result<RawHeader> {
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, "opening", e))?;
    let mut rd = BufReader::new(file).take(MAX_HEADER);
    let mut magic = String::new();
    rd.read_line(&mut magic)
        .map_err(|e| Error::io(path, "reading", e))?;
    let magic = magic.trim_end().to_string();
    if !magic.starts_with("NRRD") {
        return Err(Error::input(
            path,
            format!("first line {magic:?}"),
            "a NRRD magic line like NRRD0004",
        ));
    }
    let mut len = magic.len() as u64 + 1;
    let mut lines = Vec::new();
    let mut fields: Vec<(String, String)> = Vec::new();
    loop {
        let mut raw = Vec::new();
        let n = rd
            .read_until(b'\n', &mut raw)
            .map_err(|e| Error::io(path, "reading", e))?;
        len += n as u64;
        if n == 0 {
            break; // detached header without a final blank line
        }
        let line = String::from_utf8_lossy(&raw)
            .trim_end_matches(['\n', '\r'])
            .to_string();
        if line.is_empty() {
            break;
        }
        // Comments and `key:=value` pairs are kept as lines but are not fields.
        if !line.starts_with('#') && !line.contains(":=") {
            fields.push(parse_field(path, &line)?);
        }
        lines.push(line);
        if len >= MAX_HEADER {
            return Err(Error::input(
                path,
                "a header longer than 1 MiB with no blank line",
                "a NRRD header ending in a blank line",
            ));
        }
    }
    Ok(RawHeader {
        magic,
        lines,
        fields,
        len,
    })
}

/// A `field: value` line as (lower-cased field, value).
fn parse_field(path: &Path, line: &str) -> Result<(String, String)> {
    match line.split_once(':') {
        Some((k, v)) => Ok((k.trim().to_ascii_lowercase(), v.trim().to_string())),
        None => Err(Error::input(
            path,
            format!("header line {line:?}"),
            "\"field: value\" lines",
        )),
    }
}

/// How the samples are laid out: their type, the spatial axes and how the bytes are stored.
struct Layout {
    dtype: DType,
    /// Index of the first spatial axis (1 after a leading axis of size 1).
    spatial_from: usize,
    /// Number of spatial axes (1 to 3).
    spatial: usize,
    dims: [usize; 3],
    compression: Compression,
    endian: Endian,
}

/// Checks type, dimension, sizes, encoding and endian, in that order.
fn layout(path: &Path, h: &RawHeader) -> Result<Layout> {
    let dtype = sample_type(path, h)?;
    let (spatial_from, spatial, dims) = spatial_axes(path, h)?;
    let compression = encoding(path, h)?;
    let endian = byte_order(path, h, dtype)?;
    Ok(Layout {
        dtype,
        spatial_from,
        spatial,
        dims,
        compression,
        endian,
    })
}

fn sample_type(path: &Path, h: &RawHeader) -> Result<DType> {
    let type_s = h.get("type").ok_or_else(|| {
        Error::input(
            path,
            "no \"type\" field",
            "a NRRD header with type, dimension, sizes, encoding",
        )
    })?;
    nrrd_dtype(type_s).ok_or_else(|| {
        Error::input(
            path,
            format!("unsupported sample type \"{type_s}\""),
            "uchar, signed char, short, ushort, int, uint, float or double samples",
        )
    })
}

/// The first spatial axis, the number of spatial axes and the dims (1 for missing axes).
fn spatial_axes(path: &Path, h: &RawHeader) -> Result<(usize, usize, [usize; 3])> {
    let dimension: usize = h
        .get("dimension")
        .ok_or_else(|| Error::input(path, "no \"dimension\" field", "dimension: 3"))?
        .parse()
        .map_err(|_| Error::input(path, "a non-numeric dimension", "dimension: 3"))?;
    let sizes: Vec<u64> = parse_numbers(
        path,
        "sizes",
        h.get("sizes")
            .ok_or_else(|| Error::input(path, "no \"sizes\" field", "sizes: NX NY NZ"))?,
    )?;
    if sizes.len() != dimension {
        return Err(Error::input(
            path,
            format!("{} sizes for dimension {dimension}", sizes.len()),
            "one size per axis",
        ));
    }
    // A leading axis of size 1 (a scalar "vector" axis) is allowed; otherwise 1 to 3 axes.
    let spatial_from = if dimension == 4 && sizes[0] == 1 {
        1
    } else {
        0
    };
    if dimension - spatial_from > 3 || dimension == 0 {
        return Err(Error::input(
            path,
            format!("a {dimension}-D array with sizes {sizes:?}"),
            "a 3-D volume",
        ));
    }
    let mut dims = [1usize; 3];
    for (i, &s) in sizes[spatial_from..].iter().enumerate() {
        dims[i] = usize::try_from(s).unwrap_or(usize::MAX);
    }
    Ok((spatial_from, dimension - spatial_from, dims))
}

fn encoding(path: &Path, h: &RawHeader) -> Result<Compression> {
    let encoding = h
        .get("encoding")
        .ok_or_else(|| Error::input(path, "no \"encoding\" field", "encoding: raw or gzip"))?;
    match encoding {
        "raw" => Ok(Compression::None),
        "gzip" | "gz" => Ok(Compression::Gzip),
        other => Err(Error::input(
            path,
            format!("unsupported encoding \"{other}\""),
            "encoding raw or gzip (re-save with pynrrd or unu)",
        )),
    }
}

/// The `endian` field; only single-byte samples may go without it.
fn byte_order(path: &Path, h: &RawHeader, dtype: DType) -> Result<Endian> {
    match h.get("endian") {
        Some("little") => Ok(Endian::Little),
        Some("big") => Ok(Endian::Big),
        Some(e) => Err(Error::input(
            path,
            format!("endian: {e}"),
            "endian: little or big",
        )),
        None if dtype.size() == 1 => Ok(Endian::Little),
        None => Err(Error::input(
            path,
            "no \"endian\" field for multi-byte samples",
            "endian: little or big",
        )),
    }
}

/// Voxel-to-world map from `space directions` + `space origin`, else from `spacings`, converted
/// to RAS from an LPS or LAS space.
fn geometry(path: &Path, h: &RawHeader, layout: &Layout) -> Result<Affine> {
    let space = h.get("space").unwrap_or("").to_ascii_lowercase();
    let mut affine = Affine::IDENTITY;
    if let Some(dirs) = h.get("space directions") {
        affine = space_directions(path, h, dirs, layout.spatial)?;
    } else if let Some(sp) = h.get("spacings") {
        let sp: Vec<String> = sp.split_whitespace().map(String::from).collect();
        for (c, s) in sp.iter().skip(layout.spatial_from).take(3).enumerate() {
            let v: f64 = s.parse().unwrap_or(f64::NAN);
            affine.m[c][c] = if v.is_finite() && v != 0.0 { v } else { 1.0 };
        }
    }
    let lps = matches!(space.as_str(), "left-posterior-superior" | "lps");
    let las = matches!(space.as_str(), "left-anterior-superior" | "las");
    if lps {
        affine = affine.flip_xy();
    } else if las {
        for c in 0..4 {
            affine.m[0][c] = -affine.m[0][c];
        }
    }
    if !affine.is_valid() {
        return Err(Error::input(
            path,
            "degenerate or non-finite space directions",
            "an invertible voxel-to-world map",
        ));
    }
    Ok(affine)
}

/// The affine (in the header's space) of `space directions` (one 3-vector per spatial axis,
/// `none` for the others) and the optional `space origin`.
fn space_directions(path: &Path, h: &RawHeader, dirs: &str, spatial: usize) -> Result<Affine> {
    let mut affine = Affine::IDENTITY;
    let v = parse_vectors(path, dirs)?;
    let v: Vec<Vec<f64>> = v.into_iter().flatten().collect();
    if v.len() != spatial || v.iter().any(|x| x.len() != 3) {
        return Err(Error::input(
            path,
            format!("space directions \"{dirs}\""),
            "one 3-vector per spatial axis",
        ));
    }
    for (c, vec) in v.iter().enumerate() {
        for r in 0..3 {
            affine.m[r][c] = vec[r];
        }
    }
    if let Some(o) = h.get("space origin") {
        let o = parse_vectors(path, o)?;
        match o.first() {
            Some(Some(v)) if v.len() == 3 => {
                for r in 0..3 {
                    affine.m[r][3] = v[r];
                }
            }
            _ => {
                return Err(Error::input(
                    path,
                    "space origin without 3 numbers",
                    "space origin: (x,y,z)",
                ))
            }
        }
    }
    Ok(affine)
}

/// The detached data file (`data file`), if any; file lists are not supported.
fn data_file(path: &Path, h: &RawHeader) -> Result<Option<PathBuf>> {
    let Some(df) = h.get2("data file", "datafile") else {
        return Ok(None);
    };
    if df.starts_with("LIST") || df.contains('%') {
        return Err(Error::input(
            path,
            format!("data file \"{df}\" (several files)"),
            "a single detached data file",
        ));
    }
    data_file_beside(path, df, "the detached data file beside the header").map(Some)
}

/// Where the samples start: after the header (attached) or at the start of the data file, then
/// past `line skip` lines and `byte skip` bytes (-1: the samples end the file).
fn data_location(
    path: &Path,
    h: &RawHeader,
    layout: &Layout,
    data_file: Option<&Path>,
) -> Result<DataLocation> {
    let compression = layout.compression;
    let byte_skip: i64 = h
        .get2("byte skip", "byteskip")
        .map(|s| s.parse().unwrap_or(0))
        .unwrap_or(0);
    let line_skip: u64 = h
        .get2("line skip", "lineskip")
        .map(|s| s.parse().unwrap_or(0))
        .unwrap_or(0);
    let data_path = data_file.unwrap_or(path).to_path_buf();
    let mut offset = if data_file.is_some() { 0 } else { h.len };
    if line_skip > 0 {
        if compression != Compression::None {
            return Err(Error::input(
                path,
                "line skip with compressed data",
                "line skip with raw encoding only",
            ));
        }
        offset = skip_lines(&data_path, offset, line_skip)?;
    }
    let from_end = byte_skip == -1;
    if from_end && compression != Compression::None {
        return Err(Error::input(
            path,
            "byte skip: -1 with compressed data",
            "byte skip -1 only with raw encoding",
        ));
    }
    // Raw data skips bytes in the file, compressed data in the decompressed stream.
    let (offset, skip) = match compression {
        Compression::None => (offset + byte_skip.max(0) as u64, 0),
        _ => (offset, byte_skip.max(0) as u64),
    };
    Ok(DataLocation {
        path: data_path,
        offset,
        compression,
        skip,
        from_end,
        endian: layout.endian,
        exact_size: data_file.is_some()
            && compression == Compression::None
            && byte_skip == 0
            && line_skip == 0,
        read_trailer: false,
    })
}

/// The offset after `count` more lines of `data_path`, from `offset`.
fn skip_lines(data_path: &Path, mut offset: u64, count: u64) -> Result<u64> {
    use std::io::Seek;
    let f = std::fs::File::open(data_path).map_err(|e| Error::io(data_path, "opening", e))?;
    let mut r = BufReader::new(f);
    r.seek(std::io::SeekFrom::Start(offset))
        .map_err(|e| Error::io(data_path, "seeking in", e))?;
    for _ in 0..count {
        let mut l = Vec::new();
        offset += r
            .read_until(b'\n', &mut l)
            .map_err(|e| Error::io(data_path, "reading", e))? as u64;
    }
    Ok(offset)
}

pub(crate) fn open(path: &Path) -> Result<StreamReader> {
    let header = read_header(path)?;
    let layout = layout(path, &header)?;
    let affine = geometry(path, &header, &layout)?;
    let data_file = data_file(path, &header)?;
    let loc = data_location(path, &header, &layout, data_file.as_deref())?;
    let info = VolumeInfo {
        path: path.to_path_buf(),
        format: Format::Nrrd,
        dims: layout.dims,
        dtype: layout.dtype,
        affine,
        scaling: Scaling::IDENTITY,
        endian: layout.endian,
        compression: layout.compression,
        header: FormatHeader::Nrrd(NrrdHeader {
            magic: header.magic,
            lines: header.lines,
            data_file,
        }),
    };
    StreamReader::new(info, loc)
}

fn fmt_vec(v: [f64; 3]) -> String {
    format!("({},{},{})", fmt_num(v[0]), fmt_num(v[1]), fmt_num(v[2]))
}

/// Shortest decimal that reads back to the same f64.
pub(crate) fn fmt_num(x: f64) -> String {
    if x == 0.0 {
        return "0".into();
    }
    format!("{x}")
}

/// Header lines describing `source` in NRRD terms (RAS space).
fn new_lines(source: &VolumeInfo) -> Vec<String> {
    let a = &source.affine;
    let col = |c: usize| [a.m[0][c], a.m[1][c], a.m[2][c]];
    vec![
        "# written by isotopo".to_string(),
        format!("type: {}", nrrd_type_name(source.dtype)),
        "dimension: 3".to_string(),
        "space: right-anterior-superior".to_string(),
        format!(
            "sizes: {} {} {}",
            source.dims[0], source.dims[1], source.dims[2]
        ),
        format!(
            "space directions: {} {} {}",
            fmt_vec(col(0)),
            fmt_vec(col(1)),
            fmt_vec(col(2))
        ),
        "kinds: domain domain domain".to_string(),
        "endian: little".to_string(),
        "encoding: gzip".to_string(),
        format!("space origin: {}", fmt_vec(a.origin())),
    ]
}

/// Adjusts a header's lines for writing: the right encoding and data-file fields, no skips.
fn output_lines(lines: &[String], data_file: Option<&str>) -> (Vec<String>, Compression, Endian) {
    let mut out = Vec::new();
    let mut compression = Compression::Gzip;
    let mut endian = Endian::Little;
    for l in lines {
        let key = l
            .split_once(':')
            .map(|(k, _)| k.trim().to_ascii_lowercase())
            .unwrap_or_default();
        if l.starts_with('#') || l.contains(":=") {
            out.push(l.clone());
            continue;
        }
        match key.as_str() {
            "data file" | "datafile" | "byte skip" | "byteskip" | "line skip" | "lineskip" => {
                continue
            }
            "encoding" => {
                let v = l.split_once(':').map(|(_, v)| v.trim()).unwrap_or("");
                compression = if v == "raw" {
                    Compression::None
                } else {
                    Compression::Gzip
                };
                out.push(format!(
                    "encoding: {}",
                    if compression == Compression::None {
                        "raw"
                    } else {
                        "gzip"
                    }
                ));
            }
            "endian" => {
                let v = l.split_once(':').map(|(_, v)| v.trim()).unwrap_or("");
                endian = if v == "big" {
                    Endian::Big
                } else {
                    Endian::Little
                };
                out.push(l.clone());
            }
            _ => out.push(l.clone()),
        }
    }
    if let Some(df) = data_file {
        out.push(format!("data file: {df}"));
    }
    (out, compression, endian)
}

pub(crate) struct NrrdWriter {
    samples: SampleWriter,
    /// Detached: the header, written after the data.
    header: Option<(PathBuf, Vec<u8>)>,
}

pub(crate) fn create(path: &Path, source: &VolumeInfo) -> Result<NrrdWriter> {
    let (magic, lines) = match &source.header {
        FormatHeader::Nrrd(h) => (h.magic.clone(), h.lines.clone()),
        _ => ("NRRD0004".to_string(), new_lines(source)),
    };
    let detached = path
        .extension()
        .map(|e| e.eq_ignore_ascii_case("nhdr"))
        .unwrap_or(false);
    let (_, compression, _) = output_lines(&lines, None);
    let data_name = detached.then(|| {
        let stem = path
            .file_stem()
            .unwrap_or_default()
            .to_string_lossy()
            .to_string();
        if compression == Compression::Gzip {
            format!("{stem}.raw.gz")
        } else {
            format!("{stem}.raw")
        }
    });
    let (lines, compression, endian) = output_lines(&lines, data_name.as_deref());
    let mut text = format!("{magic}\n");
    for l in &lines {
        text.push_str(l);
        text.push('\n');
    }
    text.push('\n');
    let (out, header) = if let Some(name) = data_name {
        let data_path = path.with_file_name(name);
        super::check_output_path(&data_path, source)?;
        (
            AtomicOutput::create(&data_path, compression)?,
            Some((path.to_path_buf(), text.into_bytes())),
        )
    } else {
        let mut out = AtomicOutput::create(path, Compression::None)?;
        out.write_all(text.as_bytes())?;
        out.begin_compression(compression);
        (out, None)
    };
    Ok(NrrdWriter {
        samples: SampleWriter::new(out, endian, source),
        header,
    })
}

impl SliceWriter for NrrdWriter {
    fn write_slice(&mut self, slice: &Samples) -> Result<()> {
        self.samples.write_slice(slice)
    }
    fn finish(self: Box<Self>, _source: &VolumeInfo) -> Result<()> {
        self.samples.out.commit()?;
        if let Some((path, bytes)) = self.header {
            let mut h = AtomicOutput::create(&path, Compression::None)?;
            h.write_all(&bytes)?;
            h.commit()?;
        }
        Ok(())
    }
}
