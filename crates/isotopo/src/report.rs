//! JSON shapes of the reports, kept in one place so the keys stay stable.

use crate::error::{Error, Result};
use crate::grid::Axis;
use crate::loops::{HandleLoops, Loop};
use crate::sweep::{CycleVolume, Handle, HandleReport, NodeKind};
use crate::volume::{Affine, AtomicOutput, Compression, VolumeInfo};
use serde_json::{json, Value};
use std::io::Write;
use std::path::Path;

/// A loop as JSON: `length` (voxel edges), `length_mm`, `encloses` (`material` or `void`) and
/// `points` (the closed polyline through edge midpoints, voxel coordinates).
pub fn loop_json(l: &Loop) -> Value {
    let round = |x: f64| (x * 1000.0).round() / 1000.0;
    json!({
        "length": l.length,
        "length_mm": round(l.length_mm),
        "encloses": l.encloses,
        "points": l.points.iter().map(|p| [p[0], p[1], p[2]]).collect::<Vec<_>>(),
    })
}

/// Handles as JSON, with their loops when measured: each is [`measured_handle_json`].
pub fn analysis_json(
    report: &HandleReport,
    info: &VolumeInfo,
    loops: &[HandleLoops],
    loops_mm: Option<&[HandleLoops]>,
) -> Vec<Value> {
    report
        .handles
        .iter()
        .zip(loops)
        .enumerate()
        .map(|(i, (h, l))| {
            let mm = loops_mm.and_then(|m| m.get(i));
            measured_handle_json(h, report.axis, info, l, mm)
        })
        .collect()
}

/// A handle as JSON ([`handle_json`]) with its loops: `reeb_loop`, `cross_loop` (shortest in
/// voxel edges; null when longer than the search limit), `size` (the shorter length; null when
/// both were beyond the limit), `exact` (every search ended within its budget), `cut` (a
/// Reeb-cycle handle's cut: its Reeb loop is the shortest loop crossing it once) and, when
/// measured in millimetres too (`mm`), `reeb_loop_mm` and `cross_loop_mm` (shortest in mm) with
/// `size_mm` their shorter length (else `size_mm` is the length in mm of the shorter loop in
/// edges).
pub fn measured_handle_json(
    h: &Handle,
    axis: Axis,
    info: &VolumeInfo,
    l: &HandleLoops,
    mm: Option<&HandleLoops>,
) -> Value {
    let round = |x: f64| Value::from((x * 1000.0).round() / 1000.0);
    let mut v = handle_json(h, axis, info);
    // Where the handle is: the box of its loops (the cycle's ribbons can span a whole slice).
    if let Some(b) = l.bbox() {
        v["cycle_bbox"] = v["bbox"].clone();
        v["bbox"] = json!(b);
        v["bbox_mm"] = json!(b.to_mm(&info.affine));
    }
    v["reeb_loop"] = l.reeb.as_ref().map(loop_json).unwrap_or(Value::Null);
    v["cross_loop"] = l.cross.as_ref().map(loop_json).unwrap_or(Value::Null);
    v["size"] = l.size().map(Value::from).unwrap_or(Value::Null);
    v["size_mm"] = l
        .smallest()
        .map(|s| round(s.length_mm))
        .unwrap_or(Value::Null);
    v["exact"] = l.exact.into();
    if let Some(c) = &l.cut_points {
        v["cut"] = json!(c);
    }
    if let Some(m) = mm {
        v["reeb_loop_mm"] = m.reeb.as_ref().map(loop_json).unwrap_or(Value::Null);
        v["cross_loop_mm"] = m.cross.as_ref().map(loop_json).unwrap_or(Value::Null);
        v["size_mm"] = m
            .size_in(crate::loops::Metric::Millimetres)
            .map(round)
            .unwrap_or(Value::Null);
        v["exact"] = (l.exact && m.exact).into();
    }
    v
}

/// The same as CSV: one row per handle.
pub fn analysis_csv(
    report: &HandleReport,
    info: &VolumeInfo,
    loops: &[HandleLoops],
    loops_mm: Option<&[HandleLoops]>,
) -> String {
    let mut s = String::from(CSV_HEADER);
    for r in analysis_json(report, info, loops, loops_mm) {
        s.push_str(&csv_row(&r));
    }
    s
}

/// The first line of the `analyze --csv` table.
pub const CSV_HEADER: &str = "id,surface,kind,slice_min,slice_max,x_min,x_max,y_min,y_max,z_min,z_max,reeb_length,reeb_length_mm,reeb_encloses,cross_length,cross_length_mm,cross_encloses,size,size_mm,reeb_mm_length_mm,cross_mm_length_mm,exact\n";

/// One row of the `analyze --csv` table (with its newline), from the handle's JSON
/// ([`measured_handle_json`]).
pub fn csv_row(r: &Value) -> String {
    let f = |v: &Value| match v {
        Value::Null => String::new(),
        Value::String(x) => x.clone(),
        other => other.to_string(),
    };
    let b = &r["bbox"];
    let lp = |name: &str, field: &str| f(&r[name][field]);
    let cells = [
        r["id"].to_string(),
        r["surface"].to_string(),
        f(&r["kind"]),
        r["slices"][0].to_string(),
        r["slices"][1].to_string(),
        b["min"][0].to_string(),
        b["max"][0].to_string(),
        b["min"][1].to_string(),
        b["max"][1].to_string(),
        b["min"][2].to_string(),
        b["max"][2].to_string(),
        lp("reeb_loop", "length"),
        lp("reeb_loop", "length_mm"),
        lp("reeb_loop", "encloses"),
        lp("cross_loop", "length"),
        lp("cross_loop", "length_mm"),
        lp("cross_loop", "encloses"),
        f(&r["size"]),
        f(&r["size_mm"]),
        lp("reeb_loop_mm", "length_mm"),
        lp("cross_loop_mm", "length_mm"),
        f(&r["exact"]),
    ];
    let mut row = cells.join(",");
    row.push('\n');
    row
}

/// Writes the loops as closed polylines in world millimetres (the mesh's frame): `.obj` (`l`
/// elements, vertex colours) or `.ply` (vertices with colours, edges). Reeb loops are blue,
/// cross loops red.
pub fn write_loops(path: &Path, loops: &[HandleLoops], affine: &Affine) -> Result<()> {
    let mut w = LoopsWriter::create(path)?;
    for (i, l) in loops.iter().enumerate() {
        let pts = |x: &Loop| -> Vec<[f64; 3]> { x.points.clone() };
        w.add(
            i,
            l.reeb.as_ref().map(pts),
            l.cross.as_ref().map(pts),
            affine,
        )?;
    }
    w.commit()
}

/// [`write_loops`] a handle at a time: `.obj` goes straight to the file; `.ply`, whose header
/// counts the vertices, keeps them in a scratch file until the end, and in memory only each
/// polyline's length.
pub struct LoopsWriter {
    out: AtomicOutput,
    ply: Option<PlyParts>,
    /// OBJ: number of the next vertex (from 1).
    base: usize,
}

struct PlyParts {
    vertices: std::io::BufWriter<std::fs::File>,
    lengths: Vec<u32>,
}

const LOOPS_COMMENT: &str =
    "isotopo handle loops, world coordinates in mm (RAS); Reeb loops blue, cross loops red";
const REEB_COLOUR: [u8; 3] = [40, 90, 255];
const CROSS_COLOUR: [u8; 3] = [255, 50, 40];

fn loops_scratch(e: std::io::Error) -> Error {
    Error::scratch("use", "the loops", e, crate::spool::TMPDIR_ADVICE)
}

impl LoopsWriter {
    /// Starts `path` (`.obj` or `.ply`; written atomically at [`LoopsWriter::commit`]).
    pub fn create(path: &Path) -> Result<LoopsWriter> {
        let ext = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
            .unwrap_or_default();
        let ply = match ext.as_str() {
            "obj" => None,
            "ply" => Some(PlyParts {
                vertices: std::io::BufWriter::new(tempfile::tempfile().map_err(loops_scratch)?),
                lengths: Vec::new(),
            }),
            _ => {
                return Err(Error::usage(format!(
                    "{}: write loops as .obj or .ply",
                    path.display()
                )))
            }
        };
        let mut out = AtomicOutput::create(path, Compression::None)?;
        if ply.is_none() {
            out.write_all(format!("# {LOOPS_COMMENT}\n").as_bytes())?;
        }
        Ok(LoopsWriter { out, ply, base: 1 })
    }

    /// Handle `id`'s loops (voxel coordinates), mapped to world millimetres by `affine`.
    pub fn add(
        &mut self,
        id: usize,
        reeb: Option<Vec<[f64; 3]>>,
        cross: Option<Vec<[f64; 3]>>,
        affine: &Affine,
    ) -> Result<()> {
        let lines = [("reeb", REEB_COLOUR, reeb), ("cross", CROSS_COLOUR, cross)];
        for (name, c, pts) in lines {
            let Some(pts) = pts else { continue };
            let world: Vec<[f64; 3]> = pts.iter().map(|p| affine.apply(*p)).collect();
            match &mut self.ply {
                Some(ply) => {
                    let mut b = Vec::with_capacity(world.len() * 15);
                    for p in &world {
                        for x in p {
                            b.extend_from_slice(&(*x as f32).to_le_bytes());
                        }
                        b.extend_from_slice(&c);
                    }
                    ply.vertices.write_all(&b).map_err(loops_scratch)?;
                    ply.lengths.push(world.len() as u32);
                }
                None => self.obj_polyline(&format!("handle_{id}_{name}_loop"), c, &world)?,
            }
        }
        Ok(())
    }

    fn obj_polyline(&mut self, name: &str, c: [u8; 3], pts: &[[f64; 3]]) -> Result<()> {
        let mut s = format!("o {name}\n");
        for p in pts {
            s.push_str(&format!(
                "v {} {} {} {:.3} {:.3} {:.3}\n",
                p[0],
                p[1],
                p[2],
                c[0] as f64 / 255.0,
                c[1] as f64 / 255.0,
                c[2] as f64 / 255.0
            ));
        }
        s.push('l');
        for k in 0..pts.len() {
            s.push_str(&format!(" {}", self.base + k));
        }
        s.push_str(&format!(" {}\n", self.base));
        self.base += pts.len();
        self.out.write_all(s.as_bytes())
    }

    /// Writes what is left (a PLY's header, vertices and edges) and puts the file in place.
    pub fn commit(mut self) -> Result<()> {
        if let Some(ply) = self.ply.take() {
            let nv: u64 = ply.lengths.iter().map(|&n| n as u64).sum();
            let header = format!(
                "ply\nformat binary_little_endian 1.0\ncomment {LOOPS_COMMENT}\nelement vertex {nv}\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nelement edge {nv}\nproperty int vertex1\nproperty int vertex2\nend_header\n"
            );
            self.out.write_all(header.as_bytes())?;
            let mut file = ply
                .vertices
                .into_inner()
                .map_err(|e| loops_scratch(e.into_error()))?;
            use std::io::{ErrorKind, Read, Seek};
            file.rewind().map_err(loops_scratch)?;
            let mut buf = vec![0u8; 1 << 20];
            loop {
                match file.read(&mut buf) {
                    Ok(0) => break,
                    Ok(n) => self.out.write_all(&buf[..n])?,
                    Err(e) if e.kind() == ErrorKind::Interrupted => continue,
                    Err(e) => return Err(loops_scratch(e)),
                }
            }
            let mut base = 0i32;
            let mut edges = Vec::with_capacity(1 << 16);
            for n in ply.lengths {
                let n = n as i32;
                for k in 0..n {
                    edges.extend_from_slice(&(base + k).to_le_bytes());
                    edges.extend_from_slice(&(base + (k + 1) % n).to_le_bytes());
                }
                base += n;
                if edges.len() >= 1 << 16 {
                    self.out.write_all(&edges)?;
                    edges.clear();
                }
            }
            self.out.write_all(&edges)?;
        }
        self.out.commit()
    }
}

/// One JSON object per handle ([`handle_json`]).
pub fn handles_json(report: &HandleReport, info: &VolumeInfo) -> Vec<Value> {
    let axis = report.axis;
    let each = |h| handle_json(h, axis, info);
    report.handles.iter().map(each).collect()
}

/// A handle as JSON: `id`, `kind`, `surface`, `slices` (range along the sweep axis), `bbox`
/// (voxels) and `bbox_mm`, and `cycle` (its ribbons and contours).
pub fn handle_json(h: &Handle, axis: Axis, info: &VolumeInfo) -> Value {
    let w_axis = axis.uvw()[2];
    let l = &h.located;
    let frame = match &l.volume {
        CycleVolume::Top => crate::grid::Frame::for_axis(axis),
        CycleVolume::Mini(v) => v.frame,
    };
    // Levels are along the cycle volume's own sweep axis, reported in original indices.
    let cycle_axis = frame.uvw[2];
    let cycle: Vec<Value> = l
        .cycle
        .iter()
        .map(|n| {
            let level = frame.offset[cycle_axis] + n.level as i64;
            let axis_name = ["x", "y", "z"][cycle_axis];
            match n.kind {
                NodeKind::Ribbon => {
                    json!({"type": "ribbon", "axis": axis_name, "slice": level, "index": n.local})
                }
                NodeKind::Contour => {
                    json!({"type": "contour", "axis": axis_name, "plane": level, "index": n.local})
                }
            }
        })
        .collect();
    let mm = l.bbox.to_mm(&info.affine);
    json!({
        "id": h.id,
        "kind": l.kind,
        "surface": h.surface,
        "slices": [l.bbox.min[w_axis], l.bbox.max[w_axis]],
        "bbox": l.bbox,
        "bbox_mm": mm,
        "cycle": cycle,
        "found_directly": l.direct,
    })
}

/// Writes a JSON value to a file, atomically.
pub fn write_json(path: &Path, value: &serde_json::Value) -> Result<()> {
    let text =
        serde_json::to_string_pretty(value).map_err(|e| Error::Internal(format!("JSON: {e}")))?;
    let mut out = AtomicOutput::create(path, Compression::None)?;
    out.write_all(text.as_bytes())?;
    out.write_all(b"\n")?;
    out.commit()
}

/// The simplification report: Table-1 counts, then each removed and kept handle.
pub fn simplify_json(
    outcome: &crate::simplify::Outcome,
    before: &crate::topology::genus::GenusReport,
    after: &crate::topology::genus::GenusReport,
    info: &VolumeInfo,
) -> serde_json::Value {
    use crate::simplify::Operation;
    let removed: Vec<serde_json::Value> = outcome
        .removed
        .iter()
        .enumerate()
        .map(|(i, r)| {
            let mut v = serde_json::to_value(r).unwrap_or_default();
            v["id"] = i.into();
            v["bbox_mm"] = serde_json::json!(r.bbox.to_mm(&info.affine));
            v
        })
        .collect();
    let (max_distance, max_distance_mm) = outcome.max_distance();
    let (samples_filled, samples_cut) = outcome.samples_filled_cut();
    serde_json::json!({
        "genus_before": before.b1,
        "genus_after": after.b1,
        "b0_before": before.b0,
        "b0_after": after.b0,
        "b2_before": before.b2,
        "b2_after": after.b2,
        "surfaces_before": before.surfaces.len(),
        "surfaces_after": after.surfaces.len(),
        "intra_ribbon": outcome.intra_ribbon,
        "collapse": outcome.handles_removed_by(Operation::Collapse),
        "pinch": outcome.handles_removed_by(Operation::Pinch),
        "samples_changed": outcome.edits.len(),
        "samples_filled": samples_filled,
        "samples_cut": samples_cut,
        "max_distance": max_distance,
        "max_distance_mm": max_distance_mm,
        "passes": outcome.passes,
        "certified": outcome.certified,
        "rewinds": outcome.rewinds,
        "closures_refused": outcome.refused,
        "closures_refused_by": outcome.refused_by,
        "seconds_stages": outcome.seconds,
        "removed": removed,
        "kept": outcome.kept,
        "parts": parts_json(&outcome.parts, info),
    })
}

/// The components and cavities removed (and those the mode kept), with counts per operation.
fn parts_json(parts: &crate::simplify::Parts, info: &VolumeInfo) -> serde_json::Value {
    use crate::simplify::{PartKind, PartOperation};
    let with_mm = |v: serde_json::Value, bbox: &crate::volume::BBox| {
        let mut v = v;
        v["bbox_mm"] = serde_json::json!(bbox.to_mm(&info.affine));
        v
    };
    let removed: Vec<serde_json::Value> = parts
        .removed
        .iter()
        .map(|r| with_mm(serde_json::to_value(r).unwrap_or_default(), &r.bbox))
        .collect();
    let kept: Vec<serde_json::Value> = parts
        .kept
        .iter()
        .map(|k| with_mm(serde_json::to_value(k).unwrap_or_default(), &k.bbox))
        .collect();
    serde_json::json!({
        "components_deleted": parts.count(PartOperation::Delete),
        "components_bridged": parts.count(PartOperation::Bridge),
        "cavities_filled": parts.count(PartOperation::Fill),
        "cavities_opened": parts.count(PartOperation::Open),
        "samples_changed_components": parts.samples_changed(PartKind::Component),
        "samples_changed_cavities": parts.samples_changed(PartKind::Cavity),
        "refused": parts.refused,
        "b0_b2_after": parts.after,
        "removed": removed,
        "kept": kept,
    })
}
