//! `isotopo analyze`.

use crate::args::*;
use crate::print::*;
use crate::progress;
use clap::Args;
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
        max_slices: a.sweep.max_slices,
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
    let reeb = reeb_cycles(report);
    print_sweep_header(&info, &opts, axis);
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
            h.located.kind.name(),
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
