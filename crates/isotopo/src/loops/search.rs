//! Shortest loops that cross a given curve an odd number of times.
//!
//! Both characteristic loops of a handle are found this way (paper §2.2): the Reeb loop crosses
//! one contour of the handle's Reeb cycle once, the cross loop crosses the Reeb loop once. The
//! search runs on the double cover of the surface graph: a state is (vertex, parity), and an
//! edge flips the parity when it crosses the cut `K`. At a vertex of `K`, the edges on the left of
//! `K` are marked; an edge's flip is the number of its marked ends, mod 2. A closed walk crosses
//! `K` an odd number of times exactly when its flips sum to 1, so the shortest odd loop through a
//! vertex `s` of `K` is the shortest path from (s, 0) to (s, 1); the shortest of those over `s` is
//! the answer, and it is a simple loop.
//!
//! ```text
//!              left of K (marked)
//!      ----x-------x-------x----->  K
//!              right of K
//! ```

use crate::surface::{around, Around, PieceRef, Vertex};
use crate::sweep::MaskVolume;
use crate::topology::cases::Case;
use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

/// A fast hasher for small integer keys (vertices packed into a u64).
#[derive(Default, Clone, Copy)]
pub struct FastHasher(u64);

impl Hasher for FastHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0.rotate_left(5) ^ b as u64).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
        }
    }
    fn write_u64(&mut self, i: u64) {
        self.0 = (self.0.rotate_left(5) ^ i).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
}

pub type FastMap<K, V> = HashMap<K, V, BuildHasherDefault<FastHasher>>;

/// Packs a vertex (coordinates in -1 ..= 2^20 - 2) into a u64.
#[inline]
pub fn key(v: Vertex) -> u64 {
    let c = |x: i64| (x + 1) as u64 & 0xF_FFFF;
    c(v.p[0]) | (c(v.p[1]) << 20) | (c(v.p[2]) << 40) | ((v.axis as u64) << 60)
}

/// Neighbourhoods, computed once per vertex and kept for later searches on the same volume.
pub struct Graph<'a> {
    pub vol: &'a MaskVolume,
    pub table: &'a [Case; 256],
    index: FastMap<u64, u32>,
    arena: Vec<Around>,
}

/// Marks a vertex that is not on the surface.
const ABSENT: u32 = u32::MAX;

impl<'a> Graph<'a> {
    pub fn new(vol: &'a MaskVolume, table: &'a [Case; 256]) -> Graph<'a> {
        Graph {
            vol,
            table,
            index: FastMap::default(),
            arena: Vec::new(),
        }
    }

    /// Index of `v`'s neighbourhood in the cache (computing it the first time), or `None` if no
    /// surface crosses that edge.
    #[inline]
    pub fn index(&mut self, v: Vertex) -> Option<u32> {
        let k = key(v);
        if let Some(&i) = self.index.get(&k) {
            return (i != ABSENT).then_some(i);
        }
        let i = match around(self.vol, self.table, v) {
            Some(a) => {
                self.arena.push(a);
                self.arena.len() as u32 - 1
            }
            None => ABSENT,
        };
        self.index.insert(k, i);
        (i != ABSENT).then_some(i)
    }

    #[inline]
    pub fn at(&self, i: u32) -> &Around {
        &self.arena[i as usize]
    }

    /// A copy of `v`'s neighbourhood.
    pub fn around(&mut self, v: Vertex) -> Option<Around> {
        self.index(v).map(|i| self.arena[i as usize])
    }
}

/// Which pieces the loop may use. A segment is usable when a piece on either side of it is (so
/// a region's boundary curves are usable), a vertex when one of its four pieces is.
pub trait Region {
    fn allows(&self, p: &PieceRef) -> bool;
}

/// Every piece.
pub struct Everywhere;
impl Region for Everywhere {
    fn allows(&self, _: &PieceRef) -> bool {
        true
    }
}

/// Pieces in cubes whose lower corner lies in a box (inclusive), and optionally further filtered.
pub struct InBox<F: Fn(&PieceRef) -> bool> {
    pub lo: [i64; 3],
    pub hi: [i64; 3],
    pub filter: F,
}

impl<F: Fn(&PieceRef) -> bool> Region for InBox<F> {
    fn allows(&self, p: &PieceRef) -> bool {
        (0..3).all(|k| self.lo[k] <= p.cube[k] && p.cube[k] <= self.hi[k]) && (self.filter)(p)
    }
}

/// An explicit set of pieces (by cube and piece index; every part of a tube).
#[derive(Default)]
pub struct PieceSet(pub FastMap<([i64; 3], u8), ()>);

impl PieceSet {
    pub fn insert(&mut self, cube: [i64; 3], index: u8) {
        self.0.insert((cube, index), ());
    }
}

impl Region for PieceSet {
    fn allows(&self, p: &PieceRef) -> bool {
        self.0.contains_key(&(p.cube, p.index))
    }
}

/// Marks, for each vertex of a closed curve `K`, which of its neighbours lie on its left
/// (bit k set: neighbour k). `K` is given as its vertices in order.
fn left_marks(g: &mut Graph, cut: &[Vertex]) -> Option<FastMap<u64, u16>> {
    let n = cut.len();
    let mut marks = FastMap::default();
    for i in 0..n {
        let (prev, v, next) = (cut[(i + n - 1) % n], cut[i], cut[(i + 1) % n]);
        let a = g.around(v)?;
        let ip = a.position(prev)?;
        let inx = a.position(next)?;
        // Left: strictly after `prev`, clockwise, up to `next`.
        let mut m = 0u16;
        let mut k = (ip + 1) % a.n;
        while k != inx {
            m |= 1 << k;
            k = (k + 1) % a.n;
        }
        *marks.entry(key(v)).or_insert(0) |= m;
    }
    Some(marks)
}

/// The shortest loop (as its vertices in order) through the region that crosses `cut` an odd
/// number of times and is shorter than `limit` edges; `None` if there is none.
pub fn shortest_odd_loop(
    g: &mut Graph,
    cut: &[Vertex],
    region: &dyn Region,
    limit: usize,
) -> Option<Vec<Vertex>> {
    shortest_loop_with_parities(g, cut, &[], region, limit)
}

/// Most curves a search can take parities against.
const MAX_CUTS: usize = 16;

/// The shortest loop through the region that crosses `cut` an odd number of times and each of
/// `even` an even number of times, shorter than `limit` edges.
pub fn shortest_loop_with_parities(g: &mut Graph, cut: &[Vertex], even: &[&[Vertex]], region: &dyn Region, limit: usize) -> Option<Vec<Vertex>> {
    if cut.len() < 2 || even.len() + 1 > MAX_CUTS {
        return None;
    }
    // Left marks of every curve; bit c of a state's parity is the crossings of curve c, mod 2.
    let mut marks: Vec<FastMap<u64, u16>> = Vec::with_capacity(1 + even.len());
    marks.push(left_marks(g, cut)?);
    for c in even {
        marks.push(left_marks(g, c)?);
    }
    let goal: u32 = 1;
    let mut best: Option<Vec<Vertex>> = None;
    let mut best_len = limit;
    let mut seen: FastMap<(u64, u32), (u32, u64, u32)> = FastMap::default(); // -> (dist, pred key, pred parity)
    let mut verts: FastMap<u64, Vertex> = FastMap::default();
    let mut queue = std::collections::VecDeque::new();
    let mut sources: Vec<Vertex> = cut.to_vec();
    sources.sort();
    sources.dedup();
    for &s in &sources {
        let Some(si) = g.index(s) else { continue };
        let sa = g.at(si);
        if !sa.piece[..sa.n].iter().any(|p| region.allows(p)) {
            continue;
        }
        seen.clear();
        queue.clear();
        let ks = key(s);
        seen.insert((ks, 0), (0, u64::MAX, 0));
        verts.insert(ks, s);
        queue.push_back((s, 0u32));
        let mut found = None;
        'bfs: while let Some((v, par)) = queue.pop_front() {
            let kv = key(v);
            let d = seen[&(kv, par)].0;
            if d as usize + 1 >= best_len {
                break;
            }
            let Some(vi) = g.index(v) else { continue };
            let mut mv = [0u16; MAX_CUTS];
            for (c, m) in marks.iter().enumerate() {
                mv[c] = m.get(&kv).copied().unwrap_or(0);
            }
            let n = g.at(vi).n;
            for k in 0..n {
                // The edge v -> nbr[k] runs between piece[k-1] and piece[k].
                let (w, (left, right)) = {
                    let a = g.at(vi);
                    (a.nbr[k], a.sides(k))
                };
                if !region.allows(&left) && !region.allows(&right) {
                    continue;
                }
                let kw = key(w);
                let mut flip = 0u32;
                let mut back = None;
                for (c, m) in marks.iter().enumerate() {
                    let mut f = (mv[c] >> k) & 1 == 1;
                    if let Some(&mw) = m.get(&kw) {
                        // The same edge seen from w.
                        if back.is_none() {
                            back = g.index(w).and_then(|wi| g.at(wi).position(v));
                        }
                        if let Some(j) = back {
                            f ^= (mw >> j) & 1 == 1;
                        }
                    }
                    flip |= (f as u32) << c;
                }
                let np = par ^ flip;
                if let std::collections::hash_map::Entry::Vacant(e) = seen.entry((kw, np)) {
                    e.insert((d + 1, kv, par));
                } else {
                    continue;
                }
                verts.entry(kw).or_insert(w);
                if kw == ks && np == goal {
                    found = Some(d + 1);
                    break 'bfs;
                }
                queue.push_back((w, np));
            }
        }
        if let Some(len) = found {
            if (len as usize) < best_len {
                // Walk back from (s, goal) to (s, 0).
                let mut path = Vec::with_capacity(len as usize);
                let (mut k, mut p) = (ks, goal);
                loop {
                    let (_, pk, pp) = seen[&(k, p)];
                    if pk == u64::MAX {
                        break;
                    }
                    path.push(verts[&k]);
                    k = pk;
                    p = pp;
                }
                path.reverse();
                best_len = len as usize;
                best = Some(path);
            }
        }
    }
    best
}

/// Is the loop non-separating on the surface (within the region)? It is exactly when, starting
/// on one side of it at one of its vertices, the other side of that vertex can be reached
/// without crossing it: one breadth-first search of the double cover.
pub fn is_nonseparating(g: &mut Graph, lp: &[Vertex], region: &dyn Region) -> bool {
    let Some(marks) = left_marks(g, lp) else { return false };
    let s = lp[0];
    let ks = key(s);
    let mut seen: FastMap<(u64, bool), ()> = FastMap::default();
    let mut stack = vec![(s, false)];
    seen.insert((ks, false), ());
    while let Some((v, par)) = stack.pop() {
        let kv = key(v);
        let Some(vi) = g.index(v) else { continue };
        let mv = marks.get(&kv).copied().unwrap_or(0);
        for k in 0..g.at(vi).n {
            let (w, (left, right)) = {
                let a = g.at(vi);
                (a.nbr[k], a.sides(k))
            };
            if !region.allows(&left) && !region.allows(&right) {
                continue;
            }
            let kw = key(w);
            let mut flip = (mv >> k) & 1 == 1;
            if let Some(&mw) = marks.get(&kw) {
                if let Some(j) = g.index(w).and_then(|wi| g.at(wi).position(v)) {
                    flip ^= (mw >> j) & 1 == 1;
                }
            }
            let np = par ^ flip;
            if kw == ks && np {
                return true;
            }
            if seen.insert((kw, np), ()).is_none() {
                stack.push((w, np));
            }
        }
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sweep::{Frame, MaskVolume};
    use crate::topology::cases::{cases, Connectivity};

    /// A solid torus about z: centre (c, c, c), radii R, r.
    fn torus(n: usize, big: f64, small: f64) -> MaskVolume {
        let mut v = MaskVolume::new([n, n, n], Frame::identity());
        let c = (n as f64 - 1.0) / 2.0 + 0.01;
        for z in 0..n {
            for y in 0..n {
                for x in 0..n {
                    let (dx, dy, dz) = (x as f64 - c, y as f64 - c, z as f64 - c);
                    let q = ((dx * dx + dy * dy).sqrt() - big).hypot(dz);
                    if q < small {
                        v.set(x, y, z, true);
                    }
                }
            }
        }
        v
    }

    /// The contour in plane `w` through the first crossing found along +x from the centre line.
    fn contour_from(g: &mut Graph, w: i64, start_x: i64, y: i64) -> Vec<Vertex> {
        let mut x = start_x;
        loop {
            let v = Vertex {
                p: [x, y, w],
                axis: 0,
            };
            if crate::surface::is_crossing(g.vol, v) {
                let in_plane = |q: &Vertex| q.axis != 2 && q.p[2] == w;
                let mut out = vec![v];
                let (mut prev, mut cur) = (v, v);
                loop {
                    let a = g.around(cur).unwrap();
                    let next = (0..a.n)
                        .map(|k| a.nbr[k])
                        .find(|q| in_plane(q) && *q != prev)
                        .unwrap();
                    if next == v {
                        return out;
                    }
                    out.push(next);
                    prev = cur;
                    cur = next;
                }
            }
            x += 1;
        }
    }

    #[test]
    fn torus_loops_cross_each_other_once() {
        let vol = torus(24, 7.0, 2.6);
        for conn in [Connectivity::Six, Connectivity::TwentySix] {
            let t = cases(conn);
            let mut g = Graph::new(&vol, t);
            let mid = 11;
            // The inner equator (the contour around the hole in the middle plane): the shortest
            // loop crossing it once goes around the tube (a meridian), about 2πr long.
            let c = (24.0 - 1.0) / 2.0;
            let inner = contour_from(&mut g, mid, c as i64, c as i64);
            assert!(is_nonseparating(&mut g, &inner, &Everywhere));
            let meridian = shortest_odd_loop(&mut g, &inner, &Everywhere, usize::MAX).unwrap();
            let m = meridian.len() as f64;
            assert!(
                m > 2.0 * std::f64::consts::PI * 2.0 && m < 2.0 * std::f64::consts::PI * 3.6,
                "meridian length {m}"
            );
            // And the shortest loop crossing that meridian goes around the hole.
            let around_hole =
                shortest_odd_loop(&mut g, &meridian, &Everywhere, usize::MAX).unwrap();
            assert!(
                around_hole.len() as f64 > 2.0 * std::f64::consts::PI * (7.0 - 2.6),
                "{}",
                around_hole.len()
            );
        }
    }

    #[test]
    fn a_sphere_has_no_non_separating_loop() {
        let mut vol = MaskVolume::new([12, 12, 12], Frame::identity());
        for z in 0..12 {
            for y in 0..12 {
                for x in 0..12 {
                    let d = ((x as f64 - 5.6).powi(2)
                        + (y as f64 - 5.4).powi(2)
                        + (z as f64 - 5.5).powi(2))
                    .sqrt();
                    vol.set(x, y, z, d < 4.3);
                }
            }
        }
        let mut g = Graph::new(&vol, cases(Connectivity::Six));
        let equator = contour_from(&mut g, 5, 0, 5);
        assert!(!is_nonseparating(&mut g, &equator, &Everywhere));
    }
}
