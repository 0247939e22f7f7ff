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

    /// Shortest path from `from` to `to` (breadth-first, both included) through nodes that are
    /// not `blocked` (a node beyond the end of `blocked` is not).
    pub fn shortest_path(&mut self, from: u32, to: u32, blocked: &[bool]) -> Option<Vec<u32>> {
        let n = self.nodes.len();
        if self.stamp.len() < n {
            self.stamp.resize(n, 0);
            self.pred.resize(n, u32::MAX);
        }
        self.generation = self.generation.wrapping_add(1);
        if self.generation == 0 {
            self.stamp.iter_mut().for_each(|s| *s = 0);
            self.generation = 1;
        }
        let g = self.generation;
        let mut queue = std::collections::VecDeque::new();
        self.stamp[from as usize] = g;
        self.pred[from as usize] = u32::MAX;
        queue.push_back(from);
        let mut around = std::mem::take(&mut self.around);
        let mut found = false;
        while let Some(x) = queue.pop_front() {
            if x == to {
                found = true;
                break;
            }
            self.neighbours(x, &mut around);
            for &y in &around {
                if self.stamp[y as usize] != g && !blocked.get(y as usize).copied().unwrap_or(false)
                {
                    self.stamp[y as usize] = g;
                    self.pred[y as usize] = x;
                    queue.push_back(y);
                }
            }
        }
        self.around = around;
        if !found {
            return None;
        }
        let mut path = vec![to];
        let mut y = to;
        while self.pred[y as usize] != u32::MAX {
            y = self.pred[y as usize];
            path.push(y);
        }
        path.reverse();
        Some(path)
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
