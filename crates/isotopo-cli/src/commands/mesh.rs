//! `isotopo mesh`.

use crate::args::*;
use crate::print::*;
use crate::progress;
use clap::Args;
use isotopo::volume::{self};
use isotopo::Result;
use std::path::PathBuf;
use std::time::Instant;

#[derive(Args)]
pub(crate) struct MeshArgs {
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

pub(crate) fn run(a: MeshArgs) -> Result<()> {
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
