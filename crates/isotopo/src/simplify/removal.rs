//! The report of a handle removed.

use super::walls::Closed;
use super::Removed;
use crate::grid::MaskVolume;
use crate::loops::{HandleLoops, Metric};
use crate::sweep::LocatedHandle;
use crate::volume::Affine;

/// Farthest of `samples` (original coordinates) from the polyline's points: voxels and mm.
pub(super) fn max_distance(
    samples: &[[i64; 3]],
    points: &[[f64; 3]],
    affine: &Affine,
) -> (f64, f64) {
    let mut worst = (0.0f64, 0.0f64);
    for q in samples {
        let q = [q[0] as f64, q[1] as f64, q[2] as f64];
        let mut best = (f64::INFINITY, f64::INFINITY);
        for p in points {
            let d = [q[0] - p[0], q[1] - p[1], q[2] - p[2]];
            let vox = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            let m = affine.apply_vector(d);
            let mm = (m[0] * m[0] + m[1] * m[1] + m[2] * m[2]).sqrt();
            best = (best.0.min(vox), best.1.min(mm));
        }
        worst = (worst.0.max(best.0), worst.1.max(best.1));
    }
    worst
}

/// The report of a handle removed by `closure` at `(pass, slice)`, in original coordinates.
pub(super) fn removal(
    vol: &MaskVolume,
    h: &LocatedHandle,
    l: &HandleLoops,
    closure: &Closed,
    affine: &Affine,
    (pass, slice): (usize, i64),
) -> Removed {
    let Closed {
        which,
        lp,
        partner,
        applied,
        wall,
    } = closure;
    let changed: Vec<[i64; 3]> = applied
        .changed
        .iter()
        .map(|q| vol.frame.to_original_i(*q))
        .collect();
    let (dist, dist_mm) = max_distance(&changed, &lp.points, affine);
    Removed {
        size: l.size().unwrap_or(lp.length),
        size_mm: l.size_in(Metric::Millimetres).unwrap_or(lp.length_mm),
        reeb: l.reeb.as_ref().map(|x| x.length),
        cross: l.cross.as_ref().map(|x| x.length),
        kind: h.kind,
        closed: *which,
        operation: applied.op,
        length: lp.length,
        length_mm: lp.length_mm,
        partner: *partner,
        thickness: wall.thickness(),
        wall: wall.name(),
        samples_changed: changed.len(),
        samples: changed,
        handles: applied.handles,
        max_distance: dist,
        max_distance_mm: dist_mm,
        points: lp.points.clone(),
        bbox: l.bbox().unwrap_or(h.bbox),
        pass,
        slice,
    }
}
