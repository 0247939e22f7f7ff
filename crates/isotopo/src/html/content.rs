//! What a report says, from the jobs' results: the summary lines and the handles' rows.

use super::{HtmlHandle, HtmlReport, ReportKind};
use crate::jobs::{AnalyzeOptions, Simplified, StreamedAnalysis};
use crate::simplify::{Kept, Removed, SimplifyOptions};
use crate::volume::{BBox, VolumeInfo};
use serde_json::Value;

impl HtmlHandle {
    /// A handle of `analyze --json` (one element of its `handles`).
    pub fn from_analysis_json(h: &Value) -> HtmlHandle {
        let len = |l: &str| h[l]["length"].as_u64().map(|n| n as usize);
        let mm = |l: &str| h[l]["length_mm"].as_f64();
        let (reeb, cross) = (len("reeb_loop"), len("cross_loop"));
        let smaller = match (reeb, cross) {
            (Some(r), Some(c)) if c < r => "cross_loop",
            (None, Some(_)) => "cross_loop",
            _ => "reeb_loop",
        };
        let points = |l: &str| -> Option<Vec<[f64; 3]>> {
            serde_json::from_value(h[l]["points"].clone()).ok()
        };
        let b = &h["bbox"];
        let at = |k: &str, a: usize| b[k][a].as_i64().unwrap_or(0);
        let whole = [
            at("min", 0),
            at("min", 1),
            at("min", 2),
            at("max", 0),
            at("max", 1),
            at("max", 2),
        ];
        HtmlHandle {
            id: h["id"].as_u64().unwrap_or(0) as usize,
            surface: h["surface"].as_u64().map(|s| s as usize),
            kind: h["kind"].as_str().unwrap_or("").to_string(),
            // With a search limit, a handle missing a loop has some size at or above it: unknown.
            size: h["size"]
                .as_u64()
                .map(|s| s as usize)
                .filter(|_| reeb.is_some() && cross.is_some()),
            reeb,
            reeb_mm: mm("reeb_loop"),
            cross,
            cross_mm: mm("cross_loop"),
            encloses: h[smaller]["encloses"].as_str().map(String::from),
            status: None,
            detail: None,
            // Where the handle is: its shorter loop (the other may run far along the surface).
            bbox: points(smaller).map_or(whole, |p| points_box(&p)),
            loops: ["reeb_loop", "cross_loop"]
                .into_iter()
                .filter_map(points)
                .collect(),
            wall: Vec::new(),
        }
    }

    /// A handle `simplify` removed: the loop it closed, and its wall.
    pub fn from_removed(id: usize, r: &Removed) -> HtmlHandle {
        use crate::simplify::LoopKind;
        // The closed loop's length in mm, under its own name (a basis curve's under neither).
        let closed_mm = |kind: LoopKind| (r.closed == kind).then_some(r.length_mm);
        HtmlHandle {
            id,
            surface: None,
            kind: r.kind.name().to_string(),
            size: Some(r.size),
            reeb: r.reeb,
            reeb_mm: closed_mm(LoopKind::Reeb),
            cross: r.cross,
            cross_mm: closed_mm(LoopKind::Cross),
            encloses: Some(
                match name(&r.operation).as_str() {
                    "collapse" => "void",
                    _ => "material",
                }
                .to_string(),
            ),
            status: Some(name(&r.operation)),
            detail: Some(match r.handles {
                1 => format!("{} ({} samples)", r.wall, r.samples_changed),
                n => format!(
                    "{} ({} samples; closed {} tiny handles beside too)",
                    r.wall,
                    r.samples_changed,
                    n - 1
                ),
            }),
            bbox: loop_and_wall_box(r),
            loops: vec![r.points.clone()],
            wall: r.samples.clone(),
        }
    }

    /// A handle `simplify` kept.
    pub fn from_kept(id: usize, k: &Kept) -> HtmlHandle {
        HtmlHandle {
            id,
            surface: None,
            kind: k.kind.name().to_string(),
            size: k.size,
            reeb: k.reeb,
            cross: k.cross,
            status: Some("kept".into()),
            detail: Some(name(&k.reason).replace('_', " ")),
            bbox: bbox6(&k.bbox),
            ..HtmlHandle::default()
        }
    }
}

/// An enum's name in the reports (its serde name).
fn name(v: &impl serde::Serialize) -> String {
    match serde_json::to_value(v) {
        Ok(Value::String(s)) => s,
        _ => String::new(),
    }
}

/// The box of voxels round loop points (on half-integers).
fn points_box(points: &[[f64; 3]]) -> [i64; 6] {
    let mut b = [i64::MAX, i64::MAX, i64::MAX, i64::MIN, i64::MIN, i64::MIN];
    for p in points {
        for a in 0..3 {
            b[a] = b[a].min(p[a].floor() as i64);
            b[a + 3] = b[a + 3].max(p[a].ceil() as i64);
        }
    }
    if b[0] > b[3] {
        return [0; 6];
    }
    b
}

/// The box of a removal's closed loop and wall: what its close-up shows (the box of both loops,
/// `r.bbox`, runs along the other loop, often far longer).
fn loop_and_wall_box(r: &Removed) -> [i64; 6] {
    let mut b = [i64::MAX, i64::MAX, i64::MAX, i64::MIN, i64::MIN, i64::MIN];
    let points = r.points.iter().map(|p| p.map(|v| v.floor() as i64));
    let ceil = r.points.iter().map(|p| p.map(|v| v.ceil() as i64));
    for p in points.chain(ceil).chain(r.samples.iter().copied()) {
        for a in 0..3 {
            b[a] = b[a].min(p[a]);
            b[a + 3] = b[a + 3].max(p[a]);
        }
    }
    if b[0] > b[3] {
        return bbox6(&r.bbox);
    }
    b
}

fn bbox6(b: &BBox) -> [i64; 6] {
    [b.min[0], b.min[1], b.min[2], b.max[0], b.max[1], b.max[2]]
}

fn file_name(info: &VolumeInfo) -> String {
    info.path
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_else(|| info.path.display().to_string())
}

/// The lines every report starts with: the volume and the surface.
fn volume_lines(
    info: &VolumeInfo,
    surface: &crate::topology::SurfaceOptions,
) -> Vec<(String, String)> {
    let [sx, sy, sz] = info.spacing();
    let [nx, ny, nz] = info.dims;
    vec![
        ("volume".into(), info.path.display().to_string()),
        (
            "grid".into(),
            format!(
                "{nx} × {ny} × {nz} samples of {}, spacing {sx:.3} × {sy:.3} × {sz:.3} mm",
                info.dtype
            ),
        ),
        (
            "isosurface".into(),
            format!(
                "iso {}, inside {} it, connectivity {}",
                surface.iso,
                surface.inside.name(),
                surface.connectivity.number()
            ),
        ),
    ]
}

/// The rows of every handle of a streamed analysis, which is then rewound (for a caller that
/// reads its handles only for the report; the command line takes them in its own pass).
pub fn analysis_rows(a: &mut StreamedAnalysis) -> crate::error::Result<Vec<HtmlHandle>> {
    a.rewind();
    let mut rows = Vec::with_capacity(a.len());
    while let Some(h) = a.next_handle()? {
        rows.push(HtmlHandle::from_analysis_json(&h));
    }
    a.rewind();
    Ok(rows)
}

impl HtmlReport {
    /// The report of an analysis whose handles (from [`HtmlHandle::from_analysis_json`]) are
    /// `handles`.
    pub fn analysis(
        a: &StreamedAnalysis,
        opts: &AnalyzeOptions,
        handles: Vec<HtmlHandle>,
    ) -> HtmlReport {
        let mut summary = volume_lines(&a.info, &opts.surface);
        let reeb = handles.iter().filter(|h| h.kind == "reeb_cycle").count();
        summary.push((
            "handles".into(),
            format!(
                "{} ({} Reeb cycles, {} intra-ribbon) on {} surfaces; genus from the Euler characteristic {}",
                handles.len(),
                reeb,
                handles.len() - reeb,
                a.surfaces.len(),
                a.genus
            ),
        ));
        if let Some(t) = opts.tau.filter(|t| t.is_finite()) {
            summary.push(("search limit".into(), format!("tau {t} voxel edges")));
        }
        summary.push((
            "time".into(),
            format!(
                "{:.2} s ({:.2} s sweep, sweep axis {})",
                a.seconds,
                a.seconds_sweep,
                a.axis.name()
            ),
        ));
        HtmlReport {
            kind: ReportKind::Analyze,
            title: file_name(&a.info),
            summary,
            tau: opts.tau,
            handle_count: handles.len(),
            handles,
        }
    }

    /// Adds the solid's topology from a genus pass (b0, b1, b2, and where other meshers see
    /// another one) after the isosurface's line.
    pub fn with_topology(mut self, t: &crate::jobs::Topology) -> HtmlReport {
        let s = &t.solid;
        let m = &t.meshers;
        let lines = [
            (
                "solid".to_string(),
                format!(
                    "b0 {} components, b1 {} handles (total genus), b2 {} cavities",
                    s.b0, s.b1, s.b2
                ),
            ),
            (
                "other meshers".to_string(),
                format!(
                    "{} critical faces and {} critical cubes, {} samples at the isovalue (where meshers may see another topology); connectivity {}: b0 {}, b1 {}, b2 {}",
                    m.critical.faces,
                    m.critical.cubes,
                    m.samples_at_iso,
                    m.other_connectivity,
                    m.b0,
                    m.b1,
                    m.b2
                ),
            ),
        ];
        let at = self
            .summary
            .iter()
            .position(|(label, _)| label == "isosurface")
            .map_or(self.summary.len(), |i| i + 1);
        self.summary.splice(at..at, lines);
        self
    }

    /// The report of a simplification: its handles removed, then kept.
    pub fn simplified(s: &Simplified, opts: &SimplifyOptions) -> HtmlReport {
        let o = &s.outcome;
        let mut summary = volume_lines(&s.info, &opts.surface);
        let betti = |g: &crate::topology::genus::GenusReport| {
            format!("b0 {}, genus {}, b2 {}", g.b0, g.b1, g.b2)
        };
        summary.push(("before".into(), betti(&s.before)));
        summary.push(("after".into(), betti(&s.after)));
        let unit = match opts.metric {
            crate::loops::Metric::Millimetres => "mm",
            crate::loops::Metric::Edges => "voxel edges",
        };
        summary.push(("tau".into(), format!("{} {unit}", opts.tau)));
        use crate::simplify::Operation;
        let removed_handles: usize = o.removed.iter().map(|r| r.handles).sum();
        summary.push((
            "handles removed".into(),
            format!(
                "{removed_handles} by {} walls ({} by collapse: a wall filling a loop round void; {} by pinch: a cut across material)",
                o.removed.len(),
                o.handles_removed_by(Operation::Collapse),
                o.handles_removed_by(Operation::Pinch)
            ),
        ));
        summary.push(("handles kept".into(), o.kept.len().to_string()));
        summary.push(("samples changed".into(), o.edits.len().to_string()));
        if let Some(c) = &o.composition {
            summary.push((
                "well-composed".into(),
                format!(
                    "{} critical configurations before, {} left; {} samples flipped",
                    c.before.total(),
                    c.left.total(),
                    c.flips.len()
                ),
            ));
        }
        summary.push((
            "time".into(),
            format!(
                "{:.2} s reading, {:.2} s simplifying",
                s.seconds_read, s.seconds_simplify
            ),
        ));
        let removed = o
            .removed
            .iter()
            .enumerate()
            .map(|(i, r)| HtmlHandle::from_removed(i, r));
        let kept = o
            .kept
            .iter()
            .enumerate()
            .map(|(i, k)| HtmlHandle::from_kept(o.removed.len() + i, k));
        let handles: Vec<HtmlHandle> = removed.chain(kept).collect();
        HtmlReport {
            kind: ReportKind::Simplify,
            title: file_name(&s.info),
            summary,
            tau: (unit == "voxel edges").then_some(opts.tau),
            // Handles, not rows: a wall may close tiny handles beside its own.
            handle_count: removed_handles + o.kept.len(),
            handles,
        }
    }
}
