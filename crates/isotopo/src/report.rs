//! JSON shapes of the reports, kept in one place so the keys stay stable.

use crate::sweep::{CycleVolume, HandleReport, NodeKind};
use crate::volume::VolumeInfo;
use serde_json::{json, Value};

/// One JSON object per handle: `id`, `kind`, `surface`, `slices` (range along the sweep axis),
/// `bbox` (voxels) and `bbox_mm`, and `cycle` (its ribbons and contours).
pub fn handles_json(report: &HandleReport, info: &VolumeInfo) -> Vec<Value> {
    let axis = report.axis;
    let w_axis = axis.uvw()[2];
    report
        .handles
        .iter()
        .map(|h| {
            let l = &h.located;
            let frame = match &l.volume {
                CycleVolume::Top => crate::sweep::Frame::for_axis(axis),
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
                        NodeKind::Ribbon => json!({"type": "ribbon", "axis": axis_name, "slice": level, "index": n.local}),
                        NodeKind::Contour => json!({"type": "contour", "axis": axis_name, "plane": level, "index": n.local}),
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
        })
        .collect()
}
