//! Shortest odd loops in millimetres: the search of the parent module with each edge as long
//! as the segment between its two vertices' interpolated positions (Dijkstra's algorithm in
//! place of breadth-first search).
//!
//! As there, a state is (vertex, parity) and the shortest loop crossing `cut` an odd number of
//! times through a vertex `s` of the cut is the shortest path from (s, 0) to (s, 1). A loop of
//! length L through `s` has a middle edge (a, b): its first part runs from (s, 0) to a state of
//! `a` within L/2, and its second part, run backwards and mirrored, from (s, 0) to the state of
//! `b` across the edge, also within L/2.
//!
//! ```text
//!    (s,0) ~~~~~~> (a,p) --- (b, p^flip)        the edge closes the loop when (b, p^flip^1)
//!    (s,0) ~~~~~~> (b, p^flip^1)                is also settled: d(a,p) + |ab| + d(b, ...)
//! ```
//!
//! So a search from one source stops at half the best length found so far. A first search from
//! all of the cut at once gives a loop (closed along the cut), and, through the same meeting
//! edges, a lower bound through every edge: only the vertices of the cut within half the best
//! of an edge whose bound is below the best need a search of their own.

use super::{simple_cycle, Curves, Graph, Region};
use crate::surface::geometry::Geometry;
use crate::surface::Vertex;
use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// A loop found by [`odd_loop_mm`] and its length in millimetres.
#[derive(Clone, Debug, Default)]
pub struct OddLoopMm {
    /// The loop and its length (`None`: none below the limit).
    pub found: Option<(Vec<Vertex>, f64)>,
    /// Is `found` a shortest such loop, or (`None`) is none shorter than the limit?
    pub exact: bool,
}

/// An entry of the priority queue: distance, then the state's place on the grid (its vertex's
/// key and parity), smallest first; then the state's number. Ties among equally near states go
/// by the grid, not by the order the graph numbered its vertices in (which depends on what was
/// searched before and on the window of planes), so the loops found never depend on either.
#[derive(Clone, Copy, PartialEq)]
struct Entry(f64, u64, u32);

impl Eq for Entry {}
impl Ord for Entry {
    fn cmp(&self, o: &Self) -> Ordering {
        o.0.total_cmp(&self.0)
            .then(o.1.cmp(&self.1))
            .then(o.2.cmp(&self.2))
    }
}
impl PartialOrd for Entry {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}

/// Dense state of the searches, reset by generation stamps (kept in the graph's scratch).
#[derive(Default)]
pub(super) struct MmScratch {
    generation: u32,
    /// Per state: stamp when reached, stamp when settled, distance, predecessor, source.
    reached: Vec<u32>,
    settled: Vec<u32>,
    dist: Vec<f64>,
    pred: Vec<u32>,
    source: Vec<u32>,
    /// Per vertex: its position, once computed (stamped by `pos_generation`).
    pos_generation: u32,
    pos_stamp: Vec<u32>,
    pos: Vec<[f64; 3]>,
}

impl MmScratch {
    fn ensure(&mut self, vertices: usize) {
        let states = vertices * 2;
        if self.reached.len() < states {
            let n = states.next_power_of_two();
            self.reached.resize(n, 0);
            self.settled.resize(n, 0);
            self.dist.resize(n, 0.0);
            self.pred.resize(n, u32::MAX);
            self.source.resize(n, 0);
        }
        if self.pos_stamp.len() < vertices {
            let n = vertices.next_power_of_two();
            self.pos_stamp.resize(n, 0);
            self.pos.resize(n, [0.0; 3]);
        }
    }

    fn next_generation(&mut self) -> u32 {
        self.generation = self.generation.wrapping_add(1);
        if self.generation == 0 {
            self.reached.iter_mut().for_each(|s| *s = 0);
            self.settled.iter_mut().for_each(|s| *s = 0);
            self.generation = 1;
        }
        self.generation
    }

    fn next_positions(&mut self) {
        self.pos_generation = self.pos_generation.wrapping_add(1);
        if self.pos_generation == 0 {
            self.pos_stamp.iter_mut().for_each(|s| *s = 0);
            self.pos_generation = 1;
        }
    }
}

/// One Dijkstra search over the double cover (state = vertex << 1 | parity).
struct Search<'a, 'g> {
    geo: &'a Geometry<'a>,
    curves: &'a Curves,
    region: &'a dyn Region,
    g: &'a mut Graph<'g>,
    gen: u32,
    heap: BinaryHeap<Entry>,
}

impl<'a, 'g> Search<'a, 'g> {
    fn new(
        g: &'a mut Graph<'g>,
        geo: &'a Geometry<'a>,
        curves: &'a Curves,
        region: &'a dyn Region,
    ) -> Search<'a, 'g> {
        let gen = g.scratch.mm.next_generation();
        Search {
            geo,
            curves,
            region,
            g,
            gen,
            heap: BinaryHeap::new(),
        }
    }

    fn position(&mut self, i: u32) -> [f64; 3] {
        let sc = &mut self.g.scratch.mm;
        if sc.pos_stamp[i as usize] != sc.pos_generation {
            let p = self.geo.position(&self.g.vol.frame, self.g.vertex(i));
            let sc = &mut self.g.scratch.mm;
            sc.pos_stamp[i as usize] = sc.pos_generation;
            sc.pos[i as usize] = p;
        }
        self.g.scratch.mm.pos[i as usize]
    }

    fn length(&mut self, a: u32, b: u32) -> f64 {
        let (p, q) = (self.position(a), self.position(b));
        ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
    }

    fn start(&mut self, st: u32, src: u32) {
        self.g.scratch.mm.ensure(self.g.arena.len() + 1);
        let sc = &mut self.g.scratch.mm;
        sc.reached[st as usize] = self.gen;
        sc.dist[st as usize] = 0.0;
        sc.pred[st as usize] = u32::MAX;
        sc.source[st as usize] = src;
        let tie = self.tie(st);
        self.heap.push(Entry(0.0, tie, st));
    }

    /// The grid order of state `st` (see [`Entry`]).
    fn tie(&self, st: u32) -> u64 {
        self.g.vertex(st >> 1).key() << 1 | (st & 1) as u64
    }

    fn is_settled(&self, st: u32) -> bool {
        self.g.scratch.mm.settled.get(st as usize) == Some(&self.gen)
    }

    fn dist(&self, st: u32) -> f64 {
        self.g.scratch.mm.dist[st as usize]
    }

    /// Pops and settles the nearest state not yet settled.
    fn pop(&mut self) -> Option<(f64, u32)> {
        while let Some(Entry(d, _, st)) = self.heap.pop() {
            let sc = &mut self.g.scratch.mm;
            if sc.settled[st as usize] != self.gen {
                sc.settled[st as usize] = self.gen;
                return Some((d, st));
            }
        }
        None
    }

    /// The edges out of state `st` within the region: (neighbour's state, length).
    fn edges(&mut self, st: u32) -> Vec<(u32, f64)> {
        let (vi, par) = (st >> 1, st & 1);
        let steps = self.g.steps(self.region, vi);
        let n = self.g.arena.len() + 1;
        self.g.scratch.ensure(0, n);
        self.g.scratch.mm.ensure(n);
        let mut out = Vec::with_capacity(8);
        for (k, wi) in steps {
            let ns = (wi << 1) | (par ^ self.curves.flip(self.g, vi, k, wi));
            let w = self.length(vi, wi);
            out.push((ns, w));
        }
        out
    }

    /// Relaxes the edges out of state `st` at distance `d`.
    fn relax(&mut self, edges: &[(u32, f64)], st: u32, d: f64) {
        for &(ns, w) in edges {
            let sc = &mut self.g.scratch.mm;
            if sc.settled[ns as usize] == self.gen {
                continue;
            }
            let nd = d + w;
            if sc.reached[ns as usize] != self.gen || nd < sc.dist[ns as usize] {
                sc.reached[ns as usize] = self.gen;
                sc.dist[ns as usize] = nd;
                sc.pred[ns as usize] = st;
                sc.source[ns as usize] = sc.source[st as usize];
                let tie = self.tie(ns);
                self.heap.push(Entry(nd, tie, ns));
            }
        }
    }

    /// The vertices of the search path ending in state `st`, its source first.
    fn path_to(&self, mut st: u32) -> Vec<Vertex> {
        let mut path = Vec::new();
        while st != u32::MAX {
            path.push(self.g.vertex(st >> 1));
            st = self.g.scratch.mm.pred[st as usize];
        }
        path.reverse();
        path
    }

    /// The closed walk of a meeting edge: the path to `x`, then back from `y` (the mirrored
    /// state across the edge) to the source, which is not repeated.
    fn meeting_walk(&self, x: u32, y: u32) -> Vec<Vertex> {
        let mut walk = self.path_to(x);
        let mut back = self.path_to(y);
        back.reverse();
        back.pop();
        walk.extend(back);
        walk
    }
}

/// The shortest loop through the region, in millimetres, that crosses `cut` an odd number of
/// times, if one is shorter than `limit` mm (see the module notes).
pub fn odd_loop_mm(
    g: &mut Graph,
    geo: &Geometry,
    cut: &[Vertex],
    region: &dyn Region,
    limit: f64,
) -> OddLoopMm {
    let none = |exact| OddLoopMm { found: None, exact };
    if cut.len() < 2 {
        return none(true);
    }
    let Some(curves) = Curves::new(g, cut, &[]) else {
        return none(false);
    };
    let Some(nums) = cut
        .iter()
        .map(|&v| g.index(v))
        .collect::<Option<Vec<u32>>>()
    else {
        return none(false);
    };
    g.scratch.next_region();
    g.scratch.mm.next_positions();
    let first = first_search(g, geo, &curves, region, cut, &nums, limit);
    let Some((walk, bounds)) = first.found else {
        return none(first.conclusive);
    };
    let walk = simple_cycle(g, &curves, walk, 1);
    let mut best_len = limit;
    let mut best = None;
    if super::walk_in_region(g, region, &walk) {
        let len = geo.loop_mm(&g.vol.frame, &walk);
        if len < limit {
            (best, best_len) = (Some(walk), len);
        }
    }
    let sources = match bounds {
        Some(b) => near(g, geo, &curves, region, &b, best_len, &nums),
        None => nums.clone(),
    };
    let mut budget = g.budgets.exact;
    let mut exact = first.conclusive;
    for si in sources {
        let Some(found) = through(g, geo, &curves, region, si, best_len, &mut budget) else {
            exact = false;
            break;
        };
        if let Some(walk) = found {
            let walk = simple_cycle(g, &curves, walk, 1);
            let len = geo.loop_mm(&g.vol.frame, &walk);
            if len < best_len {
                (best, best_len) = (Some(walk), len);
            }
        }
    }
    OddLoopMm {
        found: best.map(|w| (w, best_len)),
        exact,
    }
}

/// Lower bounds on the length of an odd loop through each vertex: (vertex, bound).
type Bounds = Vec<(u32, f64)>;

/// What the search from all of the cut at once found: a closed walk (the path to an odd state
/// of the cut, then along the cut) and, when it saw every state it needed, the lower bound
/// through each vertex (its best meeting edge).
struct First {
    found: Option<(Vec<Vertex>, Option<Bounds>)>,
    conclusive: bool,
}

fn first_search(
    g: &mut Graph,
    geo: &Geometry,
    curves: &Curves,
    region: &dyn Region,
    cut: &[Vertex],
    nums: &[u32],
    limit: f64,
) -> First {
    let n = nums.len();
    let mut budget = g.budgets.first;
    let mut s = Search::new(g, geo, curves, region);
    for (i, &vi) in nums.iter().enumerate() {
        s.start(vi << 1, i as u32);
    }
    // Along the cut from position a to b, the shorter way.
    let mut prefix = vec![0.0; n + 1];
    for i in 0..n {
        prefix[i + 1] = prefix[i] + s.length(nums[i], nums[(i + 1) % n]);
    }
    let forward = |a: usize, b: usize| {
        if b >= a {
            prefix[b] - prefix[a]
        } else {
            prefix[n] - prefix[a] + prefix[b]
        }
    };
    let along = |a: usize, b: usize| forward(a, b).min(forward(b, a));
    let pos: super::FastMap<u32, usize> = nums.iter().enumerate().map(|(i, &v)| (v, i)).collect();
    let mut best: Option<(f64, u32, usize)> = None;
    let mut settled: Vec<u32> = Vec::new();
    while let Some((d, st)) = s.pop() {
        if d >= limit || best.is_some_and(|b| d >= b.0) || budget == 0 {
            break;
        }
        budget -= 1;
        settled.push(st);
        if st & 1 == 1 {
            if let Some(&j) = pos.get(&(st >> 1)) {
                let src = s.g.scratch.mm.source[st as usize] as usize;
                let total = d + along(src, j);
                if best.is_none_or(|b| total < b.0) {
                    best = Some((total, st, j));
                }
            }
        }
        let edges = s.edges(st);
        s.relax(&edges, st, d);
    }
    let conclusive = budget > 0;
    let Some((_, end, j)) = best else {
        return First {
            found: None,
            conclusive,
        };
    };
    let src = s.g.scratch.mm.source[end as usize] as usize;
    let mut walk = s.path_to(end);
    // Back along the cut from j to the source, the shorter way (both excluded).
    let step = if forward(j, src) <= forward(src, j) {
        1
    } else {
        -1
    };
    super::push_along_cut(&mut walk, cut, j, src, step);
    // Lower bounds through each edge with both ends' states settled.
    let bounds = conclusive.then(|| {
        let mut b = Vec::new();
        for &st in &settled {
            let d = s.dist(st);
            for (ns, w) in s.edges(st) {
                let other = ns ^ 1;
                if s.is_settled(other) {
                    b.push((st >> 1, d + w + s.dist(other)));
                }
            }
        }
        b
    });
    First {
        found: Some((walk, bounds)),
        conclusive,
    }
}

/// The shortest odd loop through vertex `si` shorter than `below`, as a closed walk (`Some(None)`
/// if there is none), searching half as deep; `None` if the budget ran out first.
fn through(
    g: &mut Graph,
    geo: &Geometry,
    curves: &Curves,
    region: &dyn Region,
    si: u32,
    below: f64,
    budget: &mut usize,
) -> Option<Option<Vec<Vertex>>> {
    let mut s = Search::new(g, geo, curves, region);
    s.start(si << 1, 0);
    let mut best: Option<(f64, u32, u32)> = None;
    while let Some((d, st)) = s.pop() {
        let bound = best.map_or(below, |b| b.0);
        if 2.0 * d >= bound {
            break;
        }
        if *budget == 0 {
            return None;
        }
        *budget -= 1;
        let edges = s.edges(st);
        for &(ns, w) in &edges {
            let other = ns ^ 1;
            if s.is_settled(other) {
                let len = d + w + s.dist(other);
                if len < best.map_or(below, |b| b.0) {
                    best = Some((len, st, other));
                }
            }
        }
        s.relax(&edges, st, d);
    }
    Some(best.map(|(_, x, y)| s.meeting_walk(x, y)))
}

/// The cut's vertices (numbers) within `best / 2` mm of a vertex whose bound is below `best`,
/// nearest first.
fn near(
    g: &mut Graph,
    geo: &Geometry,
    curves: &Curves,
    region: &dyn Region,
    bounds: &[(u32, f64)],
    best: f64,
    cut: &[u32],
) -> Vec<u32> {
    let on_cut: super::FastMap<u32, ()> = cut.iter().map(|&v| (v, ())).collect();
    let mut s = Search::new(g, geo, curves, region);
    let mut started: super::FastMap<u32, ()> = super::FastMap::default();
    for &(a, b) in bounds {
        if b < best && started.insert(a, ()).is_none() {
            s.start(a << 1, 0);
        }
    }
    let mut out = Vec::new();
    while let Some((d, st)) = s.pop() {
        if d > best / 2.0 {
            break;
        }
        if on_cut.contains_key(&(st >> 1)) {
            out.push(st >> 1);
        }
        // Plain distance: every edge keeps parity 0.
        let edges: Vec<(u32, f64)> = s
            .edges(st)
            .into_iter()
            .map(|(ns, w)| (ns & !1, w))
            .collect();
        s.relax(&edges, st, d);
    }
    out
}
