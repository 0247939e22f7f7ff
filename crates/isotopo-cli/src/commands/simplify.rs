//! `isotopo simplify`.

use crate::args::*;
use crate::print::*;
use crate::progress;
use clap::Args;
use isotopo::simplify::Operation;
use isotopo::volume::{self};
use isotopo::{Error, Result};
use std::path::PathBuf;
use std::time::Instant;

#[derive(Args)]
pub(crate) struct SimplifyArgs {
    #[command(flatten)]
    input: Input,
    #[command(flatten)]
    surface: SurfaceArgs,
    #[command(flatten)]
    sweep: SweepArgs,
    /// Remove handles whose size (the shorter of the Reeb and cross loops, in voxel edges) is
    /// below this; `inf` removes every handle. `isotopo analyze --plots` helps choose it.
    #[arg(
        long,
        required_unless_present_any = ["tau_mm", "spherical", "keep_handles"],
        conflicts_with = "tau_mm"
    )]
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
    /// Leave the output as the walls make it: do not make it well-composed (by default no unit
    /// face shows one diagonal and no unit cube two opposite corners alone, and floating-point
    /// samples at the isovalue move just outside, so every mesher sees one topology).
    #[arg(long)]
    no_well_composed: bool,
    /// Keep long skinny handles: those whose longer loop is more than R times the shorter.
    #[arg(long, value_name = "R")]
    max_ratio: Option<f64>,
    /// Remove the solid's components with fewer than N inside samples: each deleted, or bridged
    /// to a component that stays where the bridge flips fewer samples.
    #[arg(long, value_name = "N")]
    min_component: Option<u64>,
    /// Keep one component, the largest (the others deleted or bridged, as --min-component).
    #[arg(long)]
    largest: bool,
    /// Remove the cavities with fewer than N samples: each filled, or opened to the outside
    /// through its thinnest wall where that flips fewer samples.
    #[arg(long, value_name = "N")]
    min_cavity: Option<u64>,
    /// Remove every cavity (filled or opened, as --min-cavity).
    #[arg(long)]
    fill_cavities: bool,
    /// One component, no handle, no cavity: --largest --fill-cavities --tau inf.
    #[arg(long, conflicts_with_all = ["tau", "tau_mm"])]
    spherical: bool,
    /// Remove handles from the smallest up until K are left (the output's genus is K),
    /// whatever their size (instead of --tau).
    #[arg(long, value_name = "K", conflicts_with_all = ["tau", "tau_mm", "spherical"])]
    keep_handles: Option<usize>,
    /// Write a JSON report (genus before/after, every removed and kept handle).
    #[arg(long, value_name = "OUT.json")]
    report: Option<PathBuf>,
    /// Write a self-contained HTML report (opens offline in any browser): summary, interactive
    /// plots with a tau slider, the handles removed and kept, each in 3D before and after with
    /// its wall's samples.
    #[arg(long, value_name = "OUT.html")]
    html: Option<PathBuf>,
    /// Print the JSON report to stdout instead of the summary.
    #[arg(long)]
    json: bool,
    #[arg(long, short)]
    quiet: bool,
}

pub(crate) fn run(a: SimplifyArgs) -> Result<()> {
    use isotopo::simplify::{Mode, SimplifyOptions};
    let surface = a.surface.options()?;
    let (tau, metric, flag) = match (a.tau, a.tau_mm) {
        _ if a.spherical || a.keep_handles.is_some() => {
            (f64::INFINITY, isotopo::loops::Metric::Edges, "--tau")
        }
        (Some(t), _) => (t, isotopo::loops::Metric::Edges, "--tau"),
        (None, Some(t)) => (t, isotopo::loops::Metric::Millimetres, "--tau-mm"),
        (None, None) => return Err(Error::usage("give --tau or --tau-mm")),
    };
    if tau.is_nan() || tau < 0.0 {
        return Err(Error::usage(format!(
            "{flag} must be 0 (remove no handle: only make the output well-composed), positive or inf"
        )));
    }
    if let Some(r) = a.max_ratio {
        if r.is_nan() || r < 1.0 {
            return Err(Error::usage("--max-ratio must be at least 1"));
        }
    }
    let sopts = SimplifyOptions {
        surface,
        axis: a.sweep.axis.axis(),
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
        max_slices: a.sweep.max_slices,
        well_composed: !a.no_well_composed,
        min_component: a.min_component,
        largest: a.largest || a.spherical,
        min_cavity: a.min_cavity,
        fill_cavities: a.fill_cavities || a.spherical,
        keep_handles: a.keep_handles,
    };
    // Every output is checked before the work starts.
    let reader = a.input.open()?;
    let info = reader.info().clone();
    let mut outputs = vec![&a.output];
    outputs.extend(a.mesh.iter());
    outputs.extend(a.report.iter());
    outputs.extend(a.html.iter());
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
    let html = match &a.html {
        Some(p) => {
            let report = isotopo::html::HtmlReport::simplified(&done, &sopts);
            let opts = isotopo::html::HtmlOptions::default();
            Some(isotopo::html::write_simplified(
                p, &report, &mut done, &surface, &opts,
            )?)
        }
        None => None,
    };
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
    let collapse = outcome.handles_removed_by(Operation::Collapse);
    let pinch = outcome.handles_removed_by(Operation::Pinch);
    let (filled, cut) = outcome.samples_filled_cut();
    let (max_distance, max_distance_mm) = outcome.max_distance();
    println!(
        "{}: iso {}, inside {}, connectivity {}, sweep along {}, {}{}{}",
        info.path.display(),
        num(opts.iso),
        opts.inside.name(),
        opts.connectivity.number(),
        axis.name(),
        match (a.keep_handles, tau.is_finite()) {
            (Some(k), _) => format!("keep the {k} largest handles"),
            (None, true) => format!("tau {}", num(tau)),
            (None, false) => "tau inf".into(),
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
    print_parts(&outcome.parts);
    if !outcome.kept.is_empty() {
        use isotopo::simplify::KeepReason;
        let reasons = [
            (KeepReason::Size, "at or above tau"),
            (KeepReason::Ratio, "long and skinny (--max-ratio)"),
            (KeepReason::Mode, "excluded by --fill-only/--cut-only"),
            (KeepReason::ClosureFailed, "no clean wall found"),
            (KeepReason::Unmeasured, "Reeb loop beyond the search budget"),
            (KeepReason::PassLimit, "pass limit reached"),
            (KeepReason::KeepHandles, "the largest (--keep-handles)"),
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
    let composed = outcome.composition.as_ref().map_or(0, |c| c.flips.len());
    println!(
        "samples     {} changed ({} filled, {} cut): {} by walls, all within {:.1} voxels ({:.1} mm) of a closed loop, {} by the well-composed step; wall values: inside {}, outside {}",
        group(outcome.edits.len() as u64),
        group(filled as u64),
        group(cut as u64),
        group(outcome.edits.len().saturating_sub(composed) as u64),
        max_distance,
        max_distance_mm,
        group(composed as u64),
        values.inside.map(num).unwrap_or_else(|| "-".into()),
        values.outside.map(num).unwrap_or_else(|| "-".into())
    );
    print_composition(&done);
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
    if let (Some(p), Some(w)) = (&a.html, &html) {
        print_html(p, w);
    }
    println!(
        "time        {:.2} s ({:.2} s read, {:.2} s simplify, {:.2} s write)",
        secs, t_read, t_simplify, t_write
    );
    Ok(())
}

/// The components and cavities removed, when asked.
fn print_parts(parts: &isotopo::simplify::Parts) {
    use isotopo::simplify::{PartKind, PartOperation as Op};
    if parts.after.is_none() {
        return;
    }
    let lines = [
        (
            "components",
            PartKind::Component,
            (Op::Delete, "deleted"),
            (Op::Bridge, "bridged"),
            "no bridge under --fill-only",
        ),
        (
            "cavities  ",
            PartKind::Cavity,
            (Op::Fill, "filled"),
            (Op::Open, "opened"),
            "no opening under --cut-only",
        ),
    ];
    for (name, kind, (whole, whole_verb), (join, join_verb), why_kept) in lines {
        println!(
            "{name}  {} removed: {} {whole_verb}, {} {join_verb} ({} samples){}",
            parts.count(whole) + parts.count(join),
            parts.count(whole),
            parts.count(join),
            group(parts.samples_changed(kind) as u64),
            match parts.kept_count(kind) {
                0 => String::new(),
                n => format!("; {n} kept: {why_kept}"),
            }
        );
    }
}

/// The well-composed step's line, and what another mesher needs to see the same surface.
fn print_composition(done: &isotopo::Simplified) {
    let other = done.after_other.b1;
    if let Some(c) = &done.outcome.composition {
        println!(
            "composed    {} critical faces and {} cubes before, {} left ({}): {} samples flipped",
            group(c.before.faces),
            group(c.before.cubes),
            group(c.left.total()),
            if c.well_composed() {
                "well-composed: every mesher sees genus ".to_string() + &group(done.after.b1)
            } else {
                format!(
                    "NOT well-composed: genus {} under the other connectivity",
                    group(other)
                )
            },
            group(c.flips.len() as u64)
        );
        if !c.opened.is_empty() {
            println!(
                "            {} handles opened through critical faces nothing else mended (the other \
                 connectivity saw them there), then closed elsewhere: counted among those removed",
                group(c.opened.len() as u64)
            );
        }
    } else {
        println!(
            "composed    not asked (--no-well-composed): genus {} under the other connectivity",
            group(other)
        );
    }
    if let Some(w) = done.written.filter(|w| w.samples_at_iso > 0) {
        if w.at_iso_moved {
            println!(
                "at iso      {} samples were exactly at the isovalue: moved just outside",
                group(w.samples_at_iso)
            );
        } else {
            println!(
                "at iso      {} samples are exactly at the isovalue (isotopo counts them outside, \
                 VTK inside): mesh the output at {} for the same surface in every tool",
                group(w.samples_at_iso),
                num(done.mesh_iso())
            );
        }
    }
}
