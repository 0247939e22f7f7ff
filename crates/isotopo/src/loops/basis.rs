//! Does a set of closed curves span the surface's first homology? The check behind simplify's
//! promise that no loop shorter than tau is left.
//!
//! On a closed orientable surface of genus g, a loop is non-separating exactly when its class in
//! H1 (mod 2) is not zero, and the intersection form is non-degenerate: a non-zero class crosses
//! some member of any basis an odd number of times. So if closed curves c_1 … c_n span H1 and no
//! loop shorter than tau crosses any of them an odd number of times, no non-separating loop is
//! shorter than tau. Curves span H1 exactly when their matrix of crossing parities c_i · c_j has
//! rank 2g (the rank of the form restricted to their span is at most its dimension, and is 2g
//! on all of H1).

use crate::error::Result;
use crate::grid::MaskVolume;
use crate::surface::search::FastMap;
use crate::surface::{around, Around, Vertex};
use crate::topology::cases::{cases, Connectivity};

/// Rank (mod 2) of the matrix of crossing parities of the closed curves on the surface of
/// `vol`. `None` if a curve is not a closed walk on the surface.
///
/// Two curves cross only where they share a vertex, and what they add to their parity there
/// depends on that vertex's neighbourhood alone: so the parities are summed vertex by vertex,
/// up the volume, with only the planes round the vertices at hand in memory (out of core, in
/// windows of the volume's size; the curves kept in a gigavoxel scan run through nearly every
/// plane). The matrix is then taken apart into groups of curves joined by shared vertices, each
/// eliminated on its own.
///
/// ```text
///   a: ... a[j-1] -- u -- a[j+1] ...     at a vertex u of both curves, a's two steps from u
///   b: left of b at u: ######            each add one if they go to b's left: the steps
///                      b[i-1] -- u -- b[i+1]   into and out of u along a, each across b or not
/// ```
pub fn crossing_rank(
    vol: &mut MaskVolume,
    conn: Connectivity,
    curves: &[Vec<Vertex>],
) -> Result<Option<usize>> {
    if curves.iter().any(|c| c.len() < 3) {
        return Ok(None);
    }
    let through = places(curves);
    let Some(p) = parities(vol, conn, curves, &through)? else {
        return Ok(None);
    };
    Ok(Some(rank_by_group(curves.len(), &through, &p.odd)))
}

/// Each vertex's places on the curves, by key: (curve, index).
fn places(curves: &[Vec<Vertex>]) -> FastMap<u64, Vec<(u32, u32)>> {
    let mut through: FastMap<u64, Vec<(u32, u32)>> = FastMap::default();
    for (i, c) in curves.iter().enumerate() {
        for (k, v) in c.iter().enumerate() {
            through
                .entry(v.key())
                .or_default()
                .push((i as u32, k as u32));
        }
    }
    through
}

/// The crossing parities of [`parities`].
struct Parities {
    /// Of each pair of curves (a, b), a < b, that share a vertex.
    odd: FastMap<(u32, u32), bool>,
    /// The most planes in memory at once, out of core (for the tests: the window holds).
    #[cfg_attr(not(test), allow(dead_code))]
    most_planes: usize,
}

/// Crossing parity of each pair of curves (a, b), a < b, that share a vertex: a's steps into
/// and out of each shared vertex, summed over the vertices in order up the volume. `None` if a
/// curve's step is not an edge of the surface.
fn parities(
    vol: &mut MaskVolume,
    conn: Connectivity,
    curves: &[Vec<Vertex>],
    through: &FastMap<u64, Vec<(u32, u32)>>,
) -> Result<Option<Parities>> {
    let mut order: Vec<(i64, u64)> = through
        .keys()
        .map(|&k| (Vertex::from_key(k).p[2], k))
        .collect();
    order.sort_unstable();
    // A vertex's neighbourhood reads the planes within one of its own.
    let span = (vol.window() as i64 - 2).max(1);
    let mut parity: FastMap<(u32, u32), bool> = FastMap::default();
    let mut most_planes = 0;
    let mut at = 0;
    while at < order.len() {
        let z0 = order[at].0;
        vol.keep_window(z0 - 1, z0 + span)?;
        let vol: &MaskVolume = vol;
        while at < order.len() && order[at].0 < z0 + span {
            let u = Vertex::from_key(order[at].1);
            at += 1;
            let Some(a) = around(vol, cases(conn), u) else {
                return Ok(None);
            };
            if !add_crossings(&a, curves, &through[&u.key()], 0, &mut parity) {
                return Ok(None);
            }
        }
        if vol.out_of_core() {
            most_planes = most_planes.max(vol.planes_in_memory());
        }
    }
    Ok(Some(Parities {
        odd: parity,
        most_planes,
    }))
}

/// Adds to `parity` what the curves through `u` (at `places`) cross each other there, for the
/// pairs (c, d), c < d, with d at least `from`; false if a step of one of them from `u` is not
/// an edge of the surface (`a`: u's neighbourhood).
fn add_crossings(
    a: &Around,
    curves: &[Vec<Vertex>],
    places: &[(u32, u32)],
    from: u32,
    parity: &mut FastMap<(u32, u32), bool>,
) -> bool {
    // Each place's steps back and on, as positions round u.
    let mut steps: Vec<(u32, usize, usize)> = Vec::with_capacity(places.len());
    for &(c, k) in places {
        let c_ = &curves[c as usize];
        let n = c_.len();
        let (prev, next) = (c_[(k as usize + n - 1) % n], c_[(k as usize + 1) % n]);
        let (Some(ip), Some(inx)) = (a.position(prev), a.position(next)) else {
            return false;
        };
        steps.push((c, ip, inx));
    }
    if places.iter().all(|p| p.0 == places[0].0) {
        return true; // one curve: nothing to cross here
    }
    // The neighbours on each curve's left at u.
    let mut left: FastMap<u32, u16> = FastMap::default();
    for &(c, ip, inx) in &steps {
        *left.entry(c).or_default() |= a.left_of(ip, inx);
    }
    for &(c, ip, inx) in &steps {
        for (&d, &m) in &left {
            if c < d && d >= from {
                let crossed = ((m >> ip) ^ (m >> inx)) & 1 == 1;
                *parity.entry((c, d)).or_default() ^= crossed;
            }
        }
    }
    true
}

/// Rank of the parity matrix, group by group of curves joined by shared vertices.
fn rank_by_group(
    n: usize,
    through: &FastMap<u64, Vec<(u32, u32)>>,
    parity: &FastMap<(u32, u32), bool>,
) -> usize {
    let mut group = crate::unionfind::UnionFind::new(n);
    for list in through.values() {
        for w in list.windows(2) {
            group.union(w[0].0, w[1].0);
        }
    }
    let mut members: FastMap<u32, Vec<usize>> = FastMap::default();
    for i in 0..n {
        members.entry(group.find(i as u32)).or_default().push(i);
    }
    let mut rows_of: FastMap<u32, Vec<Vec<u64>>> = FastMap::default();
    let mut pos = vec![0usize; n];
    for (&g, list) in &members {
        for (k, &i) in list.iter().enumerate() {
            pos[i] = k;
        }
        let words = list.len().div_ceil(64);
        rows_of.insert(g, vec![vec![0u64; words]; list.len()]);
    }
    for (&(a, b), &odd) in parity {
        if odd {
            let rows = rows_of.get_mut(&group.find(a)).expect("a's group");
            let (ka, kb) = (pos[a as usize], pos[b as usize]);
            rows[ka][kb / 64] |= 1 << (kb % 64);
            rows[kb][ka / 64] |= 1 << (ka % 64);
        }
    }
    rows_of.values_mut().map(|rows| rank_mod2(rows)).sum()
}

/// Curves added a few at a time, with how much each addition raises the rank of their
/// crossing matrix (see [`crossing_rank`]): what the certificates of one sweep step check as
/// they go. An addition reads the neighbourhoods of its own curves' vertices only (two curves
/// cross only where both pass), as the surface graph reads them: no window of planes is kept
/// or let go, so the sweep's is left as it is.
#[derive(Default)]
pub struct CurveSet {
    curves: Vec<Vec<Vertex>>,
    /// Each vertex's places on the curves, by key: (curve, index).
    through: FastMap<u64, Vec<(u32, u32)>>,
    /// Crossing parity of each pair of curves (a, b), a < b, that share a vertex.
    odd: FastMap<(u32, u32), bool>,
}

impl CurveSet {
    /// The curves added.
    pub fn curves(&self) -> &[Vec<Vertex>] {
        &self.curves
    }

    /// Adds `new` and returns how much the rank grew; `None`, and nothing added, if one is not
    /// a closed walk on the surface of `vol`.
    pub fn add(
        &mut self,
        vol: &MaskVolume,
        conn: Connectivity,
        new: &[Vec<Vertex>],
    ) -> Option<usize> {
        if new.iter().any(|c| c.len() < 3) {
            return None;
        }
        let from = self.curves.len() as u32;
        let mut touched: Vec<u64> = Vec::new();
        for (i, c) in new.iter().enumerate() {
            for (k, v) in c.iter().enumerate() {
                let list = self.through.entry(v.key()).or_default();
                if list.last().is_none_or(|&(c, _)| c < from) {
                    touched.push(v.key());
                }
                list.push((from + i as u32, k as u32));
            }
        }
        self.curves.extend_from_slice(new);
        let mut odd = FastMap::default();
        let on_surface = touched.iter().all(|&k| {
            around(vol, cases(conn), Vertex::from_key(k))
                .is_some_and(|a| add_crossings(&a, &self.curves, &self.through[&k], from, &mut odd))
        });
        if !on_surface {
            self.curves.truncate(from as usize);
            for k in touched {
                let list = self.through.get_mut(&k).expect("a touched vertex");
                list.retain(|&(c, _)| c < from);
                if list.is_empty() {
                    self.through.remove(&k);
                }
            }
            return None;
        }
        let (old, added) = self.joined_to(from);
        let before = rank_of(&old, &[&self.odd]);
        self.odd.extend(odd);
        let all: Vec<u32> = old.iter().chain(&added).copied().collect();
        Some(rank_of(&all, &[&self.odd]) - before)
    }

    /// The curves before `from` joined by shared vertices to those from `from` on (which can
    /// cross them), and those.
    fn joined_to(&self, from: u32) -> (Vec<u32>, Vec<u32>) {
        let mut seen: FastMap<u32, ()> = FastMap::default();
        let mut queue: Vec<u32> = (from..self.curves.len() as u32).collect();
        queue.iter().for_each(|&c| _ = seen.insert(c, ()));
        let mut at = 0;
        while at < queue.len() {
            let c = queue[at] as usize;
            at += 1;
            for v in &self.curves[c] {
                for &(d, _) in &self.through[&v.key()] {
                    if seen.insert(d, ()).is_none() {
                        queue.push(d);
                    }
                }
            }
        }
        let (mut old, added): (Vec<u32>, Vec<u32>) = queue.into_iter().partition(|&c| c < from);
        old.sort_unstable();
        (old, added)
    }
}

/// Rank of the crossing matrix of the curves `members`, its odd entries from `maps`.
fn rank_of(members: &[u32], maps: &[&FastMap<(u32, u32), bool>]) -> usize {
    let pos: FastMap<u32, usize> = members.iter().enumerate().map(|(k, &c)| (c, k)).collect();
    let words = members.len().div_ceil(64);
    let mut rows = vec![vec![0u64; words]; members.len()];
    for map in maps {
        for (&(a, b), &odd) in map.iter() {
            if let (true, Some(&ka), Some(&kb)) = (odd, pos.get(&a), pos.get(&b)) {
                rows[ka][kb / 64] |= 1 << (kb % 64);
                rows[kb][ka / 64] |= 1 << (ka % 64);
            }
        }
    }
    rank_mod2(&mut rows)
}

/// Rank over the integers mod 2 of the rows (bit sets), by elimination in place.
fn rank_mod2(rows: &mut [Vec<u64>]) -> usize {
    let bits = rows.first().map_or(0, |r| r.len() * 64);
    let mut rank = 0;
    for col in 0..bits {
        let (w, b) = (col / 64, 1u64 << (col % 64));
        let Some(p) = (rank..rows.len()).find(|&r| rows[r][w] & b != 0) else {
            continue;
        };
        rows.swap(rank, p);
        let pivot = rows[rank].clone();
        for (r, row) in rows.iter_mut().enumerate() {
            if r != rank && row[w] & b != 0 {
                row.iter_mut().zip(&pivot).for_each(|(x, y)| *x ^= y);
            }
        }
        rank += 1;
    }
    rank
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::progress::NoProgress;
    use crate::surface::search::{crossing_parity, Graph};

    /// The oracle: the whole matrix of crossing parities, each pair of curves walked whole
    /// ([`crossing_parity`]), and its rank.
    fn pairwise_rank(vol: &MaskVolume, curves: &[Vec<Vertex>]) -> Option<usize> {
        let mut g = Graph::new(vol, cases(Connectivity::Six));
        let n = curves.len();
        let mut rows = vec![vec![false; n]; n];
        for a in 0..n {
            for b in a + 1..n {
                let odd = crossing_parity(&mut g, &curves[a], &curves[b])? == 1;
                (rows[a][b], rows[b][a]) = (odd, odd);
            }
        }
        Some(rank_of_parities(&rows))
    }

    /// Rank over GF(2) of a square matrix of parities.
    fn rank_of_parities(rows: &[Vec<bool>]) -> usize {
        let n = rows.len();
        let mut bits: Vec<Vec<u64>> = rows
            .iter()
            .map(|r| {
                let mut w = vec![0u64; n.div_ceil(64)];
                for (b, _) in r.iter().enumerate().filter(|e| *e.1) {
                    w[b / 64] |= 1 << (b % 64);
                }
                w
            })
            .collect();
        rank_mod2(&mut bits)
    }

    /// [`pairwise_rank`] for a list of curves that only grows: each new curve is walked against
    /// every curve before it once (the whole matrix again for every curve added made the test
    /// of `CurveSet::add` the slowest of the library's).
    struct GrowingPairwise<'a> {
        g: Graph<'a>,
        curves: Vec<Vec<Vertex>>,
        rows: Vec<Vec<bool>>,
    }

    impl<'a> GrowingPairwise<'a> {
        fn new(vol: &'a MaskVolume) -> Self {
            GrowingPairwise {
                g: Graph::new(vol, cases(Connectivity::Six)),
                curves: Vec::new(),
                rows: Vec::new(),
            }
        }

        /// The rank of the matrix with `new` appended to the curves.
        fn rank_with(&mut self, new: &[Vec<Vertex>]) -> Option<usize> {
            for c in new {
                let mut row = Vec::with_capacity(self.curves.len() + 1);
                for (k, old) in self.curves.iter().enumerate() {
                    let odd = crossing_parity(&mut self.g, old, c)? == 1;
                    self.rows[k].push(odd);
                    row.push(odd);
                }
                row.push(false);
                self.rows.push(row);
                self.curves.push(c.clone());
            }
            Some(rank_of_parities(&self.rows))
        }
    }

    /// The rank summed vertex by vertex up the volume is the rank of the matrix of pairwise
    /// parities, for the curves of every handle of random sponges (each handle's basis pair and
    /// its two loops, and every other handle's left out for a rank short of full), with the
    /// whole volume in memory and out of core in windows of 8 planes; a curve with a step that
    /// is not an edge gives `None`.
    #[test]
    fn ranks_summed_by_vertex_match_pairwise_parities() {
        let conn = Connectivity::Six;
        let mut ranks = Vec::new();
        for seed in 1..=6u64 {
            let vol = crate::test_rng::sponge(20, 0x9e37_79b9_7f4a_7c15 ^ seed);
            let opts = crate::AnalyzeOptions::default();
            let mut a = crate::analyze(crate::Source::from(vol.clone()), &opts, &NoProgress)
                .expect("analysed");
            let mut curves = Vec::new();
            for (i, l) in a.loops.iter().enumerate() {
                let (p, q) = l.basis.clone().expect("curves");
                curves.extend([p, q]);
                if i % 2 == 0 {
                    curves.extend(
                        [&l.reeb, &l.cross]
                            .into_iter()
                            .flatten()
                            .map(|x| x.vertices.clone()),
                    );
                }
            }
            let skip_odd: Vec<Vec<Vertex>> = curves.iter().step_by(2).cloned().collect();
            let mut reader = vol;
            let mut windowed = MaskVolume::from_reader(
                &mut reader,
                &opts.surface,
                opts.axis,
                Some(8),
                &NoProgress,
            )
            .expect("classified");
            assert!(windowed.out_of_core());
            for set in [&curves, &skip_odd] {
                let want = pairwise_rank(&a.masks, set);
                assert!(want.is_some());
                assert_eq!(
                    crossing_rank(&mut a.masks, conn, set).unwrap(),
                    want,
                    "seed {seed}"
                );
                assert_eq!(
                    crossing_rank(&mut windowed, conn, set).unwrap(),
                    want,
                    "seed {seed}"
                );
                ranks.push(want.unwrap());
            }
            // Never more planes than the window at once, and a good part of it used.
            let p = parities(&mut windowed, conn, &curves, &places(&curves))
                .unwrap()
                .unwrap();
            assert!((6..=8).contains(&p.most_planes), "{} planes", p.most_planes);
            // A curve with a vertex moved off its path is not a closed walk.
            let mut broken = curves.clone();
            broken[0][1].p[2] += 2;
            assert_eq!(crossing_rank(&mut windowed, conn, &broken).unwrap(), None);
        }
        assert!(ranks.iter().any(|&r| r >= 20), "{ranks:?}");
    }

    /// A curve set's rank grows by what the pairwise oracle's does: on random sponges, each
    /// handle's basis pair and its two loops added in turn, one or two at a time, and every pair
    /// added a second time (adding nothing). Before each offer the same offer with a vertex
    /// moved off its path (a step that is not an edge) is refused and leaves the set as it was:
    /// the growth that follows is still the oracle's (a refusal that undid the wrong curves'
    /// places lost crossings of the curves before it).
    #[test]
    fn a_curve_set_grows_in_rank_as_the_pairwise_oracle_does() {
        let conn = Connectivity::Six;
        let (mut grew, mut flat) = (0, 0);
        for seed in 1..=2u64 {
            let vol = crate::test_rng::sponge(14, 0x5eed_c0de_0f00 ^ seed);
            let opts = crate::AnalyzeOptions::default();
            let a = crate::analyze(crate::Source::from(vol), &opts, &NoProgress).expect("analysed");
            let mut offers: Vec<Vec<Vec<Vertex>>> = Vec::new();
            for l in &a.loops {
                let (p, q) = l.basis.clone().expect("curves");
                offers.push(vec![p.clone(), q.clone()]);
                let loops = [&l.reeb, &l.cross].into_iter().flatten();
                offers.extend(loops.map(|x| vec![x.vertices.clone()]));
                offers.push(vec![p, q]);
            }
            let mut set = CurveSet::default();
            let mut oracle = GrowingPairwise::new(&a.masks);
            let mut rank = 0;
            for new in &offers {
                let before = set.curves().to_vec();
                let mut broken = new.clone();
                broken[0][1].p[2] += 2;
                assert_eq!(set.add(&a.masks, conn, &broken), None, "seed {seed}");
                assert_eq!(set.curves(), &before[..]);
                let with: Vec<Vec<Vertex>> = before.iter().chain(new).cloned().collect();
                let want = oracle.rank_with(new).expect("on the surface");
                assert_eq!(oracle.curves, with);
                assert_eq!(
                    set.add(&a.masks, conn, new),
                    Some(want - rank),
                    "seed {seed}"
                );
                assert_eq!(set.curves(), &with[..]);
                *if want > rank { &mut grew } else { &mut flat } += 1;
                rank = want;
            }
            // The grown matrix is the whole one.
            assert_eq!(pairwise_rank(&a.masks, &oracle.curves), Some(rank));
        }
        assert!(grew > 10 && flat > 10, "{grew} grew, {flat} did not");
    }

    #[test]
    fn rank_of_small_matrices() {
        let mut m = vec![vec![0b01u64], vec![0b10u64]];
        assert_eq!(rank_mod2(&mut m), 2);
        let mut m = vec![vec![0b11u64], vec![0b11u64]];
        assert_eq!(rank_mod2(&mut m), 1);
        let mut m: Vec<Vec<u64>> = vec![vec![0], vec![0]];
        assert_eq!(rank_mod2(&mut m), 0);
        // Three rows, the third the sum of the first two.
        let mut m = vec![vec![0b011u64], vec![0b110u64], vec![0b101u64]];
        assert_eq!(rank_mod2(&mut m), 2);
    }
}
