//! Loop closure (paper §2.3): a thin wall spanning a loop, written into the volume.
//!
//! The wall is the set of samples within distance `d` of the triangle fan about the loop's
//! centroid. Filling (collapse: the loop goes round empty space) sets them inside; cutting
//! (pinch: the loop goes round material) sets them outside. The wall must stop paths of the
//! *other* side (docs/ARCHITECTURE.md, closing a loop): any step between two samples on opposite sides of the fan passes
//! within half its length of the fan, so `d = 1/2` stops 6-adjacent paths and `d = √3/2` stops
//! 26-adjacent ones.
//!
//! ```text
//!        loop (on the surface)              the fan about its centroid c, and the samples
//!      x---x---x                            within d of it: a wall across the tunnel
//!     /    |    \                           (fill) or across the bar (cut)
//!    x-----c-----x
//!     \    |    /
//!      x---x---x
//! ```
//!
//! Each closure is verified before it is kept, locally and exactly: the surface pieces it touches
//! all belong to the loop's surface (so no other surface changes), the surface's Euler
//! characteristic rises by a positive multiple of 2 (handles less), and the new surface around
//! the wall is one connected piece (so the surface does not fall apart, and the solid keeps its
//! components and cavities). Otherwise the volume is restored.

mod peel;

pub(crate) use peel::flip_simple;
pub use peel::{peel_walls, PeelTarget};

use crate::grid::MaskVolume;
use crate::surface::geometry::centroid;
use crate::surface::search::{Everywhere, FastMap, Graph, GraphCache, InBox, Reach, Region};
use crate::surface::{vertex_of, PieceRef, Vertex};
use crate::topology::cases::{cases, Connectivity};
use crate::volume::BBox;

/// What a closure does to the handle.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Operation {
    /// Fill: the loop goes round empty space; the wall is set inside.
    Collapse,
    /// Cut: the loop goes round material; the wall is set outside.
    Pinch,
}

impl Operation {
    /// State the wall's samples are set to.
    pub fn target(self) -> bool {
        self == Operation::Collapse
    }
}

/// The other operation.
pub fn opposite(op: Operation) -> Operation {
    match op {
        Operation::Collapse => Operation::Pinch,
        Operation::Pinch => Operation::Collapse,
    }
}

/// The wall's base half-thickness: enough to stop the adjacency of the side it separates.
pub fn base_thickness(op: Operation, conn: Connectivity) -> f64 {
    // Filling stops outside paths; cutting stops inside paths.
    let stops_26 = match (op, conn) {
        (Operation::Collapse, Connectivity::Six) => true, // outside is 26-adjacent
        (Operation::Pinch, Connectivity::TwentySix) => true, // inside is 26-adjacent
        _ => false,
    };
    if stops_26 {
        3f64.sqrt() / 2.0
    } else {
        0.5
    }
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Squared distance from `p` to the triangle (a, b, c) (closest point by regions, as in
/// Ericson's *Real-Time Collision Detection*).
pub fn point_triangle_dist2(p: [f64; 3], a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> f64 {
    let (ab, ac, ap) = (sub(b, a), sub(c, a), sub(p, a));
    let (d1, d2) = (dot(ab, ap), dot(ac, ap));
    let closest = if d1 <= 0.0 && d2 <= 0.0 {
        a
    } else {
        let bp = sub(p, b);
        let (d3, d4) = (dot(ab, bp), dot(ac, bp));
        if d3 >= 0.0 && d4 <= d3 {
            b
        } else {
            let vc = d1 * d4 - d3 * d2;
            if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
                let v = d1 / (d1 - d3);
                [a[0] + v * ab[0], a[1] + v * ab[1], a[2] + v * ab[2]]
            } else {
                let cp = sub(p, c);
                let (d5, d6) = (dot(ab, cp), dot(ac, cp));
                if d6 >= 0.0 && d5 <= d6 {
                    c
                } else {
                    let vb = d5 * d2 - d1 * d6;
                    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
                        let w = d2 / (d2 - d6);
                        [a[0] + w * ac[0], a[1] + w * ac[1], a[2] + w * ac[2]]
                    } else {
                        let va = d3 * d6 - d5 * d4;
                        if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
                            let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
                            let bc = sub(c, b);
                            [b[0] + w * bc[0], b[1] + w * bc[1], b[2] + w * bc[2]]
                        } else {
                            let denom = 1.0 / (va + vb + vc);
                            let (v, w) = (vb * denom, vc * denom);
                            [
                                a[0] + ab[0] * v + ac[0] * w,
                                a[1] + ab[1] * v + ac[1] * w,
                                a[2] + ab[2] * v + ac[2] * w,
                            ]
                        }
                    }
                }
            }
        }
    };
    let d = sub(p, closest);
    dot(d, d)
}

/// The samples near a loop's spanning fan with their distances to it, computed once for the
/// several walls (of growing thickness) tried across one loop.
pub struct NearFan {
    /// How far from the fan the samples were gathered.
    pub reach: f64,
    samples: Vec<([i64; 3], f64)>,
}

impl NearFan {
    /// The samples within `reach` of the fan spanning the closed polyline `points`.
    pub fn new(points: &[[f64; 3]], reach: f64) -> NearFan {
        let c = centroid(points);
        let r2 = reach * reach + 1e-9;
        let mut near: FastMap<[i64; 3], f64> = FastMap::default();
        for i in 0..points.len() {
            let (a, b) = (points[i], points[(i + 1) % points.len()]);
            let lo: [i64; 3] =
                std::array::from_fn(|k| (a[k].min(b[k]).min(c[k]) - reach).floor() as i64);
            let hi: [i64; 3] =
                std::array::from_fn(|k| (a[k].max(b[k]).max(c[k]) + reach).ceil() as i64);
            for z in lo[2]..=hi[2] {
                for y in lo[1]..=hi[1] {
                    for x in lo[0]..=hi[0] {
                        let p = [x as f64, y as f64, z as f64];
                        let d2 = point_triangle_dist2(p, c, a, b);
                        if d2 <= r2 {
                            let e = near.entry([x, y, z]).or_insert(d2);
                            *e = e.min(d2);
                        }
                    }
                }
            }
        }
        let mut samples: Vec<([i64; 3], f64)> = near.into_iter().collect();
        samples.sort_by_key(|s| s.0);
        NearFan { reach, samples }
    }

    /// The samples within `d` (at most the reach) of the fan, sorted.
    pub fn within(&self, d: f64) -> Vec<[i64; 3]> {
        debug_assert!(d <= self.reach);
        let d2 = d * d + 1e-9;
        self.samples
            .iter()
            .filter(|s| s.1 <= d2)
            .map(|s| s.0)
            .collect()
    }
}

/// A closure that was kept.
#[derive(Clone, Debug)]
pub struct Applied {
    pub(crate) op: Operation,
    /// Samples whose state was flipped (volume-local coordinates).
    pub changed: Vec<[i64; 3]>,
    /// Handles it removed (usually 1; a wall across two tiny neighbouring handles removes both).
    pub handles: usize,
}

/// Vertices a connectivity check may visit before it gives up (and the closure is refused).
const CONNECT_BUDGET: usize = 1 << 22;

/// Cubes (lower corners) with a corner among the given samples.
fn touched_cubes(samples: &[[i64; 3]]) -> Vec<[i64; 3]> {
    let mut set: FastMap<[i64; 3], ()> = FastMap::default();
    for q in samples {
        for dz in 0..2 {
            for dy in 0..2 {
                for dx in 0..2 {
                    set.insert([q[0] - dx, q[1] - dy, q[2] - dz], ());
                }
            }
        }
    }
    let mut v: Vec<[i64; 3]> = set.into_keys().collect();
    v.sort();
    v
}

/// The pieces of the given cubes: (cube, corner group, boundary loops), in a fixed order.
type PieceKey = ([i64; 3], u8, Vec<Vec<u8>>);

fn pieces_in(vol: &MaskVolume, conn: Connectivity, cubes: &[[i64; 3]]) -> Vec<(PieceKey, i64)> {
    let table = cases(conn);
    let mut out = Vec::new();
    for &q in cubes {
        let case = &table[crate::surface::cube_case(vol, q) as usize];
        for (k, piece) in case.pieces.iter().enumerate() {
            out.push(((q, piece.corners, piece.loops.clone()), case.chi4[k] as i64));
        }
    }
    out
}

/// Pieces of `a` not in `b` (a piece with the same corners and loops is the same surface
/// patch), as one vertex each, and their summed `chi4`. Both lists are in the order of their
/// cubes (as [`pieces_in`] makes them from sorted cubes), so each piece is looked for among
/// its own cube's pieces in `b` only (a scan of all of `b` for each piece was an eighth of the
/// embryo's `--tau inf`: a peeled wall touches thousands of cubes).
fn only_in(a: &[(PieceKey, i64)], b: &[(PieceKey, i64)]) -> (Vec<Vertex>, i64) {
    debug_assert!(a.is_sorted_by_key(|x| x.0 .0) && b.is_sorted_by_key(|x| x.0 .0));
    let mut verts = Vec::new();
    let mut chi4 = 0;
    let mut from = 0;
    for (p, c) in a {
        while from < b.len() && b[from].0 .0 < p.0 {
            from += 1;
        }
        let mut same_cube = b[from..].iter().take_while(|(x, _)| x.0 == p.0);
        if !same_cube.any(|(x, _)| x == p) {
            verts.push(vertex_of(p.0, p.2[0][0]));
            chi4 += c;
        }
    }
    (verts, chi4)
}

/// Cubes round a loop's vertices ([`Tube::thin`]: the eight that hold each; [`Tube::new`]:
/// those within two), and a box: where the two sides of a wall are likely joined. A wall
/// across one loop of a handle cuts the handle's other loop once, so the rest of that loop
/// joins the wall's two sides.
///
/// ```text
///        wall
///    ====|====      the other loop goes round the handle and comes back to the
///   /    |    \     wall's other side: a search along it finds the way round
///   \____|____/     without exploring the whole surface
/// ```
///
/// The cubes are gathered the first time the tube is searched in: most walls are checked
/// within their box alone, and round a long loop they are tens of thousands (on 128³ noise,
/// gathering them for every wall tried was a twentieth of `simplify`).
struct Tube<'l> {
    lp: &'l [Vertex],
    /// The offsets, along each axis, of the cubes taken round each vertex of the loop.
    offsets: std::ops::RangeInclusive<i64>,
    cubes: std::cell::OnceCell<FastMap<[i64; 3], ()>>,
    lo: [i64; 3],
    hi: [i64; 3],
}

impl Tube<'_> {
    /// The cubes within two of the loop's vertices.
    fn new(lp: &[Vertex], lo: [i64; 3], hi: [i64; 3]) -> Tube<'_> {
        Tube::with_offsets(lp, lo, hi, -2..=2)
    }

    /// Only the eight cubes that hold each vertex of the loop (its edge is one of theirs): the
    /// loop's own steps, about a tenth of [`Tube::new`]'s cubes, and enough wherever the loop
    /// is still on the surface beyond the box.
    fn thin(lp: &[Vertex], lo: [i64; 3], hi: [i64; 3]) -> Tube<'_> {
        Tube::with_offsets(lp, lo, hi, -1..=0)
    }

    fn with_offsets(
        lp: &[Vertex],
        lo: [i64; 3],
        hi: [i64; 3],
        offsets: std::ops::RangeInclusive<i64>,
    ) -> Tube<'_> {
        Tube {
            lp,
            offsets,
            cubes: std::cell::OnceCell::new(),
            lo,
            hi,
        }
    }

    fn cubes(&self) -> &FastMap<[i64; 3], ()> {
        self.cubes.get_or_init(|| {
            let mut cubes = FastMap::default();
            // Consecutive vertices are a step apart: most of a vertex's cubes were its
            // predecessor's too, and only the others are inserted.
            let mut prev: Option<[i64; 3]> = None;
            let d = self.offsets.clone();
            for v in self.lp {
                for dz in d.clone() {
                    for dy in d.clone() {
                        for dx in d.clone() {
                            let c = [v.p[0] + dx, v.p[1] + dy, v.p[2] + dz];
                            if prev.is_some_and(|q| (0..3).all(|k| d.contains(&(c[k] - q[k])))) {
                                continue;
                            }
                            cubes.insert(c, ());
                        }
                    }
                }
                prev = Some(v.p);
            }
            cubes
        })
    }
}

impl Region for Tube<'_> {
    fn allows(&self, p: &PieceRef) -> bool {
        (0..3).all(|k| self.lo[k] <= p.cube[k] && p.cube[k] <= self.hi[k])
            || self.cubes().contains_key(&p.cube)
    }
}

/// Is every one of `others` on the same surface as `from`? Searched near first, then over the
/// whole surface on a small budget, then along the handle's other loop (in its own cubes, then
/// within two of it); then over the whole surface from both ends ([`joined_everywhere`]) with
/// budgets growing fourfold, so a piece on a small separate surface is told apart at the cost
/// of that small surface, not of the large one.
/// (A path found within a region is a path on the surface, so only "no" needs the whole search.)
fn joined(
    g: &mut Graph,
    from: &[Vertex],
    others: &[Vertex],
    near: &dyn Region,
    along: &[Tube],
) -> bool {
    if g.reach(from, others, None, near, usize::MAX) == Reach::Reached {
        return true;
    }
    // A first look everywhere, on a small budget, before the tubes: most walls the box does
    // not join are not joined at all (a small piece closed off), which this shows at once
    // where the tubes were searched in vain first (on noise, 386 µs a wall).
    let mut budget = 1 << 10;
    if let Some(answer) = joined_everywhere(g, from, others, budget) {
        return answer;
    }
    for tube in along.iter().filter(|t| !t.lp.is_empty()) {
        if g.reach(from, others, None, tube, usize::MAX) == Reach::Reached {
            return true;
        }
    }
    while budget < CONNECT_BUDGET {
        budget *= 4;
        if let Some(answer) = joined_everywhere(g, from, others, budget) {
            return answer;
        }
    }
    false
}

/// Whether `others` are all joined to `from` on the whole surface, found within `budget`
/// vertices a search (`None`: not known yet). Searched from `from`, then back from a few
/// targets not met, each until it meets what the first search reached: a target whose search
/// runs dry first is not joined; when every one meets it, all are (searched from both ends,
/// two vertices far apart are found joined half way).
fn joined_everywhere(
    g: &mut Graph,
    from: &[Vertex],
    others: &[Vertex],
    budget: usize,
) -> Option<bool> {
    let (reach, left) = g.reach_targets(from, others, None, &Everywhere, budget);
    match reach {
        Reach::Reached => return Some(true),
        Reach::Exhausted => return Some(false),
        Reach::Budget => {}
    }
    let forward = g.last_search();
    let mut all_met = left.len() <= REVERSE_SEARCHES;
    for &p in left.iter().take(REVERSE_SEARCHES) {
        match g.meets(p, forward, &Everywhere, budget) {
            Reach::Exhausted => return Some(false),
            Reach::Reached => {}
            Reach::Budget => all_met = false,
        }
    }
    all_met.then_some(true)
}

/// Targets a connectivity check searches back from, at each budget.
const REVERSE_SEARCHES: usize = 8;

/// Sets the samples to `inside` and keeps the graph's neighbourhoods up to date.
fn flip(
    vol: &mut MaskVolume,
    cache: &mut GraphCache,
    samples: &[[i64; 3]],
    inside: bool,
    conn: Connectivity,
) {
    let mut b = BBox::EMPTY;
    for q in samples {
        vol.set(q[0] as usize, q[1] as usize, q[2] as usize, inside);
        b.include(*q);
    }
    cache.invalidate(vol, cases(conn), b.min, b.max);
}

/// Samples within `reach` of the centroid of a short loop, each of which alone may be a wall:
/// where a handle is a single corner contact, the fan's own wall can take the wrong one of the
/// two samples that touch (and cut off a spur), while the other one works.
pub fn single_sample_walls(lp: &[Vertex], reach: f64) -> Vec<[i64; 3]> {
    let points: Vec<[f64; 3]> = lp.iter().map(|v| v.midpoint()).collect();
    let c = centroid(&points);
    let mut out = Vec::new();
    let r = reach.ceil() as i64;
    let base: [i64; 3] = c.map(|x| x.round() as i64);
    for dz in -r..=r {
        for dy in -r..=r {
            for dx in -r..=r {
                let q = [base[0] + dx, base[1] + dy, base[2] + dz];
                let d2: f64 = (0..3).map(|k| (q[k] as f64 - c[k]).powi(2)).sum();
                if d2 <= reach * reach {
                    out.push((d2, q));
                }
            }
        }
    }
    out.sort_by(|a, b| a.0.total_cmp(&b.0));
    out.into_iter().map(|(_, q)| q).collect()
}

/// A wall to try across a loop (all in the volume's local coordinates).
pub struct Attempt<'a> {
    /// The loop, and a loop crossing it once (empty if none is known).
    pub lp: &'a [Vertex],
    pub partner: &'a [Vertex],
    pub(crate) op: Operation,
    /// The samples to set to `op`'s side: [`wall`] across the loop's fan, single samples, or a
    /// peeled wall.
    pub wall: Vec<[i64; 3]>,
    /// Is the wall known to remove one handle and change no component or cavity ([`peel_walls`]:
    /// simple flips but one, which cuts a ring)? Then it may also reshape other surfaces
    /// nearby (their topology cannot change), and only the count of handles is checked.
    pub certified: bool,
}

/// Writes the attempt's wall into the mask and keeps it if it removes handles of the loop's
/// surface only, and at least one; else restores the mask.
///
/// Why the checks suffice: cubes with no flipped corner keep their pieces, and so do pieces of
/// touched cubes whose corners and loops stay the same; only the others change. If some pieces
/// go, every piece that goes lies on the loop's surface S, and the pieces that come are all
/// connected, the rest of S hangs on them (it met the pieces that went at crossing points that
/// are still there), so S stays one surface and the others are untouched; its Euler
/// characteristic, a sum over pieces, then says how many handles went.
///
/// `cache` holds the surface graph's neighbourhoods of `vol`, and is kept up to date.
pub fn close(
    vol: &mut MaskVolume,
    conn: Connectivity,
    attempt: Attempt,
    cache: &mut GraphCache,
) -> Result<Applied, Refusal> {
    let Attempt {
        lp,
        partner,
        op,
        wall,
        certified,
    } = attempt;
    let target = op.target();
    let changed: Vec<[i64; 3]> = wall
        .into_iter()
        .filter(|&q| vol.contains(q))
        .filter(|q| vol.get(q[0], q[1], q[2]) != target)
        .collect();
    if changed.is_empty() {
        return Err(Refusal::NothingToChange);
    }
    let cubes = touched_cubes(&changed);
    let table = cases(conn);
    let before = pieces_in(vol, conn, &cubes);
    let lo = cubes.iter().fold([i64::MAX; 3], |m, q| {
        [m[0].min(q[0]), m[1].min(q[1]), m[2].min(q[2])]
    });
    let hi = cubes.iter().fold([i64::MIN; 3], |m, q| {
        [m[0].max(q[0]), m[1].max(q[1]), m[2].max(q[2])]
    });
    let (lo2, hi2) = (lo.map(|x| x - 2), hi.map(|x| x + 2));
    let near = InBox::cubes(lo2, hi2);
    let along = [Tube::thin(partner, lo2, hi2), Tube::new(partner, lo2, hi2)];
    for q in &changed {
        vol.set(q[0] as usize, q[1] as usize, q[2] as usize, target);
    }
    let after = pieces_in(vol, conn, &cubes);
    let (new_pieces, new_chi4) = only_in(&after, &before);
    for q in &changed {
        vol.set(q[0] as usize, q[1] as usize, q[2] as usize, !target);
    }
    // Only pieces that change matter: a wall may brush another surface's piece without changing it.
    let (old_pieces, old_chi4) = only_in(&before, &after);
    // A wall that changes none of the surface's pieces (a sample set apart from it) would make a
    // new surface of its own, however the counts come out.
    if old_pieces.is_empty() {
        return Err(Refusal::OffTheSurface);
    }
    let handles = (new_chi4 - old_chi4) / 8;
    if handles < 1 || (new_chi4 - old_chi4) % 8 != 0 {
        return Err(Refusal::EulerCharacteristic);
    }
    let mut g = Graph::with_cache(vol, table, std::mem::take(cache));
    let same_surface = certified || joined(&mut g, lp, &old_pieces, &near, &along);
    *cache = g.into_cache();
    if !same_surface {
        return Err(Refusal::OtherSurface);
    }
    flip(vol, cache, &changed, target, conn);
    let mut g = Graph::with_cache(vol, table, std::mem::take(cache));
    let ok = certified
        || !new_pieces.is_empty() && joined(&mut g, &new_pieces[..1], &new_pieces, &near, &along);
    *cache = g.into_cache();
    if !ok {
        flip(vol, cache, &changed, !target, conn);
        return Err(Refusal::FallsApart);
    }
    Ok(Applied {
        op,
        changed,
        handles: handles as usize,
    })
}

/// Why [`close`] did not keep a wall (the volume is as it was).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Refusal {
    /// Every sample of the wall is already on the wall's side.
    NothingToChange,
    /// The wall changes no piece of the surface (it would make a surface of its own).
    OffTheSurface,
    /// The surface's Euler characteristic would not rise by a positive multiple of 2.
    EulerCharacteristic,
    /// The wall changes a piece of another surface.
    OtherSurface,
    /// The surface round the wall would fall apart.
    FallsApart,
}

impl Refusal {
    /// As the reports spell it.
    pub fn name(self) -> &'static str {
        match self {
            Refusal::NothingToChange => "nothing_to_change",
            Refusal::OffTheSurface => "off_the_surface",
            Refusal::EulerCharacteristic => "euler_characteristic",
            Refusal::OtherSurface => "other_surface",
            Refusal::FallsApart => "falls_apart",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The single samples are those within the reach of the loop's centroid, nearest first.
    /// Round a unit square of x edges (centroid (5, 4.5, 4)) the squared distances are
    /// dx² + dz² + (y - 4.5)²: within 1.8 (3.24) lie 2 samples at 0.25, 8 at 1.25, 10 at 2.25;
    /// the 8 at 3.25 do not.
    #[test]
    fn single_sample_walls_lie_within_the_reach_nearest_first() {
        let square: Vec<Vertex> = [[4, 4, 4], [4, 5, 4], [5, 4, 4], [5, 5, 4]]
            .iter()
            .map(|&p| Vertex { p, axis: 0 })
            .collect();
        let got = single_sample_walls(&square, 1.8);
        let d2 = |q: &[i64; 3]| {
            let d = [q[0] as f64 - 5.0, q[1] as f64 - 4.5, q[2] as f64 - 4.0];
            d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
        };
        let rings: Vec<f64> = got.iter().map(d2).collect();
        let count = |r: f64| rings.iter().filter(|&&x| x == r).count();
        assert_eq!(
            (count(0.25), count(1.25), count(2.25)),
            (2, 8, 10),
            "{rings:?}"
        );
        assert_eq!(got.len(), 20, "{rings:?}");
        assert!(rings.windows(2).all(|w| w[0] <= w[1]), "nearest first");
    }

    /// A thin tube holds exactly the eight cubes round each vertex of its loop, a wide one those
    /// within two; and the thin one is enough to walk the whole loop (round a torus's hole, its
    /// outer equator) with no box at all, in about a tenth of the wide one's cubes.
    #[test]
    fn a_thin_tube_holds_its_loops_steps() {
        let vol = crate::test_shapes::torus(24, 7.0, 2.6);
        for conn in [Connectivity::Six, Connectivity::TwentySix] {
            let mut g = Graph::new(&vol, cases(conn));
            let (equator, _) = crate::surface::search::torus_equator_and_meridian(&mut g);
            assert!(equator.len() > 40, "{}", equator.len());
            let no_box = ([1; 3], [0; 3]);
            let (thin, wide) = (
                Tube::thin(&equator, no_box.0, no_box.1),
                Tube::new(&equator, no_box.0, no_box.1),
            );
            let within = |c: &[i64; 3], d: std::ops::RangeInclusive<i64>| {
                equator
                    .iter()
                    .any(|v| (0..3).all(|k| d.contains(&(c[k] - v.p[k]))))
            };
            let all = |d: i64| -> Vec<[i64; 3]> {
                let r = -d - 1..=d + 1;
                let mut out = Vec::new();
                for z in r.clone() {
                    for y in r.clone() {
                        for x in r.clone() {
                            out.extend(
                                equator.iter().map(|v| [v.p[0] + x, v.p[1] + y, v.p[2] + z]),
                            );
                        }
                    }
                }
                out
            };
            for c in all(2) {
                assert_eq!(thin.cubes().contains_key(&c), within(&c, -1..=0), "{c:?}");
                assert_eq!(wide.cubes().contains_key(&c), within(&c, -2..=2), "{c:?}");
            }
            let (n_thin, n_wide) = (thin.cubes().len(), wide.cubes().len());
            assert!(5 * n_thin < n_wide, "{n_thin} of {n_wide}");
            let got = g.reach(&equator[..1], &equator, None, &thin, usize::MAX);
            assert_eq!(got, Reach::Reached);
            // Nor is the box needed: without the tube's cubes, a box that holds no cube stops
            // the search at once.
            let empty = InBox::cubes(no_box.0, no_box.1);
            let got = g.reach(&equator[..1], &equator, None, &empty, usize::MAX);
            assert_ne!(got, Reach::Reached);
        }
    }

    /// The base half-thickness stops the adjacency of the side a wall separates: across a
    /// plane, no two samples adjacent by that side's rule (26 for the outside when filling under
    /// connectivity 6 and the inside when cutting under 26; else 6) lie farther than it on
    /// either side. Random planes; and each thickness is the least that does so (a plane
    /// normal to a cube's diagonal, or to an axis).
    #[test]
    fn a_walls_base_thickness_stops_its_sides_adjacency() {
        let mut rng = crate::test_rng::Rng(0x2545_f491_4f6c_dd1d);
        let mut next = || rng.unit() * 2.0 - 1.0;
        let offsets = |twenty_six: bool| -> Vec<[f64; 3]> {
            (0..27)
                .map(|k| [k % 3, (k / 3) % 3, k / 9].map(|x| x as f64 - 1.0))
                .filter(|o| {
                    let n = o.iter().filter(|&&x| x != 0.0).count();
                    n > 0 && (twenty_six || n == 1)
                })
                .collect()
        };
        // Whether some adjacent pair lies beyond `t` on both sides of the plane n . p = c.
        let leaks = |n: [f64; 3], c: f64, t: f64, twenty_six: bool| {
            let d = |p: [f64; 3]| n[0] * p[0] + n[1] * p[1] + n[2] * p[2] - c;
            (0..216).any(|k| {
                let p = [k % 6, (k / 6) % 6, k / 36].map(|x| x as f64);
                offsets(twenty_six).iter().any(|o| {
                    let q = [p[0] + o[0], p[1] + o[1], p[2] + o[2]];
                    d(p) > t && d(q) < -t
                })
            })
        };
        for op in [Operation::Collapse, Operation::Pinch] {
            for conn in [Connectivity::Six, Connectivity::TwentySix] {
                // Filling separates the outside, cutting the inside.
                let separated_26 = (op == Operation::Collapse) == (conn == Connectivity::Six);
                let t = base_thickness(op, conn);
                for _ in 0..500 {
                    let n = [next(), next(), next()];
                    let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
                    let n = n.map(|x| x / l);
                    let c = 2.5 + next();
                    assert!(!leaks(n, c, t, separated_26), "{op:?} {conn:?}: {n:?} {c}");
                }
                let (diagonal, axis) = ([1.0 / 3f64.sqrt(); 3], [0.0, 0.0, 1.0]);
                let tight = if separated_26 { diagonal } else { axis };
                let c = if separated_26 { 2.5 * 3f64.sqrt() } else { 2.5 };
                assert!(leaks(tight, c, t - 1e-9, separated_26), "{op:?} {conn:?}");
            }
        }
    }

    /// The pieces a flip changes, found cube by cube, are those a scan of every piece finds:
    /// random masks, a random set of samples flipped, both connectivities.
    #[test]
    fn the_pieces_a_flip_changes_are_found_cube_by_cube() {
        let mut rng = crate::test_rng::Rng(0x6a09_e667_f3bc_c909);
        let scan = |a: &[(PieceKey, i64)], b: &[(PieceKey, i64)]| {
            let only: Vec<&(PieceKey, i64)> = a.iter().filter(|p| !b.contains(p)).collect();
            let verts: Vec<Vertex> = only
                .iter()
                .map(|p| vertex_of(p.0 .0, p.0 .2[0][0]))
                .collect();
            (verts, only.iter().map(|p| p.1).sum::<i64>())
        };
        let mut changed_some = 0;
        for round in 0..300 {
            let conn = [Connectivity::Six, Connectivity::TwentySix][round % 2];
            let percent = 20 + rng.below(60);
            let mut vol = crate::grid::random_mask(&mut rng, 8, percent);
            let flips: Vec<[i64; 3]> = (0..1 + rng.below(12))
                .map(|_| [(); 3].map(|_| rng.below(8) as i64))
                .collect();
            let cubes = touched_cubes(&flips);
            let before = pieces_in(&vol, conn, &cubes);
            for q in &flips {
                let now = vol.get(q[0], q[1], q[2]);
                vol.set(q[0] as usize, q[1] as usize, q[2] as usize, !now);
            }
            let after = pieces_in(&vol, conn, &cubes);
            for (a, b) in [(&after, &before), (&before, &after)] {
                let got = only_in(a, b);
                assert_eq!(got, scan(a, b), "round {round}");
                changed_some += usize::from(!got.0.is_empty() && got.0.len() < a.len());
            }
        }
        assert!(changed_some > 300, "{changed_some}");
    }

    /// The connectivity check answers as one search over the whole surface with no budget
    /// does: random masks (many surfaces, and pieces closed off), random sets of surface
    /// vertices, the box round the first and no tube; and each look on a small budget, when it
    /// answers, answers the same (both ways: targets closed off, and targets met half way).
    #[test]
    fn the_connectivity_check_answers_as_a_whole_search_does() {
        let mut rng = crate::test_rng::Rng(0x3c6e_f372_fe94_f82b);
        let (mut answered, mut met_half_way, mut closed_off) = (0, 0, 0);
        for round in 0..400 {
            let conn = [Connectivity::Six, Connectivity::TwentySix][round % 2];
            let n = 14;
            let percent = [35, 50, 65][round % 3];
            let vol = crate::grid::random_mask(&mut rng, n, percent);
            let mut g = Graph::new(&vol, cases(conn));
            let mut on_surface = |rng: &mut crate::test_rng::Rng| loop {
                let p = [(); 3].map(|_| rng.below(n as u64) as i64);
                let v = Vertex {
                    p,
                    axis: rng.below(3) as u8,
                };
                if g.index(v).is_some() {
                    return v;
                }
            };
            let from = vec![on_surface(&mut rng)];
            let others: Vec<Vertex> = (0..1 + rng.below(4))
                .map(|_| on_surface(&mut rng))
                .collect();
            let whole = g.reach(&from, &others, None, &Everywhere, usize::MAX) == Reach::Reached;
            let p = from[0].p;
            let near = InBox::cubes(p.map(|x| x - 1), p.map(|x| x + 1));
            assert_eq!(
                joined(&mut g, &from, &others, &near, &[]),
                whole,
                "round {round}"
            );
            for budget in [4, 16, 64] {
                let Some(got) = joined_everywhere(&mut g, &from, &others, budget) else {
                    continue;
                };
                assert_eq!(got, whole, "round {round}, budget {budget}");
                answered += 1;
                let forward = g.reach(&from, &others, None, &Everywhere, budget);
                met_half_way += usize::from(got && forward == Reach::Budget);
                closed_off += usize::from(!got && forward == Reach::Budget);
            }
        }
        assert!(
            answered > 200 && met_half_way > 10 && closed_off > 100,
            "{answered} answered, {met_half_way} met half way, {closed_off} closed off"
        );
    }

    /// Where the first look everywhere leaves it open (surfaces of thousands of vertices), the
    /// tubes along a loop decide only "joined", and the check still answers as the whole
    /// search does: two random halves of a volume kept apart by two empty planes, so that a
    /// vertex on one half and one on the other lie on two large surfaces; the tube goes round
    /// the targets.
    #[test]
    fn the_tubes_find_only_what_is_joined() {
        let mut rng = crate::test_rng::Rng(0x1f83_d9ab_fb41_bd6b);
        let (mut apart, mut joined_by_tube_or_later) = (0, 0);
        for round in 0..80 {
            let conn = [Connectivity::Six, Connectivity::TwentySix][round % 2];
            let n = 24;
            let mut vol = crate::grid::random_mask(&mut rng, n, 50);
            for x in [n / 2 - 1, n / 2] {
                for y in 0..n {
                    for z in 0..n {
                        vol.set(x, y, z, false);
                    }
                }
            }
            let mut g = Graph::new(&vol, cases(conn));
            let mut on_surface = |rng: &mut crate::test_rng::Rng, left: bool| loop {
                let half = (n / 2 - 1) as u64;
                let x = rng.below(half) as i64 + if left { 0 } else { n as i64 / 2 + 1 };
                let p = [x, rng.below(n as u64) as i64, rng.below(n as u64) as i64];
                let v = Vertex {
                    p,
                    axis: rng.below(3) as u8,
                };
                if g.index(v).is_some() {
                    return v;
                }
            };
            let from = vec![on_surface(&mut rng, true)];
            let others = vec![on_surface(&mut rng, round % 4 < 2)];
            let whole = g.reach(&from, &others, None, &Everywhere, usize::MAX) == Reach::Reached;
            let p = from[0].p;
            let (lo, hi) = (p.map(|x| x - 1), p.map(|x| x + 1));
            let near = InBox::cubes(lo, hi);
            let along = [Tube::thin(&others, lo, hi), Tube::new(&others, lo, hi)];
            assert_eq!(
                joined(&mut g, &from, &others, &near, &along),
                whole,
                "round {round}"
            );
            // Counted where the first look leaves it open: the tubes are searched.
            if joined_everywhere(&mut g, &from, &others, 1 << 10).is_none() {
                apart += usize::from(!whole);
                joined_by_tube_or_later += usize::from(whole);
            }
        }
        assert!(
            apart > 20 && joined_by_tube_or_later > 5,
            "{apart} apart, {joined_by_tube_or_later} joined"
        );
    }

    #[test]
    fn triangle_distance() {
        let (a, b, c) = ([0.0, 0.0, 0.0], [4.0, 0.0, 0.0], [0.0, 4.0, 0.0]);
        assert_eq!(point_triangle_dist2([1.0, 1.0, 2.0], a, b, c), 4.0);
        assert_eq!(point_triangle_dist2([-1.0, -1.0, 0.0], a, b, c), 2.0);
        assert_eq!(point_triangle_dist2([3.0, 3.0, 0.0], a, b, c), 2.0);
        assert_eq!(point_triangle_dist2([2.0, -3.0, 0.0], a, b, c), 9.0);
    }

    /// Random triangles and points, against the distance computed another way: the nearest of
    /// the point's foot on the plane (when it falls inside, by signed areas) and the nearest
    /// points of the three edges. Every one of the seven regions of the plane is met.
    #[test]
    fn triangle_distance_matches_feet_and_edges() {
        let mut rng = crate::test_rng::Rng(0x9e37_79b9_7f4a_7c15);
        let mut next = || rng.unit() * 8.0 - 4.0;
        let segment = |p: [f64; 3], u: [f64; 3], v: [f64; 3]| {
            let (uv, up) = (sub(v, u), sub(p, u));
            let t = (dot(uv, up) / dot(uv, uv)).clamp(0.0, 1.0);
            let q = [u[0] + t * uv[0], u[1] + t * uv[1], u[2] + t * uv[2]];
            dot(sub(p, q), sub(p, q))
        };
        let cross = |u: [f64; 3], v: [f64; 3]| {
            [
                u[1] * v[2] - u[2] * v[1],
                u[2] * v[0] - u[0] * v[2],
                u[0] * v[1] - u[1] * v[0],
            ]
        };
        let mut regions = std::collections::HashSet::new();
        for _ in 0..20_000 {
            let [a, b, c, p]: [[f64; 3]; 4] = std::array::from_fn(|_| [next(), next(), next()]);
            let n = cross(sub(b, a), sub(c, a));
            if dot(n, n) < 1e-3 {
                continue;
            }
            let h = dot(sub(p, a), n) / dot(n, n);
            let foot = [p[0] - h * n[0], p[1] - h * n[1], p[2] - h * n[2]];
            let sides = [(a, b), (b, c), (c, a)]
                .map(|(u, v)| dot(cross(sub(v, u), sub(foot, u)), n) >= 0.0);
            let mut want = [(a, b), (b, c), (c, a)]
                .iter()
                .map(|&(u, v)| segment(p, u, v))
                .fold(f64::INFINITY, f64::min);
            if sides.iter().all(|&s| s) {
                want = want.min(h * h * dot(n, n));
            }
            let got = point_triangle_dist2(p, a, b, c);
            assert!(
                (got - want).abs() <= 1e-9 * (1.0 + want),
                "{p:?} {a:?} {b:?} {c:?}: {got} vs {want}"
            );
            regions.insert(sides);
        }
        // Inside, beyond one edge (3), beyond two (3): seven sign patterns of the foot.
        assert_eq!(regions.len(), 7);
    }

    /// A flat square loop in the plane z = 5 gives a wall of exactly that plane's samples inside
    /// it, at both thicknesses.
    #[test]
    fn flat_loop_wall_is_one_sample_thick() {
        let pts: Vec<[f64; 3]> = (0..4)
            .flat_map(|i| {
                [
                    [1.5 + i as f64, 1.0, 5.0],
                    [5.0, 1.5 + i as f64, 5.0],
                    [4.5 - i as f64, 5.0, 5.0],
                    [1.0, 4.5 - i as f64, 5.0],
                ]
            })
            .collect();
        let mut ordered = Vec::new();
        for side in 0..4 {
            for i in 0..4 {
                ordered.push(pts[i * 4 + side]);
            }
        }
        for d in [0.5, 3f64.sqrt() / 2.0] {
            let w = NearFan::new(&ordered, d).within(d);
            assert!(w.iter().all(|q| q[2] == 5), "{d}: {w:?}");
            assert!(w.contains(&[3, 3, 5]));
        }
    }
}
