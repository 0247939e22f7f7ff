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

/// What the certificates of one sweep step share: the ribbons whose generators were checked,
/// and the curves certified so far, whose crossing matrix has full rank.
#[derive(Default)]
pub(super) struct StepCurves {
    ribbons: FastMap<(i64, u32), ()>,
    curves: loops::basis::CurveSet,
}

/// The curves that prove a handle has no loop below tau, or a loop below tau found on the way.
///
/// - A Reeb-cycle handle: its cut and the shortest loop crossing it, from its measurement (no
///   loop below tau crosses the cut, nor that loop, an odd number of times); see
///   [`reeb_cycle_curves`] for two handles of one step that found the same loop.
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
    step: &mut StepCurves,
) -> Certificate {
    let Some((slice, ribbon)) = h.ribbon else {
        return match (&l.basis, l.exact) {
            (Some((p, q)), true) => {
                let pair = vec![p.clone(), q.clone()];
                reeb_cycle_curves(vol, h, pair, conn, limits, affine, caches, step)
            }
            _ => Certificate::Unsure,
        };
    };
    if step.ribbons.insert((slice, ribbon), ()).is_some() {
        return Certificate::Shared;
    }
    let mut g = Graph::with_cache(vol, cases(conn), std::mem::take(&mut caches.graph));
    let out = (|| {
        let Some(generators) = loops::ribbon_generators(&mut g, &mut caches.slices, slice, ribbon)
        else {
            return Certificate::Unsure;
        };
        let searcher = searcher(vol, limits, affine);
        for b in &generators {
            if let Some(c) = no_odd_loop_below(&searcher, &mut g, vol, b, limits) {
                return c;
            }
        }
        step.curves.add(vol, conn, &generators);
        Certificate::Curves(generators)
    })();
    caches.graph = g.into_cache();
    out
}

/// A Reeb-cycle handle's curves: its cut and the shortest loop crossing it (`pair`), and, if
/// with them the step's curves span fewer than two more dimensions, the walk round the handle's
/// own cycle once no loop below tau crosses it. Two handles of one step whose cuts lie side by
/// side may have found the same loop, through both cuts (random 18³ noise at tau 5: loops of
/// 13 and 14 edges through two contours of one plane): their four curves then span only two,
/// and a loop in the class of the two cuts together, which crosses none of them an odd number
/// of times, is not ruled out. The walk crosses its own cut once and, unlike the loop, not the
/// other's. Any curve no loop below tau crosses oddly may join the certificate, which asks only
/// that the curves span the surface's homology: a curve more never lowers the rank.
#[allow(clippy::too_many_arguments)]
fn reeb_cycle_curves(
    vol: &MaskVolume,
    h: &LocatedHandle,
    mut pair: Vec<Vec<Vertex>>,
    conn: Connectivity,
    limits: Limits,
    affine: &Affine,
    caches: &mut Caches,
    step: &mut StepCurves,
) -> Certificate {
    if step
        .curves
        .add(vol, conn, &pair)
        .is_none_or(|grew| grew == 2)
    {
        return Certificate::Curves(pair);
    }
    let mut g = Graph::with_cache(vol, cases(conn), std::mem::take(&mut caches.graph));
    let walk = loops::chained_reeb_loop(&mut g, &mut caches.slices, h);
    let searcher = searcher(vol, limits, affine);
    let below = walk
        .as_ref()
        .and_then(|w| no_odd_loop_below(&searcher, &mut g, vol, w, limits));
    caches.graph = g.into_cache();
    match (walk, below) {
        (_, Some(Certificate::Below(short))) => Certificate::Below(short),
        (Some(walk), None) => {
            step.curves.add(vol, conn, std::slice::from_ref(&walk));
            pair.push(walk);
            Certificate::Curves(pair)
        }
        // No walk, or its search cut short: the pair alone, as measured.
        _ => Certificate::Curves(pair),
    }
}

/// The loop searcher of the certificates.
fn searcher<'g>(vol: &'g MaskVolume, limits: Limits, affine: &'g Affine) -> loops::Searcher<'g> {
    loops::Searcher {
        metric: limits.metric,
        geometry: Geometry {
            affine,
            fractions: vol.fractions.as_ref(),
        },
    }
}

/// `None` when no loop below tau crosses `b` an odd number of times; else what to do: close
/// the loop found (and `b`, the curve it crosses once, as its partner), or nothing is proven.
fn no_odd_loop_below(
    searcher: &loops::Searcher,
    g: &mut Graph,
    vol: &MaskVolume,
    b: &[Vertex],
    limits: Limits,
) -> Option<Certificate> {
    let found = searcher.odd_loop(g, b, limits.below);
    match found.found {
        Some(short) => {
            let describe =
                |x: &[Vertex], p: &[Vertex]| loops::describe(vol, x, Some(p), &searcher.geometry);
            Some(Certificate::Below(HandleLoops {
                reeb: Some(describe(&short, b)),
                cross: Some(describe(b, &short)),
                exact: true,
                basis: None,
                cut_points: None,
            }))
        }
        None if !found.exact => Some(Certificate::Unsure),
        None => None,
    }
}

/// The certificate of the last pass: every handle kept for its size, and the crossing matrix of
/// their curves of full rank (2 × kept), so no loop below tau is left.
pub(super) fn certificate_holds(
    vol: &mut MaskVolume,
    conn: Connectivity,
    kept: &[(i64, Kept)],
    basis: &[(i64, Vec<Vec<Vertex>>)],
    progress: &dyn Progress,
) -> crate::error::Result<bool> {
    if kept.iter().any(|(_, k)| k.reason != KeepReason::Size) {
        return Ok(false);
    }
    let curves: Vec<Vec<Vertex>> = basis.iter().flat_map(|(_, c)| c.clone()).collect();
    let rank = loops::basis::crossing_rank(vol, conn, &curves)?;
    progress.trace(format_args!(
        "certificate: {} curves, rank {rank:?}, {} kept",
        curves.len(),
        kept.len()
    ));
    Ok(rank == Some(2 * kept.len()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::progress::NoProgress;
    use crate::simplify::measure::Caches;
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

    /// The analysed sponge the certificate tests run on: Reeb-cycle and intra-ribbon handles.
    fn sponge() -> crate::Analysis {
        let sponge = crate::test_rng::sponge(20, 0x2545_f491_4f6c_dd1d);
        let opts = crate::AnalyzeOptions::default();
        crate::analyze(crate::Source::from(sponge), &opts, &NoProgress).unwrap()
    }

    /// Certifies the sponge's handle `i` at connectivity 6 and unit spacing, searching for
    /// loops shorter than `below`.
    fn certify_sponge(
        a: &crate::Analysis,
        i: usize,
        below: f64,
        caches: &mut Caches,
        step: &mut StepCurves,
    ) -> Certificate {
        let limits = Limits {
            below,
            ..Limits::NONE
        };
        let affine = Affine::from_spacing([1.0; 3], [0.0; 3]);
        let (h, l) = (&a.report.handles[i], &a.loops[i]);
        let conn = Connectivity::Six;
        certify(&a.masks, &h.located, l, conn, limits, &affine, caches, step)
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
        let mut a = crate::analyze(crate::Source::from(torus), &opts, &NoProgress).unwrap();
        assert_eq!(a.loops.len(), 1);
        let (p, q) = a.loops[0]
            .basis
            .clone()
            .expect("a measured handle has its curves");
        let conn = Connectivity::Six;
        let mut holds = |reason, curves: Vec<Vec<Vertex>>| {
            let basis = [(0, curves)];
            certificate_holds(&mut a.masks, conn, &kept(reason), &basis, &NoProgress).unwrap()
        };
        assert!(holds(KeepReason::Size, vec![p.clone(), q.clone()]));
        assert!(!holds(KeepReason::Size, vec![p.clone(), p.clone()]));
        assert!(!holds(KeepReason::Size, vec![q.clone()]));
        assert!(!holds(KeepReason::ClosureFailed, vec![p, q]));
    }

    /// A search cut short proves nothing: on a sponge's intra-ribbon handles, certified with
    /// the searches' budgets (each generator of the ribbon searched for a loop below tau
    /// crossing it oddly), every handle gets curves or a loop below tau; with budgets of a few
    /// states, none gets curves, and those whose search found no loop are unsure.
    #[test]
    fn a_search_cut_short_proves_nothing() {
        let a = sponge();
        // A small tau: the ribbons' generators have no loop below it to find.
        let certified = |budgets: Option<crate::surface::search::Budgets>| {
            let (mut curves, mut unsure, mut below) = (0, 0, 0);
            for (i, h) in a.report.handles.iter().enumerate() {
                if h.located.ribbon.is_none() {
                    continue;
                }
                let mut caches = Caches::new(Connectivity::Six);
                if let Some(b) = budgets {
                    caches.graph.budgets = b;
                }
                let mut step = StepCurves::default();
                match certify_sponge(&a, i, 4.0, &mut caches, &mut step) {
                    Certificate::Curves(_) => curves += 1,
                    Certificate::Unsure => unsure += 1,
                    Certificate::Below(_) => below += 1,
                    Certificate::Shared => unreachable!("a fresh ribbon set"),
                }
            }
            (curves, unsure, below)
        };
        let (curves, unsure, below) = certified(None);
        assert_eq!(unsure, 0, "{curves} certified, {below} below tau");
        assert!(curves > 10, "{curves} certified, {below} below tau"); // measured 22 and 75
        let tiny = crate::surface::search::Budgets { first: 4, exact: 4 };
        let (curves, unsure, below) = certified(Some(tiny));
        assert_eq!(curves, 0, "{unsure} unsure, {below} below tau");
        assert!(unsure > 50, "{unsure} unsure, {below} below tau"); // measured 97 and 0
    }

    /// A Reeb-cycle handle whose pair adds too little to its step's curves (here: the step
    /// holds the same pair already, as when two handles of a step found one loop) gets the walk
    /// round its cycle as well, a curve crossing its cut once; with a fresh step, its pair
    /// alone. On a sponge's Reeb-cycle handles, with a tau below which the sponge has no loop
    /// (at 4, a loop of 3 edges of another handle crosses a walk).
    #[test]
    fn a_pair_adding_too_little_to_its_step_gets_the_walk_round_the_cycle_too() {
        let a = sponge();
        let conn = Connectivity::Six;
        let mut g = Graph::new(&a.masks, cases(conn));
        let mut walks = 0;
        for (i, (h, l)) in a.report.handles.iter().zip(&a.loops).enumerate() {
            let (Some((p, q)), None, true) = (&l.basis, h.located.ribbon, l.exact) else {
                continue;
            };
            let certified = |step: &mut StepCurves| {
                let mut caches = Caches::new(conn);
                match certify_sponge(&a, i, 3.0, &mut caches, step) {
                    Certificate::Curves(c) => c,
                    _ => panic!("handle {}: no curves", h.id),
                }
            };
            let pair = vec![p.clone(), q.clone()];
            assert_eq!(certified(&mut StepCurves::default()), pair);
            let mut step = StepCurves::default();
            assert_eq!(step.curves.add(&a.masks, conn, &pair), Some(2));
            let c = certified(&mut step);
            assert_eq!(c.len(), 3, "handle {}", h.id);
            assert_eq!(c[..2], pair[..]);
            assert_eq!(
                crate::surface::search::crossing_parity(&mut g, p, &c[2]),
                Some(1)
            );
            assert_eq!(step.curves.curves().len(), 5);
            walks += 1;
        }
        assert!(walks > 5, "{walks} handles");
    }

    /// The walk's search can find a loop below tau (at 4 on the sponge, a loop of 3 edges of
    /// another handle crosses some walks): that loop is the certificate's answer, to be closed,
    /// not the pair alone.
    #[test]
    fn a_loop_below_tau_crossing_the_walk_is_closed() {
        let a = sponge();
        let conn = Connectivity::Six;
        let mut below = 0;
        for (i, (h, l)) in a.report.handles.iter().zip(&a.loops).enumerate() {
            let (Some((p, q)), None, true) = (&l.basis, h.located.ribbon, l.exact) else {
                continue;
            };
            let mut step = StepCurves::default();
            step.curves.add(&a.masks, conn, &[p.clone(), q.clone()]);
            let mut caches = Caches::new(conn);
            if let Certificate::Below(short) = certify_sponge(&a, i, 4.0, &mut caches, &mut step) {
                let len = short.reeb.as_ref().map(|x| x.length);
                assert!(len.is_some_and(|n| (n as f64) < 4.0), "{len:?}");
                below += 1;
            }
        }
        assert!(below > 0, "no walk crossed by a loop below 4");
    }
}
