//! Walls across a handle's loops, tried in order until the local check accepts one: fans of
//! growing thickness, single samples, then peeled regions near the fan, in a box round the loop,
//! and in that box moved along the partner loop.

use super::plan::operation_for;
use super::{LoopKind, Mode, SimplifyOptions};
use crate::closure::{self, base_thickness, opposite, Operation};
use crate::grid::MaskVolume;
use crate::loops::{self, HandleLoops, Loop};
use crate::surface::geometry::Geometry;
use crate::surface::search::{FastMap, Graph, GraphCache};
use crate::surface::Vertex;
use crate::topology::cases::{cases, Connectivity};
use crate::volume::{Affine, BBox};

/// Loops this short that no fan wall closes get a try with single samples near their centroid,
/// within this reach (voxels; reported as the wall's thickness).
const SINGLE_SAMPLE_LOOP: usize = 8;
const SINGLE_SAMPLE_REACH: f64 = 1.8;

/// Wall half-thicknesses tried beyond the base one before giving up on a loop.
const EXTRA_THICKNESS: [f64; 3] = [0.0, 0.5, 1.0];

/// The thickest fan wall: the largest base thickness (√3/2) plus the largest extra.
const MAX_FAN_THICKNESS: f64 = 0.866_025_403_784_438_6 + 1.0;

/// A wall to try across a loop.
#[derive(Clone, Copy, Debug)]
pub(super) enum Wall {
    /// The samples within this distance of the loop's spanning fan.
    Fan(f64),
    /// One sample near the centroid of a short loop.
    Single([i64; 3]),
    /// The samples near the fan (within this distance) thinned by simple samples, then cut at
    /// the k-th sample that cuts the ring the loop goes round (see [`closure::peel_walls`]).
    Peel(f64, usize),
    /// The same with every sample of the box round the loop, this much larger than the loop's:
    /// for a long twisted loop whose fan is far from the disk it bounds.
    PeelBox(i64, usize),
    /// The same box moved along the partner loop (the j-th of [`PEEL_ALONG`] steps round it),
    /// margin as given: where the ring cannot be cut near the loop without cutting something
    /// else too (a bar hollow there, a tunnel with a speck of material in it), it may be
    /// further on.
    PeelAlong(usize, i64, usize),
}

impl Wall {
    pub(super) fn thickness(self) -> f64 {
        match self {
            Wall::Fan(d) => d,
            Wall::Single(_) => SINGLE_SAMPLE_REACH,
            Wall::Peel(d, _) => d,
            Wall::PeelBox(margin, _) | Wall::PeelAlong(_, margin, _) => margin as f64,
        }
    }

    pub(super) fn name(self) -> &'static str {
        match self {
            Wall::Fan(_) => "fan",
            Wall::Single(_) => "single_sample",
            Wall::Peel(..) => "peeled",
            Wall::PeelBox(..) => "peeled_box",
            Wall::PeelAlong(..) => "peeled_along",
        }
    }
}

/// The walls tried across a loop, in order: fans of growing thickness; for a short loop round a
/// corner or edge contact, single samples (one may do); then walls peeled down to the one sample
/// that cuts the ring the loop goes round, in regions near the fan, then in boxes round the
/// loop (see [`closure::peel_walls`]: these always remove a handle and split nothing; the
/// regions grow until one holds a cut). Or, reaching along, boxes moved along the partner.
fn walls_for(
    lp: &Loop,
    op: Operation,
    conn: Connectivity,
    partner: &[Vertex],
    reach: WallReach,
) -> Vec<Wall> {
    let wide = (lp.length as i64 / 4).max(2 * PEEL_BOX_MARGIN);
    if reach == WallReach::Along {
        if partner.is_empty() {
            return Vec::new();
        }
        let mut out = Vec::new();
        for margin in [PEEL_BOX_MARGIN, wide] {
            for j in 1..PEEL_ALONG {
                out.extend((0..PEEL_CUTS).map(|k| Wall::PeelAlong(j, margin, k)));
            }
        }
        return out;
    }
    let mut out: Vec<Wall> = EXTRA_THICKNESS
        .iter()
        .map(|extra| Wall::Fan(base_thickness(op, conn) + extra))
        .collect();
    if lp.length <= SINGLE_SAMPLE_LOOP {
        out.extend(
            closure::single_sample_walls(&lp.vertices, SINGLE_SAMPLE_REACH)
                .into_iter()
                .map(Wall::Single),
        );
    }
    for d in PEEL_REACH {
        out.extend((0..PEEL_CUTS).map(|k| Wall::Peel(d, k)));
    }
    for margin in [PEEL_BOX_MARGIN, wide] {
        out.extend((0..PEEL_CUTS).map(|k| Wall::PeelBox(margin, k)));
    }
    out
}

/// Steps round the partner loop at which the box round the loop is moved and peeled again.
const PEEL_ALONG: usize = 8;

/// Samples of a peeled region tried as the cut, nearest the loop's centroid first.
const PEEL_CUTS: usize = 8;

/// Distances from the fan of the regions peeled, tried in turn.
const PEEL_REACH: [f64; 3] = [1.5, 3.0, 5.0];

/// Margin of the first box round the loop peeled whole (the second: a quarter of the loop).
const PEEL_BOX_MARGIN: i64 = 2;

/// Samples a box peeled whole may hold (beyond, the box is not tried: peeling costs about a
/// microsecond per sample).
const MAX_PEEL_BOX: usize = 1 << 20;

/// The samples of the box round the loop's points with a margin, within the volume (none if
/// there are more than [`MAX_PEEL_BOX`]).
fn box_region(vol: &MaskVolume, points: &[[f64; 3]], margin: i64) -> (Vec<[i64; 3]>, BBox) {
    let mut b = BBox::EMPTY;
    for p in points {
        b.include(p.map(|x| x.floor() as i64 - margin));
        b.include(p.map(|x| x.ceil() as i64 + margin));
    }
    let dims = vol.dims.map(|n| n as i64);
    let lo: [i64; 3] = std::array::from_fn(|k| b.min[k].max(0));
    let hi: [i64; 3] = std::array::from_fn(|k| b.max[k].min(dims[k] - 1));
    let size: i64 = (0..3).map(|k| (hi[k] - lo[k] + 1).max(0)).product();
    if size as usize > MAX_PEEL_BOX {
        return (Vec::new(), b);
    }
    let mut out = Vec::new();
    for z in lo[2]..=hi[2] {
        for y in lo[1]..=hi[1] {
            for x in lo[0]..=hi[0] {
                out.push([x, y, z]);
            }
        }
    }
    (out, b)
}

/// Where a peeled wall across the loop looks for the ring it cuts: the box of the loop and its
/// partner (which runs round that ring), with a margin (without a partner, a quarter of the
/// loop), and the peeled region's box.
fn peel_target<'a>(
    points: &'a [[f64; 3]],
    partner: &[Vertex],
    length: usize,
    region: BBox,
) -> closure::PeelTarget<'a> {
    let margin = if partner.is_empty() {
        (length as i64 / 4).max(PEEL_RING_MARGIN)
    } else {
        PEEL_RING_MARGIN
    };
    let mut b = BBox::EMPTY;
    for p in points {
        b.include(p.map(|x| x.floor() as i64));
        b.include(p.map(|x| x.ceil() as i64));
    }
    for v in partner {
        b.include(v.p);
        b.include(v.end());
    }
    let (mut lo, mut hi) = (b.min.map(|x| x - margin), b.max.map(|x| x + margin));
    if region != BBox::EMPTY {
        lo = std::array::from_fn(|k| lo[k].min(region.min[k]));
        hi = std::array::from_fn(|k| hi[k].max(region.max[k]));
    }
    closure::PeelTarget {
        loop_points: points,
        lo,
        hi,
    }
}

/// Where a peeled wall is wanted: where the loop's partner crosses it (the partner, pushed off
/// the surface, is the ring the wall must cut), else the loop's centroid. The region is peeled
/// towards it, and cuts are tried nearest it first.
fn peel_centre(points: &[[f64; 3]], partner: &[Vertex]) -> [f64; 3] {
    let d2 = |a: [f64; 3], b: [f64; 3]| (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>();
    let crossing = points
        .iter()
        .flat_map(|&p| partner.iter().map(move |v| (d2(p, v.midpoint()), p)))
        .min_by(|a, b| a.0.total_cmp(&b.0));
    match crossing {
        Some((_, p)) => p,
        None => crate::surface::geometry::centroid(points),
    }
}

/// The loop's points moved along its partner by `j` of [`PEEL_ALONG`] steps from where the
/// partner crosses the loop (`centre`), and where that step lands. They move by whole samples
/// (the step's shift rounded towards zero: edge midpoints are half a sample off on one axis), so
/// the box round them is the loop's box moved, not grown by a plane where the shift is a half.
fn moved_along(
    points: &[[f64; 3]],
    centre: [f64; 3],
    partner: &[Vertex],
    j: usize,
) -> (Vec<[f64; 3]>, [f64; 3]) {
    let d2 = |a: [f64; 3], b: [f64; 3]| (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>();
    let start = (0..partner.len())
        .min_by(|&a, &b| {
            d2(partner[a].midpoint(), centre).total_cmp(&d2(partner[b].midpoint(), centre))
        })
        .unwrap_or(0);
    let at = partner[(start + j * partner.len() / PEEL_ALONG) % partner.len()].midpoint();
    let shift: [f64; 3] = std::array::from_fn(|k| (at[k] - centre[k]).trunc());
    let moved = points
        .iter()
        .map(|p| std::array::from_fn(|k| p[k] + shift[k]))
        .collect();
    (moved, at)
}

/// Margin of the box round a loop and its partner where a peeled wall's ring is looked for.
const PEEL_RING_MARGIN: i64 = 3;

/// Tries the walls across `lp` by each of `ops` until one is kept (see [`closure::close`]).
fn close_loop(
    vol: &mut MaskVolume,
    conn: Connectivity,
    lp: &Loop,
    partner: &[Vertex],
    ops: &[Operation],
    (reach, graph, refused, locked, no_cut): (
        WallReach,
        &mut GraphCache,
        &mut Refused,
        &Locked,
        &mut NoCut,
    ),
) -> Option<(closure::Applied, Wall)> {
    let points: Vec<[f64; 3]> = lp.vertices.iter().map(|v| v.midpoint()).collect();
    let centre = peel_centre(&points, partner);
    let mut peeled: Vec<Vec<[i64; 3]>> = Vec::new();
    let mut near = NearFanSamples {
        points: &points,
        near: None,
    };
    for &op in ops {
        for w in walls_for(lp, op, conn, partner, reach) {
            let samples = match w {
                Wall::Fan(d) => near.within(d),
                Wall::Single([u, v, w]) if vol.get(u, v, w) == op.target() => continue,
                Wall::Single(q) => vec![q],
                // Peeled once per region; its cuts are tried in turn.
                Wall::Peel(_, k) | Wall::PeelBox(_, k) | Wall::PeelAlong(_, _, k) if k > 0 => {
                    match peeled.get(k) {
                        Some(x) => x.clone(),
                        None => continue,
                    }
                }
                // Peeled in a region: near the fan, a box round the loop, or that box moved
                // along the partner (towards where the partner lands).
                Wall::Peel(..) | Wall::PeelBox(..) | Wall::PeelAlong(..) => {
                    let (region, b, at) = match w {
                        Wall::Peel(d, _) => (near.within(d), BBox::EMPTY, centre),
                        Wall::PeelBox(margin, _) => {
                            let (region, b) = box_region(vol, &points, margin);
                            (region, b, centre)
                        }
                        Wall::PeelAlong(j, margin, _) => {
                            let (moved, at) = moved_along(&points, centre, partner, j);
                            let (region, b) = box_region(vol, &moved, margin);
                            (region, b, at)
                        }
                        Wall::Fan(_) | Wall::Single(_) => unreachable!("matched above"),
                    };
                    let region: Vec<[i64; 3]> = unlocked(region, locked);
                    let target = peel_target(&points, partner, lp.length, b);
                    let key = NoCut::key(&region, at, op, &target);
                    peeled = Vec::new();
                    if !no_cut.holds(key) {
                        peeled =
                            closure::peel_walls(vol, conn, &region, at, op, &target, PEEL_CUTS);
                        if peeled.is_empty() {
                            no_cut.insert(key, &region, &target);
                        }
                    }
                    match peeled.first() {
                        Some(x) => x.clone(),
                        None => continue,
                    }
                }
            };
            let attempt = closure::Attempt {
                lp: &lp.vertices,
                partner,
                op,
                wall: unlocked(samples, locked),
                certified: !matches!(w, Wall::Fan(_) | Wall::Single(_)),
            };
            let r = closure::close(vol, conn, attempt, graph);
            match r {
                Ok(applied) => return Some((applied, w)),
                Err(why) => {
                    refused.total += 1;
                    *refused.by.entry(why.name()).or_default() += 1;
                }
            }
        }
    }
    None
}

/// Regions peeled that held no cut, by what was peeled (the region, the loop, the operation,
/// the ring's box), with the box of the samples the peeling read (the region's
/// 26-neighbourhoods and the ring's box): until an edit lands in it, peeling there again finds
/// no cut again. A handful of long loops, met again after every wall near them, had the same
/// boxes peeled again and again (the embryo's `--tau inf`: 552 boxes moved along the partner,
/// none with a cut, 4.1 s of its 13.8).
#[derive(Default)]
pub(super) struct NoCut(FastMap<u64, BBox>);

impl NoCut {
    fn key(region: &[[i64; 3]], at: [f64; 3], op: Operation, target: &closure::PeelTarget) -> u64 {
        use std::hash::{Hash, Hasher};
        let mut s = std::collections::hash_map::DefaultHasher::new();
        region.hash(&mut s);
        at.map(f64::to_bits).hash(&mut s);
        (op == Operation::Pinch).hash(&mut s);
        for p in target.loop_points {
            p.map(f64::to_bits).hash(&mut s);
        }
        (target.lo, target.hi).hash(&mut s);
        s.finish()
    }

    fn holds(&self, key: u64) -> bool {
        self.0.contains_key(&key)
    }

    fn insert(&mut self, key: u64, region: &[[i64; 3]], target: &closure::PeelTarget) {
        let mut read = BBox {
            min: target.lo,
            max: target.hi,
        };
        for &q in region {
            read.include(q.map(|x| x - 1));
            read.include(q.map(|x| x + 1));
        }
        self.0.insert(key, read);
    }

    /// Forgets the regions whose samples read an edit in `edits` may have changed.
    pub(super) fn forget_near(&mut self, edits: &[BBox]) {
        self.0
            .retain(|_, read| !edits.iter().any(|e| super::plan::overlaps(e, read, 0)));
    }
}

/// Samples no wall changes: each opened a handle to mend a critical face (see
/// [`crate::compose::ComposeOptions::open_handles`]), and a wall that flipped it back would
/// bring the face back; the handle is closed elsewhere.
pub(super) type Locked = FastMap<[i64; 3], ()>;

/// A wall or a region to peel in, without the locked samples.
fn unlocked(mut samples: Vec<[i64; 3]>, locked: &Locked) -> Vec<[i64; 3]> {
    if !locked.is_empty() {
        samples.retain(|q| !locked.contains_key(q));
    }
    samples
}

/// The samples near a loop's fan, gathered once as far as the walls tried so far need.
struct NearFanSamples<'p> {
    points: &'p [[f64; 3]],
    near: Option<closure::NearFan>,
}

impl NearFanSamples<'_> {
    /// The samples within `d` of the fan (see [`closure::NearFan::within`]).
    fn within(&mut self, d: f64) -> Vec<[i64; 3]> {
        if self.near.as_ref().is_none_or(|n| n.reach < d) {
            // Fans need up to their thickest; peeled regions, the widest reach at once.
            let reach = if d <= MAX_FAN_THICKNESS {
                MAX_FAN_THICKNESS
            } else {
                PEEL_REACH[PEEL_REACH.len() - 1]
            };
            self.near = Some(closure::NearFan::new(self.points, reach.max(d)));
        }
        self.near.as_ref().expect("set above").within(d)
    }
}

/// Closes one of a handle's loops: the candidates (loops below tau, shortest first), then, if
/// every wall across them is refused, the handle's other loop whatever its length (measured now
/// if its search stopped at tau). Walls across the loops come first; walls moved along their
/// partners (slower, and farther from the loop) only when no loop has one. Returns the loop
/// closed, how, and with which wall.
pub(super) fn close_handle<'l>(
    vol: &mut MaskVolume,
    opts: &SimplifyOptions,
    l: &'l HandleLoops,
    candidates: &[(LoopKind, &'l Loop)],
    affine: &Affine,
    (graph, refused, locked, no_cut): (&mut GraphCache, &mut Refused, &Locked, &mut NoCut),
) -> Option<Closed<'l>> {
    let mut by = |reach: WallReach| {
        let walling = (&mut *graph, &mut *refused, locked, &mut *no_cut);
        close_handle_by(vol, opts, l, candidates, affine, walling, reach)
    };
    by(WallReach::Across).or_else(|| by(WallReach::Along))
}

/// A handle closed: which curve, the curve, its partner's length, the wall and what it did.
pub(super) struct Closed<'l> {
    pub(super) which: LoopKind,
    pub(super) lp: std::borrow::Cow<'l, Loop>,
    /// Length (edges) of the curve crossing `lp` once that the walls aimed to cut, if any: a
    /// wall peeled along it lies in `lp`'s box moved by at most half of it.
    pub(super) partner: Option<usize>,
    pub(super) applied: closure::Applied,
    pub(super) wall: Wall,
}

/// Walls the local check refused: how many, and why (by [`closure::Refusal::name`]).
#[derive(Default)]
pub(super) struct Refused {
    pub(super) total: usize,
    pub(super) by: std::collections::BTreeMap<&'static str, usize>,
}

/// Where the walls tried across a loop lie.
#[derive(Clone, Copy, PartialEq, Eq)]
enum WallReach {
    /// Across the loop: fans, single samples, regions near the fan and boxes round the loop.
    Across,
    /// In the box round the loop moved along its partner.
    Along,
}

/// [`close_handle`] with the walls of one reach.
fn close_handle_by<'l>(
    vol: &mut MaskVolume,
    opts: &SimplifyOptions,
    l: &'l HandleLoops,
    candidates: &[(LoopKind, &'l Loop)],
    affine: &Affine,
    (graph, refused, locked, no_cut): (&mut GraphCache, &mut Refused, &Locked, &mut NoCut),
    reach: WallReach,
) -> Option<Closed<'l>> {
    let conn = opts.surface.connectivity;
    // The candidates are the handle's Reeb and cross loops, each the other's partner.
    let partner_of = |which: LoopKind| match which {
        LoopKind::Reeb => l.cross.as_ref(),
        LoopKind::Cross => l.reeb.as_ref(),
        LoopKind::Basis => None,
    };
    let ops_for =
        |lp: &Loop, has_partner: bool| ops_to_try(operation_for(lp), has_partner, opts.mode);
    for &(which, lp) in candidates {
        let partner = partner_of(which).map_or(&[][..], |x| &x.vertices);
        let ops = ops_for(lp, !partner.is_empty());
        if let Some((applied, wall)) = close_loop(
            vol,
            conn,
            lp,
            partner,
            &ops,
            (reach, graph, refused, locked, no_cut),
        ) {
            return Some(Closed {
                which,
                lp: std::borrow::Cow::Borrowed(lp),
                partner: (!partner.is_empty()).then_some(partner.len()),
                applied,
                wall,
            });
        }
    }
    // The other loop of the shortest candidate, however long.
    let &(which, lp) = candidates.first()?;
    let other = match which {
        LoopKind::Reeb => LoopKind::Cross,
        LoopKind::Cross | LoopKind::Basis => LoopKind::Reeb,
    };
    let found = match partner_of(which) {
        Some(x) => std::borrow::Cow::Borrowed(x),
        None => {
            let mut g = Graph::with_cache(vol, cases(conn), std::mem::take(graph));
            let x = loops::cross_loop(&mut g, &lp.vertices, usize::MAX);
            *graph = g.into_cache();
            let geometry = Geometry {
                affine,
                fractions: vol.fractions.as_ref(),
            };
            std::borrow::Cow::Owned(loops::describe(vol, &x?, Some(&lp.vertices), &geometry))
        }
    };
    let ops = ops_for(&found, true);
    if let Some((applied, wall)) = close_loop(
        vol,
        conn,
        &found,
        &lp.vertices,
        &ops,
        (reach, graph, refused, locked, no_cut),
    ) {
        return Some(Closed {
            which: other,
            lp: found,
            partner: Some(lp.vertices.len()),
            applied,
            wall,
        });
    }
    close_basis(
        vol,
        opts,
        l,
        affine,
        (graph, refused, locked, no_cut),
        reach,
    )
}

/// Last, the handle's two curves that cross once (its cut and the loop round its cycle, see
/// [`HandleLoops::basis`]), each with the other as partner: a closure of either removes the
/// handle too, and the cut, a contour, spans a flat region.
fn close_basis<'l>(
    vol: &mut MaskVolume,
    opts: &SimplifyOptions,
    l: &'l HandleLoops,
    affine: &Affine,
    (graph, refused, locked, no_cut): (&mut GraphCache, &mut Refused, &Locked, &mut NoCut),
    reach: WallReach,
) -> Option<Closed<'l>> {
    let conn = opts.surface.connectivity;
    let (p, q) = l.basis.as_ref()?;
    let ops: Vec<Operation> = [Operation::Collapse, Operation::Pinch]
        .into_iter()
        .filter(|&op| opts.mode.allows(op))
        .collect();
    for (x, y) in [(p, q), (q, p)] {
        let geometry = Geometry {
            affine,
            fractions: vol.fractions.as_ref(),
        };
        let lx = loops::describe(vol, x, Some(y), &geometry);
        if let Some((applied, wall)) = close_loop(
            vol,
            conn,
            &lx,
            y,
            &ops,
            (reach, graph, refused, locked, no_cut),
        ) {
            return Some(Closed {
                which: basis_kind(l, x),
                lp: std::borrow::Cow::Owned(lx),
                partner: Some(y.len()),
                applied,
                wall,
            });
        }
    }
    None
}

/// What a basis curve is called in the report: the loop it is, if it is one of the handle's
/// loops, else a basis curve.
fn basis_kind(l: &HandleLoops, x: &[Vertex]) -> LoopKind {
    let is = |lp: &Option<Loop>| lp.as_ref().is_some_and(|lp| lp.vertices == x);
    if is(&l.reeb) {
        LoopKind::Reeb
    } else if is(&l.cross) {
        LoopKind::Cross
    } else {
        LoopKind::Basis
    }
}

/// The operations tried on a loop, of those the mode allows: the one the side it goes round
/// calls for, and the other too when the loop has no partner (its side was then judged from its
/// fan alone: if no wall of that kind closes it, one of the other kind may; every wall is
/// verified either way).
fn ops_to_try(op: Operation, has_partner: bool, mode: Mode) -> Vec<Operation> {
    let mut ops = vec![op];
    if !has_partner && mode == Mode::Both {
        ops.push(opposite(op));
    }
    ops.retain(|&o| mode.allows(o));
    ops
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::Frame;
    use crate::loops::Encloses;

    /// A region peeled in vain is remembered until an edit lands in the box of what its peeling
    /// read (the region's samples and their neighbours, and the ring's box); an edit beyond
    /// keeps it, and the key tells apart what was peeled (another operation, another region).
    #[test]
    fn a_region_peeled_in_vain_is_forgotten_where_an_edit_lands() {
        let points = [[5.5, 5.0, 5.0], [6.0, 5.5, 5.0], [5.5, 6.0, 5.0]];
        let target = closure::PeelTarget {
            loop_points: &points,
            lo: [0, 0, 0],
            hi: [3, 3, 3],
        };
        let region = [[8, 8, 8], [9, 8, 8]];
        let at = [8.5, 8.0, 8.0];
        let key = NoCut::key(&region, at, Operation::Pinch, &target);
        assert_ne!(key, NoCut::key(&region, at, Operation::Collapse, &target));
        assert_ne!(key, NoCut::key(&region[..1], at, Operation::Pinch, &target));
        let edit = |q: [i64; 3]| BBox { min: q, max: q };
        for (q, kept) in [
            ([12, 8, 8], true),
            ([5, 5, 11], true),
            ([11, 8, 8], true),
            ([5, 5, 5], false),
            ([10, 9, 9], false),
            ([7, 7, 7], false),
            ([3, 0, 3], false),
            ([0, 0, 0], false),
        ] {
            let mut memo = NoCut::default();
            memo.insert(key, &region, &target);
            assert!(memo.holds(key));
            memo.forget_near(&[edit(q)]);
            assert_eq!(memo.holds(key), kept, "an edit at {q:?}");
        }
    }

    /// With a partner a loop gets the operation its side calls for; without one, in mode both,
    /// the other after it; never one its mode forbids.
    #[test]
    fn a_loop_gets_the_operations_its_partner_and_mode_allow() {
        use Operation::{Collapse, Pinch};
        for op in [Collapse, Pinch] {
            assert_eq!(ops_to_try(op, true, Mode::Both), [op]);
            assert_eq!(ops_to_try(op, false, Mode::Both), [op, opposite(op)]);
            for has_partner in [true, false] {
                let fill = ops_to_try(op, has_partner, Mode::FillOnly);
                assert_eq!(fill, (op == Collapse).then_some(op).as_slice());
                let cut = ops_to_try(op, has_partner, Mode::CutOnly);
                assert_eq!(cut, (op == Pinch).then_some(op).as_slice());
            }
        }
    }

    fn x_edges(points: &[[i64; 3]]) -> Vec<Vertex> {
        points.iter().map(|&p| Vertex { p, axis: 0 }).collect()
    }

    /// A loop of `length` edges (the walls only read its vertices and length).
    fn a_loop(vertices: Vec<Vertex>, length: usize) -> Loop {
        Loop {
            vertices,
            points: Vec::new(),
            length,
            length_mm: length as f64,
            encloses: Encloses::Void,
        }
    }

    /// A basis curve closed is reported as the loop it is, or as a basis curve when it is
    /// neither of the handle's loops (a top-level handle's cut).
    #[test]
    fn a_basis_curve_is_named_for_the_loop_it_is() {
        let (a, b, c) = (
            x_edges(&[[0, 0, 0], [1, 0, 0]]),
            x_edges(&[[0, 1, 0], [1, 1, 0]]),
            x_edges(&[[0, 2, 0], [1, 2, 0]]),
        );
        let l = HandleLoops {
            reeb: Some(a_loop(a.clone(), 2)),
            cross: Some(a_loop(b.clone(), 2)),
            exact: true,
            basis: Some((c.clone(), a.clone())),
            cut_points: None,
        };
        assert_eq!(basis_kind(&l, &a), LoopKind::Reeb);
        assert_eq!(basis_kind(&l, &b), LoopKind::Cross);
        assert_eq!(basis_kind(&l, &c), LoopKind::Basis);
        let none = HandleLoops {
            reeb: None,
            cross: None,
            ..l
        };
        assert_eq!(basis_kind(&none, &a), LoopKind::Basis);
    }

    /// The last resort closes a handle from its two basis curves alone (no Reeb or cross loop
    /// known): a torus's outer equator and the meridian crossing it once. In every mode, with
    /// the operation the mode allows (cutting the tube or filling the hole), the wall takes the
    /// torus to genus 0 and leaves it one component with no cavity.
    #[test]
    fn the_basis_curves_alone_close_a_torus() {
        let torus = || crate::test_shapes::torus(24, 7.0, 2.6);
        let affine = Affine::from_spacing([1.0; 3], [0.0; 3]);
        for conn in [Connectivity::Six, Connectivity::TwentySix] {
            let vol = torus();
            let mut g = Graph::new(&vol, cases(conn));
            let (equator, meridian) = crate::surface::search::torus_equator_and_meridian(&mut g);
            let l = HandleLoops {
                reeb: None,
                cross: None,
                exact: true,
                basis: Some((equator.clone(), meridian.clone())),
                cut_points: None,
            };
            for mode in [Mode::Both, Mode::FillOnly, Mode::CutOnly] {
                let mut opts = SimplifyOptions {
                    mode,
                    ..SimplifyOptions::default()
                };
                opts.surface.connectivity = conn;
                let mut vol = torus();
                let before = vol.genus(conn).unwrap();
                assert_eq!((before.b0, before.b1), (1, 1));
                let (mut graph, mut refused) = (GraphCache::default(), Refused::default());
                let walling = (
                    &mut graph,
                    &mut refused,
                    &Locked::default(),
                    &mut NoCut::default(),
                );
                let closed = close_basis(&mut vol, &opts, &l, &affine, walling, WallReach::Across)
                    .unwrap_or_else(|| panic!("{conn:?} {mode:?}: not closed"));
                assert_eq!(closed.applied.handles, 1, "{conn:?} {mode:?}");
                assert!(mode.allows(closed.applied.op), "{conn:?} {mode:?}");
                assert_eq!(closed.which, LoopKind::Basis);
                let after = vol.genus(conn).unwrap();
                assert_eq!(
                    (after.b0, after.b1, after.b2),
                    (1, 0, 0),
                    "{conn:?} {mode:?}"
                );
            }
        }
    }

    /// Gathered once for the thinnest fan, the samples near the fan are gathered again as far
    /// as a wider wall needs: every call gives what a fresh gathering to that reach gives.
    #[test]
    fn samples_near_the_fan_reach_as_far_as_each_wall_needs() {
        let points: Vec<[f64; 3]> = (0..24)
            .map(|k| {
                let t = k as f64 / 24.0 * std::f64::consts::TAU;
                [10.0 + 6.0 * t.cos(), 10.5 + 6.0 * t.sin(), 8.5]
            })
            .collect();
        let fresh = |d: f64| closure::NearFan::new(&points, d).within(d);
        let mut near = NearFanSamples {
            points: &points,
            near: None,
        };
        let widest = PEEL_REACH[PEEL_REACH.len() - 1];
        let reaches = [
            0.5,
            MAX_FAN_THICKNESS,
            PEEL_REACH[0],
            widest,
            1.0,
            widest + 2.0,
        ];
        for d in reaches {
            assert_eq!(near.within(d), fresh(d), "reach {d}");
        }
        assert!(fresh(widest).len() > fresh(MAX_FAN_THICKNESS).len());
    }

    fn names(walls: &[Wall]) -> Vec<String> {
        walls.iter().map(|w| format!("{w:?}")).collect()
    }

    /// The peeled walls in the documented order: regions near the fan at each reach, then the
    /// box round the loop with margin 2, then with a quarter of the loop (at least 4); each with
    /// its 8 cuts.
    fn peeled(wide: i64) -> Vec<String> {
        let mut out = Vec::new();
        for d in ["1.5", "3.0", "5.0"] {
            out.extend((0..8).map(|k| format!("Peel({d}, {k})")));
        }
        for m in [2, wide] {
            out.extend((0..8).map(|k| format!("PeelBox({m}, {k})")));
        }
        out
    }

    #[test]
    fn walls_across_a_loop_come_in_the_documented_order() {
        let square = x_edges(&[[4, 4, 4], [4, 5, 4], [5, 4, 4], [5, 5, 4]]);
        for (op, conn) in [
            (Operation::Collapse, Connectivity::Six),
            (Operation::Pinch, Connectivity::Six),
            (Operation::Collapse, Connectivity::TwentySix),
        ] {
            let base = base_thickness(op, conn);
            for length in [4, 8, 9, 40] {
                let lp = a_loop(square.clone(), length);
                let walls = walls_for(&lp, op, conn, &[], WallReach::Across);
                // Fans first, thicker and thicker.
                for (w, extra) in walls.iter().zip([0.0, 0.5, 1.0]) {
                    let Wall::Fan(d) = *w else {
                        panic!("{w:?} is not a fan")
                    };
                    assert!((d - base - extra).abs() < 1e-12 && d <= MAX_FAN_THICKNESS);
                }
                // Single samples only for loops of at most 8 edges.
                let singles = match length <= 8 {
                    true => closure::single_sample_walls(&square, SINGLE_SAMPLE_REACH),
                    false => Vec::new(),
                };
                let rest = &walls[3..];
                assert_eq!(
                    names(&rest[..singles.len()]),
                    names(&singles.iter().map(|&q| Wall::Single(q)).collect::<Vec<_>>())
                );
                let wide = (length as i64 / 4).max(4);
                assert_eq!(
                    names(&rest[singles.len()..]),
                    peeled(wide),
                    "length {length}"
                );
            }
        }
        assert!(!closure::single_sample_walls(&square, SINGLE_SAMPLE_REACH).is_empty());
        assert_eq!(names(&[Wall::Fan(0.5)]), ["Fan(0.5)"]);
    }

    /// The thickest fan is what the samples near the fan are first gathered for.
    #[test]
    fn the_thickest_fan_is_max_fan_thickness() {
        let lp = a_loop(x_edges(&[[0, 0, 0]]), 40);
        let mut thickest: f64 = 0.0;
        for op in [Operation::Collapse, Operation::Pinch] {
            for conn in [Connectivity::Six, Connectivity::TwentySix] {
                for w in walls_for(&lp, op, conn, &[], WallReach::Across) {
                    if let Wall::Fan(d) = w {
                        thickest = thickest.max(d);
                    }
                }
            }
        }
        assert!((thickest - MAX_FAN_THICKNESS).abs() < 1e-12, "{thickest}");
    }

    #[test]
    fn walls_along_the_partner_need_a_partner() {
        let lp = a_loop(x_edges(&[[0, 0, 0]]), 40);
        let (op, conn) = (Operation::Pinch, Connectivity::Six);
        assert!(walls_for(&lp, op, conn, &[], WallReach::Along).is_empty());
        let partner = x_edges(&[[0, 0, 0], [0, 1, 0]]);
        let mut want = Vec::new();
        for m in [2, 10] {
            for j in 1..8 {
                want.extend((0..8).map(|k| format!("PeelAlong({j}, {m}, {k})")));
            }
        }
        assert_eq!(
            names(&walls_for(&lp, op, conn, &partner, WallReach::Along)),
            want
        );
    }

    /// A `peeled_along` wall's box is the loop's box moved by whole samples, never further than
    /// the partner's step from where it crosses the loop: the loop's points and the partner's are
    /// edge midpoints, and a shift by half a sample would grow the box by one on that axis (the
    /// embryo cut at connectivity 26 had such a wall spread over six planes, its loop's box five).
    #[test]
    fn a_box_moved_along_the_partner_is_the_loops_box_moved_by_whole_samples() {
        let vol = MaskVolume::new([40, 40, 40], Frame::identity());
        // A square loop of x and y edges in the plane z = 10, and a partner of x, y and z edges
        // through its vertex (10.5, 10, 10), climbing and turning so every step is half a sample
        // off on some axis.
        let edges = |list: &[([i64; 3], u8)]| -> Vec<Vertex> {
            list.iter().map(|&(p, axis)| Vertex { p, axis }).collect()
        };
        let lp = edges(&[
            ([10, 10, 10], 0),
            ([11, 10, 10], 1),
            ([11, 11, 10], 1),
            ([10, 12, 10], 0),
            ([9, 11, 10], 1),
            ([9, 10, 10], 1),
        ]);
        let partner = edges(&[
            ([10, 10, 10], 0),
            ([10, 10, 10], 2),
            ([10, 10, 11], 1),
            ([10, 11, 11], 2),
            ([10, 11, 12], 0),
            ([11, 11, 12], 2),
            ([11, 11, 13], 1),
            ([11, 12, 13], 0),
        ]);
        let points: Vec<[f64; 3]> = lp.iter().map(|v| v.midpoint()).collect();
        let centre = peel_centre(&points, &partner);
        assert_eq!(centre, [10.5, 10.0, 10.0]);
        let (_, home) = box_region(&vol, &points, PEEL_BOX_MARGIN);
        for j in 1..PEEL_ALONG {
            let (moved, at) = moved_along(&points, centre, &partner, j);
            let (_, b) = box_region(&vol, &moved, PEEL_BOX_MARGIN);
            for k in 0..3 {
                let shift = b.min[k] - home.min[k];
                assert_eq!(
                    b.max[k] - home.max[k],
                    shift,
                    "step {j}, axis {k}: {b:?} {home:?}"
                );
                assert!(
                    shift.abs() as f64 <= (at[k] - centre[k]).abs(),
                    "step {j}, axis {k}"
                );
                assert!(b.min[k] as f64 <= at[k] && at[k] <= b.max[k] as f64);
            }
        }
    }

    #[test]
    fn a_box_region_is_the_points_box_grown_and_clamped_to_the_volume() {
        let vol = MaskVolume::new([20, 20, 20], Frame::identity());
        let (region, b) = box_region(&vol, &[[5.5, 6.0, 7.25]], 2);
        assert_eq!((b.min, b.max), ([3, 4, 5], [8, 8, 10]));
        assert_eq!(region.len(), 6 * 5 * 6);
        assert!(region
            .iter()
            .all(|p| (0..3).all(|k| b.min[k] <= p[k] && p[k] <= b.max[k])));
        // Near a corner: the box as computed, the region within the volume.
        let (region, b) = box_region(&vol, &[[0.5, 0.5, 19.5]], 3);
        assert_eq!((b.min, b.max), ([-3, -3, 16], [4, 4, 23]));
        assert_eq!(region.len(), 5 * 5 * 4);
        assert!(region.contains(&[0, 0, 19]) && region.contains(&[4, 4, 16]));
        // At most MAX_PEEL_BOX samples.
        let vol = MaskVolume::new([128, 128, 65], Frame::identity());
        let (region, _) = box_region(&vol, &[[0.0, 0.0, 1.0], [127.0, 127.0, 64.0]], 0);
        assert_eq!(region.len(), MAX_PEEL_BOX);
        let (region, b) = box_region(&vol, &[[0.0, 0.0, 0.0], [127.0, 127.0, 64.0]], 0);
        assert!(region.is_empty());
        assert_eq!(b.max, [127, 127, 64]);
    }

    #[test]
    fn the_ring_is_looked_for_round_the_loop_and_its_partner() {
        let points = [[1.5, 2.0, 3.0]];
        // The partner's edge runs from (4, 2, 3) to (4, 3, 3).
        let partner = [Vertex {
            p: [4, 2, 3],
            axis: 1,
        }];
        let t = peel_target(&points, &partner, 40, BBox::EMPTY);
        assert_eq!((t.lo, t.hi), ([-2, -1, 0], [7, 6, 6]));
        // No partner: a quarter of the loop, at least 3.
        let t = peel_target(&points, &[], 40, BBox::EMPTY);
        assert_eq!((t.lo, t.hi), ([-9, -8, -7], [12, 12, 13]));
        let t = peel_target(&points, &[], 4, BBox::EMPTY);
        assert_eq!((t.lo, t.hi), ([-2, -1, 0], [5, 5, 6]));
        // The peeled region's box is included.
        let region = BBox {
            min: [-5, 0, 1],
            max: [20, 1, 2],
        };
        let t = peel_target(&points, &partner, 40, region);
        assert_eq!((t.lo, t.hi), ([-5, -1, 0], [20, 6, 6]));
    }

    #[test]
    fn peeling_aims_where_the_partner_crosses_and_moves_along_it() {
        let points = [
            [0.5, 0.0, 0.0],
            [5.5, 0.0, 0.0],
            [10.5, 0.0, 0.0],
            [5.5, 4.0, 0.0],
        ];
        let partner = [Vertex {
            p: [5, 1, 0],
            axis: 1,
        }];
        assert_eq!(peel_centre(&points, &partner), [5.5, 0.0, 0.0]);
        assert_eq!(peel_centre(&points, &[]), [5.5, 1.0, 0.0]);
        // A partner of 8 edges along y; the crossing nearest its third.
        let partner: Vec<Vertex> = (0..8)
            .map(|y| Vertex {
                p: [5, y, 0],
                axis: 1,
            })
            .collect();
        let centre = [5.0, 2.4, 0.0];
        let (moved, at) = moved_along(&points, centre, &partner, 0);
        assert_eq!(at, [5.0, 2.5, 0.0]);
        let (moved4, at4) = moved_along(&points, centre, &partner, 4);
        assert_eq!(at4, [5.0, 6.5, 0.0]);
        let (_, at7) = moved_along(&points, centre, &partner, 7);
        assert_eq!(at7, [5.0, 1.5, 0.0], "round the partner");
        // Moved by whole samples: 0.1 and 4.1 along y.
        for (k, p) in points.iter().enumerate() {
            let (a, b) = (moved[k], moved4[k]);
            assert_eq!((a[0], a[1], a[2]), (p[0], p[1], p[2]));
            assert_eq!((b[0], b[1], b[2]), (p[0], p[1] + 4.0, p[2]));
        }
    }

    /// The thickness each wall reports (`Removed::thickness`) and the names the reports count
    /// walls by.
    #[test]
    fn walls_report_their_thickness_and_a_name_each() {
        let walls = [
            (Wall::Fan(1.25), 1.25, "fan"),
            (
                Wall::Single([1, 2, 3]),
                SINGLE_SAMPLE_REACH,
                "single_sample",
            ),
            (Wall::Peel(3.0, 2), 3.0, "peeled"),
            (Wall::PeelBox(7, 0), 7.0, "peeled_box"),
            (Wall::PeelAlong(3, 5, 1), 5.0, "peeled_along"),
        ];
        for (w, thickness, name) in walls {
            assert_eq!((w.thickness(), w.name()), (thickness, name));
        }
        assert_eq!(SINGLE_SAMPLE_REACH, 1.8);
    }
}
