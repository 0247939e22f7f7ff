//! Which of a handle's loops to close, and the boxes used to tell whether a wall came near.

use super::{KeepReason, LoopKind, SimplifyOptions};
use crate::closure::Operation;
use crate::loops::{Encloses, HandleLoops, Loop};
use crate::volume::BBox;

/// The loops worth closing, best first, or why none is.
pub(super) fn plan<'l>(
    l: &'l HandleLoops,
    opts: &SimplifyOptions,
) -> std::result::Result<Vec<(LoopKind, &'l Loop)>, KeepReason> {
    let Some(reeb) = &l.reeb else {
        return Err(KeepReason::Unmeasured);
    };
    let small: Vec<(LoopKind, &Loop)> = [
        (LoopKind::Reeb, Some(reeb)),
        (LoopKind::Cross, l.cross.as_ref()),
    ]
    .into_iter()
    .filter_map(|(k, x)| x.map(|x| (k, x)))
    .filter(|(_, x)| x.length_in(opts.metric) < opts.tau)
    .collect();
    if small.is_empty() {
        return Err(KeepReason::Size);
    }
    if let Some(r) = opts.max_ratio {
        // A missing cross loop is longer than tau · ratio (the search limit), so the ratio is
        // above r whenever the Reeb loop is below tau.
        let ratio = match &l.cross {
            Some(c) => {
                let (a, b) = (reeb.length_in(opts.metric), c.length_in(opts.metric));
                a.max(b) / a.min(b).max(1e-9)
            }
            None => f64::INFINITY,
        };
        if ratio > r {
            return Err(KeepReason::Ratio);
        }
    }
    let mut allowed: Vec<(LoopKind, &Loop)> = small
        .into_iter()
        .filter(|(_, x)| opts.mode.allows(operation_for(x)))
        .collect();
    if allowed.is_empty() {
        return Err(KeepReason::Mode);
    }
    allowed.sort_by(|a, b| {
        a.1.length_in(opts.metric)
            .total_cmp(&b.1.length_in(opts.metric))
    });
    Ok(allowed)
}

/// Closing a loop around void fills; closing one around material cuts.
pub(super) fn operation_for(l: &Loop) -> Operation {
    match l.encloses {
        Encloses::Void => Operation::Collapse,
        Encloses::Material => Operation::Pinch,
    }
}

/// Local box of a loop's vertices.
pub(super) fn loop_box(l: &Loop) -> BBox {
    let mut b = BBox::EMPTY;
    for v in &l.vertices {
        b.include(v.p);
        b.include(v.end());
    }
    b
}

/// Does the wall (a local box) come within `margin` of one of the loop's vertices? (A long
/// loop's box holds much that is far from the loop.)
pub(super) fn wall_near_loop(wall: &BBox, l: &Loop, margin: i64) -> bool {
    overlaps(wall, &loop_box(l), margin)
        && l.vertices.iter().any(|v| {
            let e = BBox {
                min: v.p,
                max: v.end(),
            };
            overlaps(wall, &e, margin)
        })
}

pub(super) fn overlaps(a: &BBox, b: &BBox, margin: i64) -> bool {
    (0..3).all(|k| a.min[k] - margin <= b.max[k] && b.min[k] <= a.max[k] + margin)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::surface::Vertex;

    /// A wall counts as near a loop when it comes within the margin of one of the loop's
    /// edges, not of the loop's box: an L-shaped loop's box holds a corner far from it.
    ///
    /// ```text
    ///   y 9  W W . . . . . . . . |      W: the wall in the far corner (7 from the loop)
    ///        . . . . . . . . . . |      |: edges along y at x = 10
    ///   y 0  - - - - - - - - - -        -: edges along x at y = 0
    /// ```
    #[test]
    fn a_wall_is_near_a_loop_only_beside_one_of_its_edges() {
        let along_x = (0..10).map(|x| Vertex {
            p: [x, 0, 0],
            axis: 0,
        });
        let along_y = (0..10).map(|y| Vertex {
            p: [10, y, 0],
            axis: 1,
        });
        let l = Loop {
            vertices: along_x.chain(along_y).collect(),
            points: Vec::new(),
            length: 20,
            length_mm: 20.0,
            encloses: Encloses::Material,
        };
        let wall = |min: [i64; 3], max: [i64; 3]| BBox { min, max };
        assert!(!wall_near_loop(&wall([0, 8, 0], [1, 9, 0]), &l, 2));
        assert!(wall_near_loop(&wall([0, 2, 0], [1, 3, 0]), &l, 2));
        assert!(!wall_near_loop(&wall([0, 3, 0], [1, 4, 0]), &l, 2));
        assert!(wall_near_loop(&wall([8, 8, 2], [8, 9, 2]), &l, 2));
        assert!(!wall_near_loop(&wall([8, 8, 3], [8, 9, 3]), &l, 2));
        assert!(!wall_near_loop(&wall([30, 30, 0], [31, 31, 0]), &l, 2));
    }
}
