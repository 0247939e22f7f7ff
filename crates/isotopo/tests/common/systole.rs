//! An independent oracle for the systole of an isosurface (test-only).
//!
//! [`systole`] gives the length of the shortest closed walk of the isosurface's *surface graph*
//! (the graph isotopo measures handle loops on, the paper's "voxel edges") that is non-trivial in
//! H1(S; Z/2), i.e. for a simple cycle, that does not separate its surface: in graph edges and in
//! mm, each minimised on its own. It ports the method of `scripts/oracle_loops.py` (its
//! `surface_graph`, `homology` and `systole`) and shares no code with isotopo's loop searches:
//! from the library it uses only the mesh extraction (`isotopo::mesh::extract`) and the volume.
//!
//! # Method
//!
//! 1. **Mesh → grid.** Every mesh vertex lies on a grid edge whose two samples are on opposite
//!    sides of the isovalue; in voxel coordinates (the in-memory volume's geometry is the
//!    identity, which is checked) it has two integer coordinates and one fractional one, at least
//!    1e-3 from an integer (isotopo clamps the interpolation fraction to [0.001, 0.999]). The
//!    vertex is keyed by that edge: its lower end and axis ([`GridEdge`]).
//! 2. **Mesh facts**, checked on every input (the error says which failed): the vertices are exactly
//!    the crossing grid edges of the volume (padded with outside), at the clamped linear
//!    interpolation; the mesh is closed, consistently oriented and a 2-manifold (every vertex's
//!    link one cycle); each triangle's three grid edges are edges of one unit cube (its lower
//!    corner is their componentwise minimum) and never all in one face of it.
//! 3. **Pieces**: the triangles of one cube, connected through shared mesh edges. Each is a disk
//!    (Euler characteristic 1, one boundary loop) or a tube (an annulus: 0, two loops); every
//!    boundary edge is a segment on the face between two face-adjacent cubes; every vertex lies in
//!    exactly four pieces, one in each cube round its grid edge, and on four face segments.
//! 4. **Surface graph**: the mesh vertices, joined by (a) every mesh edge on a piece boundary (the
//!    face segments) and (b) every mesh edge interior to a tube (isotopo takes the triangulation's
//!    diagonals through a tube, which no path on the cube faces could cross). Mesh edges inside
//!    disk pieces are *not* graph edges ([`GraphRule::WithDiskInterior`] adds them, only to show
//!    that this matters). Lengths: 1 per edge, or the distance of the two interpolated vertices.
//! 5. **Z/2 homology by tree–cotree**, per connected component, on the whole triangle mesh: a
//!    spanning tree T of the vertices over all mesh edges, a spanning tree of the triangles across
//!    the edges not in T, and the 2g edges left over. Each mesh edge gets a class in (Z/2)^(2g)
//!    (bitsets of u64 words; bits are numbered globally, so components never mix): T's edges 0,
//!    leftover edge k the unit vector e_k, cotree edges fixed by making every triangle's boundary
//!    sum to 0 (peeling dual-tree leaves towards the root; the root's boundary must then sum to 0
//!    too, which is checked). This map kills boundaries and sends the fundamental cycle of leftover
//!    edge k to e_k, so it is an isomorphism H1(S; Z/2) → (Z/2)^(2g): a closed walk is non-trivial
//!    iff the XOR of its edges' classes is non-zero. 2g = 2 - chi is checked per component.
//! 6. **Systole**: from a source s, a shortest-path tree (Dijkstra; every weight 1 in edges);
//!    every graph edge (a, b) closes the walk tree(s..a) + ab + tree(b..s) of length
//!    d(a) + w(a, b) + d(b) and class c(a) + c(b) + h(a, b); the smallest non-trivial one over all
//!    sources is kept.
//!
//! # Why it is exact
//!
//! If C is a shortest non-trivial cycle through s, C is the sum (Z/2) of the fundamental cycles of
//! its non-tree edges, so one of them is non-trivial; and its length is at most |C|, since the
//! two tree paths are no longer than the two arcs of C they replace. So the minimum over *all*
//! sources is the systole, and a minimal walk is a simple cycle (otherwise it splits into two
//! shorter closed walks, one of them still non-trivial; this is asserted). Three prunings keep it
//! exact and fast:
//! - (a) sources are only the vertices of 2g graph cycles whose classes span H1 (fundamental cycles
//!   of a breadth-first tree of the surface graph, shortest first, kept while independent; the
//!   graph is the 1-skeleton of a decomposition of the surface into disks — disk pieces, tubes cut
//!   along their diagonals — so its cycles span H1, which is checked). The intersection form is
//!   non-degenerate, so a non-trivial C pairs oddly with one of them, and two graph cycles that
//!   cross oddly share a vertex;
//! - (b) to beat the best length B so far, every vertex of C is within |C|/2 < B/2 of s along C,
//!   so a search stops at radius B/2;
//! - (c) once v has been a source, every cycle through v is accounted for, so later searches avoid
//!   v (the first source met on C still sees all of C).

use super::UnionFind;
use isotopo::mesh::{extract, Mesh};
use isotopo::progress::NoProgress;
use isotopo::topology::Connectivity;
use isotopo::volume::{Affine, InMemoryVolume};
use std::cmp::Reverse;
use std::collections::BinaryHeap;

/// Returns an error (the mesh fact that failed) unless the condition holds.
macro_rules! ensure {
    ($cond:expr, $($msg:tt)+) => {
        let holds: bool = $cond;
        if !holds {
            return Err(format!($($msg)+));
        }
    };
}

/// The systole of an isosurface; `None` when every surface has genus 0.
#[derive(Clone, Debug)]
pub struct Systole {
    /// Length of the shortest non-trivial closed walk, in graph edges.
    pub edges: Option<usize>,
    /// Length of the shortest non-trivial closed walk in mm (minimised on its own).
    pub mm: Option<f64>,
    /// Total genus of the isosurface (over all its surfaces).
    pub genus: usize,
    /// The edge systole's cycle: its vertices' grid edge midpoints, in voxel coordinates.
    pub cycle: Vec<[f64; 3]>,
}

/// Shortest non-trivial (non-separating) closed walk of the isosurface's surface graph, in edges
/// and in mm (each its own minimisation), for the volume at `iso` (inside = value > iso), given
/// connectivity.
pub fn systole(vol: &InMemoryVolume, iso: f64, conn: Connectivity) -> Systole {
    Surface::new(vol, iso, conn, GraphRule::Exact).systole()
}

/// Which mesh edges are graph edges.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GraphRule {
    /// Piece boundaries and tube interiors (the surface graph).
    Exact,
    /// Also the edges inside disk pieces: a deliberately wrong graph, for the mutation test.
    WithDiskInterior,
}

/// How a walk is measured.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Metric {
    Edges,
    Mm,
}

/// A grid edge: its lower end (voxel indices, -1 and n for the padding) and its axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct GridEdge {
    pub lo: [i32; 3],
    pub axis: usize,
}

impl GridEdge {
    /// The edge's midpoint, voxel coordinates.
    pub fn midpoint(&self) -> [f64; 3] {
        let mut p = self.lo.map(f64::from);
        p[self.axis] += 0.5;
        p
    }

    fn hi(&self) -> [i32; 3] {
        let mut p = self.lo;
        p[self.axis] += 1;
        p
    }
}

/// The isosurface as a mesh, its surface graph and its Z/2 homology.
pub struct Surface {
    /// Interpolated vertex positions, voxel coordinates (= mm, identity geometry).
    pub positions: Vec<[f64; 3]>,
    /// Each vertex's grid edge.
    pub grid_edges: Vec<GridEdge>,
    pub triangles: Vec<[u32; 3]>,
    /// Mesh edges, lower vertex first.
    pub edges: Vec<[u32; 2]>,
    /// The two triangles of each mesh edge.
    pub edge_tris: Vec<[u32; 2]>,
    /// The mesh edges of each triangle: (t0 t1), (t1 t2), (t2 t0).
    pub tri_edges: Vec<[u32; 3]>,
    /// Whether each mesh edge is a graph edge.
    pub is_graph_edge: Vec<bool>,
    /// Number of tube pieces.
    pub tubes: usize,
    /// Connected component of each vertex.
    pub component: Vec<u32>,
    /// Genus of each component.
    pub genus: Vec<usize>,
    /// Mesh adjacency (neighbour, mesh edge), over all mesh edges.
    mesh_adj: Csr,
    /// Graph adjacency (neighbour, mesh edge), over graph edges only.
    graph_adj: Csr,
    classes: Classes,
}

impl Surface {
    /// Extracts the isosurface of `vol` at `iso` and builds everything, checking the mesh facts
    /// (module doc, 2-3) and the homology (5); panics with the fact that failed.
    pub fn new(vol: &InMemoryVolume, iso: f64, conn: Connectivity, rule: GraphRule) -> Surface {
        Surface::from_mesh(mesh_of(vol, iso, conn), vol, iso, rule)
            .unwrap_or_else(|e| panic!("systole oracle: {e}"))
    }

    /// As [`Surface::new`], from a mesh extracted from `vol` at `iso`; the error names the mesh
    /// fact that does not hold (tests corrupt meshes to see them refused).
    pub fn from_mesh(
        mesh: Mesh,
        vol: &InMemoryVolume,
        iso: f64,
        rule: GraphRule,
    ) -> Result<Surface, String> {
        ensure!(
            vol.info.affine.max_diff(&Affine::IDENTITY) == 0.0,
            "the oracle needs identity geometry (voxel coordinates = mm)"
        );
        let positions: Vec<[f64; 3]> = mesh.vertices.iter().map(|p| p.map(f64::from)).collect();
        let grid_edges = positions
            .iter()
            .enumerate()
            .map(|(v, &p)| {
                grid_edge_of(p).ok_or(format!(
                    "vertex {v} at {p:?} is not clearly on one grid edge"
                ))
            })
            .collect::<Result<Vec<GridEdge>, String>>()?;
        check_against_volume(vol, iso, &grid_edges, &positions)?;
        let n = positions.len();
        let triangles = mesh.triangles;
        let me = mesh_edges(&triangles, n)?;
        check_fans(&triangles, n)?;
        let cube = cubes(&grid_edges, &triangles)?;
        let pieces = pieces(&me, &cube, &triangles, &grid_edges, n)?;
        let is_graph_edge: Vec<bool> = (0..me.edges.len())
            .map(|e| {
                let [t0, t1] = me.edge_tris[e].map(|t| t as usize);
                let boundary = cube[t0] != cube[t1];
                boundary || pieces.is_tube[pieces.of_tri[t0] as usize] || rule != GraphRule::Exact
            })
            .collect();
        let mesh_adj = Csr::new(n, me.edges.iter().enumerate().map(|(e, &uv)| (uv, e)));
        let graph_adj = Csr::new(
            n,
            me.edges
                .iter()
                .enumerate()
                .filter(|&(e, _)| is_graph_edge[e])
                .map(|(e, &uv)| (uv, e)),
        );
        let hom = homology(n, &me, &mesh_adj)?;
        Ok(Surface {
            positions,
            grid_edges,
            triangles,
            edges: me.edges,
            edge_tris: me.edge_tris,
            tri_edges: me.tri_edges,
            is_graph_edge,
            tubes: pieces.is_tube.iter().filter(|&&t| t).count(),
            component: hom.component,
            genus: hom.genus,
            mesh_adj,
            graph_adj,
            classes: hom.classes,
        })
    }

    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    pub fn total_genus(&self) -> usize {
        self.genus.iter().sum()
    }

    /// Graph neighbours of `v`: (neighbour, mesh edge).
    pub fn neighbours(&self, v: u32) -> &[(u32, u32)] {
        self.graph_adj.of(v)
    }

    /// The mesh edge joining `u` and `v`, if any.
    pub fn mesh_edge(&self, u: u32, v: u32) -> Option<u32> {
        self.mesh_adj
            .of(u)
            .iter()
            .find(|&&(x, _)| x == v)
            .map(|&(_, e)| e)
    }

    /// Length of mesh edge `e` in `metric`.
    pub fn length(&self, e: u32, metric: Metric) -> f64 {
        match metric {
            Metric::Edges => 1.0,
            Metric::Mm => {
                let [a, b] = self.edges[e as usize].map(|v| self.positions[v as usize]);
                ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
            }
        }
    }

    /// Homology class of mesh edge `e`.
    pub fn edge_class(&self, e: u32) -> &[u64] {
        self.classes.of(e)
    }

    /// Whether the closed walk through `cycle` (last vertex joined back to the first, along mesh
    /// edges) is non-trivial in H1.
    pub fn is_nontrivial(&self, cycle: &[u32]) -> bool {
        let mut c = vec![0u64; self.classes.words];
        for (i, &u) in cycle.iter().enumerate() {
            let v = cycle[(i + 1) % cycle.len()];
            let e = self
                .mesh_edge(u, v)
                .unwrap_or_else(|| panic!("vertices {u} and {v} are not joined by a mesh edge"));
            xor_into(&mut c, self.edge_class(e));
        }
        c.iter().any(|&w| w != 0)
    }

    /// Both systoles; the cycle is the edge systole's.
    pub fn systole(&self) -> Systole {
        let sources = self.hitting_set();
        let by_edges = self.shortest_nontrivial(Metric::Edges, &sources);
        let by_mm = self.shortest_nontrivial(Metric::Mm, &sources);
        if let Some((len, c)) = &by_edges {
            assert_eq!(
                *len,
                c.len() as f64,
                "edge systole: length and cycle disagree"
            );
        }
        Systole {
            edges: by_edges.as_ref().map(|(_, c)| c.len()),
            mm: by_mm.map(|(l, _)| l),
            genus: self.total_genus(),
            cycle: by_edges
                .map(|(_, c)| {
                    c.iter()
                        .map(|&v| self.grid_edges[v as usize].midpoint())
                        .collect()
                })
                .unwrap_or_default(),
        }
    }

    /// The shortest non-trivial closed walk in `metric`, as (length, simple cycle of vertices),
    /// searched from every vertex of `sources` (which must meet every non-trivial cycle: see
    /// [`Surface::hitting_set`]).
    pub fn shortest_nontrivial(&self, metric: Metric, sources: &[u32]) -> Option<(f64, Vec<u32>)> {
        const EPS: f64 = 1e-9;
        let weight: Vec<f64> = (0..self.edges.len() as u32)
            .map(|e| self.length(e, metric))
            .collect();
        let mut search = Search::new(self.vertex_count(), self.classes.words);
        let mut done = vec![false; self.vertex_count()];
        let mut best = f64::INFINITY;
        let mut best_cycle = None;
        for &s in sources {
            search.run(self, &weight, s, best / 2.0 + EPS, &done);
            for &u in &search.finished {
                for &(x, e) in self.neighbours(u) {
                    if x < u || !search.is_finished[x as usize] {
                        continue; // each edge once, both ends in the tree
                    }
                    let len =
                        search.dist[u as usize] + weight[e as usize] + search.dist[x as usize];
                    if len < best - EPS && search.closes_nontrivially(self, u, x, e) {
                        best = len;
                        best_cycle = Some(search.cycle(u, x));
                    }
                }
            }
            search.reset();
            done[s as usize] = true;
        }
        let cycle = best_cycle?;
        let mut sorted = cycle.clone();
        sorted.sort_unstable();
        sorted.dedup();
        assert!(
            sorted.len() == cycle.len() && cycle.len() >= 3,
            "a minimal non-trivial walk must be a simple cycle: {cycle:?}"
        );
        Some((best, cycle))
    }

    /// Vertices that every non-trivial closed walk passes through: those of 2g graph cycles whose
    /// classes span H1 (module doc, pruning (a)). Sorted.
    pub fn hitting_set(&self) -> Vec<u32> {
        let n = self.vertex_count();
        let words = self.classes.words;
        // Breadth-first trees of the graph, on the components of positive genus.
        let mut depth = vec![u32::MAX; n];
        let mut parent = vec![u32::MAX; n];
        let mut cls = vec![0u64; n * words];
        let mut queue = std::collections::VecDeque::new();
        for r in 0..n as u32 {
            if depth[r as usize] != u32::MAX || self.genus[self.component[r as usize] as usize] == 0
            {
                continue;
            }
            depth[r as usize] = 0;
            queue.push_back(r);
            while let Some(u) = queue.pop_front() {
                for &(x, e) in self.neighbours(u) {
                    if depth[x as usize] == u32::MAX {
                        depth[x as usize] = depth[u as usize] + 1;
                        parent[x as usize] = u;
                        set_xor(&mut cls, words, x, u, self.edge_class(e));
                        queue.push_back(x);
                    }
                }
            }
        }
        // Fundamental cycles of the non-tree edges, shortest first, kept while independent.
        let mut cand: Vec<(u32, u32, u32, u32)> = Vec::new(); // (length, u, x, edge)
        for u in 0..n as u32 {
            if depth[u as usize] == u32::MAX {
                continue;
            }
            for &(x, e) in self.neighbours(u) {
                if u < x {
                    cand.push((depth[u as usize] + depth[x as usize] + 1, u, x, e));
                }
            }
        }
        cand.sort_unstable();
        let rank = 2 * self.total_genus();
        let mut basis = Basis::new(words);
        let mut chosen = Vec::new();
        let mut c = vec![0u64; words];
        for &(_, u, x, e) in &cand {
            if basis.rank == rank {
                break;
            }
            c.copy_from_slice(&cls[u as usize * words..][..words]);
            xor_into(&mut c, &cls[x as usize * words..][..words]);
            xor_into(&mut c, self.edge_class(e));
            if basis.insert(&mut c) {
                chosen.push((u, x));
            }
        }
        assert_eq!(
            basis.rank, rank,
            "the surface graph's cycles span rank {} of H1, not 2g = {rank}",
            basis.rank
        );
        let mut hit = Vec::new();
        for (mut u, mut x) in chosen {
            // The cycle: u and x up to their lowest common ancestor.
            while u != x {
                if depth[u as usize] < depth[x as usize] {
                    std::mem::swap(&mut u, &mut x);
                }
                hit.push(u);
                u = parent[u as usize];
            }
            hit.push(u);
        }
        hit.sort_unstable();
        hit.dedup();
        hit
    }
}

// ---------------------------------------------------------------------------------------------
// The searches
// ---------------------------------------------------------------------------------------------

/// One shortest-path search with its tree, reused across sources (only touched entries reset).
struct Search {
    words: usize,
    dist: Vec<f64>,
    parent: Vec<u32>,
    /// Class of the tree path from the source, `words` per vertex.
    cls: Vec<u64>,
    is_finished: Vec<bool>,
    /// Vertices settled within the radius, in order.
    finished: Vec<u32>,
    touched: Vec<u32>,
    source: u32,
}

impl Search {
    fn new(n: usize, words: usize) -> Search {
        Search {
            words,
            dist: vec![f64::INFINITY; n],
            parent: vec![u32::MAX; n],
            cls: vec![0; n * words],
            is_finished: vec![false; n],
            finished: Vec::new(),
            touched: Vec::new(),
            source: u32::MAX,
        }
    }

    /// Dijkstra from `s` up to radius `limit`, avoiding `done` vertices. (With unit weights this is
    /// a breadth-first search; one code path keeps the two metrics identical in logic.)
    fn run(&mut self, surf: &Surface, weight: &[f64], s: u32, limit: f64, done: &[bool]) {
        // Distances are non-negative, so their bit patterns order like the numbers.
        let mut heap = BinaryHeap::new();
        self.source = s;
        self.dist[s as usize] = 0.0;
        self.cls[s as usize * self.words..][..self.words].fill(0);
        self.touched.push(s);
        heap.push(Reverse((0f64.to_bits(), s)));
        while let Some(Reverse((bits, u))) = heap.pop() {
            let d = f64::from_bits(bits);
            if d > limit {
                break;
            }
            if self.is_finished[u as usize] || d > self.dist[u as usize] {
                continue; // a stale entry
            }
            self.is_finished[u as usize] = true;
            self.finished.push(u);
            for &(x, e) in surf.neighbours(u) {
                let nd = d + weight[e as usize];
                if done[x as usize] || nd > limit || nd >= self.dist[x as usize] {
                    continue;
                }
                if self.dist[x as usize] == f64::INFINITY {
                    self.touched.push(x);
                }
                self.dist[x as usize] = nd;
                self.parent[x as usize] = u;
                set_xor(&mut self.cls, self.words, x, u, surf.edge_class(e));
                heap.push(Reverse((nd.to_bits(), x)));
            }
        }
    }

    /// Whether tree path to `u`, edge `e` = (u, x) and tree path back from `x` is non-trivial.
    fn closes_nontrivially(&self, surf: &Surface, u: u32, x: u32, e: u32) -> bool {
        let cu = &self.cls[u as usize * self.words..][..self.words];
        let cx = &self.cls[x as usize * self.words..][..self.words];
        let h = surf.edge_class(e);
        (0..self.words).any(|k| cu[k] ^ cx[k] ^ h[k] != 0)
    }

    /// The closed walk source .. u, x .. source, as a vertex list starting at the source.
    fn cycle(&self, u: u32, x: u32) -> Vec<u32> {
        let path = |mut v: u32| {
            let mut p = vec![v];
            while v != self.source {
                v = self.parent[v as usize];
                p.push(v);
            }
            p.reverse();
            p
        };
        let mut c = path(u);
        let back = path(x);
        c.extend(back[1..].iter().rev());
        c
    }

    fn reset(&mut self) {
        for &v in &self.touched {
            self.dist[v as usize] = f64::INFINITY;
            self.parent[v as usize] = u32::MAX;
            self.is_finished[v as usize] = false;
        }
        self.touched.clear();
        self.finished.clear();
    }
}

/// A basis over Z/2 of bitset vectors, by Gaussian elimination on their highest set bit.
struct Basis {
    by_lead: Vec<Option<Vec<u64>>>,
    rank: usize,
}

impl Basis {
    fn new(words: usize) -> Basis {
        Basis {
            by_lead: vec![None; 64 * words],
            rank: 0,
        }
    }

    /// Reduces `c` by the basis; adds it (and returns true) if it stays non-zero.
    fn insert(&mut self, c: &mut [u64]) -> bool {
        while let Some(lead) = highest_bit(c) {
            match &self.by_lead[lead] {
                Some(b) => xor_into(c, b),
                None => {
                    self.by_lead[lead] = Some(c.to_vec());
                    self.rank += 1;
                    return true;
                }
            }
        }
        false
    }
}

fn highest_bit(c: &[u64]) -> Option<usize> {
    (0..c.len())
        .rev()
        .find(|&k| c[k] != 0)
        .map(|k| 64 * k + 63 - c[k].leading_zeros() as usize)
}

fn xor_into(dst: &mut [u64], src: &[u64]) {
    for (d, s) in dst.iter_mut().zip(src) {
        *d ^= s;
    }
}

/// cls[x] = cls[u] ^ h, in a flat array of `words` per vertex.
fn set_xor(cls: &mut [u64], words: usize, x: u32, u: u32, h: &[u64]) {
    for k in 0..words {
        cls[x as usize * words + k] = cls[u as usize * words + k] ^ h[k];
    }
}

// ---------------------------------------------------------------------------------------------
// Building the surface: mesh, grid edges, checks, pieces
// ---------------------------------------------------------------------------------------------

/// The isosurface of `vol` at `iso`, as isotopo extracts it.
pub fn mesh_of(vol: &InMemoryVolume, iso: f64, conn: Connectivity) -> Mesh {
    let mut v = vol.clone(); // extraction reads the slices
    extract(&mut v, &super::opts(iso, conn), false, &NoProgress).expect("mesh extraction")
}

/// The grid edge a vertex lies on: two coordinates integers (up to float32 rounding), the third
/// clearly fractional (isotopo keeps it at least 1e-3 from an integer); None if unclear.
fn grid_edge_of(p: [f64; 3]) -> Option<GridEdge> {
    let off = p.map(|x| (x - x.round()).abs());
    let frac: Vec<usize> = (0..3).filter(|&a| off[a] > 1e-4).collect();
    let &[axis] = frac.as_slice() else {
        return None;
    };
    if off[axis] < 5e-4 {
        return None;
    }
    let mut lo = p.map(|x| x.round() as i32);
    lo[axis] = p[axis].floor() as i32;
    Some(GridEdge { lo, axis })
}

/// Dense index of the grid edges of the volume padded by one sample on every side.
struct GridTable {
    dims: [i32; 3],
    slot: Vec<u32>,
}

impl GridTable {
    fn new(dims: [i32; 3]) -> GridTable {
        let len = 3 * ((dims[0] + 2) * (dims[1] + 2) * (dims[2] + 2)) as usize;
        GridTable {
            dims,
            slot: vec![u32::MAX; len],
        }
    }

    fn index(&self, g: &GridEdge) -> Option<usize> {
        let [nx, ny, nz] = self.dims;
        let [i, j, k] = g.lo;
        let fits = (0..3).all(|a| g.lo[a] >= -1 && g.hi()[a] <= self.dims[a]);
        fits.then(|| {
            let cell = ((k + 1) * (ny + 2) + j + 1) * (nx + 2) + i + 1;
            g.axis * ((nx + 2) * (ny + 2) * (nz + 2)) as usize + cell as usize
        })
    }
}

/// The vertices are exactly the crossing grid edges (inside = value > iso; the padding and NaN
/// outside), each at the linear interpolation clamped to [0.001, 0.999] (0.5 where a sample is
/// padding).
fn check_against_volume(
    vol: &InMemoryVolume,
    iso: f64,
    keys: &[GridEdge],
    pos: &[[f64; 3]],
) -> Result<(), String> {
    let d = vol.dims();
    let dims = [d[0] as i32, d[1] as i32, d[2] as i32];
    let value = |p: [i32; 3]| {
        if (0..3).all(|a| p[a] >= 0 && p[a] < dims[a]) {
            vol.get(p[0] as usize, p[1] as usize, p[2] as usize)
        } else {
            f64::NAN
        }
    };
    let mut table = GridTable::new(dims);
    for (v, g) in keys.iter().enumerate() {
        let i = table.index(g).ok_or(format!(
            "vertex {v} on grid edge {g:?} outside the padded volume"
        ))?;
        ensure!(
            table.slot[i] == u32::MAX,
            "vertices {} and {v} on the same grid edge {g:?}",
            table.slot[i]
        );
        table.slot[i] = v as u32;
    }
    let mut crossings = 0;
    for axis in 0..3 {
        for k in -1..=dims[2] {
            for j in -1..=dims[1] {
                for i in -1..=dims[0] {
                    let g = GridEdge {
                        lo: [i, j, k],
                        axis,
                    };
                    if g.hi()[axis] > dims[axis] {
                        continue;
                    }
                    let (va, vb) = (value(g.lo), value(g.hi()));
                    if (va > iso) == (vb > iso) {
                        continue;
                    }
                    crossings += 1;
                    let v = table.slot[table.index(&g).expect("in the padded grid")];
                    ensure!(v != u32::MAX, "crossing grid edge {g:?} has no vertex");
                    let t = (iso - va) / (vb - va);
                    let t = if t.is_finite() {
                        t.clamp(0.001, 0.999)
                    } else {
                        0.5
                    };
                    let frac = pos[v as usize][axis] - f64::from(g.lo[axis]);
                    ensure!(
                        (frac - t).abs() < 1e-4,
                        "vertex {v} on {g:?} at fraction {frac}, interpolation gives {t}"
                    );
                }
            }
        }
    }
    ensure!(
        crossings == keys.len(),
        "{} vertices on grid edges that do not cross",
        keys.len() - crossings
    );
    Ok(())
}

/// Compressed adjacency lists: for each vertex, (neighbour, mesh edge).
struct Csr {
    start: Vec<u32>,
    list: Vec<(u32, u32)>,
}

impl Csr {
    fn new(n: usize, edges: impl Iterator<Item = ([u32; 2], usize)> + Clone) -> Csr {
        let mut start = vec![0u32; n + 1];
        for ([u, v], _) in edges.clone() {
            start[u as usize + 1] += 1;
            start[v as usize + 1] += 1;
        }
        for i in 0..n {
            start[i + 1] += start[i];
        }
        let mut fill = start.clone();
        let mut list = vec![(0, 0); start[n] as usize];
        for ([u, v], e) in edges {
            for (a, b) in [(u, v), (v, u)] {
                list[fill[a as usize] as usize] = (b, e as u32);
                fill[a as usize] += 1;
            }
        }
        Csr { start, list }
    }

    fn of(&self, v: u32) -> &[(u32, u32)] {
        &self.list[self.start[v as usize] as usize..self.start[v as usize + 1] as usize]
    }
}

struct MeshEdges {
    edges: Vec<[u32; 2]>,
    edge_tris: Vec<[u32; 2]>,
    tri_edges: Vec<[u32; 3]>,
}

/// The mesh edges; checks that every edge is in exactly two triangles, in opposite directions
/// (closed and consistently oriented), and that no triangle repeats a vertex.
fn mesh_edges(tris: &[[u32; 3]], n: usize) -> Result<MeshEdges, String> {
    // Half-edges (undirected key, 3 t + slot), sorted so that the two of each edge are adjacent.
    let mut half: Vec<(u64, u32)> = Vec::with_capacity(3 * tris.len());
    for (t, tri) in tris.iter().enumerate() {
        ensure!(
            tri[0] != tri[1] && tri[1] != tri[2] && tri[2] != tri[0],
            "triangle {t} repeats a vertex: {tri:?}"
        );
        ensure!(
            tri.iter().all(|&v| (v as usize) < n),
            "triangle {t}: bad vertex"
        );
        for s in 0..3 {
            let (a, b) = (tri[s], tri[(s + 1) % 3]);
            half.push((
                (u64::from(a.min(b)) << 32) | u64::from(a.max(b)),
                (3 * t + s) as u32,
            ));
        }
    }
    half.sort_unstable();
    let from = |h: u32| tris[h as usize / 3][h as usize % 3];
    let mut out = MeshEdges {
        edges: Vec::with_capacity(half.len() / 2),
        edge_tris: Vec::with_capacity(half.len() / 2),
        tri_edges: vec![[0; 3]; tris.len()],
    };
    for (i, pair) in half.chunks(2).enumerate() {
        let key = pair[0].0;
        let next_same = half.get(2 * i + 2).is_some_and(|h| h.0 == key);
        ensure!(
            pair.len() == 2 && pair[1].0 == key && !next_same,
            "edge {}-{} is not in exactly two triangles: the mesh is not closed or not manifold",
            key >> 32,
            key & 0xffff_ffff
        );
        let (h0, h1) = (pair[0].1, pair[1].1);
        ensure!(
            from(h0) != from(h1),
            "edge {}-{} has the same direction in both triangles: not consistently oriented",
            key >> 32,
            key & 0xffff_ffff
        );
        let e = out.edges.len() as u32;
        out.edges.push([(key >> 32) as u32, key as u32]);
        out.edge_tris.push([h0 / 3, h1 / 3]);
        out.tri_edges[h0 as usize / 3][h0 as usize % 3] = e;
        out.tri_edges[h1 as usize / 3][h1 as usize % 3] = e;
    }
    Ok(out)
}

/// Every vertex's link is one cycle: following, round v, each triangle (v, b, c) from b to c
/// visits all of v's triangles (a 2-manifold).
fn check_fans(tris: &[[u32; 3]], n: usize) -> Result<(), String> {
    // Corners grouped by vertex: (b, c) for each triangle (v, b, c), counter-clockwise.
    let mut start = vec![0usize; n + 1];
    for tri in tris {
        for &v in tri {
            start[v as usize + 1] += 1;
        }
    }
    for i in 0..n {
        start[i + 1] += start[i];
    }
    let mut fill = start.clone();
    let mut fan = vec![(0u32, 0u32); start[n]];
    for &[a, b, c] in tris {
        for (v, x, y) in [(a, b, c), (b, c, a), (c, a, b)] {
            fan[fill[v as usize]] = (x, y);
            fill[v as usize] += 1;
        }
    }
    for v in 0..n {
        let f = &fan[start[v]..start[v + 1]];
        ensure!(!f.is_empty(), "vertex {v} is in no triangle");
        let (first, mut cur) = f[0];
        let mut steps = 1;
        while cur != first {
            cur = f
                .iter()
                .find(|&&(x, _)| x == cur)
                .ok_or(format!("vertex {v}: its triangle fan is not closed"))?
                .1;
            steps += 1;
            ensure!(steps <= f.len(), "vertex {v}: its fan does not close");
        }
        ensure!(
            steps == f.len(),
            "vertex {v}: its link is not one cycle (not a 2-manifold there)"
        );
    }
    Ok(())
}

/// Lower corner of the unit cube holding each triangle's three grid edges; checks that they are
/// edges of that cube and not all in one of its faces (the cube's piece would be ambiguous).
fn cubes(keys: &[GridEdge], tris: &[[u32; 3]]) -> Result<Vec<[i32; 3]>, String> {
    tris.iter()
        .enumerate()
        .map(|(t, tri)| {
            let g = tri.map(|v| keys[v as usize]);
            let cube: [i32; 3] = std::array::from_fn(|a| g.iter().map(|e| e.lo[a]).min().unwrap());
            for e in &g {
                let ok = (0..3).all(|a| {
                    let off = e.lo[a] - cube[a];
                    off == 0 || (off == 1 && a != e.axis)
                });
                ensure!(
                    ok,
                    "triangle {t} on grid edges {g:?} is not in one unit cube"
                );
            }
            for (b, &side) in cube.iter().enumerate() {
                let flat = g.iter().all(|e| e.axis != b && e.lo[b] == side);
                ensure!(
                    !flat,
                    "triangle {t} on {g:?} lies in a face shared by two cubes"
                );
            }
            Ok(cube)
        })
        .collect()
}

struct Pieces {
    of_tri: Vec<u32>,
    is_tube: Vec<bool>,
}

/// The pieces (triangles of one cube connected through mesh edges) and whether each is a tube;
/// checks the piece facts (module doc, 3).
fn pieces(
    me: &MeshEdges,
    cube: &[[i32; 3]],
    tris: &[[u32; 3]],
    keys: &[GridEdge],
    n: usize,
) -> Result<Pieces, String> {
    let m = tris.len();
    let boundary = |e: usize| {
        let [t0, t1] = me.edge_tris[e];
        cube[t0 as usize] != cube[t1 as usize]
    };
    let mut uf = UnionFind::new(m);
    for (e, &[t0, t1]) in me.edge_tris.iter().enumerate() {
        if !boundary(e) {
            uf.union(t0, t1);
        } else {
            check_face_segment(e, me, cube, keys)?;
        }
    }
    // Pieces numbered 0.., and their triangles grouped.
    let mut id = vec![u32::MAX; m];
    let mut count = 0u32;
    let of_tri: Vec<u32> = (0..m as u32)
        .map(|t| {
            let r = uf.find(t) as usize;
            if id[r] == u32::MAX {
                id[r] = count;
                count += 1;
            }
            id[r]
        })
        .collect();
    let mut members: Vec<Vec<u32>> = vec![Vec::new(); count as usize];
    for t in 0..m {
        members[of_tri[t] as usize].push(t as u32);
    }
    let mut is_tube = vec![false; count as usize];
    let mut pieces_at = vec![0u32; n];
    let mut cubes_at: Vec<Vec<[i32; 3]>> = vec![Vec::new(); n];
    for (p, tri_list) in members.iter().enumerate() {
        is_tube[p] = piece_kind(p, tri_list, me, tris, &boundary)?;
        let mut verts: Vec<u32> = tri_list.iter().flat_map(|&t| tris[t as usize]).collect();
        verts.sort_unstable();
        verts.dedup();
        for &v in &verts {
            pieces_at[v as usize] += 1;
            cubes_at[v as usize].push(cube[tri_list[0] as usize]);
        }
    }
    for v in 0..n {
        let mut c = cubes_at[v].clone();
        c.sort_unstable();
        c.dedup();
        ensure!(
            pieces_at[v] == 4 && c.len() == 4,
            "vertex {v} lies in {} pieces in {} cubes, not 4 in 4",
            pieces_at[v],
            c.len()
        );
    }
    let mut segments = vec![0u32; n];
    for (e, &[a, b]) in me.edges.iter().enumerate() {
        if boundary(e) {
            segments[a as usize] += 1;
            segments[b as usize] += 1;
        }
    }
    if let Some(v) = segments.iter().position(|&s| s != 4) {
        return Err(format!(
            "vertex {v} is on {} face segments, not 4",
            segments[v]
        ));
    }
    Ok(Pieces { of_tri, is_tube })
}

/// A piece boundary edge joins triangles of face-adjacent cubes and lies in their common face.
fn check_face_segment(
    e: usize,
    me: &MeshEdges,
    cube: &[[i32; 3]],
    keys: &[GridEdge],
) -> Result<(), String> {
    let [c0, c1] = me.edge_tris[e].map(|t| cube[t as usize]);
    let step: Vec<i32> = (0..3).map(|a| c1[a] - c0[a]).collect();
    let b = (0..3).find(|&a| step[a] != 0).expect("different cubes");
    ensure!(
        step.iter().map(|s| s.abs()).sum::<i32>() == 1,
        "edge {e} joins triangles of cubes {c0:?} and {c1:?}, not face-adjacent"
    );
    let face = c0[b].max(c1[b]);
    for v in me.edges[e] {
        let g = keys[v as usize];
        ensure!(
            g.axis != b && g.lo[b] == face,
            "edge {e} is not in the face between cubes {c0:?} and {c1:?}"
        );
    }
    Ok(())
}

/// Whether piece `p` is a tube (true) or a disk (false); an error if it is neither. All its vertices
/// are on its boundary (they lie on cube edges), so its boundary is a union of cycles through all
/// of them; disk = (chi 1, one loop), tube = (chi 0, two loops).
fn piece_kind(
    p: usize,
    tri_list: &[u32],
    me: &MeshEdges,
    tris: &[[u32; 3]],
    boundary: &impl Fn(usize) -> bool,
) -> Result<bool, String> {
    let mut verts: Vec<u32> = tri_list.iter().flat_map(|&t| tris[t as usize]).collect();
    verts.sort_unstable();
    verts.dedup();
    let local = |v: u32| verts.binary_search(&v).expect("a vertex of the piece");
    let (mut bnd, mut interior_sides) = (Vec::new(), 0);
    for &t in tri_list {
        for e in me.tri_edges[t as usize] {
            if boundary(e as usize) {
                bnd.push(me.edges[e as usize]);
            } else {
                interior_sides += 1; // each interior edge is seen from its two triangles
            }
        }
    }
    let mut degree = vec![0; verts.len()];
    let mut uf = UnionFind::new(verts.len());
    for &[a, b] in &bnd {
        degree[local(a)] += 1;
        degree[local(b)] += 1;
        uf.union(local(a) as u32, local(b) as u32);
    }
    ensure!(
        degree.iter().all(|&d| d == 2),
        "piece {p}: its boundary is not a union of cycles through all its vertices"
    );
    let loops = (0..verts.len() as u32).filter(|&v| uf.find(v) == v).count();
    let chi = verts.len() as i64 - bnd.len() as i64 - interior_sides / 2 + tri_list.len() as i64;
    match (chi, loops) {
        (1, 1) => Ok(false),
        (0, 2) => Ok(true),
        _ => Err(format!(
            "piece {p}: Euler characteristic {chi} with {loops} boundary loops"
        )),
    }
}

// ---------------------------------------------------------------------------------------------
// Homology
// ---------------------------------------------------------------------------------------------

/// Class vectors of the mesh edges, `words` u64 per edge.
struct Classes {
    words: usize,
    bits: Vec<u64>,
}

impl Classes {
    fn of(&self, e: u32) -> &[u64] {
        &self.bits[e as usize * self.words..][..self.words]
    }
}

struct Homology {
    component: Vec<u32>,
    genus: Vec<usize>,
    classes: Classes,
}

/// Z/2 homology by tree–cotree (module doc, 5).
fn homology(n: usize, me: &MeshEdges, mesh_adj: &Csr) -> Result<Homology, String> {
    let (ne, m) = (me.edges.len(), me.tri_edges.len());
    // Primal spanning tree (breadth-first), which also numbers the components.
    let mut component = vec![u32::MAX; n];
    let mut in_tree = vec![false; ne];
    let mut ncomp = 0u32;
    let mut queue = std::collections::VecDeque::new();
    for r in 0..n as u32 {
        if component[r as usize] != u32::MAX {
            continue;
        }
        component[r as usize] = ncomp;
        queue.push_back(r);
        while let Some(u) = queue.pop_front() {
            for &(x, e) in mesh_adj.of(u) {
                if component[x as usize] == u32::MAX {
                    component[x as usize] = ncomp;
                    in_tree[e as usize] = true;
                    queue.push_back(x);
                }
            }
        }
        ncomp += 1;
    }
    // Dual spanning tree: triangles joined across edges not in the primal tree.
    let mut in_cotree = vec![false; ne];
    let mut to_parent = vec![u32::MAX; m]; // edge to the parent triangle
    let mut seen = vec![false; m];
    let (mut order, mut roots) = (Vec::with_capacity(m), Vec::new());
    for r in 0..m as u32 {
        if seen[r as usize] {
            continue;
        }
        seen[r as usize] = true;
        roots.push(r);
        queue.push_back(r);
        while let Some(t) = queue.pop_front() {
            order.push(t);
            for e in me.tri_edges[t as usize] {
                let [a, b] = me.edge_tris[e as usize];
                let o = if a == t { b } else { a };
                if !in_tree[e as usize] && !seen[o as usize] {
                    seen[o as usize] = true;
                    in_cotree[e as usize] = true;
                    to_parent[o as usize] = e;
                    queue.push_back(o);
                }
            }
        }
    }
    ensure!(
        roots.len() == ncomp as usize,
        "the dual of the cotree has {} parts for {ncomp} components",
        roots.len()
    );
    // Euler characteristic per component, and the leftover edges (one class bit each).
    let mut chi = vec![0i64; ncomp as usize];
    let comp_of_edge = |e: usize| component[me.edges[e][0] as usize] as usize;
    for c in &component {
        chi[*c as usize] += 1;
    }
    for e in 0..ne {
        chi[comp_of_edge(e)] -= 1;
    }
    for t in 0..m {
        chi[component[me.edges[me.tri_edges[t][0] as usize][0] as usize] as usize] += 1;
    }
    let leftover: Vec<usize> = (0..ne).filter(|&e| !in_tree[e] && !in_cotree[e]).collect();
    let mut per_comp = vec![0i64; ncomp as usize];
    for &e in &leftover {
        per_comp[comp_of_edge(e)] += 1;
    }
    for c in 0..ncomp as usize {
        ensure!(
            per_comp[c] == 2 - chi[c] && per_comp[c] % 2 == 0,
            "component {c}: {} leftover edges, but 2 - chi = {}",
            per_comp[c],
            2 - chi[c]
        );
    }
    let words = leftover.len().div_ceil(64);
    let mut classes = Classes {
        words,
        bits: vec![0; ne * words],
    };
    for (k, &e) in leftover.iter().enumerate() {
        classes.bits[e * words + k / 64] |= 1 << (k % 64);
    }
    // Leaves first: a triangle's edges other than the one to its parent are known by then.
    let mut sum = vec![0u64; words];
    for &t in order.iter().rev() {
        let pe = to_parent[t as usize];
        if pe == u32::MAX {
            continue; // a root: checked below
        }
        sum.fill(0);
        for e in me.tri_edges[t as usize] {
            if e != pe {
                xor_into(&mut sum, classes.of(e));
            }
        }
        classes.bits[pe as usize * words..][..words].copy_from_slice(&sum);
    }
    for &r in &roots {
        sum.fill(0);
        for e in me.tri_edges[r as usize] {
            xor_into(&mut sum, classes.of(e));
        }
        ensure!(
            sum.iter().all(|&w| w == 0),
            "dual-tree root triangle {r}: its boundary does not sum to 0"
        );
    }
    Ok(Homology {
        component,
        genus: per_comp.iter().map(|&l| l as usize / 2).collect(),
        classes,
    })
}
