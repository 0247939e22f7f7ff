//! `isotopo analyze`.

use crate::args::*;
use crate::print::*;
use crate::progress;
use clap::Args;
use isotopo::report::LoopsWriter;
use isotopo::volume::{self};
use isotopo::{Error, Result};
use std::path::PathBuf;

#[derive(Args)]
pub(crate) struct AnalyzeArgs {
    #[command(flatten)]
    input: Input,
    #[command(flatten)]
    surface: SurfaceArgs,
    #[command(flatten)]
    sweep: SweepArgs,
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
    /// Write a self-contained HTML report (opens offline in any browser): summary, interactive
    /// plots with a tau slider, a sortable table of the handles, each in 3D with its loops.
    #[arg(long, value_name = "OUT.html")]
    html: Option<PathBuf>,
    /// List every handle, not only the 30 largest.
    #[arg(long)]
    all: bool,
    #[arg(long, short)]
    quiet: bool,
}

#[derive(clap::ValueEnum, Clone, Copy, PartialEq, Eq)]
pub(crate) enum MetricArg {
    Edges,
    Mm,
    Both,
}

pub(crate) fn run(a: AnalyzeArgs) -> Result<()> {
    use isotopo::jobs::Lengths;
    let opts = a.surface.options()?;
    let axis = a.sweep.axis.axis();
    let reader = a.input.open()?;
    let info = reader.info().clone();
    for p in a.loops.iter().chain(a.html.iter()) {
        volume::check_output_path(p, &info)?;
    }
    if a.loops.is_some() && a.loops == a.html {
        return Err(Error::usage("--loops and --html name the same file"));
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
        max_slices: a.sweep.max_slices,
        tau,
        tau_mm,
        lengths,
    };
    let bars = progress::Bars::new(a.quiet || a.json || a.csv);
    // Memory stays flat in the handles: they come one at a time, out of a scratch file.
    let mut analysis = isotopo::analyze_streamed(isotopo::Source::Reader(reader), &aopts, &bars)?;
    let name = info
        .path
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_default();
    let text = !(a.json || a.csv);
    // First pass: the files, and what the text summary needs.
    let mut summary = Summary::new(if a.all { usize::MAX } else { 30 });
    let mut rows = Vec::new();
    if a.loops.is_some() || a.plots.is_some() || a.html.is_some() || text {
        let mut loops = a.loops.as_deref().map(LoopsWriter::create).transpose()?;
        let mut points = std::collections::BTreeMap::new();
        while let Some(h) = analysis.next_handle()? {
            if let Some(w) = &mut loops {
                let pts = |name: &str| -> Option<Vec<[f64; 3]>> {
                    serde_json::from_value(h[name]["points"].clone()).ok()
                };
                let id = h["id"].as_u64().unwrap_or(0) as usize;
                w.add(id, pts("reeb_loop"), pts("cross_loop"), &info.affine)?;
            }
            if a.plots.is_some() {
                *points.entry(plot_key(&h)).or_insert(0) += 1;
            }
            if text {
                summary.add(&h, tau);
            }
            if a.html.is_some() {
                rows.push(isotopo::html::HtmlHandle::from_analysis_json(&h));
            }
        }
        if let Some(w) = loops {
            w.commit()?;
        }
        if let Some(dir) = &a.plots {
            let points: Vec<isotopo::plots::PlotPoint> = points
                .into_iter()
                .map(|((reeb, cross, void), count)| isotopo::plots::PlotPoint {
                    reeb,
                    cross,
                    void,
                    count,
                })
                .collect();
            summary.plot_files = isotopo::plots::write(dir, &name, &points, tau)?;
        }
        analysis.rewind();
    }
    let html = match &a.html {
        Some(p) => {
            // b0, b1, b2 for the summary: a genus pass, a fraction of the analysis's time.
            let topology = isotopo::genus(
                isotopo::Source::Reader(a.input.open()?),
                &aopts.surface,
                &isotopo::progress::NoProgress,
            )?;
            let report = isotopo::html::HtmlReport::analysis(&analysis, &aopts, rows)
                .with_topology(&topology);
            let source = isotopo::Source::Reader(a.input.open()?);
            let opts = isotopo::html::HtmlOptions::default();
            Some(isotopo::html::write_analysis(
                p,
                &report,
                source,
                &aopts.surface,
                &opts,
            )?)
        }
        None => None,
    };
    if a.json {
        let mut out = std::io::BufWriter::new(std::io::stdout().lock());
        analysis.write_json(&aopts, true, &mut out)?;
        write_out(&mut out, "\n")?;
        return flush_out(out);
    }
    if a.csv {
        let mut out = std::io::BufWriter::new(std::io::stdout().lock());
        write_out(&mut out, isotopo::report::CSV_HEADER)?;
        while let Some(h) = analysis.next_handle()? {
            write_out(&mut out, &isotopo::report::csv_row(&h))?;
        }
        return flush_out(out);
    }
    print_sweep_header(&info, &opts, axis);
    summary.print(&analysis, tau);
    if let Some(p) = &a.loops {
        println!("loops       {}", p.display());
    }
    if let (Some(p), Some(w)) = (&a.html, &html) {
        print_html(p, w);
    }
    for f in &summary.plot_files {
        println!("plot        {}", f.display());
    }
    println!(
        "time        {:.2} s ({:.2} s sweep, {:.2} s loops)",
        analysis.seconds,
        analysis.seconds_sweep,
        analysis.seconds - analysis.seconds_sweep
    );
    Ok(())
}

/// A handle's lengths as plotted (Reeb loop, cross loop, whether the smaller encloses void),
/// from its report.
fn plot_key(h: &serde_json::Value) -> (Option<usize>, Option<usize>, bool) {
    let len = |name: &str| h[name]["length"].as_u64().map(|x| x as usize);
    let (reeb, cross) = (len("reeb_loop"), len("cross_loop"));
    let smaller = match (reeb, cross) {
        (Some(r), Some(c)) if c < r => "cross_loop",
        (None, Some(_)) => "cross_loop",
        _ => "reeb_loop",
    };
    (reeb, cross, h[smaller]["encloses"] == "void")
}

fn write_out(out: &mut impl std::io::Write, s: &str) -> Result<()> {
    out.write_all(s.as_bytes())
        .map_err(|e| Error::io(std::path::Path::new("<stdout>"), "writing", e))
}

fn flush_out(mut out: impl std::io::Write) -> Result<()> {
    out.flush()
        .map_err(|e| Error::io(std::path::Path::new("<stdout>"), "writing", e))
}

/// Size classes of the text histogram, in voxel edges: [lo, hi).
const BINS: &[(usize, usize)] = &[
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

/// The sizes the text report counts the handles below.
const BELOW: [usize; 3] = [10, 20, 50];

/// What the text report needs, gathered a handle at a time: counts, and the largest handles'
/// lines (all of them with `--all`).
struct Summary {
    reeb_cycles: usize,
    intra_ribbon: usize,
    counts: Vec<usize>,
    /// Handles smaller than each of [`BELOW`].
    below: [usize; 3],
    /// Handles with no loop within the limit.
    beyond: usize,
    /// (size, id, line) of the largest handles, at most `keep`.
    largest:
        std::collections::BinaryHeap<std::cmp::Reverse<(usize, std::cmp::Reverse<usize>, String)>>,
    keep: usize,
    plot_files: Vec<PathBuf>,
}

impl Summary {
    fn new(keep: usize) -> Summary {
        Summary {
            reeb_cycles: 0,
            intra_ribbon: 0,
            counts: vec![0; BINS.len()],
            below: [0; 3],
            beyond: 0,
            largest: Default::default(),
            keep,
            plot_files: Vec::new(),
        }
    }

    fn add(&mut self, h: &serde_json::Value, tau: Option<f64>) {
        match h["kind"].as_str() {
            Some("reeb_cycle") => self.reeb_cycles += 1,
            _ => self.intra_ribbon += 1,
        }
        let size = h["size"].as_u64().map(|s| s as usize);
        match size {
            Some(s) => {
                let bin = BINS.iter().position(|&(lo, hi)| s >= lo && s < hi);
                self.counts[bin.unwrap_or(BINS.len() - 1)] += 1;
                for (n, t) in self.below.iter_mut().zip(BELOW) {
                    *n += usize::from(s < t);
                }
            }
            None => self.beyond += 1,
        }
        let id = h["id"].as_u64().unwrap_or(0) as usize;
        // Largest first, then by id; a handle beyond the limit is the largest.
        let key = (size.unwrap_or(usize::MAX), std::cmp::Reverse(id));
        if self.largest.len() == self.keep {
            match self.largest.peek() {
                Some(std::cmp::Reverse(least)) if (least.0, least.1) < key => {
                    self.largest.pop();
                }
                _ => return,
            }
        }
        let line = handle_line(h, size, tau);
        self.largest.push(std::cmp::Reverse((key.0, key.1, line)));
    }

    fn print(&self, analysis: &isotopo::StreamedAnalysis, tau: Option<f64>) {
        let total = analysis.len();
        println!(
            "handles     {} ({} Reeb cycles, {} intra-ribbon); genus from the Euler characteristic: {}",
            total, self.reeb_cycles, self.intra_ribbon, analysis.genus
        );
        let [b10, b20, b50] = self.below;
        println!(
            "sizes       {b10} below 10, {b20} below 20, {b50} below 50, {} of 50 or more (voxel edges: the shorter of the two loops)",
            total - b50
        );
        let maxc = self
            .counts
            .iter()
            .copied()
            .max()
            .unwrap_or(1)
            .max(self.beyond)
            .max(1);
        for (&(lo, hi), &c) in BINS.iter().zip(&self.counts) {
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
        if self.beyond > 0 {
            println!(
                "  {:>8} {:<40} {}",
                format!(">={}", num(tau.unwrap_or(f64::INFINITY))),
                "#".repeat((self.beyond * 40).div_ceil(maxc)),
                self.beyond
            );
        }
        let mut lines: Vec<_> = self.largest.iter().map(|r| &r.0).collect();
        lines.sort_by_key(|l| std::cmp::Reverse((l.0, l.1)));
        if !lines.is_empty() {
            println!(
                "  {:>5} {:>7}  {:<12} {:>6} {:>18} {:>18}  bbox (voxels)",
                "id", "surface", "kind", "size", "Reeb loop", "cross loop"
            );
        }
        for (_, _, line) in &lines {
            println!("{line}");
        }
        if lines.len() < total {
            println!(
                "  … {} more (--all, --json or --csv list them)",
                total - lines.len()
            );
        }
    }
}

/// A handle's line in the text report's list.
fn handle_line(h: &serde_json::Value, size: Option<usize>, tau: Option<f64>) -> String {
    let fmt_loop = |l: &serde_json::Value| match l["length"].as_u64() {
        Some(n) => format!(
            "{} ({:.0} mm, {})",
            n,
            l["length_mm"].as_f64().unwrap_or(f64::NAN),
            if l["encloses"] == "material" {
                "mat"
            } else {
                "void"
            }
        ),
        None => format!(">={}", num(tau.unwrap_or(f64::INFINITY))),
    };
    // The box of the cycle, as the sweep found it.
    let b = if h["cycle_bbox"].is_null() {
        &h["bbox"]
    } else {
        &h["cycle_bbox"]
    };
    format!(
        "  {:>5} {:>7}  {:<12} {:>6} {:>18} {:>18}  [{}..{}, {}..{}, {}..{}]",
        h["id"].as_u64().unwrap_or(0),
        h["surface"].as_u64().unwrap_or(0),
        h["kind"].as_str().unwrap_or(""),
        size.map(|s| s.to_string()).unwrap_or_else(|| "-".into()),
        fmt_loop(&h["reeb_loop"]),
        fmt_loop(&h["cross_loop"]),
        b["min"][0],
        b["max"][0],
        b["min"][1],
        b["max"][1],
        b["min"][2],
        b["max"][2]
    )
}
