//! Numbers and JSON as the commands print them.

use isotopo::grid::Axis;
use isotopo::sweep::{HandleKind, HandleReport};
use isotopo::topology::SurfaceOptions;
use isotopo::volume::VolumeInfo;
use isotopo::{Error, Result};

/// The first line of `handles` and `analyze`: the file, the isosurface and the sweep axis.
pub(crate) fn print_sweep_header(info: &VolumeInfo, opts: &SurfaceOptions, axis: Axis) {
    println!(
        "{}: iso {}, inside {}, connectivity {}, sweep along {}",
        info.path.display(),
        num(opts.iso),
        opts.inside.name(),
        opts.connectivity.number(),
        axis.name()
    );
}

/// Handles that are Reeb cycles (the others were found inside a ribbon).
pub(crate) fn reeb_cycles(report: &HandleReport) -> usize {
    report
        .handles
        .iter()
        .filter(|h| h.located.kind == HandleKind::ReebCycle)
        .count()
}

pub(crate) fn group(n: u64) -> String {
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
pub(crate) fn num(x: f64) -> String {
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

pub(crate) fn to_json(v: &impl serde::Serialize) -> Result<String> {
    serde_json::to_string_pretty(v).map_err(|e| Error::Internal(e.to_string()))
}

/// The line naming the HTML report: where, how big, how many handles in 3D.
pub(crate) fn print_html(path: &std::path::Path, w: &isotopo::html::HtmlWritten) {
    println!(
        "html        {} ({:.1} MB; {} handles in 3D, {} triangles)",
        path.display(),
        w.bytes as f64 / 1e6,
        w.scenes,
        group(w.triangles as u64)
    );
}
