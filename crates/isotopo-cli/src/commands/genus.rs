//! `isotopo genus`.

use crate::args::*;
use crate::print::*;
use crate::progress;
use clap::Args;
use isotopo::Result;

#[derive(Args)]
pub(crate) struct GenusArgs {
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

pub(crate) fn run(a: GenusArgs) -> Result<()> {
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
    let m = &topology.meshers;
    if m.critical.total() == 0 && m.samples_at_iso == 0 {
        println!(
            "meshers     agree: well-composed, no sample at the isovalue (connectivity {} gives the same)",
            m.other_connectivity
        );
    } else {
        println!(
            "meshers     may disagree: {} critical faces and {} cubes, {} samples at the isovalue; \
             connectivity {}: b0 = {}, b1 = {}, b2 = {} (simplify makes its output well-composed)",
            group(m.critical.faces),
            group(m.critical.cubes),
            group(m.samples_at_iso),
            m.other_connectivity,
            m.b0,
            m.b1,
            m.b2
        );
    }
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
            match s.bounds {
                isotopo::topology::Bounds::Material => "material",
                isotopo::topology::Bounds::Cavity => "cavity",
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
