//! Measuring the handles a step of the sweep found, with what is kept between steps and passes
//! so the same loop is not searched twice.

use super::plan::{overlaps, wall_near_loop};
use crate::grid::MaskVolume;
use crate::loops::{self, HandleLoops, Limits, Metric, SliceCache};
use crate::surface::search::{FastMap, Graph, GraphCache};
use crate::sweep::{Handle, HandleKind, LocatedHandle};
use crate::topology::cases::{cases, Connectivity};
use crate::volume::{Affine, BBox};

/// The surface graph's neighbourhoods and the slices' surfels, kept between the steps of the
/// sweep (measuring from scratch costs ten times more) and brought up to date after each wall.
pub(super) struct Caches {
    pub(super) graph: GraphCache,
    pub(super) slices: SliceCache,
    /// Loops measured in this pass, by handle: after a rewind, the sweep finds the handles
    /// above the walls again, and those whose loops lie away from every wall need not be
    /// measured again. (A stale entry can only delay a closure to the next pass: the last pass
    /// closes nothing, so its measurements are all fresh.)
    pub(super) memo: FastMap<u64, HandleLoops>,
    /// Handles of this pass (by [`memo_key`]) whose every wall was refused: after a rewind
    /// they are kept again without trying, unless a wall landed near their loops since
    /// (which forgets their measurement too).
    pub(super) failed: FastMap<u64, ()>,
}

/// Measurements that stay exact from pass to pass: a handle's loops are searched within a reach
/// of its curves (a loop shorter than r crossing a curve lies within r/2 edges of it, so within
/// r/√2 voxels: no edge of the surface graph is longer than √2), so until a wall lands within
/// that reach, measuring it again would find the same. The last pass, which must be an exact
/// analysis of the result, then measures again only what the walls came near.
#[derive(Default)]
pub(super) struct Lasting {
    /// By [`memo_key`]: the loops, and their reach (local coordinates).
    entries: FastMap<u64, (HandleLoops, Reach)>,
}

/// Where the searches of a measurement reached: the blocks of [`LASTING_BLOCK`]³ samples within
/// the margin of its curves' vertices, or for a wide margin (long loops, no limit) the box.
enum Reach {
    Blocks(FastMap<[i64; 3], ()>),
    Box(BBox),
}

/// Side of the blocks a lasting measurement's reach is kept in.
const LASTING_BLOCK: i64 = 8;

/// Margins beyond which a reach is kept as a box (a vertex's blocks would be too many).
const LASTING_MAX_BLOCK_MARGIN: i64 = 4 * LASTING_BLOCK;

impl Lasting {
    pub(super) fn get(&self, key: u64) -> Option<&HandleLoops> {
        self.entries.get(&key).map(|e| &e.0)
    }

    /// Keeps a fresh measurement if its reach is known: its searches were exact (no budget ran
    /// out), in voxel edges, and stopped at a finite limit (or found both loops).
    pub(super) fn offer(&mut self, key: u64, l: &HandleLoops, limits: Limits) {
        let r = if limits.below.is_finite() {
            limits.below
        } else {
            match (&l.reeb, &l.cross) {
                (Some(a), Some(b)) => a.length.max(b.length) as f64,
                _ => return,
            }
        };
        if !l.exact || limits.metric != Metric::Edges {
            return;
        }
        let margin = (r * std::f64::consts::FRAC_1_SQRT_2).ceil() as i64 + 2;
        let curves = [&l.reeb, &l.cross]
            .into_iter()
            .flatten()
            .map(|x| &x.vertices[..]);
        let basis = l.basis.iter().flat_map(|(p, q)| [&p[..], &q[..]]);
        let vertices = curves.chain(basis).flatten();
        let reach = if margin > LASTING_MAX_BLOCK_MARGIN {
            let mut b = BBox::EMPTY;
            for v in vertices {
                b.include(v.p.map(|x| x - margin));
                b.include(v.p.map(|x| x + 1 + margin));
            }
            Reach::Box(b)
        } else {
            let mut blocks = FastMap::default();
            for v in vertices {
                let lo = v.p.map(|x| (x - margin).div_euclid(LASTING_BLOCK));
                let hi = v.p.map(|x| (x + 1 + margin).div_euclid(LASTING_BLOCK));
                for z in lo[2]..=hi[2] {
                    for y in lo[1]..=hi[1] {
                        for x in lo[0]..=hi[0] {
                            blocks.insert([x, y, z], ());
                        }
                    }
                }
            }
            Reach::Blocks(blocks)
        };
        self.entries.insert(key, (l.clone(), reach));
    }

    /// Forgets the measurements within reach of one of the walls (local boxes).
    pub(super) fn forget_near(&mut self, walls: &[BBox]) {
        let touched: Vec<[i64; 3]> = walls
            .iter()
            .flat_map(|w| {
                let lo = w.min.map(|x| x.div_euclid(LASTING_BLOCK));
                let hi = w.max.map(|x| x.div_euclid(LASTING_BLOCK));
                (lo[2]..=hi[2]).flat_map(move |z| {
                    (lo[1]..=hi[1]).flat_map(move |y| (lo[0]..=hi[0]).map(move |x| [x, y, z]))
                })
            })
            .collect();
        self.entries.retain(|_, (_, reach)| match reach {
            Reach::Blocks(blocks) => !touched.iter().any(|b| blocks.contains_key(b)),
            Reach::Box(b) => !walls.iter().any(|w| overlaps(w, b, 0)),
        });
    }
}

/// Identity of a located handle across rewinds: its cut and where its cycle lies.
pub(super) fn memo_key(h: &LocatedHandle) -> u64 {
    use std::hash::{Hash, Hasher};
    let mut s = std::collections::hash_map::DefaultHasher::new();
    (h.kind == HandleKind::IntraRibbon).hash(&mut s);
    h.direct.hash(&mut s);
    h.cut.hash(&mut s);
    h.bbox.min.hash(&mut s);
    h.bbox.max.hash(&mut s);
    s.finish()
}

/// Neighbourhoods simplify keeps between handles before starting afresh: its searches stop at
/// tau, so a smaller graph than analyze's (`MEASURE_GRAPH_LIMIT`) serves, and memory stays near
/// the window's. Checked before each handle, not only at each step of the sweep: one step can
/// find hundreds of handles, and on the gigavoxel (the bunny CT tiled 2 x 2 x 3) the graph grew
/// within a step to twice the limit, its arrays to 2^19 vertices (266 MiB peak instead of 240).
const SIMPLIFY_GRAPH_LIMIT: usize = 1 << 18;

impl Caches {
    pub(super) fn new(conn: Connectivity) -> Caches {
        Caches {
            graph: GraphCache::default(),
            slices: SliceCache::new(conn),
            memo: FastMap::default(),
            failed: FastMap::default(),
        }
    }

    /// Measures the handles one step of the sweep found.
    pub(super) fn measure(
        &mut self,
        vol: &MaskVolume,
        new: &[LocatedHandle],
        conn: Connectivity,
        affine: &Affine,
        limits: Limits,
        lasting: &mut Lasting,
    ) -> Vec<HandleLoops> {
        let mut g = Graph::with_cache(vol, cases(conn), std::mem::take(&mut self.graph));
        let out = new
            .iter()
            .map(|h| {
                let key = memo_key(h);
                if let Some(l) = self.memo.get(&key).or_else(|| lasting.get(key)) {
                    return l.clone();
                }
                if g.len() > SIMPLIFY_GRAPH_LIMIT {
                    g = Graph::new(vol, cases(conn));
                }
                let h = Handle {
                    id: 0,
                    surface: 0,
                    located: h.clone(),
                };
                let l = loops::measure(&mut g, &mut self.slices, &h, conn, affine, limits);
                lasting.offer(key, &l, limits);
                self.memo.insert(key, l.clone());
                l
            })
            .collect();
        self.graph = g.into_cache();
        out
    }

    /// Forgets the measurements whose loops come near one of the walls.
    pub(super) fn forget_near(&mut self, walls: &[BBox]) {
        self.memo.retain(|_, l| {
            let mut loops = [&l.reeb, &l.cross].into_iter().flatten();
            loops.all(|x| !walls.iter().any(|w| wall_near_loop(w, x, 2)))
        });
        let memo = &self.memo;
        self.failed.retain(|k, _| memo.contains_key(k));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::loops::{Encloses, Loop};
    use crate::surface::Vertex;

    /// A loop through the x edges at `points` (a measurement's curves; the tests only read
    /// their vertices and length).
    fn curve(points: &[[i64; 3]], length: usize) -> Loop {
        Loop {
            vertices: points.iter().map(|&p| Vertex { p, axis: 0 }).collect(),
            points: Vec::new(),
            length,
            length_mm: length as f64,
            encloses: Encloses::Void,
        }
    }

    fn measured(points: &[[i64; 3]], exact: bool, both: bool) -> HandleLoops {
        HandleLoops {
            reeb: Some(curve(points, 40)),
            cross: both.then(|| curve(points, 30)),
            exact,
            ..HandleLoops::default()
        }
    }

    fn limits(below: f64, metric: Metric) -> Limits {
        Limits {
            below,
            metric,
            size_only: true,
        }
    }

    fn wall(p: [i64; 3]) -> BBox {
        let mut b = BBox::EMPTY;
        b.include(p);
        b
    }

    /// The margin the documentation promises for a search limit `r`: a loop shorter than r
    /// crossing a curve lies within r/√2 voxels of it, plus two for the edges' ends.
    fn margin(r: f64) -> i64 {
        (r / std::f64::consts::SQRT_2).ceil() as i64 + 2
    }

    /// Whether the measurement offered under `lim` is still there after a wall at `at`.
    fn survives(l: &HandleLoops, lim: Limits, at: [i64; 3]) -> bool {
        let mut lasting = Lasting::default();
        lasting.offer(7, l, lim);
        assert!(lasting.get(7).is_some(), "the measurement is kept at first");
        lasting.forget_near(&[wall(at)]);
        lasting.get(7).is_some()
    }

    #[test]
    fn a_measurement_lasts_only_when_its_reach_is_known() {
        let origin = [[0, 0, 0]];
        let offered = |l: &HandleLoops, lim: Limits| {
            let mut lasting = Lasting::default();
            lasting.offer(3, l, lim);
            lasting.get(3).map(|k| k.reeb.as_ref().map(|r| r.length))
        };
        let edges = limits(20.0, Metric::Edges);
        assert_eq!(
            offered(&measured(&origin, true, false), edges),
            Some(Some(40))
        );
        assert_eq!(
            offered(&measured(&origin, false, true), edges),
            None,
            "inexact"
        );
        let mm = limits(20.0, Metric::Millimetres);
        assert_eq!(
            offered(&measured(&origin, true, true), mm),
            None,
            "millimetres"
        );
        // No limit: the reach is the longer loop's, so both must have been found.
        let inf = limits(f64::INFINITY, Metric::Edges);
        assert_eq!(offered(&measured(&origin, true, true), inf), Some(Some(40)));
        assert_eq!(
            offered(&measured(&origin, true, false), inf),
            None,
            "one loop"
        );
        assert!(Lasting::default().get(3).is_none());
    }

    /// A wall within the margin of a curve's vertex forgets the measurement; one a block of
    /// samples beyond it does not (the reach is kept in blocks of `LASTING_BLOCK`).
    #[test]
    fn a_wall_within_the_reach_forgets_and_one_beyond_it_does_not() {
        for (r, both) in [(20.0, false), (6.0, false), (40.0, true)] {
            let l = measured(&[[0, 0, 0]], true, both);
            let lim = limits(r, Metric::Edges);
            let m = margin(r);
            for near in [[m, 0, 0], [-m, 0, 0], [0, m, 0], [0, 0, -m], [1 + m, 0, 0]] {
                assert!(!survives(&l, lim, near), "r {r}: wall at {near:?}");
            }
            for far in [
                [1 + m + LASTING_BLOCK, 0, 0],
                [0, -m - LASTING_BLOCK - 1, 0],
            ] {
                assert!(survives(&l, lim, far), "r {r}: wall at {far:?}");
            }
        }
    }

    /// Up to a margin of `LASTING_MAX_BLOCK_MARGIN` the reach follows the curves: a wall in
    /// their bounding box but far from every vertex leaves the measurement. Beyond, the reach
    /// is the box grown by the margin.
    #[test]
    fn the_reach_follows_the_curves_up_to_the_largest_block_margin() {
        let corners = [[0, 0, 0], [200, 200, 0]];
        // r = 42 gives a margin of exactly LASTING_MAX_BLOCK_MARGIN.
        for r in [20.0, 42.0] {
            assert!(margin(r) <= LASTING_MAX_BLOCK_MARGIN);
            let l = measured(&corners, true, false);
            assert!(survives(&l, limits(r, Metric::Edges), [200, 0, 0]), "r {r}");
            assert!(
                !survives(&l, limits(r, Metric::Edges), [200, 190, 0]),
                "r {r}"
            );
        }
        assert_eq!(margin(42.0), LASTING_MAX_BLOCK_MARGIN);
        let r = 60.0;
        let (l, lim, m) = (
            measured(&corners, true, false),
            limits(r, Metric::Edges),
            margin(r),
        );
        assert!(m > LASTING_MAX_BLOCK_MARGIN);
        assert!(!survives(&l, lim, [200 + m, 100, 0]));
        assert!(
            !survives(&l, lim, [201 + m, 100, 0]),
            "a vertex's edge ends at x + 1"
        );
        assert!(!survives(&l, lim, [-m, 100, 0]));
        assert!(survives(&l, lim, [201 + m + 1, 100, 0]));
        assert!(survives(&l, lim, [100, 100, -m - 1]));
    }

    /// This pass's memo forgets the loops a wall comes within two samples of (and whether
    /// their walls were refused), and only those.
    #[test]
    fn a_wall_near_a_loop_forgets_that_loops_measurement_in_the_pass() {
        let mut c = Caches::new(Connectivity::Six);
        // The first loop's one vertex is the x edge from (0, 0, 0) to (1, 0, 0).
        c.memo.insert(1, measured(&[[0, 0, 0]], true, true));
        c.memo.insert(2, measured(&[[100, 0, 0]], true, false));
        c.failed.insert(1, ());
        c.failed.insert(2, ());
        c.forget_near(&[wall([4, 0, 0])]);
        assert!(
            c.memo.contains_key(&1) && c.failed.contains_key(&1),
            "3 samples away"
        );
        c.forget_near(&[wall([3, 0, 0])]);
        assert!(!c.memo.contains_key(&1) && !c.failed.contains_key(&1));
        assert!(c.memo.contains_key(&2) && c.failed.contains_key(&2));
    }
}
