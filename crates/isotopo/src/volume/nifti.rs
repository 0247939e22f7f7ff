//! NIfTI-1 and NIfTI-2 (`.nii`, `.nii.gz`): read both, write back the input's own header.
//!
//! Geometry follows nibabel: the sform when `sform_code > 0`, else the qform when `qform_code > 0`,
//! else the Analyze fallback (voxel sizes, centred, x flipped). `scl_slope`/`scl_inter` scale raw
//! samples into values (a slope of 0 or NaN means no scaling).

use super::stream::{AtomicOutput, DataLocation, SampleWriter, StreamReader};
use super::{Affine, Compression, DType, Endian, Format, FormatHeader, Scaling, VolumeInfo};
use crate::error::{Error, Result};
use flate2::read::MultiGzDecoder;
use std::io::Read;
use std::path::Path;

/// The header as found in the file: bytes 0..vox_offset (header, extension flag, extensions).
#[derive(Clone, Debug)]
pub struct NiftiHeader {
    /// 1 or 2.
    pub version: u8,
    pub endian: Endian,
    pub bytes: Vec<u8>,
}

const EXPECT: &str = "a NIfTI-1 (348-byte) or NIfTI-2 (540-byte) header";

fn dtype_from_code(code: i32) -> Option<DType> {
    Some(match code {
        2 => DType::U8,
        4 => DType::I16,
        8 => DType::I32,
        16 => DType::F32,
        64 => DType::F64,
        256 => DType::I8,
        512 => DType::U16,
        768 => DType::U32,
        _ => return None,
    })
}

fn code_from_dtype(t: DType) -> i16 {
    match t {
        DType::U8 => 2,
        DType::I16 => 4,
        DType::I32 => 8,
        DType::F32 => 16,
        DType::F64 => 64,
        DType::I8 => 256,
        DType::U16 => 512,
        DType::U32 => 768,
    }
}

fn code_name(code: i32) -> String {
    match code {
        1 => "binary (1-bit)".into(),
        32 => "complex64".into(),
        128 => "RGB24".into(),
        1024 => "int64".into(),
        1280 => "uint64".into(),
        1536 => "float128".into(),
        1792 => "complex128".into(),
        2048 => "complex256".into(),
        2304 => "RGBA32".into(),
        c => format!("datatype code {c}"),
    }
}

/// Reads little- or big-endian fields from header bytes.
struct Fields<'a> {
    b: &'a [u8],
    e: Endian,
}

impl Fields<'_> {
    fn i16(&self, o: usize) -> i16 {
        let a = self.b[o..o + 2].try_into().unwrap();
        match self.e {
            Endian::Little => i16::from_le_bytes(a),
            Endian::Big => i16::from_be_bytes(a),
        }
    }
    fn i32(&self, o: usize) -> i32 {
        let a = self.b[o..o + 4].try_into().unwrap();
        match self.e {
            Endian::Little => i32::from_le_bytes(a),
            Endian::Big => i32::from_be_bytes(a),
        }
    }
    fn i64(&self, o: usize) -> i64 {
        let a = self.b[o..o + 8].try_into().unwrap();
        match self.e {
            Endian::Little => i64::from_le_bytes(a),
            Endian::Big => i64::from_be_bytes(a),
        }
    }
    fn f32(&self, o: usize) -> f64 {
        let a = self.b[o..o + 4].try_into().unwrap();
        (match self.e {
            Endian::Little => f32::from_le_bytes(a),
            Endian::Big => f32::from_be_bytes(a),
        }) as f64
    }
    fn f64(&self, o: usize) -> f64 {
        let a = self.b[o..o + 8].try_into().unwrap();
        match self.e {
            Endian::Little => f64::from_le_bytes(a),
            Endian::Big => f64::from_be_bytes(a),
        }
    }
}

/// Header fields, whatever the version.
struct Parsed {
    dim: [i64; 8],
    datatype: i32,
    pixdim: [f64; 8],
    vox_offset: f64,
    scl_slope: f64,
    scl_inter: f64,
    qform_code: i32,
    sform_code: i32,
    quatern: [f64; 3],
    qoffset: [f64; 3],
    srow: [[f64; 4]; 3],
}

fn parse(b: &[u8], version: u8, e: Endian) -> Parsed {
    let f = Fields { b, e };
    if version == 1 {
        Parsed {
            dim: std::array::from_fn(|i| f.i16(40 + 2 * i) as i64),
            datatype: f.i16(70) as i32,
            pixdim: std::array::from_fn(|i| f.f32(76 + 4 * i)),
            vox_offset: f.f32(108),
            scl_slope: f.f32(112),
            scl_inter: f.f32(116),
            qform_code: f.i16(252) as i32,
            sform_code: f.i16(254) as i32,
            quatern: [f.f32(256), f.f32(260), f.f32(264)],
            qoffset: [f.f32(268), f.f32(272), f.f32(276)],
            srow: std::array::from_fn(|r| std::array::from_fn(|c| f.f32(280 + 16 * r + 4 * c))),
        }
    } else {
        Parsed {
            dim: std::array::from_fn(|i| f.i64(16 + 8 * i)),
            datatype: f.i16(12) as i32,
            pixdim: std::array::from_fn(|i| f.f64(104 + 8 * i)),
            vox_offset: f.i64(168) as f64,
            scl_slope: f.f64(176),
            scl_inter: f.f64(184),
            qform_code: f.i32(344),
            sform_code: f.i32(348),
            quatern: [f.f64(352), f.f64(360), f.f64(368)],
            qoffset: [f.f64(376), f.f64(384), f.f64(392)],
            srow: std::array::from_fn(|r| std::array::from_fn(|c| f.f64(400 + 32 * r + 8 * c))),
        }
    }
}

/// The quaternion form of the header (qform) as an affine.
fn qform_affine(p: &Parsed) -> Affine {
    let [b, c, d] = p.quatern;
    let a = (1.0 - (b * b + c * c + d * d)).max(0.0).sqrt();
    let r = [
        [
            a * a + b * b - c * c - d * d,
            2.0 * (b * c - a * d),
            2.0 * (b * d + a * c),
        ],
        [
            2.0 * (b * c + a * d),
            a * a + c * c - b * b - d * d,
            2.0 * (c * d - a * b),
        ],
        [
            2.0 * (b * d - a * c),
            2.0 * (c * d + a * b),
            a * a + d * d - c * c - b * b,
        ],
    ];
    let qfac = if p.pixdim[0] < 0.0 { -1.0 } else { 1.0 };
    let zooms = [p.pixdim[1], p.pixdim[2], p.pixdim[3] * qfac];
    Affine::from_parts(r, zooms, p.qoffset)
}

fn best_affine(p: &Parsed, dims: [usize; 3]) -> Affine {
    if p.sform_code > 0 {
        let mut a = Affine::IDENTITY;
        a.m = p.srow;
        if a.is_valid() {
            return a;
        }
    }
    if p.qform_code > 0 {
        let a = qform_affine(p);
        if a.is_valid() {
            return a;
        }
    }
    // Analyze fallback, as nibabel: radiological x, origin at the centre of the grid.
    let z = |i: usize| {
        if p.pixdim[i] > 0.0 && p.pixdim[i].is_finite() {
            p.pixdim[i]
        } else {
            1.0
        }
    };
    let zooms = [-z(1), z(2), z(3)];
    let origin: [f64; 3] = std::array::from_fn(|i| -zooms[i] * (dims[i] as f64 - 1.0) / 2.0);
    Affine::from_spacing(zooms, origin)
}

fn is_gz(path: &Path) -> bool {
    path.to_string_lossy().to_ascii_lowercase().ends_with(".gz")
}

/// The header's version and byte order, from the header-size field (348 or 540, either byte
/// order) and the magic; `head` is the first (up to 540) bytes of the stream.
fn version(path: &Path, head: &[u8]) -> Result<(u8, Endian)> {
    let n = head.len();
    if n < 348 {
        return Err(Error::input(
            path,
            format!("a file of only {n} bytes"),
            EXPECT,
        ));
    }
    let le = i32::from_le_bytes(head[0..4].try_into().unwrap());
    let (version, endian) = match le {
        348 => (1, Endian::Little),
        540 => (2, Endian::Little),
        x if x.swap_bytes() == 348 => (1, Endian::Big),
        x if x.swap_bytes() == 540 => (2, Endian::Big),
        x => {
            return Err(Error::input(path, format!("header size field {x}"), EXPECT));
        }
    };
    if n < header_size(version) {
        return Err(Error::input(
            path,
            format!("a NIfTI-{version} header cut off after {n} bytes"),
            EXPECT,
        ));
    }
    check_magic(path, head, version)?;
    Ok((version, endian))
}

fn header_size(version: u8) -> usize {
    if version == 1 {
        348
    } else {
        540
    }
}

/// Single-file magic: `n+1` (NIfTI-1) or `n+2` (NIfTI-2); `ni1` is a .hdr/.img pair.
fn check_magic(path: &Path, head: &[u8], version: u8) -> Result<()> {
    if version == 1 {
        let magic = &head[344..348];
        if magic == b"ni1\0" {
            return Err(Error::input(
                path,
                "a NIfTI-1 header of a .hdr/.img pair",
                "a single-file NIfTI (.nii or .nii.gz); convert the pair with nibabel or fslchfiletype",
            ));
        }
        if magic != b"n+1\0" {
            return Err(Error::input(
                path,
                format!("magic {:?}", String::from_utf8_lossy(magic)),
                "NIfTI-1 magic \"n+1\"",
            ));
        }
    } else if &head[4..8] != b"n+2\0" {
        return Err(Error::input(
            path,
            format!("magic {:?}", String::from_utf8_lossy(&head[4..8])),
            "NIfTI-2 magic \"n+2\"",
        ));
    }
    Ok(())
}

/// The three spatial sizes; further axes must have size 1.
fn dims(path: &Path, p: &Parsed) -> Result<[usize; 3]> {
    let ndim = p.dim[0];
    if !(1..=7).contains(&ndim) {
        return Err(Error::input(
            path,
            format!("dim[0] = {ndim}"),
            "1 to 7 dimensions",
        ));
    }
    let mut dims = [1usize; 3];
    for i in 0..ndim as usize {
        let d = p.dim[i + 1];
        if d < 1 {
            return Err(Error::input(
                path,
                format!("dim[{}] = {d}", i + 1),
                "positive sizes",
            ));
        }
        if i < 3 {
            dims[i] = d as usize;
        } else if d > 1 {
            return Err(Error::input(
                path,
                format!("a {ndim}-D image with {d} samples along axis {}", i + 1),
                "a 3-D volume (extra axes of size 1)",
            ));
        }
    }
    Ok(dims)
}

fn sample_type(path: &Path, p: &Parsed) -> Result<DType> {
    dtype_from_code(p.datatype).ok_or_else(|| {
        Error::input(
            path,
            format!("unsupported sample type {}", code_name(p.datatype)),
            "uint8, int8, uint16, int16, uint32, int32, float32 or float64 samples",
        )
    })
}

/// Where the samples start in the (decompressed) stream.
fn vox_offset(path: &Path, p: &Parsed, version: u8) -> Result<u64> {
    let vox_offset = p.vox_offset;
    if !(vox_offset.is_finite() && vox_offset >= 0.0 && vox_offset <= (1u64 << 32) as f64) {
        return Err(Error::input(
            path,
            format!("vox_offset {vox_offset}"),
            "a byte offset after the header",
        ));
    }
    // NIfTI allows vox_offset 0 in .hdr/.img pairs only; single files put data after the header.
    Ok((vox_offset as u64).max(header_size(version) as u64 + 4))
}

/// The bytes before the samples (header, extension flag, extensions), kept for writing back.
fn header_bytes(
    path: &Path,
    gz: bool,
    head: Vec<u8>,
    input: &mut dyn Read,
    vox_offset: u64,
) -> Result<Vec<u8>> {
    // `head` holds the first bytes of the stream (`input` the rest); keep exactly those before
    // the samples.
    let mut bytes = head;
    if (bytes.len() as u64) >= vox_offset {
        bytes.truncate(vox_offset as usize);
    } else {
        // Read, not allocated from the header: the buffer grows only as far as the file goes.
        let want = vox_offset - bytes.len() as u64;
        input
            .take(want)
            .read_to_end(&mut bytes)
            .map_err(|e| gz_error(path, gz, e))?;
        if (bytes.len() as u64) < vox_offset {
            return Err(Error::input(
                path,
                format!("the file ends before vox_offset {vox_offset}"),
                "sample data after the header",
            ));
        }
    }
    Ok(bytes)
}

/// `scl_slope`/`scl_inter`; a slope of 0 or NaN (or a non-finite intercept) means none.
fn scaling(p: &Parsed) -> Scaling {
    if p.scl_slope.is_finite() && p.scl_slope != 0.0 && p.scl_inter.is_finite() {
        Scaling {
            slope: p.scl_slope,
            inter: p.scl_inter,
        }
    } else {
        Scaling::IDENTITY
    }
}

pub(crate) fn open(path: &Path) -> Result<StreamReader> {
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, "opening", e))?;
    let gz = is_gz(path);
    let mut input: Box<dyn Read> = if gz {
        Box::new(MultiGzDecoder::new(std::io::BufReader::new(file)))
    } else {
        Box::new(std::io::BufReader::new(file))
    };
    let mut head = vec![0u8; 540];
    let n = read_up_to(&mut input, &mut head).map_err(|e| gz_error(path, gz, e))?;
    head.truncate(n);
    let (version, endian) = version(path, &head)?;
    let p = parse(&head, version, endian);
    let dims = dims(path, &p)?;
    let dtype = sample_type(path, &p)?;
    let vox_offset = vox_offset(path, &p, version)?;
    let bytes = header_bytes(path, gz, head, &mut input, vox_offset)?;
    let compression = if gz {
        Compression::Gzip
    } else {
        Compression::None
    };
    let info = VolumeInfo {
        path: path.to_path_buf(),
        format: Format::Nifti,
        dims,
        dtype,
        affine: best_affine(&p, dims),
        scaling: scaling(&p),
        endian,
        compression,
        header: FormatHeader::Nifti(NiftiHeader {
            version,
            endian,
            bytes,
        }),
    };
    // A gzip stream cannot seek: the header bytes are skipped after decompressing.
    let loc = DataLocation {
        path: path.to_path_buf(),
        offset: if gz { 0 } else { vox_offset },
        compression,
        skip: if gz { vox_offset } else { 0 },
        from_end: false,
        endian,
        exact_size: false,
        read_trailer: false,
    };
    StreamReader::new(info, loc)
}

fn read_up_to(r: &mut dyn Read, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut n = 0;
    while n < buf.len() {
        match r.read(&mut buf[n..]) {
            Ok(0) => break,
            Ok(k) => n += k,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(n)
}

fn gz_error(path: &Path, gz: bool, e: std::io::Error) -> Error {
    if gz {
        Error::input(
            path,
            format!("corrupt gzip data ({e})"),
            "a gzip-compressed NIfTI file",
        )
    } else {
        Error::io(path, "reading", e)
    }
}

/// Quaternion (b, c, d), qfac and whether the direction matrix was a rotation (else no qform).
fn quaternion(dir: [[f64; 3]; 3]) -> Option<([f64; 3], f64)> {
    let mut r = dir;
    let det = r[0][0] * (r[1][1] * r[2][2] - r[1][2] * r[2][1])
        - r[0][1] * (r[1][0] * r[2][2] - r[1][2] * r[2][0])
        + r[0][2] * (r[1][0] * r[2][1] - r[1][1] * r[2][0]);
    let qfac = if det < 0.0 { -1.0 } else { 1.0 };
    if qfac < 0.0 {
        for row in r.iter_mut() {
            row[2] = -row[2];
        }
    }
    // Orthonormal columns?
    for i in 0..3 {
        for j in 0..3 {
            let dot: f64 = (0..3).map(|k| r[k][i] * r[k][j]).sum();
            let want = if i == j { 1.0 } else { 0.0 };
            if (dot - want).abs() > 1e-4 {
                return None;
            }
        }
    }
    let (r11, r12, r13) = (r[0][0], r[0][1], r[0][2]);
    let (r21, r22, r23) = (r[1][0], r[1][1], r[1][2]);
    let (r31, r32, r33) = (r[2][0], r[2][1], r[2][2]);
    let trace = r11 + r22 + r33 + 1.0;
    let (a, mut b, mut c, mut d): (f64, f64, f64, f64);
    if trace > 0.5 {
        a = 0.5 * trace.sqrt();
        b = 0.25 * (r32 - r23) / a;
        c = 0.25 * (r13 - r31) / a;
        d = 0.25 * (r21 - r12) / a;
    } else {
        let xd = 1.0 + r11 - (r22 + r33);
        let yd = 1.0 + r22 - (r11 + r33);
        let zd = 1.0 + r33 - (r11 + r22);
        if xd > 1.0 {
            b = 0.5 * xd.sqrt();
            c = 0.25 * (r12 + r21) / b;
            d = 0.25 * (r13 + r31) / b;
            a = 0.25 * (r32 - r23) / b;
        } else if yd > 1.0 {
            c = 0.5 * yd.sqrt();
            b = 0.25 * (r12 + r21) / c;
            d = 0.25 * (r23 + r32) / c;
            a = 0.25 * (r13 - r31) / c;
        } else {
            d = 0.5 * zd.sqrt();
            b = 0.25 * (r13 + r31) / d;
            c = 0.25 * (r23 + r32) / d;
            a = 0.25 * (r21 - r12) / d;
        }
        if a < 0.0 {
            b = -b;
            c = -c;
            d = -d;
        }
    }
    Some(([b, c, d], qfac))
}

/// What a fresh header states about a volume, in either version.
struct Fresh {
    dims: [usize; 3],
    dtype: DType,
    /// qfac, then the voxel sizes.
    pixdim: [f64; 8],
    slope: f64,
    inter: f64,
    /// Quaternion (b, c, d) when the direction matrix is a rotation (then a qform is written).
    quatern: Option<[f64; 3]>,
    /// The affine, written as the sform (and its last column as the qform's offset).
    m: [[f64; 4]; 3],
}

impl Fresh {
    fn of(source: &VolumeInfo) -> Fresh {
        let spacing = source.affine.spacing();
        let quat = quaternion(source.affine.direction());
        let qfac = quat.map(|q| q.1).unwrap_or(1.0);
        // A slope of 0 means no scaling.
        let (slope, inter) = if source.scaling.is_identity() {
            (0.0, 0.0)
        } else {
            (source.scaling.slope, source.scaling.inter)
        };
        Fresh {
            dims: source.dims,
            dtype: source.dtype,
            pixdim: [qfac, spacing[0], spacing[1], spacing[2], 1.0, 1.0, 1.0, 1.0],
            slope,
            inter,
            quatern: quat.map(|q| q.0),
            m: source.affine.m,
        }
    }
}

/// A fresh header describing `source` (when it comes from another format): NIfTI-1 unless a
/// size does not fit its 16-bit dims.
fn new_header(source: &VolumeInfo) -> NiftiHeader {
    let fresh = Fresh::of(source);
    let (version, bytes) = if source.dims.iter().any(|&d| d > i16::MAX as usize) {
        (2, nifti2_bytes(&fresh))
    } else {
        (1, nifti1_bytes(&fresh))
    };
    NiftiHeader {
        version,
        endian: Endian::Little,
        bytes,
    }
}

/// A little-endian NIfTI-1 header, empty extension flag included (352 bytes).
fn nifti1_bytes(f: &Fresh) -> Vec<u8> {
    let [nx, ny, nz] = f.dims;
    let m = f.m;
    let mut b = vec![0u8; 352];
    let put16 = |b: &mut Vec<u8>, o: usize, v: i16| b[o..o + 2].copy_from_slice(&v.to_le_bytes());
    let put32 = |b: &mut Vec<u8>, o: usize, v: i32| b[o..o + 4].copy_from_slice(&v.to_le_bytes());
    let putf =
        |b: &mut Vec<u8>, o: usize, v: f64| b[o..o + 4].copy_from_slice(&(v as f32).to_le_bytes());
    put32(&mut b, 0, 348);
    b[39] = 0; // dim_info
    let dim = [3i16, nx as i16, ny as i16, nz as i16, 1, 1, 1, 1];
    for (i, d) in dim.iter().enumerate() {
        put16(&mut b, 40 + 2 * i, *d);
    }
    put16(&mut b, 70, code_from_dtype(f.dtype));
    put16(&mut b, 72, (f.dtype.size() * 8) as i16);
    for (i, p) in f.pixdim.iter().enumerate() {
        putf(&mut b, 76 + 4 * i, *p);
    }
    putf(&mut b, 108, 352.0);
    putf(&mut b, 112, f.slope);
    putf(&mut b, 116, f.inter);
    b[123] = 2 | 8; // mm, seconds
    let descrip = b"isotopo";
    b[148..148 + descrip.len()].copy_from_slice(descrip);
    if let Some(q) = f.quatern {
        put16(&mut b, 252, 1);
        for (i, v) in q.iter().enumerate() {
            putf(&mut b, 256 + 4 * i, *v);
        }
        for i in 0..3 {
            putf(&mut b, 268 + 4 * i, m[i][3]);
        }
    }
    put16(&mut b, 254, 1);
    for r in 0..3 {
        for c in 0..4 {
            putf(&mut b, 280 + 16 * r + 4 * c, m[r][c]);
        }
    }
    b[344..348].copy_from_slice(b"n+1\0");
    b
}

/// A little-endian NIfTI-2 header, empty extension flag included (544 bytes).
fn nifti2_bytes(f: &Fresh) -> Vec<u8> {
    let [nx, ny, nz] = f.dims;
    let m = f.m;
    let mut b = vec![0u8; 544];
    let put16 = |b: &mut Vec<u8>, o: usize, v: i16| b[o..o + 2].copy_from_slice(&v.to_le_bytes());
    let put32 = |b: &mut Vec<u8>, o: usize, v: i32| b[o..o + 4].copy_from_slice(&v.to_le_bytes());
    let put64 = |b: &mut Vec<u8>, o: usize, v: i64| b[o..o + 8].copy_from_slice(&v.to_le_bytes());
    let putf = |b: &mut Vec<u8>, o: usize, v: f64| b[o..o + 8].copy_from_slice(&v.to_le_bytes());
    put32(&mut b, 0, 540);
    b[4..12].copy_from_slice(b"n+2\0\r\n\x1a\n");
    put16(&mut b, 12, code_from_dtype(f.dtype));
    put16(&mut b, 14, (f.dtype.size() * 8) as i16);
    let dim = [3i64, nx as i64, ny as i64, nz as i64, 1, 1, 1, 1];
    for (i, d) in dim.iter().enumerate() {
        put64(&mut b, 16 + 8 * i, *d);
    }
    for (i, p) in f.pixdim.iter().enumerate() {
        putf(&mut b, 104 + 8 * i, *p);
    }
    put64(&mut b, 168, 544);
    putf(&mut b, 176, f.slope);
    putf(&mut b, 184, f.inter);
    if let Some(q) = f.quatern {
        put32(&mut b, 344, 1);
        for (i, v) in q.iter().enumerate() {
            putf(&mut b, 352 + 8 * i, *v);
        }
        for i in 0..3 {
            putf(&mut b, 376 + 8 * i, m[i][3]);
        }
    }
    put32(&mut b, 348, 1);
    for r in 0..3 {
        for c in 0..4 {
            putf(&mut b, 400 + 32 * r + 8 * c, m[r][c]);
        }
    }
    put32(&mut b, 500, 2 | 8);
    b
}

pub(crate) fn create(
    path: &Path,
    compression: Compression,
    source: &VolumeInfo,
) -> Result<SampleWriter> {
    let header = match &source.header {
        FormatHeader::Nifti(h) => h.clone(),
        _ => new_header(source),
    };
    let mut out = AtomicOutput::create(path, compression)?;
    out.write_all(&header.bytes)?;
    Ok(SampleWriter::new(out, header.endian, source))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quaternion_round_trip() {
        // A rotation about z by 30° with a flipped third axis.
        let (s, c) = (0.5f64, 0.75f64.sqrt());
        let dir = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, -1.0]];
        let (q, qfac) = quaternion(dir).unwrap();
        assert_eq!(qfac, -1.0);
        let p = Parsed {
            dim: [3, 1, 1, 1, 1, 1, 1, 1],
            datatype: 2,
            pixdim: [qfac, 2.0, 3.0, 4.0, 1.0, 1.0, 1.0, 1.0],
            vox_offset: 352.0,
            scl_slope: 0.0,
            scl_inter: 0.0,
            qform_code: 1,
            sform_code: 0,
            quatern: q,
            qoffset: [1.0, 2.0, 3.0],
            srow: [[0.0; 4]; 3],
        };
        let a = qform_affine(&p);
        let want = Affine::from_parts(dir, [2.0, 3.0, 4.0], [1.0, 2.0, 3.0]);
        assert!(a.max_diff(&want) < 1e-9, "{a:?} vs {want:?}");
    }
}
