//! NumPy `.npy`. Arrays are indexed `[x, y, z]`, like nibabel's `get_fdata()`: a Fortran-ordered
//! array streams directly; a C-ordered one (z fastest) is read in blocks of z-slices with strided
//! reads, so memory stays bounded either way. Written files are Fortran-ordered (`np.load` gives
//! back the same array).

use super::stream::{AtomicOutput, DataLocation, SampleWriter, StreamReader};
use super::{
    check_dims, Affine, Compression, DType, Endian, Format, FormatHeader, ReadOptions, Samples,
    Scaling, SliceReader, VolumeInfo,
};
use crate::error::{Error, Result};
use std::io::Read;
use std::path::Path;

const EXPECT: &str = "a NumPy .npy file of a 1- to 3-D numeric array";

struct NpyHeader {
    dtype: DType,
    endian: Endian,
    fortran: bool,
    shape: Vec<usize>,
    data_offset: u64,
}

fn parse_descr(path: &Path, d: &str) -> Result<(DType, Endian)> {
    // The byte order is one character; split after it, not after a byte (a header is not
    // always ASCII).
    let cut = d.chars().next().map_or(0, char::len_utf8);
    let (order, ty) = d.split_at(cut);
    let endian = match order {
        "<" | "|" => Endian::Little,
        ">" => Endian::Big,
        "=" => Endian::NATIVE,
        _ => {
            return Err(Error::input(
                path,
                format!("dtype '{d}'"),
                "a numeric dtype like '<i2'",
            ))
        }
    };
    let t = match ty {
        "u1" | "b1" => DType::U8,
        "i1" => DType::I8,
        "u2" => DType::U16,
        "i2" => DType::I16,
        "u4" => DType::U32,
        "i4" => DType::I32,
        "f4" => DType::F32,
        "f8" => DType::F64,
        _ => {
            return Err(Error::input(
                path,
                format!("unsupported dtype '{d}'"),
                "uint8, int8, uint16, int16, uint32, int32, float32, float64 or bool (convert with arr.astype)",
            ))
        }
    };
    Ok((t, endian))
}

/// Value of `'key': value` in the header dict (value up to the next top-level comma).
fn dict_value<'a>(dict: &'a str, key: &str) -> Option<&'a str> {
    let k1 = format!("'{key}'");
    let k2 = format!("\"{key}\"");
    let start = dict
        .find(&k1)
        .map(|i| i + k1.len())
        .or_else(|| dict.find(&k2).map(|i| i + k2.len()))?;
    let rest = dict[start..].trim_start().strip_prefix(':')?.trim_start();
    let mut depth = 0;
    for (i, c) in rest.char_indices() {
        match c {
            '(' | '[' => depth += 1,
            ')' | ']' => {
                if depth == 0 {
                    return Some(rest[..i].trim());
                }
                depth -= 1;
                if depth == 0 {
                    return Some(rest[..=i].trim());
                }
            }
            ',' | '}' if depth == 0 => return Some(rest[..i].trim()),
            _ => {}
        }
    }
    None
}

fn read_header(path: &Path) -> Result<NpyHeader> {
    let mut f = std::fs::File::open(path).map_err(|e| Error::io(path, "opening", e))?;
    let mut pre = [0u8; 12];
    let n = f
        .read(&mut pre)
        .map_err(|e| Error::io(path, "reading", e))?;
    if n < 10 || &pre[..6] != b"\x93NUMPY" {
        return Err(Error::input(path, "no NumPy magic", EXPECT));
    }
    let major = pre[6];
    let (len, start) = match major {
        1 => (u16::from_le_bytes([pre[8], pre[9]]) as usize, 10),
        2 | 3 => (
            u32::from_le_bytes(pre[8..12].try_into().unwrap()) as usize,
            12,
        ),
        v => {
            return Err(Error::input(
                path,
                format!("npy format version {v}"),
                "version 1, 2 or 3",
            ))
        }
    };
    if len > 1 << 20 {
        return Err(Error::input(path, format!("a {len}-byte header"), EXPECT));
    }
    let mut f = std::fs::File::open(path).map_err(|e| Error::io(path, "opening", e))?;
    let mut all = vec![0u8; start + len];
    f.read_exact(&mut all)
        .map_err(|_| Error::input(path, "a file that ends inside its header", EXPECT))?;
    let dict = String::from_utf8_lossy(&all[start..]).to_string();
    let descr = dict_value(&dict, "descr")
        .ok_or_else(|| Error::input(path, "no 'descr' in the header", EXPECT))?;
    let descr = descr.trim_matches(|c| c == '\'' || c == '"');
    let (dtype, endian) = parse_descr(path, descr)?;
    let fortran = match dict_value(&dict, "fortran_order") {
        Some("True") => true,
        Some("False") => false,
        other => {
            return Err(Error::input(
                path,
                format!("fortran_order {other:?}"),
                "True or False",
            ))
        }
    };
    let shape_s = dict_value(&dict, "shape")
        .ok_or_else(|| Error::input(path, "no 'shape' in the header", EXPECT))?;
    let inner = shape_s.trim_start_matches('(').trim_end_matches(')');
    let shape: Vec<usize> = inner
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| s.trim_end_matches('L').parse::<usize>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|_| Error::input(path, format!("shape {shape_s}"), "a tuple of sizes"))?;
    Ok(NpyHeader {
        dtype,
        endian,
        fortran,
        shape,
        data_offset: (start + len) as u64,
    })
}

pub(crate) fn open(path: &Path, options: &ReadOptions) -> Result<Box<dyn SliceReader>> {
    let h = read_header(path)?;
    let mut shape = h.shape.clone();
    while shape.len() > 3 && shape.last() == Some(&1) {
        shape.pop();
    }
    if shape.is_empty() || shape.len() > 3 {
        return Err(Error::input(
            path,
            format!("an array of shape {:?}", h.shape),
            "a 1- to 3-D array indexed [x, y, z]",
        ));
    }
    let mut dims = [1usize; 3];
    dims[..shape.len()].copy_from_slice(&shape);
    let info = VolumeInfo {
        path: path.to_path_buf(),
        format: Format::Npy,
        dims,
        dtype: h.dtype,
        affine: Affine::from_spacing(options.raw_spacing.unwrap_or([1.0; 3]), [0.0; 3]),
        scaling: Scaling::IDENTITY,
        endian: h.endian,
        compression: Compression::None,
        header: FormatHeader::Npy,
    };
    // One axis of extent > 1 at most, or Fortran order: the bytes are already x-fastest.
    let nontrivial = dims.iter().filter(|&&d| d > 1).count();
    if h.fortran || nontrivial <= 1 {
        let loc = DataLocation {
            path: path.to_path_buf(),
            offset: h.data_offset,
            compression: Compression::None,
            skip: 0,
            from_end: false,
            endian: h.endian,
            exact_size: true,
            read_trailer: false,
        };
        return Ok(Box::new(StreamReader::new(info, loc)?));
    }
    Ok(Box::new(COrderReader::new(info, h)?))
}

/// Reads a C-ordered `[x, y, z]` array (z fastest) as z-slices, a block of slices at a time.
struct COrderReader {
    info: VolumeInfo,
    file: std::fs::File,
    offset: u64,
    position: usize,
    /// Slices `block_start .. block_start + block_len`, as bytes laid out `[x][y][dz]`.
    block: Vec<u8>,
    block_start: usize,
    block_len: usize,
    bytes: Vec<u8>,
}

const BLOCK_BYTES: usize = 64 << 20;

impl COrderReader {
    fn new(info: VolumeInfo, h: NpyHeader) -> Result<COrderReader> {
        check_dims(&info.path, info.dims, info.dtype)?;
        let need = info.voxel_count() * info.dtype.size() as u64;
        let file =
            std::fs::File::open(&info.path).map_err(|e| Error::io(&info.path, "opening", e))?;
        let len = file
            .metadata()
            .map_err(|e| Error::io(&info.path, "reading", e))?
            .len();
        let have = len.saturating_sub(h.data_offset);
        if have != need {
            return Err(Error::input(
                &info.path,
                format!("{have} bytes of data"),
                format!("{need} bytes for shape {:?} of {}", h.shape, info.dtype),
            ));
        }
        Ok(COrderReader {
            info,
            file,
            offset: h.data_offset,
            position: 0,
            block: Vec::new(),
            block_start: 0,
            block_len: 0,
            bytes: Vec::new(),
        })
    }

    fn load_block(&mut self, z0: usize) -> Result<()> {
        let [nx, ny, nz] = self.info.dims;
        let s = self.info.dtype.size();
        let per_slice = nx * ny * s;
        let b = (BLOCK_BYTES / per_slice.max(1)).clamp(1, nz - z0);
        if self.block.len() < nx * ny * b * s {
            crate::memory::reserve(
                "a block of slices of a C-ordered .npy (read across its layout)",
                (nx * ny * b * s - self.block.len()) as u64,
            )?;
        }
        self.block.resize(nx * ny * b * s, 0);
        for xy in 0..nx * ny {
            let at = self.offset + ((xy * nz + z0) * s) as u64;
            read_at(
                &self.file,
                &mut self.block[xy * b * s..(xy + 1) * b * s],
                at,
            )
            .map_err(|e| Error::io(&self.info.path, "reading", e))?;
        }
        self.block_start = z0;
        self.block_len = b;
        Ok(())
    }
}

#[cfg(unix)]
fn read_at(f: &std::fs::File, buf: &mut [u8], at: u64) -> std::io::Result<()> {
    use std::os::unix::fs::FileExt;
    f.read_exact_at(buf, at)
}

#[cfg(not(unix))]
fn read_at(f: &std::fs::File, buf: &mut [u8], at: u64) -> std::io::Result<()> {
    use std::io::{Read, Seek, SeekFrom};
    let mut f = f;
    f.seek(SeekFrom::Start(at))?;
    f.read_exact(buf)
}

impl SliceReader for COrderReader {
    fn info(&self) -> &VolumeInfo {
        &self.info
    }

    fn read_slice(&mut self, out: &mut Samples) -> Result<()> {
        let [nx, ny, _] = self.info.dims;
        let z = self.position;
        if z >= self.block_start + self.block_len || z < self.block_start || self.block_len == 0 {
            self.load_block(z)?;
        }
        let s = self.info.dtype.size();
        let (b, dz) = (self.block_len, z - self.block_start);
        self.bytes.resize(nx * ny * s, 0);
        // Element (x, y) of this slice sits at [x][y][dz] in the block; the slice wants x fastest.
        for y in 0..ny {
            for x in 0..nx {
                let src = ((x * ny + y) * b + dz) * s;
                let dst = (y * nx + x) * s;
                self.bytes[dst..dst + s].copy_from_slice(&self.block[src..src + s]);
            }
        }
        if out.dtype() != self.info.dtype {
            *out = Samples::new(self.info.dtype);
        }
        out.decode(&self.bytes, self.info.endian);
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

fn descr(t: DType) -> &'static str {
    match t {
        DType::U8 => "|u1",
        DType::I8 => "|i1",
        DType::U16 => "<u2",
        DType::I16 => "<i2",
        DType::U32 => "<u4",
        DType::I32 => "<i4",
        DType::F32 => "<f4",
        DType::F64 => "<f8",
    }
}

pub(crate) fn create(path: &Path, source: &VolumeInfo) -> Result<SampleWriter> {
    let [nx, ny, nz] = source.dims;
    let mut dict = format!(
        "{{'descr': '{}', 'fortran_order': True, 'shape': ({nx}, {ny}, {nz}), }}",
        descr(source.dtype)
    );
    // Magic (6) + version (2) + length (2) + dict + '\n' is padded to a multiple of 64.
    let total = 10 + dict.len() + 1;
    dict.push_str(&" ".repeat((64 - total % 64) % 64));
    dict.push('\n');
    let mut out = AtomicOutput::create(path, Compression::None)?;
    let mut head = b"\x93NUMPY\x01\x00".to_vec();
    head.extend_from_slice(&(dict.len() as u16).to_le_bytes());
    head.extend_from_slice(dict.as_bytes());
    out.write_all(&head)?;
    Ok(SampleWriter::new(out, Endian::Little, source))
}
