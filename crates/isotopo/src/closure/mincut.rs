//! The smallest wall across a loop: a minimum cut of the side a closure changes.
//!
//! A fan wall ([`super::wall`]) takes every sample near the loop's spanning fan. Round a long,
//! twisted loop the fan passes through other parts of the surface, and that wall changes them
//! too (refused by the check). The wall that only does what the closure needs is found here.
//! Take the side the closure changes (the empty space round a tunnel to fill, the material of a
//! bar to cut), with its own adjacency. A path of that side from one face of the fan to the other
//! that does not cross the fan closes, across the fan, into a loop linked once with the loop to
//! close (the fan is a disk it bounds): those are the paths the wall must stop. So the wall is a
//! minimum set of samples separating the samples just on one face of the fan from those just on
//! the other and from everything outside a box round the loop:
//!
//! ```text
//!      outside the box: sink          W (left unchanged) lies between the fan and the wall;
//!     .........................       the wall D is the fewest samples whose removal cuts
//!     .   D D D D D D D D     .       every path of the side from the fan's + face (source)
//!     .   D      W      D     .       to its - face or out of the box (sink)
//!     .  x---+ + + + +---x    .
//!     .  loop  fan   -        .
//!     .........................
//! ```
//!
//! Either face can be the source; both are tried, in boxes of growing margins, and every wall
//! is verified by [`super::close`] like any other. The cut is a maximum flow (Dinic's
//! algorithm) on the samples of the box, each with capacity one.

use super::{centroid, Operation};
use crate::loops::search::FastMap;
use crate::surface::Vertex;
use crate::sweep::MaskVolume;
use crate::topology::cases::Connectivity;

/// Offsets of the 26 neighbours, the 6 face neighbours first.
const NEIGHBOURS: [[i64; 3]; 26] = {
    let mut out = [[0i64; 3]; 26];
    let mut n = 0;
    // Face neighbours, then edge and corner ones (the order a 6-adjacency takes a prefix of).
    let mut pass = 0;
    while pass < 2 {
        let mut i = 0;
        while i < 27 {
            let d = [
                (i % 3) as i64 - 1,
                (i / 3 % 3) as i64 - 1,
                (i / 9) as i64 - 1,
            ];
            let m = d[0].abs() + d[1].abs() + d[2].abs();
            if m != 0 && ((pass == 0) == (m == 1)) {
                out[n] = d;
                n += 1;
            }
            i += 1;
        }
        pass += 1;
    }
    out
};

/// The adjacency of the samples a closure changes: filling changes outside samples, cutting
/// inside ones; connectivity 6 makes inside samples 6-adjacent and outside ones 26-adjacent.
fn changed_side_neighbours(op: Operation, conn: Connectivity) -> &'static [[i64; 3]] {
    let six = match op {
        Operation::Collapse => conn == Connectivity::TwentySix,
        Operation::Pinch => conn == Connectivity::Six,
    };
    if six {
        &NEIGHBOURS[..6]
    } else {
        &NEIGHBOURS[..]
    }
}

/// The loop's spanning fan as triangles (apex first), with an index of the voxels each is near.
struct Fan {
    triangles: Vec<[[f64; 3]; 3]>,
    /// Voxel (lower corner) -> triangles within one voxel of it.
    near: FastMap<[i64; 3], Vec<u32>>,
}

impl Fan {
    fn new(points: &[[f64; 3]]) -> Fan {
        // An apex off every grid plane and diagonal, so that no segment between samples passes
        // exactly through an edge of the fan.
        let c = centroid(points);
        let apex = [c[0] + 0.001_234, c[1] + 0.002_345, c[2] + 0.003_101];
        let mut triangles = Vec::with_capacity(points.len());
        let mut near: FastMap<[i64; 3], Vec<u32>> = FastMap::default();
        for i in 0..points.len() {
            let t = [apex, points[i], points[(i + 1) % points.len()]];
            let lo: [i64; 3] =
                std::array::from_fn(|k| (t[0][k].min(t[1][k]).min(t[2][k])).floor() as i64 - 1);
            let hi: [i64; 3] =
                std::array::from_fn(|k| (t[0][k].max(t[1][k]).max(t[2][k])).ceil() as i64 + 1);
            for z in lo[2]..=hi[2] {
                for y in lo[1]..=hi[1] {
                    for x in lo[0]..=hi[0] {
                        near.entry([x, y, z]).or_default().push(i as u32);
                    }
                }
            }
            triangles.push(t);
        }
        Fan { triangles, near }
    }

    /// How the segment from sample `a` to sample `b` crosses the fan: `None` an even number of
    /// times, else whether `a` lies on the + face (the side the triangles' normals point to) at
    /// its first crossing.
    fn crossing(&self, a: [i64; 3], b: [i64; 3]) -> Option<bool> {
        let list = self.near.get(&a)?;
        let (p, q) = (a.map(|x| x as f64), b.map(|x| x as f64));
        let d = sub(q, p);
        let mut count = 0;
        let mut first: Option<(f64, bool)> = None;
        for &t in list {
            let [v0, v1, v2] = self.triangles[t as usize];
            let (e1, e2) = (sub(v1, v0), sub(v2, v0));
            let h = cross(d, e2);
            let det = dot(e1, h);
            if det.abs() < 1e-12 {
                continue;
            }
            let f = 1.0 / det;
            let s = sub(p, v0);
            let u = f * dot(s, h);
            if !(0.0..=1.0).contains(&u) {
                continue;
            }
            let qq = cross(s, e1);
            let v = f * dot(d, qq);
            if v < 0.0 || u + v > 1.0 {
                continue;
            }
            let at = f * dot(e2, qq);
            if at <= 0.0 || at >= 1.0 {
                continue;
            }
            count += 1;
            if first.is_none_or(|(x, _)| at < x) {
                // a is on the + face when the segment runs against the normal.
                first = Some((at, dot(d, cross(e1, e2)) < 0.0));
            }
        }
        (count % 2 == 1).then(|| first.map(|x| x.1)).flatten()
    }
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// Capacity of an arc that a cut never takes.
const UNBOUNDED: u32 = u32::MAX / 4;

/// Samples a minimum-cut wall may look at (its box), beyond which none is tried.
const MAX_BOX_SAMPLES: usize = 1 << 21;

/// A minimum-cut wall for closing the loop `lp` (vertices in the volume's local coordinates) by
/// `op`: samples of the changed side within `margin` of the loop's box, with the fan's + face
/// as the source when `plus_source` (else its - face). `None` if no finite cut exists (the two
/// faces are joined by samples that cannot change, like the padding) or the box is too large.
pub fn min_cut_wall(
    vol: &MaskVolume,
    conn: Connectivity,
    lp: &[Vertex],
    op: Operation,
    margin: i64,
    plus_source: bool,
) -> Option<Vec<[i64; 3]>> {
    let points: Vec<[f64; 3]> = lp.iter().map(|v| v.midpoint()).collect();
    let fan = Fan::new(&points);
    let dims = vol.dims.map(|n| n as i64);
    // The box (padding included: it cannot change, but paths of outside may run through it).
    let lo: [i64; 3] = std::array::from_fn(|k| {
        (points
            .iter()
            .map(|p| p[k])
            .fold(f64::INFINITY, f64::min)
            .floor() as i64
            - margin)
            .max(-1)
    });
    let hi: [i64; 3] = std::array::from_fn(|k| {
        (points
            .iter()
            .map(|p| p[k])
            .fold(f64::NEG_INFINITY, f64::max)
            .ceil() as i64
            + margin)
            .min(dims[k])
    });
    let size: [usize; 3] = std::array::from_fn(|k| (hi[k] - lo[k] + 1) as usize);
    if size.iter().product::<usize>() > MAX_BOX_SAMPLES {
        return None;
    }
    let side = !op.target();
    let in_volume = |q: [i64; 3]| (0..3).all(|k| q[k] >= 0 && q[k] < dims[k]);
    let state = |q: [i64; 3]| in_volume(q) && vol.get(q[0], q[1], q[2]);
    let in_box = |q: [i64; 3]| (0..3).all(|k| lo[k] <= q[k] && q[k] <= hi[k]);
    // Number the box's samples of the changed side.
    let mut id: FastMap<[i64; 3], u32> = FastMap::default();
    let mut samples: Vec<[i64; 3]> = Vec::new();
    for z in lo[2]..=hi[2] {
        for y in lo[1]..=hi[1] {
            for x in lo[0]..=hi[0] {
                let q = [x, y, z];
                if state(q) == side {
                    id.insert(q, samples.len() as u32);
                    samples.push(q);
                }
            }
        }
    }
    let foreign = foreign_neighbours(vol, conn, lp, op, lo, hi);
    // Flow network: sample i is arc 2i -> 2i + 1 (capacity 1, or unbounded for padding and for
    // samples beside another piece of the other side); S = 2n, T = 2n + 1.
    let n = samples.len() as u32;
    let (source, sink) = (2 * n, 2 * n + 1);
    let mut net = Network::new(2 * n as usize + 2);
    for (i, &q) in samples.iter().enumerate() {
        let i = i as u32;
        let fixed = !in_volume(q) || foreign.contains_key(&q);
        net.arc(2 * i, 2 * i + 1, if fixed { UNBOUNDED } else { 1 });
        for d in changed_side_neighbours(op, conn) {
            let r = [q[0] + d[0], q[1] + d[1], q[2] + d[2]];
            if state(r) != side {
                continue;
            }
            match (fan.crossing(q, r), id.get(&r)) {
                // Out of the box (the fan is well inside it): left as it is.
                (None, None) => net.arc(2 * i + 1, sink, UNBOUNDED),
                (None, Some(&j)) => net.arc(2 * i + 1, 2 * j, UNBOUNDED),
                // Across the fan: the sample on the source's face stays on the wall's side.
                (Some(q_plus), _) => {
                    if q_plus == plus_source {
                        net.arc(source, 2 * i, UNBOUNDED);
                    } else {
                        net.arc(2 * i + 1, sink, UNBOUNDED);
                    }
                }
            }
        }
    }
    debug_assert!(samples.iter().all(|&q| in_box(q)));
    let reach = net.min_cut(source, sink, samples.len() as u32 + 1)?;
    let wall: Vec<[i64; 3]> = (0..n)
        .filter(|&i| reach[2 * i as usize] && !reach[2 * i as usize + 1])
        .map(|i| samples[i as usize])
        .collect();
    (!wall.is_empty()).then_some(wall)
}

/// Samples of the changed side next to a piece of the other side that is not the loop's own
/// (a component of the box's samples of the other side holding none of the loop's ends there):
/// flipping one would join that piece to the wall (a blob floating in a tunnel to fill, a
/// cavity beside a bar to cut), so the cut must go round them.
fn foreign_neighbours(
    vol: &MaskVolume,
    conn: Connectivity,
    lp: &[Vertex],
    op: Operation,
    lo: [i64; 3],
    hi: [i64; 3],
) -> FastMap<[i64; 3], ()> {
    let other = op.target();
    let dims = vol.dims.map(|n| n as i64);
    let in_box = |q: [i64; 3]| (0..3).all(|k| lo[k] <= q[k] && q[k] <= hi[k]);
    let state =
        |q: [i64; 3]| (0..3).all(|k| q[k] >= 0 && q[k] < dims[k]) && vol.get(q[0], q[1], q[2]);
    // The other side's adjacency: that of the samples the wall joins once flipped.
    let adj = changed_side_neighbours(super::opposite(op), conn);
    // The loop's ends on the other side, and their components within the box.
    let mut own: FastMap<[i64; 3], ()> = FastMap::default();
    let mut stack: Vec<[i64; 3]> = Vec::new();
    for v in lp {
        for q in [v.p, v.end()] {
            if in_box(q) && state(q) == other && own.insert(q, ()).is_none() {
                stack.push(q);
            }
        }
    }
    while let Some(q) = stack.pop() {
        for d in adj {
            let r = [q[0] + d[0], q[1] + d[1], q[2] + d[2]];
            if in_box(r) && state(r) == other && own.insert(r, ()).is_none() {
                stack.push(r);
            }
        }
    }
    let mut out: FastMap<[i64; 3], ()> = FastMap::default();
    for z in lo[2]..=hi[2] {
        for y in lo[1]..=hi[1] {
            for x in lo[0]..=hi[0] {
                let q = [x, y, z];
                if state(q) != other || own.contains_key(&q) {
                    continue;
                }
                for d in adj {
                    let r = [q[0] + d[0], q[1] + d[1], q[2] + d[2]];
                    if in_box(r) && state(r) != other {
                        out.insert(r, ());
                    }
                }
            }
        }
    }
    out
}

/// A flow network with integer capacities, for Dinic's maximum flow.
struct Network {
    /// Arcs in pairs (forward, backward): head and residual capacity.
    head: Vec<u32>,
    cap: Vec<u32>,
    /// Arcs out of each node (indices into `head`).
    out: Vec<Vec<u32>>,
}

impl Network {
    fn new(nodes: usize) -> Network {
        Network {
            head: Vec::new(),
            cap: Vec::new(),
            out: vec![Vec::new(); nodes],
        }
    }

    fn arc(&mut self, from: u32, to: u32, cap: u32) {
        let e = self.head.len() as u32;
        self.head.extend([to, from]);
        self.cap.extend([cap, 0]);
        self.out[from as usize].push(e);
        self.out[to as usize].push(e + 1);
    }

    /// Saturates a maximum flow from `s` to `t` and returns the nodes still reachable from `s`
    /// (the source side of a minimum cut), or `None` if the flow reaches `limit`.
    fn min_cut(&mut self, s: u32, t: u32, limit: u32) -> Option<Vec<bool>> {
        let nodes = self.out.len();
        let mut flow = 0u32;
        let mut level = vec![u32::MAX; nodes];
        let mut next = vec![0usize; nodes];
        loop {
            // Levels by breadth-first search in the residual network.
            level.iter_mut().for_each(|l| *l = u32::MAX);
            level[s as usize] = 0;
            let mut queue = std::collections::VecDeque::from([s]);
            while let Some(x) = queue.pop_front() {
                for &e in &self.out[x as usize] {
                    let y = self.head[e as usize];
                    if self.cap[e as usize] > 0 && level[y as usize] == u32::MAX {
                        level[y as usize] = level[x as usize] + 1;
                        queue.push_back(y);
                    }
                }
            }
            if level[t as usize] == u32::MAX {
                return Some(level.iter().map(|&l| l != u32::MAX).collect());
            }
            next.iter_mut().for_each(|x| *x = 0);
            while let Some(f) = self.augment(s, t, &level, &mut next) {
                flow = flow.saturating_add(f);
                if flow >= limit {
                    return None;
                }
            }
        }
    }

    /// One augmenting path along increasing levels (iterative depth-first search), pushing as
    /// much as it carries.
    fn augment(&mut self, s: u32, t: u32, level: &[u32], next: &mut [usize]) -> Option<u32> {
        let mut path: Vec<u32> = Vec::new(); // arcs
        let mut x = s;
        loop {
            if x == t {
                let f = path.iter().map(|&e| self.cap[e as usize]).min()?;
                for &e in &path {
                    self.cap[e as usize] -= f;
                    self.cap[(e ^ 1) as usize] += f;
                }
                return Some(f);
            }
            let arcs = &self.out[x as usize];
            let mut advanced = false;
            while next[x as usize] < arcs.len() {
                let e = arcs[next[x as usize]];
                let y = self.head[e as usize];
                if self.cap[e as usize] > 0 && level[y as usize] == level[x as usize] + 1 {
                    path.push(e);
                    x = y;
                    advanced = true;
                    break;
                }
                next[x as usize] += 1;
            }
            if !advanced {
                // Dead end: retreat one arc, and never try this node again in this phase.
                let e = path.pop()?;
                x = self.head[(e ^ 1) as usize];
                next[x as usize] += 1;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sweep::Frame;

    /// A 3×3 bar along x through a box: the loop round it (at x = 4) is cut by the nine samples
    /// of one cross-section, and filling is impossible (the loop goes round material).
    #[test]
    fn the_cut_of_a_bar_is_one_cross_section() {
        let mut vol = MaskVolume::new([10, 7, 7], Frame::identity());
        for x in 0..10 {
            for y in 2..5 {
                for z in 2..5 {
                    vol.set(x, y, z, true);
                }
            }
        }
        // The loop round the bar in the plane x = 4: crossings on the y and z edges around
        // the 3×3 section, counter-clockwise.
        let mut lp = Vec::new();
        for y in 2..5 {
            lp.push(Vertex {
                p: [4, y, 1],
                axis: 2,
            });
        }
        for z in 2..5 {
            lp.push(Vertex {
                p: [4, 4, z],
                axis: 1,
            });
        }
        for y in (2..5).rev() {
            lp.push(Vertex {
                p: [4, y, 4],
                axis: 2,
            });
        }
        for z in (2..5).rev() {
            lp.push(Vertex {
                p: [4, 1, z],
                axis: 1,
            });
        }
        for plus in [true, false] {
            let wall = min_cut_wall(&vol, Connectivity::Six, &lp, Operation::Pinch, 2, plus)
                .expect("a cut");
            assert_eq!(wall.len(), 9, "{wall:?}");
            let x0 = wall[0][0];
            assert!(wall.iter().all(|q| q[0] == x0), "{wall:?}");
        }
    }

    #[test]
    fn max_flow_of_two_disjoint_paths() {
        // s=0 -> 1 -> 3=t, s -> 2 -> t, and 1 -> 2.
        let mut net = Network::new(4);
        net.arc(0, 1, 1);
        net.arc(0, 2, 1);
        net.arc(1, 3, 1);
        net.arc(2, 3, 1);
        net.arc(1, 2, 1);
        let side = net.min_cut(0, 3, 10).unwrap();
        assert_eq!(side, vec![true, false, false, false]);
        let mut net = Network::new(3);
        net.arc(0, 1, UNBOUNDED);
        net.arc(1, 2, UNBOUNDED);
        assert!(net.min_cut(0, 2, 100).is_none());
    }
}
