//! The Reeb graph of the sweep: contour and ribbon nodes, union-find labels with rollback (so the
//! sweep can step back after a closure edits the volume), and breadth-first shortest paths.
//!
//! ```text
//!   plane s+1   (c3)     (c4)        contours are nodes, ribbons are nodes; an edge joins a
//!                 \       /          ribbon to each contour on its boundary. A cycle closes
//!   slice s       [ r2 ]  /          when a ribbon meets two contours already connected
//!                 /  \   /           below it: that cycle is a handle.
//!   plane s     (c1) (c2)
//! ```

/// What a node stands for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NodeKind {
    /// A contour in plane `level`.
    Contour,
    /// A ribbon in the slice between planes `level` and `level + 1`.
    Ribbon,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
/// A node of the Reeb graph: a contour of a plane or a ribbon of a slice.
pub struct Node {
    /// Contour or ribbon.
    pub kind: NodeKind,
    /// The contour's plane, or the ribbon's slice (its lower plane).
    pub level: i32,
    /// Index among the contours of its plane, or the ribbons of its slice.
    pub local: u32,
}

/// Union-find without path compression, so unions can be undone in reverse order.
#[derive(Clone, Debug, Default)]
pub struct RollbackUnionFind {
    parent: Vec<u32>,
    size: Vec<u32>,
    /// (child root that was attached, previous size of its new root)
    log: Vec<(u32, u32)>,
    /// No rollback will come: unions are not logged (8 bytes each saved).
    unlogged: bool,
}

impl RollbackUnionFind {
    pub fn push(&mut self) -> u32 {
        let i = self.parent.len() as u32;
        self.parent.push(i);
        self.size.push(1);
        i
    }

    #[inline]
    pub fn find(&self, mut x: u32) -> u32 {
        while self.parent[x as usize] != x {
            x = self.parent[x as usize];
        }
        x
    }

    pub fn union(&mut self, a: u32, b: u32) -> bool {
        let (mut ra, mut rb) = (self.find(a), self.find(b));
        if ra == rb {
            return false;
        }
        if self.size[ra as usize] < self.size[rb as usize] {
            std::mem::swap(&mut ra, &mut rb);
        }
        if !self.unlogged {
            self.log.push((rb, self.size[ra as usize]));
        }
        self.parent[rb as usize] = ra;
        self.size[ra as usize] += self.size[rb as usize];
        true
    }

    /// Forgets the unions so far and logs none from now on: no rollback can come.
    pub fn stop_logging(&mut self) {
        self.log = Vec::new();
        self.unlogged = true;
    }

    /// Is rolling back possible (unions logged)?
    pub fn logging(&self) -> bool {
        !self.unlogged
    }

    /// A point to roll back to: (elements, unions).
    pub fn checkpoint(&self) -> (usize, usize) {
        (self.parent.len(), self.log.len())
    }

    /// Undoes every union and element added since the checkpoint.
    pub fn rollback(&mut self, to: (usize, usize)) {
        while self.log.len() > to.1 {
            let (child, old_size) = self.log.pop().unwrap();
            let root = self.parent[child as usize];
            self.parent[child as usize] = child;
            self.size[root as usize] = old_size;
        }
        self.parent.truncate(to.0);
        self.size.truncate(to.0);
    }
}

/// A node in 8 bytes: its level, and its index with the kind in the top bit.
#[derive(Clone, Copy, Debug)]
struct PackedNode {
    level: i32,
    local_and_kind: u32,
}

const RIBBON_BIT: u32 = 1 << 31;

impl PackedNode {
    fn unpack(self) -> Node {
        let kind = if self.local_and_kind & RIBBON_BIT != 0 {
            NodeKind::Ribbon
        } else {
            NodeKind::Contour
        };
        Node {
            kind,
            level: self.level,
            local: self.local_and_kind & !RIBBON_BIT,
        }
    }
}

/// No half-edge: the end of a node's list.
const NONE: u32 = u32::MAX;

/// Contour and ribbon nodes and the edges between them.
///
/// A noisy volume has a node for every few hundred voxels, all kept until the sweep ends (a new
/// cycle may run down to the first plane), so a node costs about 60 bytes here: packed nodes,
/// and edges as lists of half-edges in one array rather than a vector per node.
///
/// ```text
///   edge k joins a and b:  half[2k] = (b, next of a),  half[2k+1] = (a, next of b)
///   first[a] -> newest half-edge of a -> ... -> NONE
/// ```
/// Edges are only ever removed newest first (rewinding), which restores every `first` exactly.
#[derive(Clone, Debug, Default)]
pub struct ReebGraph {
    nodes: Vec<PackedNode>,
    first: Vec<u32>,
    /// (the other end, the next half-edge of the same node)
    half: Vec<(u32, u32)>,
    pub uf: RollbackUnionFind,
    /// Breadth-first search scratch: visit stamp and predecessor per node, a node's neighbours.
    stamp: Vec<u32>,
    pred: Vec<u32>,
    generation: u32,
    around: Vec<u32>,
}

impl ReebGraph {
    pub(crate) fn add_node(&mut self, kind: NodeKind, level: i32, local: u32) -> u32 {
        let id = self.nodes.len() as u32;
        let bit = if kind == NodeKind::Ribbon {
            RIBBON_BIT
        } else {
            0
        };
        self.nodes.push(PackedNode {
            level,
            local_and_kind: (local & !RIBBON_BIT) | bit,
        });
        self.first.push(NONE);
        self.uf.push();
        id
    }

    pub(crate) fn add_edge(&mut self, a: u32, b: u32) {
        let k = self.half.len() as u32;
        self.half.push((b, self.first[a as usize]));
        self.half.push((a, self.first[b as usize]));
        self.first[a as usize] = k;
        self.first[b as usize] = k + 1;
        self.uf.union(a, b);
    }

    /// Node `n`.
    pub(crate) fn node(&self, n: u32) -> Node {
        self.nodes[n as usize].unpack()
    }

    /// How many nodes, and how many edges (what [`ReebGraph::truncate`] goes back to).
    pub(crate) fn size(&self) -> (usize, usize) {
        (self.nodes.len(), self.half.len() / 2)
    }

    pub fn connected(&self, a: u32, b: u32) -> bool {
        self.uf.find(a) == self.uf.find(b)
    }

    /// The neighbours of `x` into `out`, oldest edge first.
    fn neighbours(&self, x: u32, out: &mut Vec<u32>) {
        out.clear();
        let mut e = self.first[x as usize];
        while e != NONE {
            let (y, next) = self.half[e as usize];
            out.push(y);
            e = next;
        }
        out.reverse();
    }

    /// Shortest path from `from` to `to` (both included) through nodes that are not `blocked`
    /// (a node beyond the end of `blocked` is not).
    ///
    /// Breadth-first from both ends, a whole level of the smaller side at a time, until the
    /// two meet: the first level that meets closes a shortest path. With the cut contours
    /// blocked the graph is nearly a tree, so a search from one end would visit every node
    /// within the cycle's length of it; from both ends, those within half of it (128³ noise at
    /// tau inf: a tenth of the whole run went into these searches).
    ///
    /// ```text
    ///   from o--o--o--o--o  ·  o--o--o--o--o to     each side k levels deep; the next level
    ///          \           ^            /           of the smaller side reaches a node the
    ///           o         meet          o            other side stamped: path k + 1 + k'
    /// ```
    pub fn shortest_path(&mut self, from: u32, to: u32, blocked: &[bool]) -> Option<Vec<u32>> {
        let is_blocked = |y: u32| blocked.get(y as usize).copied().unwrap_or(false);
        if from == to {
            return Some(vec![from]);
        }
        if is_blocked(to) {
            return None;
        }
        let n = self.nodes.len();
        if self.stamp.len() < n {
            self.stamp.resize(n, 0);
            self.pred.resize(n, u32::MAX);
        }
        // Two stamps per search: one per side.
        self.generation = self.generation.wrapping_add(2);
        if self.generation < 2 {
            self.stamp.iter_mut().for_each(|s| *s = 0);
            self.generation = 2;
        }
        let (fwd_stamp, bwd_stamp) = (self.generation, self.generation + 1);
        for (x, st) in [(from, fwd_stamp), (to, bwd_stamp)] {
            self.stamp[x as usize] = st;
            self.pred[x as usize] = u32::MAX;
        }
        let (mut fwd, mut bwd) = (vec![from], vec![to]);
        let mut around = std::mem::take(&mut self.around);
        let meet = loop {
            if fwd.is_empty() || bwd.is_empty() {
                break None;
            }
            let forward = fwd.len() <= bwd.len();
            let (frontier, mine, theirs) = match forward {
                true => (&mut fwd, fwd_stamp, bwd_stamp),
                false => (&mut bwd, bwd_stamp, fwd_stamp),
            };
            let mut next = Vec::new();
            let mut met = None;
            for &x in frontier.iter() {
                self.neighbours(x, &mut around);
                for &y in &around {
                    let st = self.stamp[y as usize];
                    if st == mine || is_blocked(y) {
                        continue;
                    }
                    if st == theirs {
                        // No meet before this level: every meet of it closes a shortest
                        // path (of both sides' depths plus one). Keep the first.
                        met = met.or(Some(if forward { (x, y) } else { (y, x) }));
                        continue;
                    }
                    self.stamp[y as usize] = mine;
                    self.pred[y as usize] = x;
                    next.push(y);
                }
            }
            if met.is_some() {
                break met;
            }
            *frontier = next;
        };
        self.around = around;
        // (a, b): a reached from `from`, b from `to`, joined by an edge.
        let (a, b) = meet?;
        let mut path = self.chain(a);
        path.reverse();
        path.extend(self.chain(b));
        Some(path)
    }

    /// The nodes from `x` back to the start of its side's search, `x` first.
    fn chain(&self, mut x: u32) -> Vec<u32> {
        let mut out = vec![x];
        while self.pred[x as usize] != u32::MAX {
            x = self.pred[x as usize];
            out.push(x);
        }
        out
    }

    /// Goes back to `size` (from [`ReebGraph::size`]): removes the newer edges, newest first,
    /// then the newer nodes (no older edge reaches them).
    pub fn truncate(&mut self, size: (usize, usize)) {
        while self.half.len() > 2 * size.1 {
            let (a, next_b) = self.half.pop().expect("a pair");
            let (b, next_a) = self.half.pop().expect("a pair");
            self.first[a as usize] = next_a;
            self.first[b as usize] = next_b;
        }
        self.nodes.truncate(size.0);
        self.first.truncate(size.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Without path compression, finds walk up the tree: union by size keeps every tree's
    /// depth within log2 of its size, however the unions come (here each new element joined
    /// to the one big set, then pairs of sets of equal size).
    #[test]
    fn unions_by_size_keep_the_trees_shallow() {
        let depth = |uf: &RollbackUnionFind, mut x: u32| {
            let mut d = 0;
            while uf.parent[x as usize] != x {
                x = uf.parent[x as usize];
                d += 1;
            }
            d
        };
        let mut chain = RollbackUnionFind::default();
        chain.push();
        for i in 1..1024 {
            chain.push();
            assert!(chain.union(i, 0));
        }
        assert!((0..1024).all(|x| depth(&chain, x) <= 1));
        let mut pairs = RollbackUnionFind::default();
        for _ in 0..1024 {
            pairs.push();
        }
        let mut step = 1u32;
        while step < 1024 {
            for i in (0..1024u32).step_by(2 * step as usize) {
                assert!(pairs.union(i + step, i));
            }
            step *= 2;
        }
        assert!((0..1024).all(|x| depth(&pairs, x) <= 10));
        assert_eq!(pairs.find(1023), pairs.find(0));
    }

    #[test]
    fn rollback_restores_components() {
        let mut uf = RollbackUnionFind::default();
        for _ in 0..6 {
            uf.push();
        }
        uf.union(0, 1);
        let cp = uf.checkpoint();
        uf.union(1, 2);
        uf.push();
        uf.union(6, 0);
        assert_eq!(uf.find(2), uf.find(6));
        uf.rollback(cp);
        assert_eq!(uf.find(0), uf.find(1));
        assert_ne!(uf.find(0), uf.find(2));
        assert_eq!(uf.checkpoint(), cp);
    }

    #[test]
    fn shortest_path_finds_the_short_way_round() {
        let mut g = ReebGraph::default();
        for i in 0..6 {
            g.add_node(NodeKind::Contour, 0, i);
        }
        // 0-1-2-3 and 0-4-3, 5 isolated.
        for (a, b) in [(0, 1), (1, 2), (2, 3), (0, 4), (4, 3)] {
            g.add_edge(a, b);
        }
        assert_eq!(g.shortest_path(0, 3, &[]), Some(vec![0, 4, 3]));
        assert_eq!(g.shortest_path(0, 5, &[]), None);
        // With 4 blocked, the long way.
        let blocked = [false, false, false, false, true];
        assert_eq!(g.shortest_path(0, 3, &blocked), Some(vec![0, 1, 2, 3]));
    }

    /// The search from both ends finds paths as short as a breadth-first search from one end
    /// (the oracle, written out here), through edges of the graph and no blocked node: 400
    /// random graphs, sparse trees with a few extra edges (as the sweep's graph is, its cut
    /// contours blocked) and denser ones, some nodes blocked, every pair of ends tried.
    #[test]
    fn shortest_paths_from_both_ends_are_as_short_as_from_one() {
        use crate::test_rng::Rng;
        let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
        let (mut found, mut none) = (0, 0);
        for round in 0..400 {
            let n = 2 + rng.below(30) as u32;
            let extra = if round % 2 == 0 {
                rng.below(4)
            } else {
                rng.below(40)
            };
            let mut g = ReebGraph::default();
            let mut adj = vec![Vec::new(); n as usize];
            let mut edge = |g: &mut ReebGraph, a: u32, b: u32| {
                g.add_edge(a, b);
                adj[a as usize].push(b);
                adj[b as usize].push(a);
            };
            for i in 0..n {
                g.add_node(NodeKind::Contour, i as i32, i);
                // A forest: each node joined to an earlier one, now and then not at all.
                if i > 0 && rng.below(8) != 0 {
                    edge(&mut g, i, rng.below(i as u64) as u32);
                }
            }
            for _ in 0..extra {
                let (a, b) = (rng.below(n as u64) as u32, rng.below(n as u64) as u32);
                if a != b {
                    edge(&mut g, a, b);
                }
            }
            let blocked: Vec<bool> = (0..n).map(|_| rng.below(6) == 0).collect();
            // The oracle: distances from `from` by a plain breadth-first search (which may
            // start at a blocked node, never step on one).
            let bfs = |from: u32| {
                let mut d = vec![u32::MAX; n as usize];
                let mut queue = std::collections::VecDeque::from([from]);
                d[from as usize] = 0;
                while let Some(x) = queue.pop_front() {
                    for &y in &adj[x as usize] {
                        if d[y as usize] == u32::MAX && !blocked[y as usize] {
                            d[y as usize] = d[x as usize] + 1;
                            queue.push_back(y);
                        }
                    }
                }
                d
            };
            for from in 0..n {
                let d = bfs(from);
                for to in 0..n {
                    let path = g.shortest_path(from, to, &blocked);
                    let want = (d[to as usize] != u32::MAX).then_some(d[to as usize]);
                    let Some(p) = path else {
                        assert_eq!(want, None, "{from} -> {to}, round {round}");
                        none += 1;
                        continue;
                    };
                    found += 1;
                    assert_eq!(Some(p.len() as u32 - 1), want, "{from} -> {to}: {p:?}");
                    assert_eq!((p[0], p[p.len() - 1]), (from, to));
                    for w in p.windows(2) {
                        assert!(adj[w[0] as usize].contains(&w[1]), "{p:?}");
                    }
                    assert!(p[1..].iter().all(|&x| !blocked[x as usize]), "{p:?}");
                }
            }
        }
        assert!(found > 20_000 && none > 5_000, "{found} paths, {none} none");
    }

    /// The searches' stamps wrap round after 2^31 searches: the stamps are cleared then, and a
    /// search right after the wrap finds the same paths as any other (a stale stamp would make
    /// a node look visited).
    #[test]
    fn shortest_paths_survive_the_stamps_wrapping_round() {
        // Searched before the wrap or not: no stamp, or stale ones.
        for (start, before) in [
            (u32::MAX - 3, true),
            (u32::MAX - 1, true),
            (u32::MAX - 1, false),
        ] {
            let mut g = ReebGraph::default();
            for i in 0..6 {
                g.add_node(NodeKind::Contour, 0, i);
            }
            // 0-1-2-3 and 0-4-3, 5 isolated.
            for (a, b) in [(0, 1), (1, 2), (2, 3), (0, 4), (4, 3)] {
                g.add_edge(a, b);
            }
            if before {
                assert_eq!(g.shortest_path(0, 2, &[]), Some(vec![0, 1, 2]));
            }
            g.generation = start;
            for _ in 0..3 {
                assert_eq!(
                    g.shortest_path(0, 3, &[]),
                    Some(vec![0, 4, 3]),
                    "from {start}"
                );
                assert_eq!(g.shortest_path(2, 4, &[]).map(|p| p.len()), Some(3));
                assert_eq!(g.shortest_path(0, 5, &[]), None);
            }
            assert!(g.generation < 32, "wrapped round: {}", g.generation);
        }
    }

    #[test]
    fn truncate_restores_edges_and_nodes() {
        let mut g = ReebGraph::default();
        for i in 0..4 {
            g.add_node(NodeKind::Ribbon, i, i as u32);
        }
        g.add_edge(0, 1);
        g.add_edge(1, 2);
        let size = g.size();
        let cp = g.uf.checkpoint();
        g.add_node(NodeKind::Contour, 7, 3);
        g.add_edge(4, 1);
        g.add_edge(2, 3);
        g.add_edge(3, 0);
        assert_eq!(g.shortest_path(0, 3, &[]), Some(vec![0, 3]));
        assert_eq!(g.shortest_path(4, 0, &[]), Some(vec![4, 1, 0]));
        g.truncate(size);
        g.uf.rollback(cp);
        assert_eq!(g.size(), (4, 2));
        assert_eq!(g.shortest_path(0, 2, &[]), Some(vec![0, 1, 2]));
        assert_eq!(g.shortest_path(0, 3, &[]), None);
        let mut around = Vec::new();
        g.neighbours(1, &mut around);
        assert_eq!(around, vec![0, 2]);
        assert_eq!(
            g.node(2),
            Node {
                kind: NodeKind::Ribbon,
                level: 2,
                local: 2
            }
        );
    }
}
