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
//! is 4.4 MB. three.js (MIT, pinned in `assets/viewer/package.json`, bundled by
//! `assets/viewer/build.sh`) is embedded compressed too (about 140 KB).

mod blob;
mod bricks;
mod content;
mod scene;

use crate::error::Result;
use crate::jobs::Simplified;
use crate::topology::SurfaceOptions;
use crate::volume::{AtomicOutput, Compression, Samples, SliceReader, VolumeInfo};
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
    /// Bytes of mesh arrays (before compression, about 4 to 1) past which no more close-ups are
    /// meshed. Default 24 MB.
    pub max_mesh_bytes: usize,
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
            max_mesh_bytes: 24_000_000,
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

/// Writes the report of an analysis to `path` (atomically), reading the volume once more
/// (`reader` from slice 0) for the meshes.
pub fn write_analysis(
    path: &Path,
    report: &HtmlReport,
    reader: &mut dyn SliceReader,
    opts: &SurfaceOptions,
    html: &HtmlOptions,
) -> Result<HtmlWritten> {
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
    let mut mesh = |values, dims, offset, blob: &mut Blob| -> Result<MeshRef> {
        let m = scene::mesh_box(values, dims, offset, 1.0, opts, blob)?;
        triangles += m.t[1];
        Ok(m)
    };
    let mut meshed = Vec::new();
    // The bricks come smallest handle first: past the budget, the larger handles lose theirs.
    for c in std::mem::take(&mut gather.crops) {
        if blob.len() > html.max_mesh_bytes {
            break;
        }
        let offset = c.min.map(|v| v as f32);
        // After the edits: only where a sample changed (null: the same as before).
        let after = match c.after {
            Some(a) if a != c.before => Some(mesh(a, c.dims, offset, &mut blob)?),
            _ => None,
        };
        let before = mesh(c.before, c.dims, offset, &mut blob)?;
        meshed.push(serde_json::json!({ "before": before, "after": after }));
    }
    let overview = [0, 1]
        .iter()
        .take(if after { 2 } else { 1 })
        .map(|&w| scene::mesh_coarse(&gather.coarse, w, opts, &mut blob))
        .collect::<Result<Vec<_>>>()?;
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
    let data = data_json(report, info, &order, &scenes, overview, html);
    let text = fill_template(report, &data, &blob);
    let mut out = AtomicOutput::create(path, Compression::None)?;
    out.write_all(text.as_bytes())?;
    out.commit()?;
    Ok(HtmlWritten {
        bytes: text.len() as u64,
        scenes: scenes.of.iter().flatten().count(),
        triangles,
    })
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

/// The page's data: everything but the meshes' arrays.
fn data_json(
    report: &HtmlReport,
    info: &VolumeInfo,
    order: &[usize],
    scenes: &Scenes,
    overview: Overview,
    html: &HtmlOptions,
) -> serde_json::Value {
    // Loops for the smallest handles first, within the budget; as doubled integers (the points
    // are on half-integers), flat.
    let mut with_loops = vec![false; report.handles.len()];
    let mut points = 0;
    for &i in order {
        let n: usize = report.handles[i].loops.iter().map(Vec::len).sum();
        if points + n > html.max_loop_points {
            break;
        }
        points += n;
        with_loops[i] = true;
    }
    let handles: Vec<serde_json::Value> = report
        .handles
        .iter()
        .enumerate()
        .map(|(i, h)| {
            let mut v = serde_json::to_value(h).unwrap_or_default();
            v["bricks"] = serde_json::json!(scenes.of[i]);
            if with_loops[i] {
                v["loops"] =
                    serde_json::json!(h.loops.iter().map(|l| doubled(l)).collect::<Vec<_>>());
                v["wall"] = serde_json::json!(h.wall.iter().flatten().collect::<Vec<_>>());
            }
            v
        })
        .collect();
    let m = &info.affine.m;
    serde_json::json!({
        "kind": report.kind,
        "title": report.title,
        "summary": report.summary,
        "tau": report.tau.filter(|t| t.is_finite()),
        "handle_count": report.handle_count,
        "dims": info.dims,
        "affine": [m[0], m[1], m[2], [0.0, 0.0, 0.0, 1.0]],
        "handles": handles,
        "bricks": scenes.bricks,
        "overview": overview.meshes,
        "overview_factor": overview.factor,
        "version": env!("CARGO_PKG_VERSION"),
    })
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

fn fill_template(report: &HtmlReport, data: &serde_json::Value, blob: &Blob) -> String {
    let data = blob::gzip_base64(data.to_string().as_bytes());
    let three = blob::gzip_base64(THREE.as_bytes());
    // The title last: a file name may hold anything, markers included.
    TEMPLATE
        .replace("{{CSS}}", CSS)
        .replace("{{THREE_LICENSE}}", &escape(THREE_LICENSE))
        .replace("{{THREE}}", &three)
        .replace("{{DATA}}", &data)
        .replace("{{BIN}}", &blob.to_base64_gzip())
        .replace("{{SCRIPT}}", SCRIPT)
        .replace("{{TITLE}}", &escape(&report.title))
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
