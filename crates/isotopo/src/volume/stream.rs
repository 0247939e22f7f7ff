//! Byte streams under every format: reading samples from (possibly compressed) data at an
//! offset, and writing files atomically (temp file + rename).

use super::{
    check_dims, Compression, DType, Endian, FormatHeader, Samples, SliceReader, SliceWriter,
    VolumeInfo,
};
use crate::error::{Error, Result};
use flate2::read::{MultiGzDecoder, ZlibDecoder};
use std::fs::File;
use std::io::{self, BufReader, BufWriter, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

const IO_BUFFER: usize = 1 << 20;
/// The buffer in front of an uncompressed file: a slice read at least this long goes straight
/// from the file into the slice's bytes (a 512 × 512 int16 slice is 512 KiB); a bigger buffer
/// would copy every slice through it once more.
const PLAIN_BUFFER: usize = 1 << 16;
/// Deflate cannot shrink data by much more than 1032:1; a header claiming more samples than that
/// is corrupt, and is refused before allocating.
const MAX_DEFLATE_RATIO: u64 = 1100;

/// Where a volume's samples are: file, offset, compression, byte order.
#[derive(Clone, Debug)]
pub(crate) struct DataLocation {
    /// File holding the samples (the header file itself for attached data).
    pub path: PathBuf,
    /// File offset of the first (possibly compressed) byte.
    pub offset: u64,
    pub compression: Compression,
    /// Bytes to skip in the decompressed stream before the first sample (NRRD `byte skip`).
    pub skip: u64,
    /// Samples are the last bytes of the file (NRRD `byte skip: -1`, MetaImage `HeaderSize = -1`).
    pub from_end: bool,
    pub endian: Endian,
    /// For uncompressed data: the file must hold exactly the samples after the offset (headerless
    /// formats), rather than at least them.
    pub exact_size: bool,
    /// Read what follows the samples into the header (MGH's optional trailer).
    pub read_trailer: bool,
}

/// Streams z-slices from a [`DataLocation`]; used by every format but TIFF and C-ordered NumPy.
pub(crate) struct StreamReader {
    info: VolumeInfo,
    loc: DataLocation,
    input: Option<Box<dyn Read + Send>>,
    position: usize,
}

fn data_bytes(info: &VolumeInfo) -> u64 {
    info.voxel_count() * info.dtype.size() as u64
}

impl StreamReader {
    pub fn new(info: VolumeInfo, loc: DataLocation) -> Result<StreamReader> {
        check_dims(&info.path, info.dims, info.dtype)?;
        let slice_bytes = info.slice_len() as u64 * info.dtype.size() as u64;
        if slice_bytes > (1 << 34) {
            return Err(Error::input(
                &info.path,
                format!(
                    "one z-slice of {}×{} {} samples would take {} GiB",
                    info.dims[0],
                    info.dims[1],
                    info.dtype,
                    slice_bytes >> 30
                ),
                "slices of at most 16 GiB",
            ));
        }
        let file_len = std::fs::metadata(&loc.path)
            .map_err(|e| Error::io(&loc.path, "opening the data file of", e))?
            .len();
        let need = data_bytes(&info);
        let mut loc = loc;
        if loc.compression == Compression::None {
            if loc.from_end {
                if file_len < need {
                    return Err(truncated_at_open(&info, &loc.path, file_len, need));
                }
                loc.offset = file_len - need;
            }
            let have = file_len.saturating_sub(loc.offset + loc.skip);
            if have < need {
                return Err(truncated_at_open(&info, &loc.path, have, need));
            }
            if loc.exact_size && have > need {
                return Err(Error::input(
                    &loc.path,
                    format!(
                        "{} bytes of data, {} more than {}×{}×{} {} samples need",
                        have,
                        have - need,
                        info.dims[0],
                        info.dims[1],
                        info.dims[2],
                        info.dtype
                    ),
                    format!("exactly {need} bytes (check the dimensions and the type)"),
                ));
            }
        } else {
            let compressed = file_len.saturating_sub(loc.offset).max(1);
            if need / compressed > MAX_DEFLATE_RATIO {
                return Err(Error::input(
                    &loc.path,
                    format!(
                        "a header claiming {}×{}×{} {} samples ({} MB) for {} bytes of compressed data",
                        info.dims[0], info.dims[1], info.dims[2], info.dtype, need >> 20, compressed
                    ),
                    "dimensions consistent with the file size (the header is corrupt)",
                ));
            }
        }
        let mut r = StreamReader {
            info,
            loc,
            input: None,
            position: 0,
        };
        r.rewind()?;
        Ok(r)
    }

    fn read_error(&self, e: io::Error) -> Error {
        let nz = self.info.nz();
        let place = if self.position < nz {
            format!("in z-slice {} of {nz}", self.position + 1)
        } else {
            "after the last z-slice (checksum or trailer)".to_string()
        };
        match e.kind() {
            io::ErrorKind::UnexpectedEof => Error::input(
                &self.loc.path,
                format!("data ends {place} (the file is truncated)"),
                format!(
                    "{}×{}×{} {} samples",
                    self.info.dims[0], self.info.dims[1], self.info.dims[2], self.info.dtype
                ),
            ),
            io::ErrorKind::InvalidInput | io::ErrorKind::InvalidData
                if self.loc.compression != Compression::None =>
            {
                Error::input(
                    &self.loc.path,
                    format!(
                        "corrupt {} data {place} ({e})",
                        compression_name(self.loc.compression)
                    ),
                    "a valid compressed stream",
                )
            }
            _ => Error::io(&self.loc.path, "reading", e),
        }
    }
}

impl StreamReader {
    /// After the last slice: keeps a trailer if the format has one, and for compressed data reads
    /// to the end of the stream, so that the checksum is verified and corruption is caught.
    fn read_to_end(&mut self) -> Result<()> {
        if !self.loc.read_trailer && self.loc.compression == Compression::None {
            return Ok(());
        }
        let mut rest = Vec::new();
        let input = self.input.as_mut().expect("stream open");
        let mut limited = input.take(1 << 20);
        limited
            .read_to_end(&mut rest)
            .map_err(|e| self.read_error(e))?;
        if self.loc.compression != Compression::None {
            // Drain anything beyond the trailer limit too: the checksum is at the very end.
            let input = self.input.as_mut().expect("stream open");
            io::copy(input, &mut io::sink()).map_err(|e| self.read_error(e))?;
        }
        if self.loc.read_trailer {
            if let FormatHeader::Mgh(h) = &mut self.info.header {
                h.tail = rest;
            }
        }
        Ok(())
    }
}

fn compression_name(c: Compression) -> &'static str {
    match c {
        Compression::None => "raw",
        Compression::Gzip => "gzip",
        Compression::Zlib => "zlib",
    }
}

fn truncated_at_open(info: &VolumeInfo, path: &Path, have: u64, need: u64) -> Error {
    Error::input(
        path,
        format!("only {have} bytes of sample data (the file is truncated, or the header is wrong)"),
        format!(
            "{need} bytes for {}×{}×{} {} samples",
            info.dims[0], info.dims[1], info.dims[2], info.dtype
        ),
    )
}

impl SliceReader for StreamReader {
    fn info(&self) -> &VolumeInfo {
        &self.info
    }

    fn read_slice(&mut self, out: &mut Samples) -> Result<()> {
        if self.position >= self.info.nz() {
            return Err(Error::Internal(format!(
                "read past the last slice of {}",
                self.info.path.display()
            )));
        }
        if out.dtype() != self.info.dtype {
            *out = Samples::new(self.info.dtype);
        }
        let input = self.input.as_mut().expect("stream open");
        if let Err(e) = out.read_from(self.info.slice_len(), self.loc.endian, input) {
            return Err(self.read_error(e));
        }
        self.position += 1;
        if self.position == self.info.nz() {
            self.read_to_end()?;
        }
        Ok(())
    }

    fn position(&self) -> usize {
        self.position
    }

    fn rewind(&mut self) -> Result<()> {
        let path = &self.loc.path;
        let mut file = File::open(path).map_err(|e| Error::io(path, "opening", e))?;
        file.seek(SeekFrom::Start(self.loc.offset))
            .map_err(|e| Error::io(path, "seeking in", e))?;
        let buffered = |capacity| BufReader::with_capacity(capacity, file);
        let mut input: Box<dyn Read + Send> = match self.loc.compression {
            Compression::None => Box::new(buffered(PLAIN_BUFFER)),
            Compression::Gzip => Box::new(BufReader::with_capacity(
                IO_BUFFER,
                MultiGzDecoder::new(buffered(IO_BUFFER)),
            )),
            Compression::Zlib => Box::new(BufReader::with_capacity(
                IO_BUFFER,
                ZlibDecoder::new(buffered(IO_BUFFER)),
            )),
        };
        if self.loc.skip > 0 {
            let skipped = io::copy(&mut (&mut input).take(self.loc.skip), &mut io::sink())
                .map_err(|e| Error::io(path, "reading", e))?;
            if skipped < self.loc.skip {
                return Err(Error::input(
                    path,
                    format!("data ends within the {} bytes to skip", self.loc.skip),
                    "sample data after the skipped bytes",
                ));
            }
        }
        self.input = Some(input);
        self.position = 0;
        Ok(())
    }
}

/// Refuses output paths that would destroy the input: the same file (also via another name or a
/// link), or the input's detached data file. Also checks that the directory exists.
pub fn check_output_path(out: &Path, source: &VolumeInfo) -> Result<()> {
    let dir = match out.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    if !dir.is_dir() {
        return Err(Error::usage(format!(
            "{}: the output directory {} does not exist",
            out.display(),
            dir.display()
        )));
    }
    let mut inputs = vec![source.path.clone()];
    match &source.header {
        FormatHeader::Nrrd(h) => inputs.extend(h.data_file.clone()),
        FormatHeader::MetaImage(h) => inputs.extend(h.data_file.clone()),
        _ => {}
    }
    for input in inputs {
        if same_file(out, &input) {
            return Err(Error::usage(format!(
                "{}: the output would overwrite the input {}; choose another output path",
                out.display(),
                input.display()
            )));
        }
    }
    Ok(())
}

fn same_file(a: &Path, b: &Path) -> bool {
    if let (Ok(ma), Ok(mb)) = (std::fs::metadata(a), std::fs::metadata(b)) {
        #[cfg(unix)]
        {
            use std::os::unix::fs::MetadataExt;
            return ma.dev() == mb.dev() && ma.ino() == mb.ino();
        }
        #[cfg(not(unix))]
        {
            let _ = (ma, mb);
        }
    }
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(x), Ok(y)) => x == y,
        _ => false,
    }
}

/// A file being written that no folder lists yet, in the folder of the file it will become.
///
/// On Linux it is an unnamed file (`O_TMPFILE`), given a name only when complete
/// ([`Staged::persist`]): a run stopped before then, by SIGKILL too, leaves nothing behind (only
/// the instant between linking and renaming it can leave a hidden name). Where the filesystem has
/// no unnamed files, without `/proc` (needed to link one), elsewhere than Linux, or with
/// `ISOTOPO_NAMED_STAGING` set, a hidden `.isotopo-XXXXXX.part` beside the target stands in,
/// removed when dropped (but left by a SIGKILL).
pub(crate) struct Staged {
    file: File,
    /// The stand-in's name, when the file has one.
    named: Option<tempfile::TempPath>,
}

/// The folder a file at `path` goes in.
fn folder_of(path: &Path) -> &Path {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

impl Staged {
    /// A new, empty staged file in the folder of `target`, with the permissions a new file gets
    /// (0666 less the umask).
    pub(crate) fn beside(target: &Path) -> Result<Staged> {
        let dir = folder_of(target);
        #[cfg(target_os = "linux")]
        if std::env::var_os("ISOTOPO_NAMED_STAGING").is_none() {
            if let Some(file) = unnamed_in(dir) {
                return Ok(Staged { file, named: None });
            }
        }
        let mut builder = tempfile::Builder::new();
        builder.prefix(".isotopo-").suffix(".part");
        #[cfg(unix)]
        builder.permissions(std::os::unix::fs::PermissionsExt::from_mode(0o666));
        let tmp = builder
            .tempfile_in(dir)
            .map_err(|e| Error::io(target, "creating", e))?;
        let (file, path) = tmp.into_parts();
        Ok(Staged {
            file,
            named: Some(path),
        })
    }

    /// The open file, to write to (and seek in, and read back).
    pub(crate) fn file(&self) -> &File {
        &self.file
    }

    /// Gives the complete file its name `path` (replacing any file there), synced to disk
    /// first, and the folder after, so the name survives a power cut.
    pub(crate) fn persist(self, path: &Path) -> Result<()> {
        let err = |action, e: io::Error| Error::io(path, action, e);
        self.file.sync_all().map_err(|e| err("writing", e))?;
        match self.named {
            Some(named) => named.persist(path).map_err(|e| err("placing", e.error))?,
            #[cfg(target_os = "linux")]
            None => link_into_place(&self.file, path).map_err(|e| err("placing", e))?,
            #[cfg(not(target_os = "linux"))]
            None => unreachable!("unnamed files are made on Linux only"),
        };
        // A folder can be opened and synced on Unix only; elsewhere the rename is the end.
        #[cfg(unix)]
        File::open(folder_of(path))
            .and_then(|d| d.sync_all())
            .map_err(|e| err("placing", e))?;
        Ok(())
    }
}

/// An unnamed file in `dir` (`O_TMPFILE`), or `None` where the filesystem has none or `/proc`
/// is missing (an unnamed file is linked through `/proc/self/fd`).
#[cfg(target_os = "linux")]
fn unnamed_in(dir: &Path) -> Option<File> {
    use rustix::fs::{openat, Mode, OFlags, CWD};
    if !Path::new("/proc/self/fd").is_dir() {
        return None;
    }
    let flags = OFlags::RDWR | OFlags::TMPFILE | OFlags::CLOEXEC;
    openat(CWD, dir, flags, Mode::from_raw_mode(0o666))
        .ok()
        .map(File::from)
}

/// Names an unnamed file `path`: linked under a fresh hidden name in `path`'s folder, then
/// renamed over `path` (a link cannot replace a file). Only the instant between the two steps
/// can leave the hidden name behind.
#[cfg(target_os = "linux")]
fn link_into_place(file: &File, path: &Path) -> io::Result<()> {
    use rustix::fs::{linkat, AtFlags, CWD};
    use std::os::fd::AsRawFd;
    let fd = format!("/proc/self/fd/{}", file.as_raw_fd());
    let mut attempt = 0u32;
    let hidden = loop {
        let name = format!(".isotopo-{}.part", hidden_suffix(attempt));
        let hidden = folder_of(path).join(name);
        match linkat(CWD, fd.as_str(), CWD, &hidden, AtFlags::SYMLINK_FOLLOW) {
            Ok(()) => break hidden,
            Err(e) if e == rustix::io::Errno::EXIST && attempt < 100 => attempt += 1,
            Err(e) => return Err(e.into()),
        }
    };
    std::fs::rename(&hidden, path).inspect_err(|_| {
        let _ = std::fs::remove_file(&hidden);
    })
}

/// A name no other run picks at the same time: the process, the time, a count.
#[cfg(target_os = "linux")]
fn hidden_suffix(attempt: u32) -> String {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.subsec_nanos());
    format!("{}-{nanos:09}-{attempt}", std::process::id())
}

/// A file being written: bytes go to an unnamed staged file beside the target, which becomes the
/// target only on [`AtomicOutput::commit`]. Dropped without commit, it leaves nothing behind.
pub struct AtomicOutput {
    path: PathBuf,
    sink: Sink,
    /// The staged file's name, if it has one (see [`Staged`]).
    named: Option<tempfile::TempPath>,
}

enum Sink {
    /// Only while switching from plain to compressed.
    Switching,
    Plain(BufWriter<File>),
    Gzip(flate2::write::GzEncoder<BufWriter<File>>),
    Zlib(flate2::write::ZlibEncoder<BufWriter<File>>),
}

/// gzip level for written files: 6 is zlib's default and what most tools use.
const GZIP_LEVEL: u32 = 6;

impl AtomicOutput {
    /// Starts writing `path`: stages a file in its folder, whose content is compressed from the
    /// first byte as `compression` says.
    pub fn create(path: &Path, compression: Compression) -> Result<AtomicOutput> {
        let staged = Staged::beside(path)?;
        let mut out = AtomicOutput {
            path: path.to_path_buf(),
            sink: Sink::Plain(BufWriter::with_capacity(IO_BUFFER, staged.file)),
            named: staged.named,
        };
        out.begin_compression(compression);
        Ok(out)
    }

    /// Everything written from now on is compressed (NRRD and MetaImage: after the text header).
    pub fn begin_compression(&mut self, compression: Compression) {
        let level = flate2::Compression::new(GZIP_LEVEL);
        self.sink = match std::mem::replace(&mut self.sink, Sink::Switching) {
            Sink::Plain(w) => match compression {
                Compression::None => Sink::Plain(w),
                Compression::Gzip => Sink::Gzip(flate2::write::GzEncoder::new(w, level)),
                Compression::Zlib => Sink::Zlib(flate2::write::ZlibEncoder::new(w, level)),
            },
            other => other,
        };
    }

    /// The target path, where the file appears on [`AtomicOutput::commit`].
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Appends `bytes` to the staged file (through the compressor, if compression has begun).
    pub fn write_all(&mut self, bytes: &[u8]) -> Result<()> {
        let r = match &mut self.sink {
            Sink::Plain(w) => w.write_all(bytes),
            Sink::Gzip(w) => w.write_all(bytes),
            Sink::Zlib(w) => w.write_all(bytes),
            Sink::Switching => unreachable!("sink left switching"),
        };
        r.map_err(|e| Error::io(&self.path, "writing", e))
    }

    /// Completes compression, flushes, and moves the file into place.
    pub fn commit(self) -> Result<()> {
        let path = self.path.clone();
        self.into_staged()?.persist(&path)
    }

    /// Completes compression and flushes, without moving the file into place: the bytes
    /// written, to read back (from the start) and copy elsewhere. The file is gone once closed.
    pub(crate) fn into_bytes_written(self) -> Result<File> {
        let path = self.path.clone();
        let staged = self.into_staged()?;
        let mut file = staged.file;
        file.seek(SeekFrom::Start(0))
            .map_err(|e| Error::io(&path, "reading", e))?;
        Ok(file)
    }

    fn into_staged(self) -> Result<Staged> {
        let err = |e: io::Error| Error::io(&self.path, "writing", e);
        let buffered = match self.sink {
            Sink::Plain(w) => w,
            Sink::Gzip(w) => w.finish().map_err(err)?,
            Sink::Zlib(w) => w.finish().map_err(err)?,
            Sink::Switching => unreachable!("sink left switching"),
        };
        let file = buffered.into_inner().map_err(|e| err(e.into_error()))?;
        Ok(Staged {
            file,
            named: self.named,
        })
    }
}

/// Output of a format whose header is written before the samples: one atomic file, header bytes
/// first (uncompressed for NRRD/MetaImage headers, inside the stream for NIfTI/MGZ).
pub(crate) struct SampleWriter {
    pub out: AtomicOutput,
    pub endian: Endian,
    pub dtype: DType,
    pub slice_len: usize,
    pub buf: Vec<u8>,
}

impl SampleWriter {
    /// Samples of `source`'s type and slice size, written to `out` in `endian` byte order.
    pub fn new(out: AtomicOutput, endian: Endian, source: &VolumeInfo) -> SampleWriter {
        SampleWriter {
            out,
            endian,
            dtype: source.dtype,
            slice_len: source.slice_len(),
            buf: Vec::new(),
        }
    }

    pub fn write_slice(&mut self, slice: &Samples) -> Result<()> {
        if slice.dtype() != self.dtype || slice.len() != self.slice_len {
            return Err(Error::Internal(format!(
                "slice of {} {} written to a {} volume with {} samples per slice",
                slice.len(),
                slice.dtype(),
                self.dtype,
                self.slice_len
            )));
        }
        self.buf.clear();
        slice.encode(self.endian, &mut self.buf);
        let buf = std::mem::take(&mut self.buf);
        let r = self.out.write_all(&buf);
        self.buf = buf;
        r
    }
}

/// A format whose header goes before the samples and nothing after them (NIfTI, NumPy, raw).
impl SliceWriter for SampleWriter {
    fn write_slice(&mut self, slice: &Samples) -> Result<()> {
        SampleWriter::write_slice(self, slice)
    }
    fn finish(self: Box<Self>, _source: &VolumeInfo) -> Result<()> {
        self.out.commit()
    }
}
