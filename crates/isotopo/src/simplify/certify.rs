//! The certificate that no loop below tau is left: closed curves per kept handle, and the rank
//! of their crossing matrix.

use super::measure::Caches;
use super::{KeepReason, Kept};
use crate::grid::MaskVolume;
use crate::loops::{self, HandleLoops, Limits};
use crate::progress::Progress;
use crate::surface::geometry::Geometry;
use crate::surface::search::{FastMap, Graph};
use crate::surface::Vertex;
use crate::sweep::LocatedHandle;
use crate::topology::cases::{cases, Connectivity};
use crate::volume::Affine;

/// What [`certify`] found for a handle with no loop below tau.
pub(super) enum Certificate {
    /// Closed curves that no loop below tau crosses an odd number of times.
    Curves(Vec<Vec<Vertex>>),
    /// Its ribbon's curves came with another handle of the same step.
    Shared,
    /// A loop below tau after all: the handle's loops to close (the loop, and the curve it
    /// crosses once as its partner).
    Below(HandleLoops),
    /// A search ran out of its budget: nothing is proven.
    Unsure,
}

/// The curves that prove a handle has no loop below tau, or a loop below tau found on the way.
///
/// - A Reeb-cycle handle: its cut and the loop round its cycle, from its measurement (no loop
///   below tau crosses the cut, nor that loop, an odd number of times).
/// - An intra-ribbon handle: its ribbon's homology generators (2 × the ribbon's genus closed
///   curves on the surface, shared by the ribbon's handles), each searched for a loop below tau
///   crossing it an odd number of times.
#[allow(clippy::too_many_arguments)]
pub(super) fn certify(
    vol: &MaskVolume,
    h: &LocatedHandle,
    l: &HandleLoops,
    conn: Connectivity,
    limits: Limits,
    affine: &Affine,
    caches: &mut Caches,
    ribbons: &mut FastMap<(i64, u32), ()>,
) -> Certificate {
    let Some((slice, ribbon)) = h.ribbon else {
        return match (&l.basis, l.exact) {
            (Some((p, q)), true) => Certificate::Curves(vec![p.clone(), q.clone()]),
            _ => Certificate::Unsure,
        };
    };
    if ribbons.insert((slice, ribbon), ()).is_some() {
        return Certificate::Shared;
    }
    let mut g = Graph::with_cache(vol, cases(conn), std::mem::take(&mut caches.graph));
    let out = (|| {
        let Some(generators) = loops::ribbon_generators(&mut g, &mut caches.slices, slice, ribbon)
        else {
            return Certificate::Unsure;
        };
        let searcher = loops::Searcher {
            metric: limits.metric,
            geometry: Geometry {
                affine,
                fractions: vol.fractions.as_ref(),
            },
        };
        for b in &generators {
            let found = searcher.odd_loop(&mut g, b, limits.below);
            match found.found {
                Some(short) => {
                    let describe = |x: &[Vertex], p: &[Vertex]| {
                        loops::describe(vol, x, Some(p), &searcher.geometry)
                    };
                    return Certificate::Below(HandleLoops {
                        reeb: Some(describe(&short, b)),
                        cross: Some(describe(b, &short)),
                        exact: true,
                        basis: None,
                        cut_points: None,
                    });
                }
                None if !found.exact => return Certificate::Unsure,
                None => {}
            }
        }
        Certificate::Curves(generators)
    })();
    caches.graph = g.into_cache();
    out
}

/// The certificate of the last pass: every handle kept for its size, and the crossing matrix of
/// their curves of full rank (2 × kept), so no loop below tau is left.
pub(super) fn certificate_holds(
    vol: &MaskVolume,
    conn: Connectivity,
    kept: &[(i64, Kept)],
    basis: &[(i64, Vec<Vec<Vertex>>)],
    progress: &dyn Progress,
) -> bool {
    if kept.iter().any(|(_, k)| k.reason != KeepReason::Size) {
        return false;
    }
    let curves: Vec<Vec<Vertex>> = basis.iter().flat_map(|(_, c)| c.clone()).collect();
    let mut g = Graph::new(vol, cases(conn));
    let rank = loops::basis::crossing_rank(&mut g, &curves);
    progress.trace(format_args!(
        "certificate: {} curves, rank {rank:?}, {} kept",
        curves.len(),
        kept.len()
    ));
    rank == Some(2 * kept.len())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::progress::NoProgress;
    use crate::simplify::Kept;
    use crate::volume::{BBox, InMemoryVolume};

    fn kept(reason: KeepReason) -> Vec<(i64, Kept)> {
        let k = Kept {
            size: Some(30),
            size_mm: Some(30.0),
            reeb: Some(30),
            cross: Some(60),
            kind: crate::sweep::HandleKind::ReebCycle,
            reason,
            bbox: BBox::EMPTY,
        };
        vec![(0, k)]
    }

    /// A torus's cut and Reeb loop cross once: they certify its one handle. The same curve
    /// twice spans nothing, and a handle kept for another reason than its size is no proof.
    #[test]
    fn the_certificate_needs_curves_that_span_every_loop() {
        let torus = InMemoryVolume::from_fn([30, 30, 12], |x, y, z| {
            let (x, y, z) = (x as f32 - 14.5, y as f32 - 14.5, z as f32 - 5.5);
            3.5 - ((x * x + y * y).sqrt() - 9.0).hypot(z)
        });
        let opts = crate::AnalyzeOptions::default();
        let a = crate::analyze(crate::Source::from(torus), &opts, &NoProgress).unwrap();
        assert_eq!(a.loops.len(), 1);
        let (p, q) = a.loops[0]
            .basis
            .clone()
            .expect("a measured handle has its curves");
        let conn = Connectivity::Six;
        let holds = |reason, curves: Vec<Vec<Vertex>>| {
            certificate_holds(&a.masks, conn, &kept(reason), &[(0, curves)], &NoProgress)
        };
        assert!(holds(KeepReason::Size, vec![p.clone(), q.clone()]));
        assert!(!holds(KeepReason::Size, vec![p.clone(), p.clone()]));
        assert!(!holds(KeepReason::Size, vec![q.clone()]));
        assert!(!holds(KeepReason::ClosureFailed, vec![p, q]));
    }
}
