//! `isotopo info`.

use crate::args::*;
use crate::print::*;
use crate::progress;
use clap::Args;
use isotopo::volume::{self, Endian};
use isotopo::{Error, Result};

#[derive(Args)]
pub(crate) struct InfoArgs {
    #[command(flatten)]
    input: Input,
    /// Print one JSON object instead of text.
    #[arg(long)]
    json: bool,
    /// No progress bar.
    #[arg(long, short)]
    quiet: bool,
}

pub(crate) fn run(a: InfoArgs) -> Result<()> {
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
