//! `isotopo`: the command line. Argument parsing, progress and printing only; the work is in the
//! `isotopo` library.

mod progress;

use clap::{Args, Parser, Subcommand};
use isotopo::grid::Axis;
use isotopo::topology::{Connectivity, Inside, SurfaceOptions};
use isotopo::volume::{self, DType, Endian, ReadOptions};
use isotopo::{Error, Result};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

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
    /// Genus of every surface of the isosurface and the solid's Betti numbers (one streaming pass).
    Genus(GenusArgs),
    /// Extract the isosurface as a mesh (.ply binary, .obj or .stl), in world millimetres.
    Mesh(MeshArgs),
    /// Locate every handle with a sweep (Reeb graph of contours and ribbons).
    Handles(HandlesArgs),
    /// Locate every handle and measure it: Reeb loop, cross loop, size; statistics and plots.
    Analyze(AnalyzeArgs),
    /// Remove every handle smaller than --tau by writing thin walls into the volume.
    Simplify(SimplifyArgs),
}

#[derive(Args)]
struct SimplifyArgs {
    #[command(flatten)]
    input: Input,
    #[command(flatten)]
    surface: SurfaceArgs,
    #[command(flatten)]
    window: WindowArgs,
    /// Remove handles whose size (the shorter of the Reeb and cross loops, in voxel edges) is
    /// below this; `inf` removes every handle. `isotopo analyze --plots` helps choose it.
    #[arg(long, required_unless_present = "tau_mm", conflicts_with = "tau_mm")]
    tau: Option<f64>,
    /// Like --tau, in millimetres along the interpolated surface (the file's spacing): for
    /// anisotropic scans, where an edge along one axis is longer than along another.
    #[arg(long, value_name = "MM")]
    tau_mm: Option<f64>,
    /// Output volume (same format, type, header and geometry as the input unless the extension
    /// says otherwise).
    #[arg(long, short)]
    output: PathBuf,
    /// Also write the simplified isosurface as a mesh (.ply, .obj or .stl).
    #[arg(long, value_name = "OUT")]
    mesh: Option<PathBuf>,
    /// Only add material: close loops around empty space (handle collapse).
    #[arg(long, conflicts_with = "cut_only")]
    fill_only: bool,
    /// Only remove material: close loops around material (handle pinch).
    #[arg(long)]
    cut_only: bool,
    /// Keep long skinny handles: those whose longer loop is more than R times the shorter.
    #[arg(long, value_name = "R")]
    max_ratio: Option<f64>,
    /// Sweep direction.
    #[arg(long, value_enum, default_value = "z")]
    axis: AxisArg,
    /// Write a JSON report (genus before/after, every removed and kept handle).
    #[arg(long, value_name = "OUT.json")]
    report: Option<PathBuf>,
    /// Print the JSON report to stdout instead of the summary.
    #[arg(long)]
    json: bool,
    #[arg(long, short)]
    quiet: bool,
}

#[derive(Args)]
struct AnalyzeArgs {
    #[command(flatten)]
    input: Input,
    #[command(flatten)]
    surface: SurfaceArgs,
    #[command(flatten)]
    window: WindowArgs,
    /// Sweep direction.
    #[arg(long, value_enum, default_value = "z")]
    axis: AxisArg,
    /// Stop the searches at this length (voxel edges): longer loops cannot matter when
    /// simplifying with this threshold. Default: no limit.
    #[arg(long)]
    tau: Option<f64>,
    /// Stop the searches in millimetres at this length. Default: no limit.
    #[arg(long, value_name = "MM")]
    tau_mm: Option<f64>,
    /// Which shortest loops to measure: in voxel edges (the paper's unit, what --tau counts), in
    /// millimetres along the interpolated surface (what --tau-mm counts; about three times as
    /// long), or both. Default: edges, or mm with --tau-mm alone, both with --tau and --tau-mm.
    #[arg(long, value_enum)]
    metric: Option<MetricArg>,
    /// Print one JSON object (handles with their loops) instead of text.
    #[arg(long, conflicts_with = "csv")]
    json: bool,
    /// Print one CSV row per handle instead of text.
    #[arg(long)]
    csv: bool,
    /// Write the loops as polylines (.obj or .ply, world mm; Reeb loops blue, cross loops red).
    #[arg(long, value_name = "OUT")]
    loops: Option<PathBuf>,
    /// Write a histogram of handle sizes and a Reeb vs cross loop scatter plot (SVG and PNG).
    #[arg(long, value_name = "DIR")]
    plots: Option<PathBuf>,
    /// List every handle, not only the 30 largest.
    #[arg(long)]
    all: bool,
    #[arg(long, short)]
    quiet: bool,
}

#[derive(clap::ValueEnum, Clone, Copy, PartialEq, Eq)]
enum MetricArg {
    Edges,
    Mm,
    Both,
}

#[derive(clap::ValueEnum, Clone, Copy)]
enum AxisArg {
    X,
    Y,
    Z,
}

impl AxisArg {
    fn axis(self) -> Axis {
        match self {
            AxisArg::X => Axis::X,
            AxisArg::Y => Axis::Y,
            AxisArg::Z => Axis::Z,
        }
    }
}

#[derive(Args)]
struct HandlesArgs {
    #[command(flatten)]
    input: Input,
    #[command(flatten)]
    surface: SurfaceArgs,
    #[command(flatten)]
    window: WindowArgs,
    /// Sweep direction.
    #[arg(long, value_enum, default_value = "z")]
    axis: AxisArg,
    /// Print one JSON object instead of text.
    #[arg(long)]
    json: bool,
    /// List every handle, not only the first 30.
    #[arg(long)]
    all: bool,
    #[arg(long, short)]
    quiet: bool,
}

/// How much of the volume stays in memory.
#[derive(Args, Clone)]
struct WindowArgs {
    /// Planes of the volume held in memory at once (as inside bits); the rest wait in a scratch
    /// file (in TMPDIR) and are read back when a long handle needs them. 0: the whole volume.
    /// Default: as many as fit in 16 MiB, the whole volume when it fits.
    #[arg(long, value_name = "N")]
    max_slices: Option<usize>,
}

/// Which isosurface: the isovalue, the inside side and the digital connectivity.
#[derive(Args, Clone)]
struct SurfaceArgs {
    /// Isovalue, in the volume's values (after any NIfTI scl_slope/scl_inter).
    #[arg(long, allow_negative_numbers = true)]
    iso: f64,
    /// Inside is above the isovalue (CT, probability maps) or below it (signed distance fields).
    #[arg(long, value_enum, default_value = "above")]
    inside: InsideArg,
    /// Digital connectivity of the solid: 6 (inside 6-adjacent, outside 26) or 26 (the reverse).
    #[arg(long, default_value = "6", value_parser = parse_connectivity)]
    connectivity: Connectivity,
}

#[derive(clap::ValueEnum, Clone, Copy)]
enum InsideArg {
    Above,
    Below,
}

impl SurfaceArgs {
    fn options(&self) -> Result<SurfaceOptions> {
        if !self.iso.is_finite() {
            return Err(Error::usage("--iso must be a finite number"));
        }
        Ok(SurfaceOptions {
            iso: self.iso,
            inside: match self.inside {
                InsideArg::Above => Inside::Above,
                InsideArg::Below => Inside::Below,
            },
            connectivity: self.connectivity,
        })
    }
}

fn parse_connectivity(s: &str) -> std::result::Result<Connectivity, String> {
    match s {
        "6" => Ok(Connectivity::Six),
        "26" => Ok(Connectivity::TwentySix),
        _ => Err("use 6 or 26".into()),
    }
}

#[derive(Args)]
struct GenusArgs {
    #[command(flatten)]
    input: Input,
    #[command(flatten)]
    surface: SurfaceArgs,
    /// Print one JSON object (b0, b1, b2, chi, surfaces…) instead of text.
    #[arg(long)]
    json: bool,
    /// List every surface, not only the 20 of highest genus.
    #[arg(long)]
    all: bool,
    #[arg(long, short)]
    quiet: bool,
}

#[derive(Args)]
struct MeshArgs {
    #[command(flatten)]
    input: Input,
    #[command(flatten)]
    surface: SurfaceArgs,
    /// Output mesh: .ply (binary), .obj or .stl.
    #[arg(long, short)]
    output: PathBuf,
    /// Keep only the surface of largest area.
    #[arg(long)]
    largest: bool,
    /// Print a JSON summary (counts, Euler characteristic, timings).
    #[arg(long)]
    json: bool,
    #[arg(long, short)]
    quiet: bool,
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

/// glibc serves large allocations from `mmap` only until the first one is freed, then raises its
/// threshold (up to 32 MiB) and keeps freed blocks in the heap: the loop searches' arrays, grown
/// and dropped handle after handle, would then hold the peak resident set far above what is in
/// use. A fixed threshold keeps large blocks in `mmap`, so freeing them returns the memory.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn return_freed_memory() {
    extern "C" {
        fn mallopt(param: i32, value: i32) -> i32;
    }
    const M_MMAP_THRESHOLD: i32 = -3;
    // SAFETY: mallopt only changes allocator settings; called before any thread starts.
    unsafe {
        mallopt(M_MMAP_THRESHOLD, 256 << 10);
    }
}

#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
fn return_freed_memory() {}

/// `isotopo info scan.nii | head` should end quietly when `head` does, as other command-line
/// tools do, not panic on the closed pipe: restore the default action of SIGPIPE (Rust ignores it).
#[cfg(unix)]
fn quiet_on_closed_pipe() {
    extern "C" {
        fn signal(signum: i32, handler: usize) -> usize;
    }
    const SIGPIPE: i32 = 13;
    const SIG_DFL: usize = 0;
    // SAFETY: sets a signal disposition to the default, before any thread starts.
    unsafe {
        signal(SIGPIPE, SIG_DFL);
    }
}

#[cfg(not(unix))]
fn quiet_on_closed_pipe() {}

fn main() -> ExitCode {
    return_freed_memory();
    quiet_on_closed_pipe();
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Info(a) => cmd_info(a),
        Command::Convert(a) => cmd_convert(a),
        Command::Genus(a) => cmd_genus(a),
        Command::Mesh(a) => cmd_mesh(a),
        Command::Handles(a) => cmd_handles(a),
        Command::Analyze(a) => cmd_analyze(a),
        Command::Simplify(a) => cmd_simplify(a),
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

fn to_json(v: &impl serde::Serialize) -> Result<String> {
    serde_json::to_string_pretty(v).map_err(|e| Error::Internal(e.to_string()))
}

fn cmd_genus(a: GenusArgs) -> Result<()> {
    let opts = a.surface.options()?;
    let bars = progress::Bars::new(a.quiet || a.json);
    let source = isotopo::Source::Reader(a.input.open()?);
    let topology = isotopo::genus(source, &opts, &bars)?;
    if a.json {
        println!("{}", to_json(&topology.to_json(&opts))?);
        return Ok(());
    }
    let (info, r, secs) = (&topology.info, &topology.solid, topology.seconds);
    println!(
        "{}: iso {}, inside {}, connectivity {}",
        info.path.display(),
        num(opts.iso),
        opts.inside.name(),
        opts.connectivity.number()
    );
    println!(
        "solid       b0 = {} components, b1 = {} handles (total genus), b2 = {} cavities, chi = {}",
        r.b0, r.b1, r.b2, r.chi
    );
    let with_genus = r.surfaces.iter().filter(|s| s.genus > 0).count();
    println!(
        "surfaces    {} ({} enclosing material, {} cavities; {} with genus > 0)",
        r.surfaces.len(),
        r.b0,
        r.b2,
        with_genus
    );
    let shown = if a.all {
        r.surfaces.len()
    } else {
        r.surfaces.len().min(20)
    };
    if shown > 0 {
        println!(
            "  {:>5} {:>6}  {:<8} {:>12} {:>9}  bbox (voxels)",
            "id", "genus", "encloses", "area mm²", "surfels"
        );
    }
    for s in r.surfaces.iter().take(shown) {
        println!(
            "  {:>5} {:>6}  {:<8} {:>12.1} {:>9}  [{}..{}, {}..{}, {}..{}]",
            s.id,
            s.genus,
            match s.encloses {
                isotopo::topology::Encloses::Material => "material",
                isotopo::topology::Encloses::Cavity => "cavity",
            },
            s.area,
            s.surfels,
            s.bbox.min[0],
            s.bbox.max[0],
            s.bbox.min[1],
            s.bbox.max[1],
            s.bbox.min[2],
            s.bbox.max[2]
        );
    }
    if shown < r.surfaces.len() {
        println!("  … {} more (--all lists them)", r.surfaces.len() - shown);
    }
    println!(
        "time        {:.2} s ({:.1} Mvoxels/s)",
        secs,
        info.voxel_count() as f64 / secs / 1e6
    );
    Ok(())
}

fn cmd_mesh(a: MeshArgs) -> Result<()> {
    let opts = a.surface.options()?;
    let mut reader = a.input.open()?;
    volume::check_output_path(&a.output, reader.info())?;
    let bars = progress::Bars::new(a.quiet || a.json);
    let t = Instant::now();
    let mesh = isotopo::mesh::extract(reader.as_mut(), &opts, a.largest, &bars)?;
    let extraction = t.elapsed().as_secs_f64();
    let t = Instant::now();
    mesh.write(&a.output)?;
    let writing = t.elapsed().as_secs_f64();
    // The mesh is closed (every edge joins two triangles), so E = 3F/2.
    let chi = mesh.closed_euler_characteristic();
    if a.json {
        let v = serde_json::json!({
            "output": a.output,
            "vertices": mesh.vertices.len(),
            "triangles": mesh.triangles.len(),
            "euler_characteristic": chi,
            "seconds_extraction": extraction,
            "seconds_writing": writing,
        });
        println!("{}", to_json(&v)?);
    } else if !a.quiet {
        println!(
            "{}: {} vertices, {} triangles, Euler characteristic {} ({:.2} s extraction, {:.2} s writing)",
            a.output.display(),
            group(mesh.vertices.len() as u64),
            group(mesh.triangles.len() as u64),
            chi,
            extraction,
            writing
        );
    }
    Ok(())
}

fn cmd_handles(a: HandlesArgs) -> Result<()> {
    let opts = a.surface.options()?;
    let axis = a.axis.axis();
    let bars = progress::Bars::new(a.quiet || a.json);
    let aopts = isotopo::AnalyzeOptions {
        surface: opts,
        axis,
        max_slices: a.window.max_slices,
        ..isotopo::AnalyzeOptions::default()
    };
    let found = isotopo::handles(isotopo::Source::Reader(a.input.open()?), &aopts, &bars)?;
    let (info, report, secs) = (&found.info, &found.report, found.seconds);
    let handles = isotopo::report::handles_json(report, info);
    if a.json {
        println!("{}", to_json(&found.to_json(&aopts))?);
        return Ok(());
    }
    let reeb = report
        .handles
        .iter()
        .filter(|h| h.located.kind == isotopo::sweep::HandleKind::ReebCycle)
        .count();
    println!(
        "{}: iso {}, inside {}, connectivity {}, sweep along {}",
        info.path.display(),
        num(opts.iso),
        opts.inside.name(),
        opts.connectivity.number(),
        axis.name()
    );
    println!(
        "handles     {} located ({} Reeb cycles, {} intra-ribbon); genus from the Euler characteristic: {}{}",
        report.handles.len(),
        reeb,
        report.handles.len() - reeb,
        report.genus,
        if report.handles.len() as i64 == report.genus { " (all found)" } else { " (MISMATCH)" }
    );
    let shown = if a.all {
        report.handles.len()
    } else {
        report.handles.len().min(30)
    };
    if shown > 0 {
        println!(
            "  {:>5} {:>7}  {:<12} {:>9}  bbox (voxels)                 bbox (mm)",
            "id", "surface", "kind", "slices"
        );
    }
    for h in handles.iter().take(shown) {
        let b = &h["bbox"];
        let m = &h["bbox_mm"];
        println!(
            "  {:>5} {:>7}  {:<12} {:>9}  [{}..{}, {}..{}, {}..{}]  [{:.1}..{:.1}, {:.1}..{:.1}, {:.1}..{:.1}]",
            h["id"],
            h["surface"],
            h["kind"].as_str().unwrap_or(""),
            format!("{}..{}", h["slices"][0], h["slices"][1]),
            b["min"][0],
            b["max"][0],
            b["min"][1],
            b["max"][1],
            b["min"][2],
            b["max"][2],
            m[0][0].as_f64().unwrap_or(0.0),
            m[1][0].as_f64().unwrap_or(0.0),
            m[0][1].as_f64().unwrap_or(0.0),
            m[1][1].as_f64().unwrap_or(0.0),
            m[0][2].as_f64().unwrap_or(0.0),
            m[1][2].as_f64().unwrap_or(0.0)
        );
    }
    if shown < report.handles.len() {
        println!(
            "  … {} more (--all lists them, --json gives the cycles)",
            report.handles.len() - shown
        );
    }
    println!("time        {:.2} s", secs);
    Ok(())
}

fn cmd_analyze(a: AnalyzeArgs) -> Result<()> {
    use isotopo::jobs::Lengths;
    let opts = a.surface.options()?;
    let axis = a.axis.axis();
    let reader = a.input.open()?;
    let info = reader.info().clone();
    if let Some(p) = &a.loops {
        volume::check_output_path(p, &info)?;
    }
    let positive = |t: Option<f64>, flag: &str| match t {
        Some(t) if t.is_nan() || t <= 0.0 => {
            Err(Error::usage(format!("{flag} must be positive (or inf)")))
        }
        t => Ok(t),
    };
    let tau = positive(a.tau, "--tau")?;
    let tau_mm = positive(a.tau_mm, "--tau-mm")?;
    let lengths = match a.metric {
        Some(MetricArg::Edges) => Lengths::Edges,
        Some(MetricArg::Mm) => Lengths::Millimetres,
        Some(MetricArg::Both) => Lengths::Both,
        None => match (tau, tau_mm) {
            (Some(_), Some(_)) => Lengths::Both,
            (None, Some(_)) => Lengths::Millimetres,
            _ => Lengths::Edges,
        },
    };
    let aopts = isotopo::AnalyzeOptions {
        surface: opts,
        axis,
        max_slices: a.window.max_slices,
        tau,
        tau_mm,
        lengths,
    };
    let bars = progress::Bars::new(a.quiet || a.json || a.csv);
    let analysis = isotopo::analyze(isotopo::Source::Reader(reader), &aopts, &bars)?;
    let (report, loops) = (&analysis.report, &analysis.loops);
    let (secs, t_sweep) = (analysis.seconds, analysis.seconds_sweep);
    if let Some(p) = &a.loops {
        isotopo::report::write_loops(p, loops, &info.affine)?;
    }
    let name = info
        .path
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_default();
    let mut plot_files = Vec::new();
    if let Some(dir) = &a.plots {
        let points: Vec<isotopo::plots::PlotPoint> = loops
            .iter()
            .map(|l| isotopo::plots::PlotPoint {
                reeb: l.reeb.as_ref().map(|x| x.length),
                cross: l.cross.as_ref().map(|x| x.length),
                void: l
                    .smallest()
                    .map(|x| x.encloses == isotopo::loops::Encloses::Void)
                    .unwrap_or(false),
            })
            .collect();
        plot_files = isotopo::plots::write(dir, &name, &points, tau)?;
    }
    if a.json {
        println!("{}", to_json(&analysis.to_json(&aopts))?);
        return Ok(());
    }
    if a.csv {
        print!("{}", analysis.to_csv());
        return Ok(());
    }
    let reeb = report
        .handles
        .iter()
        .filter(|h| h.located.kind == isotopo::sweep::HandleKind::ReebCycle)
        .count();
    println!(
        "{}: iso {}, inside {}, connectivity {}, sweep along {}",
        info.path.display(),
        num(opts.iso),
        opts.inside.name(),
        opts.connectivity.number(),
        axis.name()
    );
    println!(
        "handles     {} ({} Reeb cycles, {} intra-ribbon); genus from the Euler characteristic: {}",
        report.handles.len(),
        reeb,
        report.handles.len() - reeb,
        report.genus
    );
    let sizes: Vec<Option<usize>> = loops.iter().map(|l| l.size()).collect();
    let below = |t: usize| sizes.iter().filter(|s| s.is_some_and(|s| s < t)).count();
    println!(
        "sizes       {} below 10, {} below 20, {} below 50, {} of 50 or more (voxel edges: the shorter of the two loops)",
        below(10),
        below(20),
        below(50),
        report.handles.len() - below(50)
    );
    // A text histogram of sizes.
    let bins: &[(usize, usize)] = &[
        (0, 4),
        (4, 5),
        (5, 7),
        (7, 9),
        (9, 12),
        (12, 16),
        (16, 24),
        (24, 32),
        (32, 50),
        (50, 100),
        (100, 200),
        (200, usize::MAX),
    ];
    let counts: Vec<usize> = bins
        .iter()
        .map(|&(lo, hi)| {
            sizes
                .iter()
                .filter(|s| s.is_some_and(|s| s >= lo && s < hi))
                .count()
        })
        .collect();
    let beyond = sizes.iter().filter(|s| s.is_none()).count();
    let maxc = counts.iter().copied().max().unwrap_or(1).max(beyond).max(1);
    for (&(lo, hi), &c) in bins.iter().zip(&counts) {
        if c == 0 && lo >= 50 {
            continue;
        }
        let label = if hi == usize::MAX {
            format!("{lo}+")
        } else {
            format!("{lo}-{}", hi - 1)
        };
        println!(
            "  {:>8} {:<40} {}",
            label,
            "#".repeat((c * 40).div_ceil(maxc)),
            c
        );
    }
    if beyond > 0 {
        println!(
            "  {:>8} {:<40} {}",
            format!(">={}", num(tau.unwrap_or(f64::INFINITY))),
            "#".repeat((beyond * 40).div_ceil(maxc)),
            beyond
        );
    }
    // Largest handles first: those are the ones a threshold should keep.
    let mut order: Vec<usize> = (0..loops.len()).collect();
    order.sort_by_key(|&i| std::cmp::Reverse(sizes[i].unwrap_or(usize::MAX)));
    let shown = if a.all {
        order.len()
    } else {
        order.len().min(30)
    };
    if shown > 0 {
        println!(
            "  {:>5} {:>7}  {:<12} {:>6} {:>18} {:>18}  bbox (voxels)",
            "id", "surface", "kind", "size", "Reeb loop", "cross loop"
        );
    }
    let fmt_loop = |l: &Option<isotopo::loops::Loop>| match l {
        Some(l) => format!(
            "{} ({:.0} mm, {})",
            l.length,
            l.length_mm,
            if l.encloses == isotopo::loops::Encloses::Material {
                "mat"
            } else {
                "void"
            }
        ),
        None => format!(">={}", num(tau.unwrap_or(f64::INFINITY))),
    };
    for &i in order.iter().take(shown) {
        let h = &report.handles[i];
        let b = &h.located.bbox;
        println!(
            "  {:>5} {:>7}  {:<12} {:>6} {:>18} {:>18}  [{}..{}, {}..{}, {}..{}]",
            h.id,
            h.surface,
            if h.located.kind == isotopo::sweep::HandleKind::ReebCycle {
                "reeb_cycle"
            } else {
                "intra_ribbon"
            },
            sizes[i]
                .map(|s| s.to_string())
                .unwrap_or_else(|| "-".into()),
            fmt_loop(&loops[i].reeb),
            fmt_loop(&loops[i].cross),
            b.min[0],
            b.max[0],
            b.min[1],
            b.max[1],
            b.min[2],
            b.max[2]
        );
    }
    if shown < order.len() {
        println!(
            "  … {} more (--all, --json or --csv list them)",
            order.len() - shown
        );
    }
    if let Some(p) = &a.loops {
        println!("loops       {}", p.display());
    }
    for f in &plot_files {
        println!("plot        {}", f.display());
    }
    println!(
        "time        {:.2} s ({:.2} s sweep, {:.2} s loops)",
        secs,
        t_sweep,
        secs - t_sweep
    );
    Ok(())
}

fn cmd_simplify(a: SimplifyArgs) -> Result<()> {
    use isotopo::simplify::{Mode, SimplifyOptions};
    let surface = a.surface.options()?;
    let (tau, metric, flag) = match (a.tau, a.tau_mm) {
        (Some(t), _) => (t, isotopo::loops::Metric::Edges, "--tau"),
        (None, Some(t)) => (t, isotopo::loops::Metric::Millimetres, "--tau-mm"),
        (None, None) => return Err(Error::usage("give --tau or --tau-mm")),
    };
    if tau.is_nan() || tau <= 0.0 {
        return Err(Error::usage(format!("{flag} must be positive (or inf)")));
    }
    if let Some(r) = a.max_ratio {
        if r.is_nan() || r < 1.0 {
            return Err(Error::usage("--max-ratio must be at least 1"));
        }
    }
    let sopts = SimplifyOptions {
        surface,
        axis: a.axis.axis(),
        tau,
        metric,
        mode: if a.fill_only {
            Mode::FillOnly
        } else if a.cut_only {
            Mode::CutOnly
        } else {
            Mode::Both
        },
        max_ratio: a.max_ratio,
        max_slices: a.window.max_slices,
    };
    // Every output is checked before the work starts.
    let reader = a.input.open()?;
    let info = reader.info().clone();
    let mut outputs = vec![&a.output];
    outputs.extend(a.mesh.iter());
    outputs.extend(a.report.iter());
    for (i, p) in outputs.iter().enumerate() {
        volume::check_output_path(p, &info)?;
        if outputs[..i].contains(p) {
            return Err(Error::usage(format!(
                "{}: given as two different outputs",
                p.display()
            )));
        }
    }
    if volume::Format::from_path(&a.output).is_none() {
        return Err(Error::usage(format!(
            "{}: cannot tell the output format from the extension; use the input's ({})",
            a.output.display(),
            info.format.name()
        )));
    }
    let bars = progress::Bars::new(a.quiet || a.json);
    let t0 = Instant::now();
    let mut done = isotopo::simplify(isotopo::Source::Reader(reader), &sopts, &bars)?;
    let t = Instant::now();
    done.write(&a.output, &bars)?;
    let t_write = t.elapsed().as_secs_f64();
    let mut mesh_genus = None;
    if let Some(p) = &a.mesh {
        let mut out = volume::open(&a.output, &a.input.options())?;
        let mesh = isotopo::mesh::extract(out.as_mut(), &surface, false, &bars)?;
        mesh.write(p)?;
        mesh_genus = Some(mesh.closed_euler_characteristic());
    }
    let secs = t0.elapsed().as_secs_f64();
    let mut v = done.report(&sopts);
    let extra = serde_json::json!({
        "output": a.output,
        "mesh": a.mesh,
        "mesh_euler_characteristic": mesh_genus,
        "seconds": secs,
        "seconds_write": t_write,
    });
    if let (Some(obj), serde_json::Value::Object(e)) = (v.as_object_mut(), extra) {
        obj.extend(e);
    }
    if let Some(p) = &a.report {
        isotopo::report::write_json(p, &v)?;
    }
    if a.json {
        println!("{}", to_json(&v)?);
        return Ok(());
    }
    if a.quiet {
        return Ok(());
    }
    let (before, after, outcome, values) =
        (&done.before, &done.after, &done.outcome, &done.wall_values);
    let (t_read, t_simplify) = (done.seconds_read, done.seconds_simplify);
    let opts = &surface;
    let axis = sopts.axis;
    let collapse = v["collapse"].as_u64().unwrap_or(0);
    let pinch = v["pinch"].as_u64().unwrap_or(0);
    println!(
        "{}: iso {}, inside {}, connectivity {}, sweep along {}, tau {}{}{}",
        info.path.display(),
        num(opts.iso),
        opts.inside.name(),
        opts.connectivity.number(),
        axis.name(),
        if tau.is_finite() {
            num(tau)
        } else {
            "inf".into()
        },
        match sopts.mode {
            Mode::Both => "",
            Mode::FillOnly => ", fill only",
            Mode::CutOnly => ", cut only",
        },
        a.max_ratio
            .map(|r| format!(", max ratio {}", num(r)))
            .unwrap_or_default()
    );
    println!(
        "grid        {}×{}×{} {}",
        info.dims[0],
        info.dims[1],
        info.dims[2],
        info.dtype.name()
    );
    println!(
        "genus       {} -> {}   (components {} -> {}, cavities {} -> {})",
        before.b1, after.b1, before.b0, after.b0, before.b2, after.b2
    );
    println!(
        "removed     {} handles: {} collapse (fill), {} pinch (cut); intra-ribbon handles: {}",
        collapse + pinch,
        collapse,
        pinch,
        outcome.intra_ribbon
    );
    if !outcome.kept.is_empty() {
        use isotopo::simplify::KeepReason;
        let reasons = [
            (KeepReason::Size, "at or above tau"),
            (KeepReason::Ratio, "long and skinny (--max-ratio)"),
            (KeepReason::Mode, "excluded by --fill-only/--cut-only"),
            (KeepReason::ClosureFailed, "no clean wall found"),
            (KeepReason::Unmeasured, "Reeb loop beyond the search budget"),
            (KeepReason::PassLimit, "pass limit reached"),
        ];
        let parts: Vec<String> = reasons
            .iter()
            .filter_map(|(r, name)| {
                let n = outcome.kept.iter().filter(|k| k.reason == *r).count();
                (n > 0).then(|| format!("{n} {name}"))
            })
            .collect();
        println!(
            "kept        {} handles: {}",
            outcome.kept.len(),
            parts.join(", ")
        );
    }
    match outcome.certified {
        Some(true) => println!(
            "checked     no loop shorter than tau {} is left (every loop of the result crosses a checked curve)",
            num(tau)
        ),
        Some(false) => println!(
            "checked     NOT proven that no loop shorter than tau {} is left (see the kept handles)",
            num(tau)
        ),
        None => {}
    }
    println!(
        "samples     {} changed ({} filled, {} cut), all within {:.1} voxels ({:.1} mm) of a closed loop; wall values: inside {}, outside {}",
        group(outcome.edits.len() as u64),
        group(v["samples_filled"].as_u64().unwrap_or(0)),
        group(v["samples_cut"].as_u64().unwrap_or(0)),
        v["max_distance"].as_f64().unwrap_or(0.0),
        v["max_distance_mm"].as_f64().unwrap_or(0.0),
        values.inside.map(num).unwrap_or_else(|| "-".into()),
        values.outside.map(num).unwrap_or_else(|| "-".into())
    );
    println!(
        "sweep       {} passes, {} rewinds, {} closures refused by the local check",
        outcome.passes, outcome.rewinds, outcome.refused
    );
    println!("output      {}", a.output.display());
    if let (Some(p), Some(chi)) = (&a.mesh, mesh_genus) {
        println!("mesh        {} (Euler characteristic {})", p.display(), chi);
    }
    if let Some(p) = &a.report {
        println!("report      {}", p.display());
    }
    println!(
        "time        {:.2} s ({:.2} s read, {:.2} s simplify, {:.2} s write)",
        secs, t_read, t_simplify, t_write
    );
    Ok(())
}
