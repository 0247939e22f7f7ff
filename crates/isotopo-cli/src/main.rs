//! `isotopo`: the command line. Argument parsing, progress and printing only; the work is in the
//! `isotopo` library.

mod progress;

use clap::{Args, Parser, Subcommand};
use isotopo::volume::{self, DType, Endian, ReadOptions};
use isotopo::{Error, Result};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Parser)]
#[command(name = "isotopo", version, about = "Find, measure and remove small topological handles of isosurfaces of 3D volumes", long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Describe a volume: dims, type, geometry, value statistics and a suggested isovalue.
    Info(InfoArgs),
    /// Convert a volume to another format (chosen by the output extension).
    Convert(ConvertArgs),
}

/// How to read the input; the raw options describe headerless files.
#[derive(Args, Clone)]
struct Input {
    /// Input volume: .nii .nii.gz .nrrd .nhdr .mgh .mgz .mha .mhd .npy .tif, or raw.
    file: PathBuf,
    /// Dimensions of a headerless raw file, e.g. 256,256,128.
    #[arg(long, value_name = "NX,NY,NZ", value_parser = parse_dims)]
    raw_dims: Option<[usize; 3]>,
    /// Sample type of a raw file: uint8, int8, uint16, int16, uint32, int32, float32, float64.
    #[arg(long, value_name = "T", value_parser = parse_dtype)]
    raw_type: Option<DType>,
    /// Byte order of a raw file.
    #[arg(long, value_name = "little|big", value_parser = parse_endian)]
    raw_endian: Option<Endian>,
    /// Voxel size in mm for files that carry none (raw, NumPy, TIFF).
    #[arg(long, value_name = "SX,SY,SZ", value_parser = parse_spacing)]
    raw_spacing: Option<[f64; 3]>,
    /// Bytes to skip at the start of a raw file.
    #[arg(long, value_name = "BYTES", default_value_t = 0)]
    raw_offset: u64,
}

impl Input {
    fn options(&self) -> ReadOptions {
        ReadOptions {
            raw_dims: self.raw_dims,
            raw_type: self.raw_type,
            raw_endian: self.raw_endian,
            raw_spacing: self.raw_spacing,
            raw_offset: self.raw_offset,
        }
    }
    fn open(&self) -> Result<Box<dyn volume::SliceReader>> {
        volume::open(&self.file, &self.options())
    }
}

#[derive(Args)]
struct InfoArgs {
    #[command(flatten)]
    input: Input,
    /// Print one JSON object instead of text.
    #[arg(long)]
    json: bool,
    /// No progress bar.
    #[arg(long, short)]
    quiet: bool,
}

#[derive(Args)]
struct ConvertArgs {
    #[command(flatten)]
    input: Input,
    /// Output file; its extension picks the format.
    #[arg(long, short)]
    output: PathBuf,
    #[arg(long, short)]
    quiet: bool,
}

fn parse_dims(s: &str) -> std::result::Result<[usize; 3], String> {
    let v: Vec<usize> = s
        .split([',', 'x', 'X'])
        .map(|t| {
            t.trim()
                .parse::<usize>()
                .map_err(|_| format!("\"{t}\" is not a size"))
        })
        .collect::<std::result::Result<_, _>>()?;
    <[usize; 3]>::try_from(v).map_err(|_| "expected three sizes NX,NY,NZ".to_string())
}

fn parse_spacing(s: &str) -> std::result::Result<[f64; 3], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|t| {
            t.trim()
                .parse::<f64>()
                .map_err(|_| format!("\"{t}\" is not a number"))
        })
        .collect::<std::result::Result<_, _>>()?;
    let a =
        <[f64; 3]>::try_from(v).map_err(|_| "expected three sizes SX,SY,SZ in mm".to_string())?;
    if a.iter().any(|x| !(x.is_finite() && *x > 0.0)) {
        return Err("voxel sizes must be positive".into());
    }
    Ok(a)
}

fn parse_dtype(s: &str) -> std::result::Result<DType, String> {
    DType::parse(s).ok_or_else(|| format!("unknown type \"{s}\"; use uint8, int8, uint16, int16, uint32, int32, float32 or float64"))
}

fn parse_endian(s: &str) -> std::result::Result<Endian, String> {
    match s {
        "little" | "le" => Ok(Endian::Little),
        "big" | "be" => Ok(Endian::Big),
        _ => Err("use little or big".into()),
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Info(a) => cmd_info(a),
        Command::Convert(a) => cmd_convert(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("isotopo: error: {e}");
            ExitCode::from(if e.is_user_error() { 2 } else { 1 })
        }
    }
}

fn group(n: u64) -> String {
    let s = n.to_string();
    let mut out = String::new();
    for (i, c) in s.chars().enumerate() {
        if i > 0 && (s.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

/// Compact number: up to 6 significant digits, no trailing zeros.
fn num(x: f64) -> String {
    if x.is_nan() {
        return "nan".into();
    }
    if x == x.trunc() && x.abs() < 1e15 {
        return format!("{}", x as i64);
    }
    let s = format!("{:.6}", x);
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s.len() > 12 {
        format!("{x:.4e}")
    } else {
        s.to_string()
    }
}

fn cmd_info(a: InfoArgs) -> Result<()> {
    let mut reader = a.input.open()?;
    let info = reader.info().clone();
    let bars = progress::Bars::new(a.quiet || a.json);
    let stats = volume::stats::compute(reader.as_mut(), &bars)?;
    if a.json {
        let v = serde_json::json!({
            "file": info.path,
            "format": info.format.name(),
            "dims": info.dims,
            "dtype": info.dtype.name(),
            "spacing": info.spacing(),
            "affine": info.affine.m,
            "scaling": {"slope": info.scaling.slope, "inter": info.scaling.inter},
            "stats": stats,
            "suggested_iso": stats.otsu,
        });
        println!(
            "{}",
            serde_json::to_string_pretty(&v).map_err(|e| Error::Internal(e.to_string()))?
        );
        return Ok(());
    }
    let [nx, ny, nz] = info.dims;
    let sp = info.spacing();
    println!("file        {}", info.path.display());
    let comp = match info.compression {
        volume::Compression::None => "",
        volume::Compression::Gzip => ", gzip",
        volume::Compression::Zlib => ", zlib",
    };
    let endian = if info.dtype.size() > 1 {
        match info.endian {
            Endian::Little => ", little-endian",
            Endian::Big => ", big-endian",
        }
    } else {
        ""
    };
    println!("format      {}{comp}{endian}", info.format.name());
    println!(
        "dims        {nx} × {ny} × {nz}  ({} voxels)",
        group(info.voxel_count())
    );
    println!("type        {}", info.dtype);
    if !info.scaling.is_identity() {
        println!(
            "scaling     value = raw × {} + {}",
            num(info.scaling.slope),
            num(info.scaling.inter)
        );
    }
    println!(
        "spacing     {} × {} × {} mm",
        num(sp[0]),
        num(sp[1]),
        num(sp[2])
    );
    for (r, row) in info.affine.m.iter().enumerate() {
        let label = if r == 0 { "affine" } else { "" };
        println!(
            "{label:<12}[{:>9} {:>9} {:>9} {:>10} ]",
            num(row[0]),
            num(row[1]),
            num(row[2]),
            num(row[3])
        );
    }
    println!(
        "values      min {}  max {}  mean {}",
        num(stats.min),
        num(stats.max),
        num(stats.mean)
    );
    let q: Vec<String> = stats
        .quantiles
        .iter()
        .map(|(p, v)| format!("{}% {}", num(p * 100.0), num(*v)))
        .collect();
    println!(
        "quantiles   {}{}",
        q.join("  "),
        if stats.exact {
            ""
        } else {
            "  (to 1/4096 of the range)"
        }
    );
    println!(
        "NaN / ±Inf  {} / {} / {}",
        group(stats.nan),
        group(stats.pos_inf),
        group(stats.neg_inf)
    );
    println!("histogram   (bar length ~ log of count)");
    let maxc = stats.counts.iter().copied().max().unwrap_or(0);
    let maxl = ((maxc as f64) + 1.0).ln();
    for (i, &c) in stats.counts.iter().enumerate() {
        let len = if c == 0 {
            0
        } else {
            (((c as f64) + 1.0).ln() / maxl * 40.0).ceil() as usize
        };
        println!(
            "  {:>10} .. {:<10} {:<40} {}",
            num(stats.edges[i]),
            num(stats.edges[i + 1]),
            "#".repeat(len),
            group(c)
        );
    }
    println!("suggested isovalue (Otsu): {}", num(stats.otsu));
    Ok(())
}

fn cmd_convert(a: ConvertArgs) -> Result<()> {
    let mut reader = a.input.open()?;
    let bars = progress::Bars::new(a.quiet);
    let _ = &bars;
    volume::convert(reader.as_mut(), &a.output)
}
