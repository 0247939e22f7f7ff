//! A self-contained HTML report for choosing `tau` by looking (`analyze --html`,
//! `simplify --html`): one file that opens offline in any browser, nothing fetched.
//!
//! It holds a summary; the histogram of handle sizes and the Reeb-vs-cross scatter plot as
//! interactive SVG with a tau slider (the paper's figures 10 and 11, with the tau lines of its
//! figure 11); a sortable table of the handles; a 3D view (three.js, WebGL) of the isosurface
//! round the chosen handle with its loops, before and after for `simplify` with the wall's
//! samples marked; and an overview, every loop over a coarse mesh of the whole surface.
//!
//! ```text
//!   handles (rows) ─┬─▶ bricks::plan (which bricks)
//!   volume slices ──┼─▶ scene::Gather ─▶ meshes ─▶ blob (u16 vertices, u16/u32 indices)
//!                   │                                  │ gzip + base64
//!   summary ────────┴─▶ data (JSON) ─ gzip + base64 ───┴─▶ report.html (+ report.js, css,
//!                                                          three.js bundle, all embedded)
//! ```
//!
//! Size stays small: full-detail meshes only round the handles shown in 3D, in bricks of 16³
//! cells each meshed once (at most [`HtmlOptions::box_side`] samples across a handle,
//! [`HtmlOptions::max_box_samples`] in all, the smallest handles first: they are the ones tau
//! decides about; for `simplify`, a second mesh only for the bricks the edits changed), and a
//! coarse whole surface ([`HtmlOptions::overview_side`]); vertices quantized to 16 bits and
//! delta-coded; everything gzip-compressed. On the MNI sample (706 handles, all in 3D) a report
//! is 4.2 MB. three.js (MIT, pinned in `assets/viewer/package.json`, bundled by
//! `assets/viewer/build.sh`) is embedded compressed too (about 140 KB).

mod blob;
mod bricks;
mod content;
mod scene;

pub use content::analysis_rows;

use crate::error::Result;
use crate::jobs::{Simplified, Source};
use crate::topology::SurfaceOptions;
use crate::volume::{AtomicOutput, Compression, Samples, VolumeInfo};
use blob::Blob;
use scene::{Coarse, Gather, MeshRef};
use std::path::Path;

/// What goes into a report, and how much.
#[derive(Clone, Debug)]
pub struct HtmlOptions {
    /// Largest side (samples) of the box meshed round a handle, in bricks of 16 cells; a larger
    /// handle shows its middle. Default 48.
    pub box_side: usize,
    /// Samples of all the bricks together (each meshed once, however many handles it shows);
    /// handles beyond show on the overview only. Default 6,000,000.
    pub max_box_samples: usize,
    /// Bytes of mesh arrays (before compression, about 2 to 1) past which no more close-ups are
    /// meshed. Default 8 MB.
    pub max_mesh_bytes: usize,
    /// Triangles of the overview at most: past them it is coarsened twice as much, again if
    /// need be. Default 250,000.
    pub max_overview_triangles: usize,
    /// Largest side (samples) of the coarsened volume the overview meshes. Default 96.
    pub overview_side: usize,
    /// Loop points kept in all (the smallest handles' first); handles beyond are listed
    /// without their loops. Default 300,000.
    pub max_loop_points: usize,
}

impl Default for HtmlOptions {
    fn default() -> HtmlOptions {
        HtmlOptions {
            box_side: 48,
            max_box_samples: 6_000_000,
            max_mesh_bytes: 8_000_000,
            max_overview_triangles: 250_000,
            overview_side: 96,
            max_loop_points: 300_000,
        }
    }
}

/// Which job the report is of.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ReportKind {
    /// `analyze`: every handle with both loops.
    Analyze,
    /// `simplify`: the handles removed (with the loop closed and the wall) and kept.
    Simplify,
}

/// A handle as the report lists it.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct HtmlHandle {
    /// Its id (as in `--json`).
    pub id: usize,
    /// The surface it is on, when known.
    pub surface: Option<usize>,
    /// `reeb_cycle` or `intra_ribbon`.
    pub kind: String,
    /// The shorter loop, in voxel edges (`None`: no loop within the search limit).
    pub size: Option<usize>,
    /// The Reeb loop's length: edges, millimetres.
    pub reeb: Option<usize>,
    /// The Reeb loop's length in millimetres.
    pub reeb_mm: Option<f64>,
    /// The cross loop's length: edges.
    pub cross: Option<usize>,
    /// The cross loop's length in millimetres.
    pub cross_mm: Option<f64>,
    /// What the shorter loop goes round: `material` or `void`.
    pub encloses: Option<String>,
    /// For `simplify`: `collapse` or `pinch` (removed), or `kept`.
    pub status: Option<String>,
    /// For `simplify`: why it was kept, or how its wall was made.
    pub detail: Option<String>,
    /// Box of its loops, voxel indices: min x, y, z, max x, y, z (inclusive).
    pub bbox: [i64; 6],
    /// Loops to draw, voxel coordinates (half-integers): Reeb then cross (`analyze`); the loop
    /// closed (`simplify`).
    #[serde(skip)]
    pub loops: Vec<Vec<[f64; 3]>>,
    /// For `simplify`: the samples its wall flipped.
    #[serde(skip)]
    pub wall: Vec<[i64; 3]>,
}

/// A report's content, before the volume is read for its meshes.
#[derive(Clone, Debug)]
pub struct HtmlReport {
    /// `analyze` or `simplify`.
    pub kind: ReportKind,
    /// The heading (the volume's file name).
    pub title: String,
    /// Lines of the summary table: label, value.
    pub summary: Vec<(String, String)>,
    /// The tau used (`simplify`) or asked (`analyze --tau`), in voxel edges.
    pub tau: Option<f64>,
    /// The handle count a reader compares with (`analyze --json`'s handles).
    pub handle_count: usize,
    /// The handles listed.
    pub handles: Vec<HtmlHandle>,
}

/// What was written.
#[derive(Clone, Debug)]
pub struct HtmlWritten {
    /// Bytes of the file.
    pub bytes: u64,
    /// Handles with a 3D view of their own.
    pub scenes: usize,
    /// Triangles in all meshes.
    pub triangles: usize,
}

/// Writes the report of an analysis to `path` (atomically), reading the volume (`source`, the
/// one analysed) once more for the meshes.
pub fn write_analysis(
    path: &Path,
    report: &HtmlReport,
    source: Source,
    opts: &SurfaceOptions,
    html: &HtmlOptions,
) -> Result<HtmlWritten> {
    let mut reader = source.open()?;
    reader.rewind()?;
    let info = reader.info().clone();
    let mut slice = Samples::new(info.dtype);
    write(path, report, &info, opts, html, &mut |take| {
        for z in 0..info.nz() {
            reader.read_slice(&mut slice)?;
            take(z, &slice, None);
        }
        Ok(())
    })
}

/// Writes the report of a simplification to `path` (atomically): the meshes before and after
/// the edits, read from the input once more.
pub fn write_simplified(
    path: &Path,
    report: &HtmlReport,
    simplified: &mut Simplified,
    opts: &SurfaceOptions,
    html: &HtmlOptions,
) -> Result<HtmlWritten> {
    let info = simplified.info.clone();
    write(path, report, &info, opts, html, &mut |take| {
        simplified.for_each_slice(|z, before, after| {
            take(z, before, Some(after));
            Ok(())
        })
    })
}

/// Hands each z-slice in order (input, and edited when there is one) to the callback.
type SliceFeed<'a> =
    dyn FnMut(&mut dyn FnMut(usize, &Samples, Option<&Samples>)) -> Result<()> + 'a;

fn write(
    path: &Path,
    report: &HtmlReport,
    info: &VolumeInfo,
    opts: &SurfaceOptions,
    html: &HtmlOptions,
    feed: &mut SliceFeed,
) -> Result<HtmlWritten> {
    let after = report.kind == ReportKind::Simplify;
    let order = smallest_first(&report.handles);
    let plan = bricks::plan(&report.handles, &order, info.dims, html, after);
    let coarse = Coarse::new(info.dims, html.overview_side, after);
    let mut gather = Gather::new(info.dims, plan.crops, coarse, info.scaling);
    feed(&mut |z, before, edited| gather.add_slice(z, before, edited))?;
    let mut blob = Blob::default();
    let mut triangles = 0;
    let mut mesh = |values: &[f32], c: &scene::Crop, blob: &mut Blob| -> Result<MeshRef> {
        let offset = c.min.map(|v| v as f32);
        let open = c.open_sides(info.dims);
        let m = scene::mesh_box(values, c.dims, offset, 1.0, open, opts, blob)?;
        triangles += m.t[1];
        Ok(m)
    };
    let mut meshed = Vec::new();
    // The bricks come smallest handle first: past the budget, the larger handles lose theirs.
    for c in std::mem::take(&mut gather.crops) {
        if blob.len() > html.max_mesh_bytes {
            break;
        }
        // After the edits: only where a sample changed (null: the same as before).
        let after = match &c.after {
            // Bitwise: NaN samples are the same sample.
            Some(a) if !same_bits(a, &c.before) => Some(mesh(a, &c, &mut blob)?),
            _ => None,
        };
        let before = mesh(&c.before, &c, &mut blob)?;
        meshed.push(serde_json::json!({
            "min": c.min,
            "dims": c.dims,
            "before": before,
            "after": after,
        }));
    }
    let overview = overview_meshes(&mut gather.coarse, after, opts, html, &mut blob)?;
    triangles += overview.iter().map(|m| m.t[1]).sum::<usize>();
    let mut bricks_of = plan.bricks_of;
    for b in bricks_of.iter_mut() {
        if b.as_ref()
            .is_some_and(|b| b.iter().any(|&k| k >= meshed.len()))
        {
            *b = None;
        }
    }
    let overview = Overview {
        meshes: overview,
        factor: gather.coarse.factor,
    };
    let scenes = Scenes {
        bricks: meshed,
        of: bricks_of,
    };
    let m = &info.affine.m;
    let data = Data {
        kind: report.kind,
        title: &report.title,
        summary: &report.summary,
        tau: report.tau.filter(|t| t.is_finite()),
        handle_count: report.handle_count,
        dims: info.dims,
        affine: [m[0], m[1], m[2], [0.0, 0.0, 0.0, 1.0]],
        handles: Rows {
            report,
            scenes: &scenes,
            with_loops: with_loops(report, &order, html),
        },
        bricks: &scenes.bricks,
        overview: &overview.meshes,
        overview_factor: overview.factor,
        version: env!("CARGO_PKG_VERSION"),
        margin: bricks::MARGIN,
    };
    let mut out = AtomicOutput::create(path, Compression::None)?;
    write_page(&mut out, report, &data, &blob)?;
    out.commit()?;
    let bytes = std::fs::metadata(path).map(|m| m.len()).unwrap_or(0);
    Ok(HtmlWritten {
        bytes,
        scenes: scenes.of.iter().flatten().count(),
        triangles,
    })
}

/// The coarse whole surface, before (and after), coarsened further while it has too many
/// triangles (a volume of noise is surface everywhere).
fn overview_meshes(
    coarse: &mut Coarse,
    after: bool,
    opts: &SurfaceOptions,
    html: &HtmlOptions,
    blob: &mut Blob,
) -> Result<Vec<MeshRef>> {
    loop {
        let mut trial = Blob::default();
        let first = scene::mesh_coarse(coarse, 0, opts, &mut trial)?;
        if first.t[1] <= html.max_overview_triangles || coarse.dims.iter().all(|&d| d <= 8) {
            break;
        }
        coarse.halve();
    }
    (0..if after { 2 } else { 1 })
        .map(|w| scene::mesh_coarse(coarse, w, opts, blob))
        .collect()
}

fn same_bits(a: &[f32], b: &[f32]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
}

/// Handle indices, smallest first (no loop within the limit: last), then by id.
fn smallest_first(handles: &[HtmlHandle]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..handles.len()).collect();
    order.sort_by_key(|&i| (handles[i].size.unwrap_or(usize::MAX), handles[i].id));
    order
}

/// The bricks meshed (before, and after where it differs), and each handle's bricks.
struct Scenes {
    bricks: Vec<serde_json::Value>,
    of: Vec<Option<Vec<usize>>>,
}

/// The coarse whole surface (before, and after for `simplify`), and its coarsening factor.
struct Overview {
    meshes: Vec<MeshRef>,
    factor: usize,
}

/// The page's data: everything but the meshes' arrays (see `report.js`).
#[derive(serde::Serialize)]
struct Data<'a> {
    kind: ReportKind,
    title: &'a str,
    summary: &'a [(String, String)],
    tau: Option<f64>,
    handle_count: usize,
    dims: [usize; 3],
    affine: [[f64; 4]; 4],
    handles: Rows<'a>,
    bricks: &'a [serde_json::Value],
    overview: &'a [MeshRef],
    overview_factor: usize,
    version: &'static str,
    /// Voxels of surface a close-up shows beyond a handle's box (the page clips there).
    margin: i64,
}

/// A handle's row: its fields, its bricks, and its loops and wall (doubled voxel coordinates,
/// flat) when within the budget.
#[derive(serde::Serialize)]
struct Row<'a> {
    #[serde(flatten)]
    handle: &'a HtmlHandle,
    bricks: &'a Option<Vec<usize>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    loops: Option<Vec<Vec<i64>>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    wall: Option<Vec<i64>>,
}

/// Every handle's row, made as it is serialized (no value tree of 100,000 handles in memory).
struct Rows<'a> {
    report: &'a HtmlReport,
    scenes: &'a Scenes,
    with_loops: Vec<bool>,
}

impl serde::Serialize for Rows<'_> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        use serde::ser::SerializeSeq;
        let mut seq = s.serialize_seq(Some(self.report.handles.len()))?;
        for (i, h) in self.report.handles.iter().enumerate() {
            let drawn = self.with_loops[i];
            seq.serialize_element(&Row {
                handle: h,
                bricks: &self.scenes.of[i],
                loops: drawn.then(|| h.loops.iter().map(|l| doubled(l)).collect()),
                wall: drawn.then(|| h.wall.iter().flatten().map(|&v| 2 * v).collect()),
            })?;
        }
        seq.end()
    }
}

/// Which handles keep their loops: the smallest first, within [`HtmlOptions::max_loop_points`].
fn with_loops(report: &HtmlReport, order: &[usize], html: &HtmlOptions) -> Vec<bool> {
    let mut with = vec![false; report.handles.len()];
    let mut points = 0;
    for &i in order {
        let n: usize = report.handles[i].loops.iter().map(Vec::len).sum();
        if points + n > html.max_loop_points {
            break;
        }
        points += n;
        with[i] = true;
    }
    with
}

fn doubled(points: &[[f64; 3]]) -> Vec<i64> {
    points
        .iter()
        .flatten()
        .map(|&v| (v * 2.0).round() as i64)
        .collect()
}

const TEMPLATE: &str = include_str!("../../assets/report/report.html");
const CSS: &str = include_str!("../../assets/report/report.css");
const SCRIPT: &str = include_str!("../../assets/report/report.js");
const THREE: &str = include_str!("../../assets/viewer/three.bundle.js");
const THREE_LICENSE: &str = include_str!("../../assets/viewer/LICENSE-three.txt");

/// Writes the page: the template with its markers filled, piece by piece (the data and the
/// meshes go straight from their encoders to the file).
fn write_page(out: &mut AtomicOutput, report: &HtmlReport, data: &Data, blob: &Blob) -> Result<()> {
    let mut rest = TEMPLATE;
    while let Some(at) = rest.find("{{") {
        out.write_all(&rest.as_bytes()[..at])?;
        let end = at + rest[at..].find("}}").unwrap_or(0) + 2;
        match &rest[at..end] {
            "{{CSS}}" => out.write_all(CSS.as_bytes())?,
            "{{SCRIPT}}" => out.write_all(SCRIPT.as_bytes())?,
            "{{TITLE}}" => out.write_all(escape(&report.title).as_bytes())?,
            "{{THREE_LICENSE}}" => out.write_all(escape(THREE_LICENSE).as_bytes())?,
            "{{THREE}}" => out.write_all(blob::gzip_base64(THREE.as_bytes()).as_bytes())?,
            "{{DATA}}" => {
                let text = blob::gzip_base64_with(|w| {
                    serde_json::to_writer(w, data).map_err(std::io::Error::other)
                })
                .map_err(|e| crate::error::Error::Internal(format!("report data: {e}")))?;
                out.write_all(text.as_bytes())?
            }
            "{{BIN}}" => out.write_all(blob.to_base64_gzip().as_bytes())?,
            other => out.write_all(other.as_bytes())?,
        }
        rest = &rest[end..];
    }
    out.write_all(rest.as_bytes())
}

/// `text` safe in HTML text and attribute values.
fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_embedded_scripts_cannot_end_their_script_element() {
        for (name, text) in [("report.js", SCRIPT), ("report.css", CSS)] {
            assert!(!text.to_lowercase().contains("</script"), "{name}");
            assert!(!text.contains("{{"), "{name} has a template marker");
        }
    }
}
