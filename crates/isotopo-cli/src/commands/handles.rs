//! `isotopo handles`.

use crate::args::*;
use crate::print::*;
use crate::progress;
use clap::Args;
use isotopo::Result;

#[derive(Args)]
pub(crate) struct HandlesArgs {
    #[command(flatten)]
    input: Input,
    #[command(flatten)]
    surface: SurfaceArgs,
    #[command(flatten)]
    sweep: SweepArgs,
    /// Print one JSON object instead of text.
    #[arg(long)]
    json: bool,
    /// List every handle, not only the first 30.
    #[arg(long)]
    all: bool,
    #[arg(long, short)]
    quiet: bool,
}

pub(crate) fn run(a: HandlesArgs) -> Result<()> {
    let opts = a.surface.options()?;
    let axis = a.sweep.axis.axis();
    let bars = progress::Bars::new(a.quiet || a.json);
    let aopts = isotopo::AnalyzeOptions {
        surface: opts,
        axis,
        max_slices: a.sweep.max_slices,
        ..isotopo::AnalyzeOptions::default()
    };
    let found = isotopo::handles(isotopo::Source::Reader(a.input.open()?), &aopts, &bars)?;
    let (info, report, secs) = (&found.info, &found.report, found.seconds);
    if a.json {
        println!("{}", to_json(&found.to_json(&aopts))?);
        return Ok(());
    }
    let reeb = reeb_cycles(report);
    print_sweep_header(info, &opts, axis);
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
    let w = axis.uvw()[2];
    for h in report.handles.iter().take(shown) {
        let (b, kind) = (&h.located.bbox, h.located.kind);
        let m = b.to_mm(&info.affine);
        println!(
            "  {:>5} {:>7}  {:<12} {:>9}  [{}..{}, {}..{}, {}..{}]  [{:.1}..{:.1}, {:.1}..{:.1}, {:.1}..{:.1}]",
            h.id,
            h.surface,
            kind.name(),
            format!("{}..{}", b.min[w], b.max[w]),
            b.min[0],
            b.max[0],
            b.min[1],
            b.max[1],
            b.min[2],
            b.max[2],
            m[0][0],
            m[1][0],
            m[0][1],
            m[1][1],
            m[0][2],
            m[1][2]
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
