//! The isosurface as a graph, read straight from the inside mask: vertices are the crossing
//! points on grid edges, edges are the segments on cube faces, and the pieces (surfels) are its
//! faces. Loops are closed paths in this graph; their length in edges is the paper's unit
//! ("voxel edges": a loop around a one-voxel bridge has length 4).
//!
//! Around a crossing point on a grid edge lie four cubes, each holding one piece through it, and
//! four faces, each holding one segment from it:
//!
//! ```text
//!            n1                  the pieces' boundary loops (counter-clockwise seen from
//!       P1   |   P0              outside the solid) chain the neighbours into one cycle
//!     n2 --- v --- n0            around v: P runs n0 -> v -> n1 … The order n0, n1, n2, n3 is
//!       P2   |   P3              clockwise seen from outside; piece[k] lies between nbr[k]
//!            n3                  and nbr[k+1].
//! ```
//!
//! A tube piece (the tunnel inside one cube) is an annulus: no path along segments crosses it.
//! So its triangulation's diagonals, which join its two boundary loops, are edges of the graph
//! too; a vertex on a tube has one or two more neighbours, inside the tube's sector.

pub mod geometry;
pub mod search;

use crate::grid::MaskVolume;
use crate::topology::cases::{Case, EDGE_CORNERS};
use crate::topology::mask::PlaneMask;

/// A crossing point: the grid edge from `p` to `p + e[axis]` (volume-local coordinates; -1 and
/// `n` are the padding).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Vertex {
    /// The edge's lower end.
    pub p: [i64; 3],
    /// The edge's direction: 0, 1 or 2 for x, y, z.
    pub axis: u8,
}

impl Vertex {
    /// Packs the vertex into a u64 (coordinates -1 ..= 2^20 - 2; volumes are at most
    /// [`crate::volume::MAX_DIM`] samples along an axis).
    #[inline]
    pub fn key(&self) -> u64 {
        let c = |x: i64| (x + 1) as u64 & 0xF_FFFF;
        c(self.p[0]) | (c(self.p[1]) << 20) | (c(self.p[2]) << 40) | ((self.axis as u64) << 60)
    }

    /// The vertex a [`Vertex::key`] stands for.
    #[inline]
    pub fn from_key(k: u64) -> Vertex {
        let c = |shift: u32| ((k >> shift) & 0xF_FFFF) as i64 - 1;
        Vertex {
            p: [c(0), c(20), c(40)],
            axis: (k >> 60) as u8,
        }
    }

    /// Midpoint of the edge, in volume-local voxel coordinates.
    pub fn midpoint(&self) -> [f64; 3] {
        let mut m = [self.p[0] as f64, self.p[1] as f64, self.p[2] as f64];
        m[self.axis as usize] += 0.5;
        m
    }

    /// Far end of the edge.
    pub fn end(&self) -> [i64; 3] {
        let mut q = self.p;
        q[self.axis as usize] += 1;
        q
    }
}

/// A piece: the cube with lower corner `cube`, and the piece's index in that cube's case. A
/// tube's triangles are told apart by `part` (1 + the triangle's index; 0 for any other piece),
/// so that they are the faces of the graph between the tube's diagonals.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct PieceRef {
    /// The cube's lower corner.
    pub cube: [i64; 3],
    /// The piece's index in the cube's case.
    pub index: u8,
    /// For a tube, 1 + the triangle's index; 0 for any other piece.
    pub part: u8,
}

/// Most neighbours a vertex can have: four segments, plus diagonals through tubes.
pub const MAX_DEGREE: usize = 12;

/// The neighbourhood of a crossing point, stored compactly (a search may number millions):
/// neighbours and pieces as one byte each — a neighbour lies in one of the four cubes around
/// the edge, so it is the centre moved by -1, 0 or 1 along each axis, plus its own axis; a
/// piece is which of those cubes, which piece, which tube triangle.
#[derive(Clone, Copy, Debug)]
pub struct Around {
    /// The crossing point's edge, lower end (volumes have fewer than 2^31 samples a side: 40
    /// bytes in all, where a search's time goes mostly to fetching these from memory).
    at: [i32; 3],
    axis: u8,
    /// Number of neighbours (4, or more on a tube).
    n: u8,
    nbr: [u8; MAX_DEGREE],
    piece: [u8; MAX_DEGREE],
    /// Bit k: the edge to neighbour k is a diagonal through a tube, not a segment on a face.
    diagonal: u16,
}

/// The two axes other than `axis`, in increasing order.
#[inline]
fn other_axes(axis: u8) -> (usize, usize) {
    match axis {
        0 => (1, 2),
        1 => (0, 2),
        _ => (0, 1),
    }
}

// Two to a cache line and a bit: the searches' working set.
const _: () = assert!(std::mem::size_of::<Around>() == 40);

impl Around {
    /// Number of neighbours (4, or more on a tube).
    #[inline]
    pub fn n(&self) -> usize {
        self.n as usize
    }

    /// No neighbours: the vertex is gone from the surface.
    pub fn clear(&mut self) {
        self.n = 0;
    }

    /// The crossing point itself.
    #[inline]
    pub fn center(&self) -> Vertex {
        Vertex {
            p: self.at.map(i64::from),
            axis: self.axis,
        }
    }

    /// Neighbour `k`, clockwise seen from outside.
    #[inline]
    pub fn nbr(&self, k: usize) -> Vertex {
        let c = self.nbr[k];
        let (d, axis) = (c / 3, c % 3);
        let mut p = self.center().p;
        p[0] += (d % 3) as i64 - 1;
        p[1] += (d / 3 % 3) as i64 - 1;
        p[2] += (d / 9) as i64 - 1;
        Vertex { p, axis }
    }

    /// The byte that stands for neighbour `w` of `center` (`None` if `w` is not that close).
    #[inline]
    fn code(center: Vertex, w: Vertex) -> Option<u8> {
        let mut d = 0u8;
        for k in (0..3).rev() {
            let x = w.p[k] - center.p[k];
            if !(-1..=1).contains(&x) {
                return None;
            }
            d = d * 3 + (x + 1) as u8;
        }
        Some(d * 3 + w.axis)
    }

    /// The vertices joined to this one, in order round it.
    pub fn neighbours(&self) -> Vec<Vertex> {
        (0..self.n()).map(|k| self.nbr(k)).collect()
    }

    /// The piece between neighbours `k` and `k + 1`.
    #[inline]
    pub fn piece(&self, k: usize) -> PieceRef {
        let code = self.piece[k];
        let (lo, hi) = other_axes(self.axis);
        let mut cube = self.center().p;
        cube[lo] -= (code & 1) as i64;
        cube[hi] -= ((code >> 1) & 1) as i64;
        PieceRef {
            cube,
            index: (code >> 2) & 3,
            part: code >> 4,
        }
    }

    /// The pieces on either side of the edge to neighbour `k`.
    #[inline]
    pub fn sides(&self, k: usize) -> (PieceRef, PieceRef) {
        let n = self.n();
        (self.piece((k + n - 1) % n), self.piece(k))
    }

    /// Is the edge to neighbour `k` a diagonal through a tube?
    #[inline]
    pub fn diagonal(&self, k: usize) -> bool {
        (self.diagonal >> k) & 1 == 1
    }

    /// Where `w` lies among the neighbours.
    pub fn position(&self, w: Vertex) -> Option<usize> {
        let c = Around::code(self.center(), w)?;
        self.nbr[..self.n()].iter().position(|&x| x == c)
    }

    /// The neighbours on the left of a curve that comes in from neighbour `from` and goes on to
    /// neighbour `to` (positions): those strictly after `from`, clockwise, up to `to`, as bits.
    pub fn left_of(&self, from: usize, to: usize) -> u16 {
        let mut m = 0u16;
        let n = self.n();
        let mut k = (from + 1) % n;
        while k != to {
            m |= 1 << k;
            k = (k + 1) % n;
        }
        m
    }
}

/// Case of the cube with lower corner `q`.
#[inline]
pub fn cube_case(vol: &MaskVolume, q: [i64; 3]) -> u8 {
    case_in_planes(vol.plane(q[2]), vol.plane(q[2] + 1), q)
}

/// Case of the cube with lower corner `q`, whose planes are `below` (w = q\[2\]) and `above`.
#[inline]
fn case_in_planes(below: &PlaneMask, above: &PlaneMask, q: [i64; 3]) -> u8 {
    let (x, y) = (q[0] as isize, q[1] as isize);
    let mut c = 0u8;
    for (b, plane) in [(0, below), (4, above)] {
        for (k, (dx, dy)) in [(0, 0), (1, 0), (0, 1), (1, 1)].into_iter().enumerate() {
            c |= (plane.get(x + dx, y + dy) as u8) << (b + k);
        }
    }
    c
}

/// The cube edge (local index) along `axis` at local offsets (`ob`, `oc`) on the two other axes,
/// taken in increasing axis order.
#[inline]
fn local_edge(axis: u8, o_lo: i64, o_hi: i64) -> u8 {
    // x-edges 0..4 at (y, z); y-edges 4..8 at (x, z); z-edges 8..12 at (x, y).
    4 * axis + (o_lo + 2 * o_hi) as u8
}

/// Global vertex of local edge `e` of the cube with lower corner `q`.
#[inline]
pub fn vertex_of(q: [i64; 3], e: u8) -> Vertex {
    let (a, _) = EDGE_CORNERS[e as usize];
    Vertex {
        p: [
            q[0] + (a & 1) as i64,
            q[1] + ((a >> 1) & 1) as i64,
            q[2] + ((a >> 2) & 1) as i64,
        ],
        axis: e / 4,
    }
}

/// Is there a crossing on this edge?
#[inline]
pub fn is_crossing(vol: &MaskVolume, v: Vertex) -> bool {
    let q = v.end();
    vol.get(v.p[0], v.p[1], v.p[2]) != vol.get(q[0], q[1], q[2])
}

/// The neighbourhood of `v`, or `None` if the surface does not cross that edge.
pub fn around(vol: &MaskVolume, table: &[Case; 256], v: Vertex) -> Option<Around> {
    if !is_crossing(vol, v) {
        return None;
    }
    let (lo, hi) = other_axes(v.axis);
    // The planes the four cubes span (w - 1 ..= w + 1; w and w + 1 for an edge along w), looked
    // up once: out of core, looking one up can read it back.
    let w = v.p[2];
    let mid = vol.plane(w);
    let below = if v.axis == 2 { mid } else { vol.plane(w - 1) };
    let planes = [below, mid, vol.plane(w + 1)];
    // The four cubes around the edge: one (prev, next, piece code, diagonal) link each; a tube
    // gives one link per triangle through v instead, so the chain passes through its diagonals.
    let mut links = [(0u64, 0u64, 0u8, false); MAX_DEGREE];
    let mut n = 0;
    for (slot, (dl, dh)) in [(0i64, 0i64), (1, 0), (0, 1), (1, 1)]
        .into_iter()
        .enumerate()
    {
        let mut q = v.p;
        q[lo] -= dl;
        q[hi] -= dh;
        let at = (q[2] - w + 1) as usize;
        let case = &table[case_in_planes(planes[at], planes[at + 1], q) as usize];
        let e = local_edge(v.axis, dl, dh);
        let pi = case.edge_owner[e as usize];
        let piece = &case.pieces[pi as usize];
        let code = slot as u8 | (pi << 2);
        if piece.loops.len() == 1 {
            let lp = &piece.loops[0];
            let len = lp.len();
            let at = lp.iter().position(|&x| x == e)?;
            links[n] = (
                vertex_of(q, lp[(at + len - 1) % len]).key(),
                vertex_of(q, lp[(at + 1) % len]).key(),
                code,
                false,
            );
            n += 1;
        } else {
            // Triangle (e, x, y), counter-clockwise: it arrives at e from y and leaves to x.
            let other = |x: u8| !piece.loops.iter().any(|l| l.contains(&e) && l.contains(&x));
            for (ti, t) in piece.triangles.iter().enumerate() {
                let Some(m) = t.iter().position(|&x| x == e) else {
                    continue;
                };
                if n == MAX_DEGREE {
                    return None;
                }
                let (x, y) = (t[(m + 1) % 3], t[(m + 2) % 3]);
                links[n] = (
                    vertex_of(q, y).key(),
                    vertex_of(q, x).key(),
                    code | ((1 + ti as u8) << 4),
                    other(x),
                );
                n += 1;
            }
        }
    }
    // Chain: `chain[k]` runs nbr[k-1] -> v -> nbr[k], so it lies between those two.
    let mut out = Around {
        at: v.p.map(|c| c as i32),
        axis: v.axis,
        n: n as u8,
        nbr: [0; MAX_DEGREE],
        piece: [0; MAX_DEGREE],
        diagonal: 0,
    };
    let mut chain = [0u8; MAX_DEGREE];
    let mut cur = links[0];
    for k in 0..n {
        chain[k] = cur.2;
        out.nbr[k] = Around::code(v, Vertex::from_key(cur.1))?;
        if cur.3 {
            out.diagonal |= 1 << k;
        }
        if k + 1 < n {
            cur = *links[..n].iter().find(|l| l.0 == cur.1)?;
        }
    }
    // piece[k] between nbr[k] and nbr[k + 1].
    for k in 0..n {
        out.piece[k] = chain[(k + 1) % n];
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::{Frame, MaskVolume};
    use crate::topology::cases::{cases, Connectivity};

    /// One inside sample: the surface around it is an octahedron-like sphere; every crossing has
    /// four distinct neighbours and four distinct pieces.
    /// The piece between two consecutive neighbours has both on its boundary.
    #[test]
    fn pieces_lie_between_their_neighbours() {
        let mut vol = MaskVolume::new([4, 4, 4], Frame::identity());
        for (x, y, z) in [(1, 1, 1), (2, 1, 1), (1, 2, 1), (1, 1, 2), (2, 2, 2)] {
            vol.set(x, y, z, true);
        }
        let t = cases(Connectivity::Six);
        for z in -1..4 {
            for y in -1..4 {
                for x in -1..4 {
                    for axis in 0..3 {
                        let v = Vertex { p: [x, y, z], axis };
                        let Some(a) = around(&vol, t, v) else {
                            continue;
                        };
                        for k in 0..a.n() {
                            let p = a.piece(k);
                            let case = &t[cube_case(&vol, p.cube) as usize];
                            let verts: Vec<Vertex> = case.pieces[p.index as usize]
                                .loops
                                .iter()
                                .flatten()
                                .map(|&e| vertex_of(p.cube, e))
                                .collect();
                            assert!(
                                verts.contains(&v)
                                    && verts.contains(&a.nbr(k))
                                    && verts.contains(&a.nbr((k + 1) % a.n())),
                                "{v:?} piece {k}"
                            );
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn around_a_single_sample() {
        let mut vol = MaskVolume::new([3, 3, 3], Frame::identity());
        vol.set(1, 1, 1, true);
        for conn in [Connectivity::Six, Connectivity::TwentySix] {
            let t = cases(conn);
            let v = Vertex {
                p: [0, 1, 1],
                axis: 0,
            };
            let a = around(&vol, t, v).expect("crossing");
            assert_eq!(a.n(), 4);
            let mut n = a.neighbours();
            n.sort();
            n.dedup();
            assert_eq!(n.len(), 4);
            // Each neighbour's neighbourhood contains v back.
            for w in a.neighbours() {
                let b = around(&vol, t, w).unwrap();
                assert!(b.position(v).is_some());
            }
        }
    }
}

#[cfg(test)]
mod tube_tests {
    use super::*;
    use crate::grid::{Frame, MaskVolume};
    use crate::topology::cases::{cases, Connectivity};

    /// Six samples around two body-diagonal outside corners: under 6 the cube between them holds
    /// a tube; its vertices get diagonals to the other end, and adjacency stays symmetric.
    #[test]
    fn tubes_have_diagonals_and_adjacency_is_symmetric() {
        let mut vol = MaskVolume::new([2, 2, 2], Frame::identity());
        for b in 1..7u8 {
            vol.set(
                (b & 1) as usize,
                ((b >> 1) & 1) as usize,
                ((b >> 2) & 1) as usize,
                true,
            );
        }
        let t = cases(Connectivity::Six);
        let mut diagonals = 0;
        for z in -1..2 {
            for y in -1..2 {
                for x in -1..2 {
                    for axis in 0..3 {
                        let v = Vertex { p: [x, y, z], axis };
                        let Some(a) = around(&vol, t, v) else {
                            continue;
                        };
                        diagonals += (0..a.n()).filter(|&k| a.diagonal(k)).count();
                        for w in a.neighbours() {
                            assert!(
                                around(&vol, t, w).unwrap().position(v).is_some(),
                                "{v:?} -> {w:?} not symmetric"
                            );
                        }
                    }
                }
            }
        }
        assert_eq!(
            diagonals, 12,
            "a tube strip has 6 diagonals, seen from both ends"
        );
    }
}

#[cfg(test)]
mod key_tests {
    use super::*;

    #[test]
    fn keys_round_trip() {
        for v in [
            Vertex {
                p: [-1, -1, -1],
                axis: 0,
            },
            Vertex {
                p: [0, 5, 1_000_000],
                axis: 2,
            },
            Vertex {
                p: [123, 456, 789],
                axis: 1,
            },
        ] {
            assert_eq!(Vertex::from_key(v.key()), v);
        }
    }
}
