//! The sweep (paper §2.1): a Reeb graph of the isosurface built slice by slice, whose cycles,
//! together with the handles inside single slices, account for the whole genus.
//!
//! For each slice the surfels are grouped into ribbons and the contours of its upper plane are
//! labelled. Ribbons and contours become nodes of the Reeb graph; a ribbon is joined to each
//! contour on its boundary. When a ribbon meets a contour already connected to it through the
//! graph, a cycle closes: that is a handle, described by the shortest such cycle (breadth-first
//! search). A ribbon that is of positive genus once its contours are capped hides handles
//! within its slice; those are found by sweeping a capped mini-volume of the slice along an
//! orthogonal axis (`mini`). Genus of a surface = its Reeb cycles + the genus of its capped
//! ribbons, so every handle is found.
//!
//! Small handles often stay inside one slice of the mini-volume too (their loops run through the
//! caps; the tunnel inside a single cube stays inside a slice along every axis). The mini-volume
//! ribbons that hold them are small, and their handles are found directly (`local`).
//!
//! Every handle carries a *cut*: a closed curve on the surface that its Reeb loop must cross
//! once — the shortest contour of its cycle, or for a handle found directly, the loop crossing
//! its non-separating loop.

pub(crate) mod contours;
pub(crate) mod local;
pub(crate) mod mini;
mod reeb;

pub(crate) use reeb::ReebGraph;
use reeb::RollbackUnionFind;
pub use reeb::{Node, NodeKind};

use crate::error::{Error, Result};
use crate::grid::{Axis, Frame, MaskVolume};
use crate::progress::Progress;
use crate::surface::search::{walk_contour, Graph, PieceSet};
use crate::surface::{vertex_of, Vertex};
use crate::topology::cases::{cases, Case, Connectivity};
use crate::topology::slice::SliceSurfels;
use crate::unionfind::UnionFind;
use crate::volume::BBox;
use std::sync::Arc;

/// How a handle was found.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum HandleKind {
    /// A cycle of the Reeb graph.
    ReebCycle,
    /// Inside one slice, found in the capped mini-volume of that slice.
    IntraRibbon,
}

impl HandleKind {
    /// As in the reports: "reeb_cycle" or "intra_ribbon".
    pub fn name(self) -> &'static str {
        match self {
            HandleKind::ReebCycle => "reeb_cycle",
            HandleKind::IntraRibbon => "intra_ribbon",
        }
    }
}

/// The volume a handle's cycle and cut live in.
#[derive(Clone, Debug)]
pub enum CycleVolume {
    /// The swept volume itself.
    Top,
    /// A mini-volume (rotated, cropped, capped). Only cubes in the handle's `allowed` box show
    /// the original surface.
    Mini(Arc<MaskVolume>),
}

/// A handle located by the sweep.
#[derive(Clone, Debug)]
pub struct LocatedHandle {
    /// Closed by a Reeb cycle or inside a ribbon.
    pub kind: HandleKind,
    /// For intra-ribbon handles: found by the mini-volume's sweep (a cycle), or directly.
    pub direct: bool,
    /// The cycle (alternating ribbon and contour nodes) in the coordinates of `volume`; for a
    /// handle found directly, the one ribbon of the mini-volume that holds it.
    pub cycle: Vec<Node>,
    /// Per node of `cycle`: for a contour, one of its vertices (in its plane; the contour is the
    /// walk along the plane from there); unused for a ribbon.
    pub contour_starts: Vec<Vertex>,
    /// Position in `cycle` of the contour cut for this handle (Reeb-cycle handles).
    pub cut_at: usize,
    /// The volume `cycle`, `cut` and `contour_starts` are in.
    pub volume: CycleVolume,
    /// The closed curve its Reeb loop crosses once (vertices in order, in `volume`'s
    /// coordinates).
    pub cut: Vec<Vertex>,
    /// For intra-ribbon handles: the cubes (lower corners, in `volume`'s local coordinates,
    /// inclusive) that show the original surface; loops must stay there.
    pub allowed: Option<([i64; 3], [i64; 3])>,
    /// A node of the top-level Reeb graph on the handle's surface.
    pub(crate) top_node: u32,
    /// The contour node of the sweep's Reeb graph cut for this handle (Reeb-cycle handles).
    pub(crate) cut_node: Option<u32>,
    /// For intra-ribbon handles: the slice and index (in that slice's surfels) of the ribbon of
    /// the swept volume that holds the handle.
    pub ribbon: Option<(i64, u32)>,
    /// Cube bounds of the cycle's ribbons, original coordinates (lower corners, inclusive).
    pub bbox: BBox,
}

/// Which surface a piece lies on: the piece in the cube with lower corner (u, v) of slice `w`
/// that owns corner `corner`.
#[derive(Clone, Copy, Debug)]
struct Probe {
    u: i64,
    v: i64,
    w: i64,
    corner: u8,
}

/// A ribbon of positive genus found by a sweep that does not recurse (the mini-volume's).
struct Unresolved {
    slice: i64,
    ribbon: u32,
    genus: usize,
    node: u32,
}

/// One sweep's result over one volume.
struct SweepLevel {
    handles: Vec<LocatedHandle>,
    unresolved: Vec<Unresolved>,
    graph: ReebGraph,
    /// (ribbon node, 4 × its share of its surface's Euler characteristic)
    ribbon_chi4: Vec<(u32, i32)>,
    /// (ribbon node, lowest cube in original coordinates (z, y, x) and corner): numbers surfaces.
    ribbon_key: Vec<(u32, [i32; 4])>,
    probe_node: Option<u32>,
}

/// Maps a corner bit of this volume's frame to the original frame.
fn corner_to_original(bit: u8, frame: &Frame) -> u8 {
    let local = [bit & 1, (bit >> 1) & 1, (bit >> 2) & 1];
    let mut o = [0u8; 3];
    for k in 0..3 {
        o[frame.uvw[k]] = local[k];
    }
    o[0] | (o[1] << 1) | (o[2] << 2)
}

/// For each set of corners of a cube (bit b: corner b of this volume's frame), the least of
/// them in the original frame (a piece's corner in its ribbon's key).
fn least_original_corners(frame: &Frame) -> [u8; 256] {
    let mut t = [0u8; 256];
    for (mask, least) in t.iter_mut().enumerate() {
        *least = (0..8u8)
            .filter(|&b| mask & (1 << b) != 0)
            .map(|b| corner_to_original(b, frame))
            .min()
            .unwrap_or(0);
    }
    t
}

/// Original-coordinate box of the cubes (padded indices) `min ..= max` of slice `w`.
fn cube_box(frame: &Frame, min: [u32; 2], max: [u32; 2], w: i64) -> BBox {
    let mut b = BBox::EMPTY;
    for p in [
        [min[0] as i64 - 1, min[1] as i64 - 1, w],
        [max[0] as i64 - 1, max[1] as i64 - 1, w],
    ] {
        b.include(frame.to_original_i(p));
    }
    b
}

/// A vertex of the contour made of segment `slot` of the `k`-th square of `list` (a slice's
/// `top` list): the segment's first end.
fn contour_vertex(
    s: &SliceSurfels,
    list: &[u32],
    k: usize,
    slot: usize,
    face: usize,
    table: &[Case; 256],
) -> Vertex {
    let cube = s.cubes[list[k] as usize];
    let (e, _) = table[cube.case as usize].face_segment[face][slot];
    vertex_of([cube.i as i64 - 1, cube.j as i64 - 1, s.z as i64], e)
}

/// Where a node of the sweep's Reeb graph lies, in 24 bytes (a noisy volume has hundreds of
/// thousands of nodes; coordinates fit in 32 bits, [`Sweeper::step`] refuses longer axes): a
/// ribbon's cube box in original coordinates, or a contour's first vertex and its length.
#[derive(Clone, Copy, Debug, Default)]
struct NodePlace {
    a: [i32; 3],
    b: [i32; 3],
}

impl NodePlace {
    fn ribbon(b: BBox) -> NodePlace {
        NodePlace {
            a: b.min.map(|x| x as i32),
            b: b.max.map(|x| x as i32),
        }
    }

    fn contour(v: Vertex, length: u32) -> NodePlace {
        NodePlace {
            a: v.p.map(|x| x as i32),
            b: [v.axis as i32, length as i32, 0],
        }
    }

    fn ribbon_box(self) -> BBox {
        BBox {
            min: self.a.map(i64::from),
            max: self.b.map(i64::from),
        }
    }

    /// A contour's vertex and length.
    fn contour_at(self) -> (Vertex, u32) {
        let v = Vertex {
            p: self.a.map(i64::from),
            axis: self.b[0] as u8,
        };
        (v, self.b[1] as u32)
    }
}

/// Longest axis a sweep takes: coordinates with the padding, and node places, fit in an i32.
const MAX_AXIS: usize = (i32::MAX - 4) as usize;

/// The sweep's state at the start of one slice, to step back to.
#[derive(Clone, Copy, Debug)]
struct Checkpoint {
    /// The Reeb graph's nodes and edges.
    graph: (usize, usize),
    uf: (usize, usize),
    handles: usize,
    unresolved: usize,
    ribbons: usize,
    probe_node: Option<u32>,
    /// First node of the contours of the slice's upper plane.
    contour_base: u32,
}

/// A sweep in progress over one volume: [`Sweeper::step`] processes the next slice, and
/// [`Sweeper::rewind`] steps back to an earlier slice after the volume was edited there (the
/// Reeb graph and its union-find are rolled back; slices below are kept as they were).
///
/// At depth 0 ribbons of positive genus are resolved in mini-volumes; at depth 1 (inside a
/// mini-volume) they are returned as unresolved.
pub struct Sweeper {
    conn: Connectivity,
    depth: u32,
    probe: Option<Probe>,
    /// The next slice to process (-1 ..= nw).
    pub next: i64,
    graph: ReebGraph,
    /// Contours of the last processed slice's upper plane, and their nodes.
    prev_contours: contours::PlaneContours,
    prev_contour_node: Vec<u32>,
    /// Per node: the cube box of a ribbon, or a vertex and the length of a contour.
    places: Vec<NodePlace>,
    /// Handles found so far, with the slice where each was found.
    handles: Vec<(i64, LocatedHandle)>,
    unresolved: Vec<Unresolved>,
    ribbon_chi4: Vec<(u32, i32)>,
    ribbon_key: Vec<(u32, [i32; 4])>,
    probe_node: Option<u32>,
    /// Checkpoint at the start of slice s, at index s + 1.
    checkpoints: Vec<Checkpoint>,
    uf: UnionFind,
    /// [`least_original_corners`] of the volume's frame, made at the first step.
    least_corner: Option<Box<[u8; 256]>>,
    /// The surfels of the slice processed last, for a caller that keeps slices.
    last_surfels: Option<(i64, SliceSurfels)>,
    /// Per node: is it the contour cut for a handle found so far? Cycles are found avoiding
    /// these, and cut at a contour of their own. The graph less its cuts stays connected (a
    /// cut lies on a cycle of it, and a contour node has one edge up and one down), so every
    /// new cycle has such a path; the cuts are then independent, and a loop chained along
    /// handle j's cycle crosses no cut of an earlier handle: the crossings of cuts and such
    /// loops form a triangular matrix with ones on its diagonal, so together they span the
    /// homology of the Reeb graph's part of the surface (what simplify's certificate needs).
    is_cut: Vec<bool>,
}

impl Sweeper {
    /// A sweep of a surface of connectivity `conn`, before its first slice.
    pub fn new(conn: Connectivity) -> Sweeper {
        Sweeper::at_depth(conn, 0, None)
    }

    fn at_depth(conn: Connectivity, depth: u32, probe: Option<Probe>) -> Sweeper {
        Sweeper {
            conn,
            depth,
            probe,
            next: -1,
            graph: ReebGraph::default(),
            prev_contours: contours::PlaneContours::default(),
            prev_contour_node: Vec::new(),
            places: Vec::new(),
            handles: Vec::new(),
            unresolved: Vec::new(),
            ribbon_chi4: Vec::new(),
            ribbon_key: Vec::new(),
            probe_node: None,
            checkpoints: Vec::new(),
            uf: UnionFind::default(),
            least_corner: None,
            last_surfels: None,
            is_cut: Vec::new(),
        }
    }

    /// Has every slice been processed?
    pub fn done(&self, vol: &MaskVolume) -> bool {
        self.next >= vol.dims[2] as i64
    }

    /// Lets go of the cycles, cuts and mini-volumes of the handles found so far (a caller that
    /// took what it needed from them, like simplify; a mini-volume can take megabytes, and a long
    /// volume has thousands of handles). They stay counted, so rewinding works as before.
    pub fn release_handles(&mut self) {
        for (_, h) in &mut self.handles {
            h.cycle = Vec::new();
            h.contour_starts = Vec::new();
            h.cut = Vec::new();
            h.volume = CycleVolume::Top;
        }
    }

    /// Handles found so far (slice where found, handle).
    pub fn handles(&self) -> &[(i64, LocatedHandle)] {
        &self.handles
    }

    fn add_node(&mut self, kind: NodeKind, level: i32, local: u32) -> u32 {
        let id = self.graph.add_node(kind, level, local);
        self.is_cut.push(false);
        self.places.push(NodePlace::default());
        id
    }

    /// Processes the next slice; returns how many handles it found.
    ///
    /// ```text
    ///   plane s+1   ── top contours (new nodes) ──
    ///   slice s        ribbons (new nodes): a ribbon joined to a contour it already reaches
    ///                  closes a Reeb cycle; a ribbon of genus g holds g handles of its own
    ///   plane s     ── bottom contours (from the step below) ──
    /// ```
    pub fn step(&mut self, vol: &MaskVolume) -> Result<usize> {
        if vol.dims.iter().any(|&d| d > MAX_AXIS) {
            return Err(Error::usage(format!(
                "an axis of {:?} samples is longer than the sweep takes ({MAX_AXIS})",
                vol.dims
            )));
        }
        let s = self.next;
        let found_before = self.handles.len();
        self.push_checkpoint(s);
        let cur = SliceSurfels::build(vol.plane(s), vol.plane(s + 1), s as i32, self.conn);
        let ribbon_node = self.add_ribbons(vol, &cur, s);
        self.locate_probe(&cur, &ribbon_node, s)?;
        let bottom_of = self.bottom_contours(&cur, s)?;
        self.close_cycles(vol, &bottom_of, &ribbon_node, s)?;
        let (top, contour_node, top_count) = self.add_top_contours(&cur, &ribbon_node, s);
        for r in 0..cur.ribbons.len() {
            let b = bottom_of[r].len() as i64 + top_count[r] as i64;
            self.ribbon_handles(vol, &cur, r, b, ribbon_node[r], s)?;
        }
        self.prev_contours = top;
        self.prev_contour_node = contour_node;
        self.next = s + 1;
        self.last_surfels = Some((s, cur));
        Ok(self.handles.len() - found_before)
    }

    /// What [`Sweeper::rewind`] needs to undo slice `s` and everything above.
    fn push_checkpoint(&mut self, s: i64) {
        self.checkpoints.truncate((s + 1) as usize);
        self.checkpoints.push(Checkpoint {
            graph: self.graph.size(),
            uf: self.graph.uf.checkpoint(),
            handles: self.handles.len(),
            unresolved: self.unresolved.len(),
            ribbons: self.ribbon_chi4.len(),
            probe_node: self.probe_node,
            contour_base: 0,
        });
    }

    /// A node per ribbon of slice `s`, with its box, Euler characteristic and the key that
    /// numbers surfaces (its lowest cube in original coordinates).
    fn add_ribbons(&mut self, vol: &MaskVolume, cur: &SliceSurfels, s: i64) -> Vec<u32> {
        let ribbon_node: Vec<u32> = (0..cur.ribbons.len())
            .map(|r| {
                let id = self.add_node(NodeKind::Ribbon, s as i32, r as u32);
                let rb = &cur.ribbons[r];
                self.places[id as usize] =
                    NodePlace::ribbon(cube_box(&vol.frame, rb.min, rb.max, s));
                self.ribbon_chi4.push((id, rb.surface_chi4));
                id
            })
            .collect();
        let least_corner = self
            .least_corner
            .get_or_insert_with(|| Box::new(least_original_corners(&vol.frame)));
        let keys = ribbon_keys(cur, &vol.frame, cases(self.conn), least_corner, s);
        for (r, k) in keys.into_iter().enumerate() {
            self.ribbon_key.push((ribbon_node[r], k));
        }
        ribbon_node
    }

    /// The node of the ribbon the probe's corner lies on, when the probe is in slice `s`.
    fn locate_probe(&mut self, cur: &SliceSurfels, ribbon_node: &[u32], s: i64) -> Result<()> {
        let Some(p) = self.probe.filter(|p| p.w == s) else {
            return Ok(());
        };
        let table = cases(self.conn);
        let q = cur
            .find_cube((p.u + 1) as u32, (p.v + 1) as u32)
            .ok_or_else(|| Error::Internal("probe cube is not on the surface".into()))?;
        let cube = cur.cubes[q];
        let k = table[cube.case as usize]
            .pieces
            .iter()
            .position(|pc| pc.corners & (1 << p.corner) != 0)
            .ok_or_else(|| Error::Internal("probe corner owns no piece".into()))?;
        self.probe_node =
            Some(ribbon_node[cur.piece_ribbon[cube.first_piece as usize + k] as usize]);
        Ok(())
    }

    /// The contour nodes of plane s below each ribbon of slice s, distinct.
    fn bottom_contours(&self, cur: &SliceSurfels, s: i64) -> Result<Vec<Vec<u32>>> {
        let table = cases(self.conn);
        let mut bottom_of: Vec<Vec<u32>> = vec![Vec::new(); cur.ribbons.len()];
        if cur.bottom.len() * 2 != self.prev_contours.of_segment.len() {
            return Err(Error::Internal(format!(
                "plane {s}: {} squares below, {} above",
                self.prev_contours.of_segment.len() / 2,
                cur.bottom.len()
            )));
        }
        for (k, &q) in cur.bottom.iter().enumerate() {
            for slot in 0..2 {
                let c = self.prev_contours.of_segment[2 * k + slot];
                if c == u32::MAX {
                    continue;
                }
                let r = cur.face_ribbon(table, q as usize, 4, slot) as usize;
                let node = self.prev_contour_node[c as usize];
                if !bottom_of[r].contains(&node) {
                    bottom_of[r].push(node);
                }
            }
        }
        Ok(bottom_of)
    }

    /// Joins each ribbon to the contours below it: a contour already connected to the ribbon
    /// closes a Reeb cycle, a handle.
    fn close_cycles(
        &mut self,
        vol: &MaskVolume,
        bottom_of: &[Vec<u32>],
        ribbon_node: &[u32],
        s: i64,
    ) -> Result<()> {
        let surface = Graph::new(vol, cases(self.conn));
        for (r, bottom) in bottom_of.iter().enumerate() {
            let rn = ribbon_node[r];
            for &c in bottom {
                if self.graph.connected(c, rn) {
                    let h = self.reeb_cycle(&surface, rn, c)?;
                    self.handles.push((s, h));
                }
                self.graph.add_edge(c, rn);
            }
        }
        Ok(())
    }

    /// The handle of the cycle that joining ribbon node `rn` to contour node `c` closes. The
    /// cycle avoids the contours cut for earlier handles and is cut at its shortest contour
    /// (see `is_cut`).
    fn reeb_cycle(&mut self, surface: &Graph, rn: u32, c: u32) -> Result<LocatedHandle> {
        let path = self
            .graph
            .shortest_path(rn, c, &self.is_cut)
            .ok_or_else(|| Error::Internal("connected nodes without a path".into()))?;
        let mut bbox = BBox::EMPTY;
        let mut shortest: Option<(Vertex, u32, i32, u32)> = None;
        for &n in &path {
            let node = self.graph.node(n);
            let place = self.places[n as usize];
            match node.kind {
                NodeKind::Ribbon => bbox.union(&place.ribbon_box()),
                NodeKind::Contour => {
                    let (v, len) = place.contour_at();
                    if shortest.is_none_or(|x| len < x.1) {
                        shortest = Some((v, len, node.level, n));
                    }
                }
            }
        }
        let (v, _, level, cut_node) =
            shortest.ok_or_else(|| Error::Internal("a Reeb cycle without contours".into()))?;
        self.is_cut[cut_node as usize] = true;
        let cut = walk_contour(surface, v, level as i64)
            .ok_or_else(|| Error::Internal("a contour does not close".into()))?;
        let cycle = path.iter().map(|&n| self.graph.node(n)).collect();
        // A ribbon's entry is unused: zeros, not its box corner.
        let unused = Vertex { p: [0; 3], axis: 0 };
        let contour_starts = path
            .iter()
            .map(|&n| match self.graph.node(n).kind {
                NodeKind::Contour => self.places[n as usize].contour_at().0,
                NodeKind::Ribbon => unused,
            })
            .collect();
        let cut_at = path.iter().position(|&n| n == cut_node).unwrap_or(0);
        Ok(LocatedHandle {
            kind: HandleKind::ReebCycle,
            direct: false,
            cycle,
            volume: CycleVolume::Top,
            cut,
            allowed: None,
            top_node: rn,
            cut_node: Some(cut_node),
            ribbon: None,
            contour_starts,
            cut_at,
            bbox,
        })
    }

    /// The contours of plane s + 1, each a new node joined to the ribbon below it. Returns
    /// them, their nodes, and how many each ribbon has.
    fn add_top_contours(
        &mut self,
        cur: &SliceSurfels,
        ribbon_node: &[u32],
        s: i64,
    ) -> (contours::PlaneContours, Vec<u32>, Vec<u32>) {
        let table = cases(self.conn);
        let top = contours::label(cur, 5, table, &mut self.uf);
        let base = self.graph.size().0 as u32;
        self.checkpoints
            .last_mut()
            .expect("pushed by step")
            .contour_base = base;
        let contour_node: Vec<u32> = (0..top.count())
            .map(|c| self.add_node(NodeKind::Contour, s as i32 + 1, c as u32))
            .collect();
        let mut top_count = vec![0u32; cur.ribbons.len()];
        let mut joined = vec![false; top.count()];
        for (k, &q) in cur.top.iter().enumerate() {
            for slot in 0..2 {
                let c = top.of_segment[2 * k + slot];
                if c == u32::MAX || joined[c as usize] {
                    continue;
                }
                joined[c as usize] = true;
                let r = cur.face_ribbon(table, q as usize, 5, slot) as usize;
                let node = contour_node[c as usize];
                self.graph.add_edge(node, ribbon_node[r]);
                // The segment's first end lies in plane s + 1 (face 5 of the cube).
                let mut v = contour_vertex(cur, &cur.top, k, slot, 5, table);
                v.p[2] = s + 1;
                self.places[node as usize] = NodePlace::contour(v, top.length[c as usize]);
                top_count[r] += 1;
            }
        }
        (top, contour_node, top_count)
    }

    /// Handles inside ribbon `r` (with `b` contours): the genus of the ribbon with its contours
    /// capped. At depth 0 they are located now; deeper, left for the caller.
    fn ribbon_handles(
        &mut self,
        vol: &MaskVolume,
        cur: &SliceSurfels,
        r: usize,
        b: i64,
        node: u32,
        s: i64,
    ) -> Result<()> {
        let twice_genus4 = 8 - cur.ribbons[r].chi4 as i64 - 4 * b;
        if twice_genus4 % 8 != 0 || twice_genus4 < 0 {
            return Err(Error::Internal(format!(
                "slice {s} ribbon {r}: capped Euler characteristic is not that of a closed surface"
            )));
        }
        let g = (twice_genus4 / 8) as usize;
        if g == 0 {
            return Ok(());
        }
        if self.depth == 0 {
            for mut h in intra_ribbon(vol, cur, r, s, self.conn, g)? {
                h.top_node = node;
                h.ribbon = Some((s, r as u32));
                self.handles.push((s, h));
            }
        } else {
            self.unresolved.push(Unresolved {
                slice: s,
                ribbon: r as u32,
                genus: g,
                node,
            });
        }
        Ok(())
    }

    /// The surfels of the slice the last step processed (once).
    pub fn take_surfels(&mut self) -> Option<(i64, SliceSurfels)> {
        self.last_surfels.take()
    }

    /// A sweep that will not be rewound keeps no record to undo its unions (on 256³ noise, 4
    /// MB); [`Sweeper::rewind`] is then an error.
    pub fn without_rewind(mut self) -> Sweeper {
        self.graph.uf.stop_logging();
        self
    }

    /// Steps back so that slice `s0` is processed next, forgetting everything found from it on
    /// (the volume may have changed there, but not below).
    pub fn rewind(&mut self, vol: &MaskVolume, s0: i64) -> Result<()> {
        let s0 = s0.max(-1);
        if s0 >= self.next {
            return Ok(());
        }
        if !self.graph.uf.logging() {
            return Err(Error::Internal(
                "a sweep made without rewind was rewound".into(),
            ));
        }
        let cp = self.checkpoints[(s0 + 1) as usize];
        // Contours of plane s0 were made with slice s0 - 1; their nodes stay, their edges up to
        // the slice being redone go.
        let keep_from = if s0 >= 0 {
            self.checkpoints[s0 as usize].contour_base as usize
        } else {
            cp.graph.0
        };
        for (_, h) in &self.handles[cp.handles..] {
            if let Some(n) = h.cut_node.filter(|&n| (n as usize) < self.is_cut.len()) {
                self.is_cut[n as usize] = false;
            }
        }
        self.is_cut.truncate(cp.graph.0);
        self.graph.truncate(cp.graph);
        self.graph.uf.rollback(cp.uf);
        self.places.truncate(cp.graph.0);
        self.handles.truncate(cp.handles);
        self.unresolved.truncate(cp.unresolved);
        self.ribbon_chi4.truncate(cp.ribbons);
        self.ribbon_key.truncate(cp.ribbons);
        self.probe_node = cp.probe_node;
        self.checkpoints.truncate((s0 + 1) as usize);
        if s0 >= 0 {
            let below =
                SliceSurfels::build(vol.plane(s0 - 1), vol.plane(s0), (s0 - 1) as i32, self.conn);
            self.prev_contours = contours::label(&below, 5, cases(self.conn), &mut self.uf);
            self.prev_contour_node = (0..self.prev_contours.count() as u32)
                .map(|c| keep_from as u32 + c)
                .collect();
        } else {
            self.prev_contours = contours::PlaneContours::default();
            self.prev_contour_node.clear();
        }
        self.next = s0;
        Ok(())
    }

    /// 4 × Euler characteristic summed over every ribbon so far, per Reeb-graph component.
    fn finish(self) -> SweepLevel {
        SweepLevel {
            handles: self.handles.into_iter().map(|(_, h)| h).collect(),
            unresolved: self.unresolved,
            graph: self.graph,
            ribbon_chi4: self.ribbon_chi4,
            ribbon_key: self.ribbon_key,
            probe_node: self.probe_node,
        }
    }
}

/// Sweeps one volume from end to end.
fn sweep_level(
    vol: &mut MaskVolume,
    conn: Connectivity,
    depth: u32,
    probe: Option<Probe>,
    progress: &dyn Progress,
) -> Result<SweepLevel> {
    let mut sweeper = Sweeper::at_depth(conn, depth, probe);
    if depth == 0 {
        progress.start("sweep", vol.dims[2] as u64 + 1);
    }
    while !sweeper.done(vol) {
        sweeper.step(vol)?;
        vol.follow_sweep(sweeper.next)?;
        if depth == 0 {
            progress.advance(1);
            progress.message(&format!("{} handles", sweeper.handles.len()));
            crate::progress::between_steps(progress, "sweep")?;
        }
    }
    if depth == 0 {
        progress.finish();
    }
    Ok(sweeper.finish())
}

/// What [`find_handles_each`] calls after each step: the volume, the handles the step found,
/// and whether the sweep is done (a last call, with no handle).
pub type StepHandles<'a> = dyn FnMut(&MaskVolume, Vec<LocatedHandle>, bool) -> Result<()> + 'a;

/// Sweeps `vol` (already arranged for its axis) like [`find_handles`], but hands over the
/// handles each step finds as it goes (`each`, with the volume as it stands; once more with no
/// handle and `last` after the last step), so that a caller measuring and writing them need not hold them all. Returns how
/// to number them: their surfaces, resolved once the whole volume is swept.
pub fn find_handles_each(
    vol: &mut MaskVolume,
    conn: Connectivity,
    progress: &dyn Progress,
    each: &mut StepHandles<'_>,
) -> Result<SurfaceNumbers> {
    let mut sweeper = Sweeper::at_depth(conn, 0, None).without_rewind();
    progress.start("sweep", vol.dims[2] as u64 + 1);
    let mut found = 0;
    while !sweeper.done(vol) {
        let n = sweeper.step(vol)?;
        vol.follow_sweep(sweeper.next)?;
        // Never rewound: the handles can go (the checkpoints' counts are then stale).
        let new: Vec<LocatedHandle> = sweeper.handles.drain(..).map(|(_, h)| h).collect();
        debug_assert_eq!(new.len(), n);
        found += n;
        each(vol, new, false)?;
        progress.advance(1);
        progress.message(&format!("{found} handles"));
        crate::progress::between_steps(progress, "sweep")?;
    }
    progress.finish();
    // The last call comes once the sweep's own state is gone but its Reeb graph: a caller
    // measuring what is left has that memory back.
    let numbers = SurfaceNumbers::of(sweeper.finish());
    each(vol, Vec::new(), true)?;
    Ok(numbers)
}

/// The closed surfaces of a sweep, numbered as the genus pass numbers them, and which one each
/// node of its Reeb graph lies on.
pub struct SurfaceNumbers {
    /// The Reeb graph's components (its nodes and edges are let go).
    uf: RollbackUnionFind,
    id_of: std::collections::HashMap<u32, usize>,
    /// Every closed surface, by id (their `handles` counts are left to the caller).
    pub surfaces: Vec<SweepSurface>,
    /// Total genus from the Euler characteristic.
    pub genus: i64,
}

impl SurfaceNumbers {
    fn of(level: SweepLevel) -> SurfaceNumbers {
        let uf = &level.graph.uf;
        // Surfaces: components holding ribbons, numbered by their lowest cube.
        let mut key_of_root: std::collections::HashMap<u32, [i32; 4]> = Default::default();
        for &(n, k) in &level.ribbon_key {
            let e = key_of_root.entry(uf.find(n)).or_insert([i32::MAX; 4]);
            *e = (*e).min(k);
        }
        let mut roots: Vec<(u32, [i32; 4])> = key_of_root.into_iter().collect();
        roots.sort_by_key(|&(_, k)| k);
        let id_of: std::collections::HashMap<u32, usize> = roots
            .iter()
            .enumerate()
            .map(|(i, &(r, _))| (r, i))
            .collect();
        let mut chi4 = vec![0i64; roots.len()];
        for &(n, c) in &level.ribbon_chi4 {
            chi4[id_of[&uf.find(n)]] += i64::from(c);
        }
        let surfaces: Vec<SweepSurface> = chi4
            .iter()
            .enumerate()
            .map(|(id, &c)| SweepSurface {
                id,
                genus: (2 - c / 4) / 2,
                handles: 0,
            })
            .collect();
        let genus = surfaces.iter().map(|s| s.genus).sum();
        SurfaceNumbers {
            uf: level.graph.uf,
            id_of,
            surfaces,
            genus,
        }
    }

    /// The surface a handle lies on.
    pub fn surface_of(&self, h: &LocatedHandle) -> usize {
        self.id_of[&self.uf.find(h.top_node)]
    }

    /// The order handles are numbered in: by surface, then lowest position (z, y, x).
    pub fn order_key(&self, key: NumberKey) -> (usize, [i64; 3]) {
        let surface = self.id_of[&self.uf.find(key.top_node)];
        (surface, key.at.map(i64::from))
    }
}

/// What numbers a handle once the sweep is done ([`SurfaceNumbers::order_key`]), kept where
/// the handle itself is let go.
#[derive(Clone, Copy, Debug)]
pub struct NumberKey {
    top_node: u32,
    /// Lowest corner of its box, (z, y, x).
    at: [i32; 3],
}

impl LocatedHandle {
    /// See [`NumberKey`].
    pub fn number_key(&self) -> NumberKey {
        // Beyond 2^31 samples an axis (no real volume) the order of positions saturates.
        let b = self
            .bbox
            .min
            .map(|x| x.clamp(i32::MIN as i64, i32::MAX as i64) as i32);
        NumberKey {
            top_node: self.top_node,
            at: [b[2], b[1], b[0]],
        }
    }
}

/// The `g` handles of ribbon `r` of slice `s`, from its capped mini-volume: the cycles of an
/// orthogonal sweep, and those still inside one of that sweep's slices found directly.
fn intra_ribbon(
    vol: &MaskVolume,
    cur: &SliceSurfels,
    r: usize,
    s: i64,
    conn: Connectivity,
    g: usize,
) -> Result<Vec<LocatedHandle>> {
    let rb = &cur.ribbons[r];
    // Cube i spans samples i-1 and i (padded indices).
    let u = (rb.min[0] as i64 - 1, rb.max[0] as i64);
    let v = (rb.min[1] as i64 - 1, rb.max[1] as i64);
    let mut mini = mini::build(vol, s, u, v, conn);
    let probe = ribbon_probe(cur, r, s, mini.origin, conn)?;
    let level = sweep_level(
        &mut mini.volume,
        conn,
        1,
        Some(probe),
        &crate::progress::NoProgress,
    )?;
    let target = level
        .probe_node
        .ok_or_else(|| Error::Internal("probe not found in the mini-volume".into()))?;
    let root = level.graph.uf.find(target);
    let on_target = |n: u32| level.graph.uf.find(n) == root;
    // The original slice in mini coordinates: cubes whose lower corner has v' = the slice's
    // plane (below caps come first) and u', w' inside the crop.
    let [nu, _, nw] = mini.volume.dims;
    let allowed = (
        [0, mini.below as i64, 0],
        [nu as i64 - 2, mini.below as i64, nw as i64 - 2],
    );
    let shared = Arc::new(mini.volume);
    let mut found: Vec<LocatedHandle> = Vec::new();
    for mut h in level.handles.into_iter().filter(|h| on_target(h.top_node)) {
        h.kind = HandleKind::IntraRibbon;
        h.volume = CycleVolume::Mini(shared.clone());
        h.allowed = Some(allowed);
        h.bbox = clip(&h.bbox, &shared, allowed);
        found.push(h);
    }
    let mut graph = Graph::new(&shared, cases(conn));
    for un in level.unresolved.iter().filter(|x| on_target(x.node)) {
        for cut in direct_loops(&mut graph, &shared, un, conn, s)? {
            found.push(direct_handle(&shared, un, cut, allowed));
        }
    }
    if found.len() != g {
        return Err(Error::Internal(format!(
            "slice {s}: a ribbon of genus {g} gave {} handles in its mini-volume",
            found.len()
        )));
    }
    Ok(found)
}

/// A piece of ribbon `r` of slice `s`, in the coordinates of a mini-volume at `origin`:
/// (u', v', w') = (v, w, u).
fn ribbon_probe(
    cur: &SliceSurfels,
    r: usize,
    s: i64,
    origin: [i64; 3],
    conn: Connectivity,
) -> Result<Probe> {
    let rb = &cur.ribbons[r];
    let cube = cur.cubes[rb.first_cube as usize];
    let case = &cases(conn)[cube.case as usize];
    let k = (0..case.n_pieces as usize)
        .find(|&k| cur.piece_ribbon[cube.first_piece as usize + k] as usize == r)
        .ok_or_else(|| Error::Internal("ribbon's first cube has no piece of it".into()))?;
    let corner = case.pieces[k].corners.trailing_zeros() as u8;
    let local = [
        cube.i as i64 - 1 - origin[0],
        cube.j as i64 - 1 - origin[1],
        s - origin[2],
    ];
    let c = [corner & 1, (corner >> 1) & 1, (corner >> 2) & 1];
    Ok(Probe {
        u: local[1],
        v: local[2],
        w: local[0],
        corner: c[1] | (c[2] << 1) | (c[0] << 2),
    })
}

/// The handles of a ribbon the mini-volume's own sweep left unresolved, found directly on the
/// ribbon's pieces: one loop of each handle's pair (found in slice `s` of the volume).
fn direct_loops(
    graph: &mut Graph,
    shared: &MaskVolume,
    un: &Unresolved,
    conn: Connectivity,
    s: i64,
) -> Result<Vec<Vec<Vertex>>> {
    let sl = SliceSurfels::build(
        shared.plane(un.slice),
        shared.plane(un.slice + 1),
        un.slice as i32,
        conn,
    );
    let (verts, region) = ribbon_region(&sl, conn, un.ribbon, un.slice);
    let pairs = local::handles(graph, &verts, &region, un.genus).ok_or_else(|| {
        Error::Internal(format!(
            "slice {s}: no handle loops found directly in a mini-volume ribbon of genus {}",
            un.genus
        ))
    })?;
    Ok(pairs.into_iter().map(|(_, l2)| l2).collect())
}

/// The pieces of ribbon `ribbon` of the slice `sl` (between planes `slice` and `slice + 1`),
/// and their crossing points, sorted.
fn ribbon_region(
    sl: &SliceSurfels,
    conn: Connectivity,
    ribbon: u32,
    slice: i64,
) -> (Vec<Vertex>, PieceSet) {
    let table = cases(conn);
    let mut verts = Vec::new();
    let mut region = PieceSet::default();
    for cube in &sl.cubes {
        let case = &table[cube.case as usize];
        let q = [cube.i as i64 - 1, cube.j as i64 - 1, slice];
        for k in 0..case.n_pieces as usize {
            if sl.piece_ribbon[cube.first_piece as usize + k] != ribbon {
                continue;
            }
            region.insert(q, k as u8);
            for lp in &case.pieces[k].loops {
                verts.extend(lp.iter().map(|&e| vertex_of(q, e)));
            }
        }
    }
    verts.sort();
    verts.dedup();
    (verts, region)
}

/// The handle of a loop [`direct_loops`] found.
fn direct_handle(
    shared: &Arc<MaskVolume>,
    un: &Unresolved,
    cut: Vec<Vertex>,
    allowed: ([i64; 3], [i64; 3]),
) -> LocatedHandle {
    let mut bbox = BBox::EMPTY;
    for x in &cut {
        bbox.include(shared.frame.to_original_i(x.p));
    }
    LocatedHandle {
        kind: HandleKind::IntraRibbon,
        direct: true,
        cycle: vec![Node {
            kind: NodeKind::Ribbon,
            level: un.slice as i32,
            local: un.ribbon,
        }],
        volume: CycleVolume::Mini(shared.clone()),
        cut,
        allowed: Some(allowed),
        top_node: 0,
        cut_node: None,
        ribbon: None,
        contour_starts: Vec::new(),
        cut_at: 0,
        bbox: clip(&bbox, shared, allowed),
    }
}

/// Clips an original-coordinate box to the original-geometry part of a mini-volume.
fn clip(b: &BBox, mini: &MaskVolume, allowed: ([i64; 3], [i64; 3])) -> BBox {
    let lo = mini.frame.to_original_i(allowed.0);
    let hi = mini.frame.to_original_i(allowed.1);
    let mut out = BBox::EMPTY;
    let (mn, mx): (Vec<i64>, Vec<i64>) =
        (0..3).map(|k| (lo[k].min(hi[k]), lo[k].max(hi[k]))).unzip();
    out.include([0, 1, 2].map(|k| b.min[k].clamp(mn[k], mx[k])));
    out.include([0, 1, 2].map(|k| b.max[k].clamp(mn[k], mx[k])));
    out
}

/// One closed surface as the sweep sees it.
#[derive(Clone, Debug, serde::Serialize)]
pub struct SweepSurface {
    /// Same numbering as the genus pass: by lowest point (z, y, x).
    pub id: usize,
    /// Genus from the Euler characteristic of its surfels.
    pub genus: i64,
    /// Handles the sweep located on it.
    pub handles: usize,
}

/// A located handle with its surface resolved.
#[derive(Clone, Debug)]
pub struct Handle {
    /// Number in the report, from 0.
    pub id: usize,
    /// The id of the surface it is on.
    pub surface: usize,
    /// Where the sweep found it.
    pub located: LocatedHandle,
}

/// Every handle of a volume's isosurface.
pub struct HandleReport {
    /// The sweep's axis.
    pub axis: Axis,
    /// Every handle, by id.
    pub handles: Vec<Handle>,
    /// Every closed surface, by id.
    pub surfaces: Vec<SweepSurface>,
    /// Total genus from the Euler characteristic.
    pub genus: i64,
}

/// Sweeps `vol` (already arranged for `axis`) and locates every handle.
pub fn find_handles(
    vol: &mut MaskVolume,
    axis: Axis,
    conn: Connectivity,
    progress: &dyn Progress,
) -> Result<HandleReport> {
    let mut level = sweep_level(vol, conn, 0, None, progress)?;
    let located = std::mem::take(&mut level.handles);
    let SurfaceNumbers {
        uf,
        id_of,
        mut surfaces,
        genus,
    } = SurfaceNumbers::of(level);
    let numbers = SurfaceNumbers {
        uf,
        id_of,
        surfaces: Vec::new(),
        genus,
    };
    let mut handles: Vec<Handle> = located
        .into_iter()
        .map(|h| Handle {
            id: 0,
            surface: numbers.surface_of(&h),
            located: h,
        })
        .collect();
    // Number handles by surface, then position.
    handles.sort_by_key(|h| numbers.order_key(h.located.number_key()));
    for (i, h) in handles.iter_mut().enumerate() {
        h.id = i;
        surfaces[h.surface].handles += 1;
    }
    Ok(HandleReport {
        axis,
        handles,
        surfaces,
        genus,
    })
}

/// The key of each ribbon of slice `s` that numbers surfaces: the least, over its pieces, of
/// (z, y, x) of the piece's cube and the piece's least inside corner, in original coordinates
/// (`least_corner` from [`least_original_corners`] of `frame`).
fn ribbon_keys(
    cur: &SliceSurfels,
    frame: &Frame,
    table: &[Case; 256],
    least_corner: &[u8; 256],
    s: i64,
) -> Vec<[i32; 4]> {
    let mut keys = vec![[i32::MAX; 4]; cur.ribbons.len()];
    for cube in &cur.cubes {
        let case = &table[cube.case as usize];
        let o = frame.to_original_i([cube.i as i64 - 1, cube.j as i64 - 1, s]);
        for k in 0..case.n_pieces as usize {
            let r = cur.piece_ribbon[cube.first_piece as usize + k] as usize;
            let corner = least_corner[case.pieces[k].corners as usize];
            keys[r] = keys[r].min([o[2] as i32, o[1] as i32, o[0] as i32, corner as i32]);
        }
    }
    keys
}

#[cfg(test)]
mod tests {
    use super::*;

    /// (cube, piece index), with the piece's crossing points and its inside corners.
    type Piece = (([i64; 3], u8), Vec<Vertex>, u8);

    /// Every piece of every cube of the slice `sl` (lower plane `z`), from the case table.
    fn pieces_of(sl: &SliceSurfels, conn: Connectivity, z: i64) -> Vec<Piece> {
        let mut pieces = Vec::new();
        for cube in &sl.cubes {
            let case = &cases(conn)[cube.case as usize];
            let q = [cube.i as i64 - 1, cube.j as i64 - 1, z];
            for (k, piece) in case.pieces.iter().enumerate() {
                let mut vs: Vec<Vertex> = piece
                    .loops
                    .iter()
                    .flatten()
                    .map(|&e| vertex_of(q, e))
                    .collect();
                vs.sort();
                vs.dedup();
                pieces.push(((q, k as u8), vs, piece.corners));
            }
        }
        pieces
    }

    /// The pieces joined into classes wherever two share a crossing point.
    fn joined_by_points(pieces: &[Piece]) -> UnionFind {
        let mut uf = UnionFind::new(pieces.len());
        let mut owner: crate::surface::search::FastMap<Vertex, usize> = Default::default();
        for (i, (_, vs, _)) in pieces.iter().enumerate() {
            for v in vs {
                if let Some(&j) = owner.get(v) {
                    uf.union(i as u32, j as u32);
                }
                owner.insert(*v, i);
            }
        }
        uf
    }

    /// A ribbon is a connected piece of surface within its slice: the region a handle is looked
    /// for in directly is exactly one class of the slice's pieces joined by shared crossing
    /// points (found here by a union-find over every piece of every cube, not from the slice's
    /// labels), with its crossing points; the ribbons' regions share no piece and cover all.
    /// Each ribbon's key (which numbers surfaces) is the least of its pieces'. Random masks
    /// (cubes of two and more pieces are common), both connectivities.
    #[test]
    fn a_ribbons_region_is_one_connected_class_of_pieces() {
        let mut rng = crate::test_rng::Rng(0x5851_f42d_4c95_7f2d);
        let mut multi = 0;
        for round in 0..24 {
            let n = 9;
            let mut vol = MaskVolume::new([n, n, 4], Frame::identity());
            let dense = 25 + rng.below(50);
            for k in 0..n * n * 4 {
                vol.set(k % n, k / n % n, k / (n * n), rng.below(100) < dense);
            }
            let conn = [Connectivity::Six, Connectivity::TwentySix][round % 2];
            for z in -1..4i64 {
                let sl = SliceSurfels::build(vol.plane(z), vol.plane(z + 1), z as i32, conn);
                let pieces = pieces_of(&sl, conn, z);
                let several =
                    |c: &&crate::topology::slice::Cube| cases(conn)[c.case as usize].n_pieces > 1;
                multi += sl.cubes.iter().filter(several).count();
                let mut uf = joined_by_points(&pieces);
                let least = least_original_corners(&Frame::identity());
                let keys = ribbon_keys(&sl, &Frame::identity(), cases(conn), &least, z);
                let mut seen = vec![false; pieces.len()];
                for r in 0..sl.ribbons.len() as u32 {
                    let at = format!("round {round} z {z} ribbon {r}");
                    let (verts, region) = ribbon_region(&sl, conn, r, z);
                    let members: Vec<usize> = (0..pieces.len())
                        .filter(|&i| region.0.contains_key(&pieces[i].0))
                        .collect();
                    assert_eq!(members.len(), region.0.len(), "{at}: a piece of no cube");
                    let class = uf.find(*members.first().expect("a ribbon has pieces") as u32);
                    let want: Vec<usize> = (0..pieces.len())
                        .filter(|&i| uf.find(i as u32) == class)
                        .collect();
                    assert_eq!(members, want, "{at}");
                    let mut vs: Vec<Vertex> =
                        members.iter().flat_map(|&i| pieces[i].1.clone()).collect();
                    vs.sort();
                    vs.dedup();
                    assert_eq!(verts, vs, "{at}");
                    // The ribbon's key: the least (z, y, x, least inside corner) of its pieces.
                    let key = members
                        .iter()
                        .map(|&i| {
                            let ((q, _), _, corners) = pieces[i];
                            let c = corners.trailing_zeros();
                            [q[2] as i32, q[1] as i32, q[0] as i32, c as i32]
                        })
                        .min();
                    assert_eq!(Some(keys[r as usize]), key, "{at}: key");
                    for i in members {
                        assert!(!seen[i], "{at}: a piece in two ribbons");
                        seen[i] = true;
                    }
                }
                assert!(
                    seen.iter().all(|&s| s),
                    "round {round} z {z}: a piece in no ribbon"
                );
            }
        }
        assert!(multi > 1000, "{multi} cubes of several pieces");
    }

    /// The least corner of each set of a cube's corners, in the original frame: with the
    /// identity frame, the lowest bit set; with the axes permuted (local x, y, z are original
    /// y, z, x), the corners one step along local x, y and z are the original corners 2, 4
    /// and 1, so of the first and the last the least is 1.
    #[test]
    fn the_least_original_corner_of_each_set_of_corners() {
        let t = least_original_corners(&Frame::identity());
        assert_eq!(t[0], 0);
        for mask in 1..256usize {
            assert_eq!(t[mask] as u32, mask.trailing_zeros(), "mask {mask:#010b}");
        }
        let permuted = Frame {
            uvw: [1, 2, 0],
            offset: [0; 3],
        };
        let t = least_original_corners(&permuted);
        assert_eq!([t[1 << 1], t[1 << 2], t[1 << 4]], [2, 4, 1]);
        assert_eq!(t[1 << 1 | 1 << 4], 1);
        assert_eq!(t[1 << 1 | 1 << 2], 2);
        assert!((1..256).all(|mask| t[mask] == 0 || mask & 1 == 0));
    }

    /// A ribbon's probe names, in the mini-volume's axes ((u', v', w') = (y, z, x)), a corner
    /// of a cube of the ribbon that a piece of that ribbon owns: mapped back to the volume's
    /// axes and looked up as the mini-volume's sweep looks it up (the first piece owning it),
    /// for every ribbon of every slice of random volumes, both connectivities, with the
    /// mini-volume's origin anywhere.
    #[test]
    fn a_ribbons_probe_names_a_corner_of_its_own_pieces() {
        let mut rng = crate::test_rng::Rng(0x2545_f491_4f6c_dd1d);
        let mut next = || rng.next_u64();
        let mut checked = 0;
        for conn in [Connectivity::Six, Connectivity::TwentySix] {
            for _ in 0..4 {
                let n = 12;
                let mut vol = MaskVolume::new([n; 3], Frame::identity());
                for k in 0..n * n * n {
                    vol.set(k % n, (k / n) % n, k / (n * n), next() % 2 == 0);
                }
                let table = cases(conn);
                for s in -1..n as i64 {
                    let cur = SliceSurfels::build(vol.plane(s), vol.plane(s + 1), s as i32, conn);
                    for r in 0..cur.ribbons.len() {
                        let origin = [next() % 5, next() % 5, next() % 5].map(|x| x as i64 - 2);
                        let p = ribbon_probe(&cur, r, s, origin, conn).unwrap();
                        let (x, y, z) = (p.w + origin[0], p.u + origin[1], p.v + origin[2]);
                        assert_eq!(z, s);
                        let corner =
                            (p.corner >> 2) & 1 | (p.corner & 1) << 1 | (p.corner >> 1 & 1) << 2;
                        let q = cur.find_cube((x + 1) as u32, (y + 1) as u32).unwrap();
                        let cube = cur.cubes[q];
                        let k = table[cube.case as usize]
                            .pieces
                            .iter()
                            .position(|pc| pc.corners & (1 << corner) != 0)
                            .unwrap();
                        assert_eq!(
                            cur.piece_ribbon[cube.first_piece as usize + k] as usize,
                            r,
                            "{conn:?} slice {s} ribbon {r}"
                        );
                        checked += 1;
                    }
                }
            }
        }
        assert!(checked > 500, "{checked} ribbons");
    }

    /// Each step hands over, once, the surfels of the slice it swept: the loop searches keep
    /// them as that slice's, so they must be what building the slice afresh gives (slice -1,
    /// under the volume's first plane, included). Random masks, both connectivities.
    #[test]
    fn a_step_hands_over_the_slice_it_swept() {
        let mut rng = crate::test_rng::Rng(0x9e37_79b9_7f4a_7c15);
        for conn in [Connectivity::Six, Connectivity::TwentySix] {
            let n = 8;
            let vol = crate::grid::random_mask(&mut rng, n, 50);
            let mut sweeper = Sweeper::new(conn);
            for s in -1..n as i64 {
                sweeper.step(&vol).unwrap();
                let (at, got) = sweeper.take_surfels().expect("the slice just swept");
                let want = SliceSurfels::build(vol.plane(s), vol.plane(s + 1), s as i32, conn);
                assert_eq!(at, s);
                assert!(!want.cubes.is_empty(), "{conn:?} slice {s} is empty");
                let seen = |x: &SliceSurfels| {
                    let ribbons = x.ribbons.len();
                    (x.z, x.cubes.clone(), x.piece_ribbon.clone(), ribbons)
                };
                assert_eq!(seen(&got), seen(&want), "{conn:?} slice {s}");
                assert_eq!((&got.bottom, &got.top), (&want.bottom, &want.top));
                assert!(sweeper.take_surfels().is_none(), "handed over twice");
            }
        }
    }

    /// A handle's kind is spelled one way everywhere: its name (the HTML report's) is its
    /// JSON value (the JSON and CSV reports').
    #[test]
    fn a_handle_kinds_name_is_its_json_value() {
        for kind in [HandleKind::ReebCycle, HandleKind::IntraRibbon] {
            assert_eq!(serde_json::to_value(kind).unwrap(), kind.name());
        }
        assert_ne!(HandleKind::ReebCycle.name(), HandleKind::IntraRibbon.name());
    }
}
