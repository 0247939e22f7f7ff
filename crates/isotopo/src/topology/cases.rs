//! The 256 cube cases, derived in code from the digital-topology rule (docs/ARCHITECTURE.md,
//! conventions).
//!
//! A cube has 8 corner samples, each inside or outside. The rule: under connectivity 6 the
//! surface in a cube has one piece per group of *inside* corners joined along cube edges; under
//! 26, one piece per group of *outside* corners. A piece's boundary is made of segments on the
//! cube's faces, each joining the crossing points on two edges of the face and cutting off that
//! group's corners. The same rule in a face: a face whose corners alternate (diagonal pattern)
//! gets two segments, which cut off the two corners of the group's kind.
//!
//! Corner `b = x + 2y + 4z`; a case is the byte whose bit `b` says corner `b` is inside.
//!
//! ```text
//!         6 ------- 7          edges (12): along x: 0 (0-1)  1 (2-3)  2 (4-5)  3 (6-7)
//!        /|        /|                      along y: 4 (0-2)  5 (1-3)  6 (4-6)  7 (5-7)
//!       4 ------- 5 |                      along z: 8 (0-4)  9 (1-5) 10 (2-6) 11 (3-7)
//!       | 2 ------|-3      z  y
//!       |/        |/       | /         faces (6): 0 -x  1 +x  2 -y  3 +y  4 -z  5 +z
//!       0 ------- 1        |/__ x
//! ```
//!
//! A piece is a disk, or — only when exactly two body-diagonal corners stand apart from the
//! other six (e.g. corners 0 and 7 inside under 26) — a tube joining them: the "cube-interior
//! tunnel" that makes the surface follow the chosen connectivity instead of guessing.
//!
//! Every piece's boundary loops are oriented counter-clockwise seen from outside the solid, so
//! the triangles point outward and the two pieces sharing a face segment run it in opposite
//! directions.

use std::sync::OnceLock;

/// Digital connectivity of the solid (see docs/ARCHITECTURE.md, conventions).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
pub enum Connectivity {
    /// Inside samples 6-adjacent, outside 26-adjacent (the default).
    Six,
    /// Inside samples 26-adjacent, outside 6-adjacent.
    TwentySix,
}

impl Connectivity {
    /// The adjacency of inside samples as a number: 6 or 26.
    pub fn number(self) -> u32 {
        match self {
            Connectivity::Six => 6,
            Connectivity::TwentySix => 26,
        }
    }

    /// The other connectivity (the complement's).
    pub fn other(self) -> Connectivity {
        match self {
            Connectivity::Six => Connectivity::TwentySix,
            Connectivity::TwentySix => Connectivity::Six,
        }
    }

    /// Corners of this state form the pieces ("group" corners): inside under 6, outside under 26.
    #[inline]
    pub fn group_state(self) -> bool {
        self == Connectivity::Six
    }
}

/// Corner indices `(a, b)` of each edge, `a < b`.
pub const EDGE_CORNERS: [(u8, u8); 12] = [
    (0, 1),
    (2, 3),
    (4, 5),
    (6, 7),
    (0, 2),
    (1, 3),
    (4, 6),
    (5, 7),
    (0, 4),
    (1, 5),
    (2, 6),
    (3, 7),
];

/// Axis of each edge (0 = x, 1 = y, 2 = z).
pub const EDGE_AXIS: [u8; 12] = [0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2, 2];

/// Corners of each face in cyclic order. Face `f` is perpendicular to axis `f / 2`, on the side
/// `f % 2`; its corners are listed by their coordinates `(u, v)` on the two other axes
/// `u = (a+1) % 3`, `v = (a+2) % 3`, in the order (0,0) (1,0) (1,1) (0,1). The order depends only
/// on the face's position, so the two cubes sharing a face list its corners alike.
pub const FACE_CORNERS: [[u8; 4]; 6] = face_corners();

/// Local edge `k` of a face joins its corners `k` and `k+1` (mod 4); this is the cube edge.
pub const FACE_EDGES: [[u8; 4]; 6] = face_edges();

const fn corner_of(coords: [u8; 3]) -> u8 {
    coords[0] + 2 * coords[1] + 4 * coords[2]
}

const fn face_corners() -> [[u8; 4]; 6] {
    let mut out = [[0u8; 4]; 6];
    let uv = [(0u8, 0u8), (1, 0), (1, 1), (0, 1)];
    let mut f = 0;
    while f < 6 {
        let a = f / 2;
        let side = (f % 2) as u8;
        let mut k = 0;
        while k < 4 {
            let mut c = [0u8; 3];
            c[a] = side;
            c[(a + 1) % 3] = uv[k].0;
            c[(a + 2) % 3] = uv[k].1;
            out[f][k] = corner_of(c);
            k += 1;
        }
        f += 1;
    }
    out
}

const fn edge_between(a: u8, b: u8) -> u8 {
    let (lo, hi) = if a < b { (a, b) } else { (b, a) };
    let mut e = 0;
    while e < 12 {
        if EDGE_CORNERS[e].0 == lo && EDGE_CORNERS[e].1 == hi {
            return e as u8;
        }
        e += 1;
    }
    panic!("corners not joined by an edge");
}

const fn face_edges() -> [[u8; 4]; 6] {
    let fc = face_corners();
    let mut out = [[0u8; 4]; 6];
    let mut f = 0;
    while f < 6 {
        let mut k = 0;
        while k < 4 {
            out[f][k] = edge_between(fc[f][k], fc[f][(k + 1) % 4]);
            k += 1;
        }
        f += 1;
    }
    out
}

/// Corner positions, for orienting loops and triangulating with edge midpoints.
fn corner_pos(c: u8) -> [f64; 3] {
    [(c & 1) as f64, ((c >> 1) & 1) as f64, ((c >> 2) & 1) as f64]
}

/// Midpoint of a cube edge.
pub fn edge_midpoint(e: u8) -> [f64; 3] {
    let (a, b) = EDGE_CORNERS[e as usize];
    let (p, q) = (corner_pos(a), corner_pos(b));
    [
        (p[0] + q[0]) / 2.0,
        (p[1] + q[1]) / 2.0,
        (p[2] + q[2]) / 2.0,
    ]
}

/// Segments of a face, as pairs of local edges `(k0, k1)`, `k0 < k1`, in canonical order (by
/// `k0`). `states` bit `k` = local corner `k` inside. Depends only on the face's four corners and
/// the connectivity, so both cubes sharing a face agree on its segments and their order.
pub fn face_segments(states: u8, conn: Connectivity) -> ([(u8, u8); 2], usize) {
    let s = |k: u8| (states >> (k % 4)) & 1 == 1;
    let crossing: Vec<u8> = (0..4u8).filter(|&k| s(k) != s(k + 1)).collect();
    match crossing.len() {
        0 => ([(0, 0); 2], 0),
        2 => ([(crossing[0], crossing[1]), (0, 0)], 1),
        4 => {
            // Alternating corners: cut off the two corners of the group state. Corner k lies
            // between local edges k-1 and k.
            let cut: Vec<u8> = (0..4u8).filter(|&k| s(k) == conn.group_state()).collect();
            let mut segs = [(0u8, 0u8); 2];
            for (i, &k) in cut.iter().enumerate() {
                let (a, b) = ((k + 3) % 4, k);
                segs[i] = (a.min(b), a.max(b));
            }
            segs.sort();
            (segs, 2)
        }
        _ => unreachable!("a face has an even number of crossing edges"),
    }
}

/// The face state bits (bit k = local corner k inside) of face `f` in cube case `case`.
#[inline]
pub fn face_states(case: u8, f: usize) -> u8 {
    let fc = &FACE_CORNERS[f];
    let mut s = 0;
    for k in 0..4 {
        s |= ((case >> fc[k]) & 1) << k;
    }
    s
}

/// Marker for "no piece".
pub const NONE: u8 = u8::MAX;

/// One surface piece of a cube case.
#[derive(Clone, Debug, Default)]
pub struct Piece {
    /// The group's corners (bit mask).
    pub corners: u8,
    /// Boundary loops, each a cycle of cube edges (crossing points), counter-clockwise from
    /// outside the solid. One loop: a disk. Two: a tube.
    pub loops: Vec<Vec<u8>>,
    /// Triangles over cube edges, outward-facing.
    pub triangles: Vec<[u8; 3]>,
    /// 4 × this piece's share of the surface's Euler characteristic: `8 - 4·loops - segments`
    /// (a piece is an open sphere-with-holes, each segment is shared by two pieces and each
    /// crossing point by four).
    pub chi4: i8,
    /// 4 × its share of the Euler characteristic of its *ribbon* (the surface within one z-slice,
    /// whose z-faces and z-plane crossing points are on the ribbon's boundary):
    /// `8 - 4·loops - 2·side segments - 4·z-face segments + z-edge points + 2·x/y-edge points`.
    pub ribbon_chi4: i8,
    /// Number of boundary segments on z-faces (faces 4 and 5).
    pub z_face_segments: u8,
}

/// Most triangles any case has (checked when the table is derived).
pub const MAX_TRIANGLES: usize = 6;

/// A cube case under one connectivity.
///
/// Laid out for the per-cube loops, which read a case of most cubes of every slice: the fields
/// they read come first, in the first 64 bytes (one cache line; the areas read `n_triangles` to
/// `triangle_piece`, the ribbons' sums `n_pieces` to `top_segments`).
#[derive(Clone, Debug, Default)]
#[repr(C, align(64))]
pub struct Case {
    /// Number of pieces.
    pub n_pieces: u8,
    /// Number of triangles of all pieces together: `triangles[..n_triangles]` are used.
    pub n_triangles: u8,
    /// The crossed edges (those with an owner in `edge_owner`) past the first four: bit `e`
    /// for edge `e`.
    pub crossed_after_first: u16,
    /// The first four crossed edges, by number; where fewer are crossed, the first again (so
    /// that a cube's first four crossing points are made without a branch).
    pub first_crossed: [u8; 4],
    /// All triangles of all pieces, piece by piece, as cube edges (outward-facing).
    pub triangles: [[u8; 3]; MAX_TRIANGLES],
    /// Piece (index into `pieces`) of each triangle.
    pub triangle_piece: [u8; MAX_TRIANGLES],
    /// Per piece: [`Piece::chi4`].
    pub chi4: [i8; 4],
    /// Per piece: [`Piece::ribbon_chi4`].
    pub ribbon_chi4: [i8; 4],
    /// Per piece: the upper corner of the first z-edge its boundary crosses, or [`NONE`].
    pub z_upper: [u8; 4],
    /// Per piece: its boundary segments on the lower face (face 4; the plane below).
    pub bottom_segments: [u8; 4],
    /// Per piece: its boundary segments on the upper face (face 5; the plane above).
    pub top_segments: [u8; 4],
    /// For each face and segment slot (canonical order): the owning piece, or [`NONE`].
    pub face_owner: [[u8; 2]; 6],
    /// For each face and slot: the segment's end points as cube edges, in the owning piece's
    /// loop direction.
    pub face_segment: [[(u8, u8); 2]; 6],
    /// For each cube edge: the piece whose boundary passes through its crossing point, or [`NONE`].
    pub edge_owner: [u8; 12],
    /// The surface pieces in the cube, in order of their lowest corner.
    pub pieces: Vec<Piece>,
}

/// Union-find over 8 corners, for grouping.
fn groups(case: u8, conn: Connectivity) -> Vec<u8> {
    let state = |c: u8| (case >> c) & 1 == 1;
    let mut parent: [u8; 8] = [0, 1, 2, 3, 4, 5, 6, 7];
    fn find(p: &mut [u8; 8], x: u8) -> u8 {
        let mut r = x;
        while p[r as usize] != r {
            r = p[r as usize];
        }
        r
    }
    for &(a, b) in &EDGE_CORNERS {
        if state(a) == conn.group_state() && state(b) == conn.group_state() {
            let (ra, rb) = (find(&mut parent, a), find(&mut parent, b));
            parent[ra.max(rb) as usize] = ra.min(rb);
        }
    }
    let mut masks = [0u8; 8];
    for c in 0..8 {
        if state(c) == conn.group_state() {
            let r = find(&mut parent, c);
            masks[r as usize] |= 1 << c;
        }
    }
    masks.into_iter().filter(|&m| m != 0).collect()
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Outward normal of face `f` of the unit cube.
fn face_normal(f: usize) -> [f64; 3] {
    let mut n = [0.0; 3];
    n[f / 2] = if f % 2 == 1 { 1.0 } else { -1.0 };
    n
}

/// One boundary segment of a case before pieces are numbered: the group owning it, where it lies
/// (face and segment slot) and its direction along the owner's loop (`from` → `to`, cube edges).
struct Segment {
    group: usize,
    face: usize,
    slot: usize,
    from: u8,
    to: u8,
}

fn derive_case(case: u8, conn: Connectivity) -> Case {
    let groups = groups(case, conn);
    let segs = oriented_segments(case, conn, &groups);
    let mut out = Case {
        face_owner: [[NONE; 2]; 6],
        edge_owner: [NONE; 12],
        z_upper: [NONE; 4],
        ..Default::default()
    };
    // Pieces: groups owning segments, in order of their lowest corner.
    for (g, &mask) in groups.iter().enumerate() {
        let mine: Vec<&Segment> = segs.iter().filter(|s| s.group == g).collect();
        if mine.is_empty() {
            continue;
        }
        let piece = make_piece(mask, &mine);
        record_piece(&mut out, case, &piece, &mine);
        out.pieces.push(piece);
    }
    out.n_pieces = out.pieces.len() as u8;
    let crossed: Vec<u8> = (0..12)
        .filter(|&e| out.edge_owner[e as usize] != NONE)
        .collect();
    for k in 0..4 {
        out.first_crossed[k] = crossed.get(k).or(crossed.first()).copied().unwrap_or(0);
    }
    out.crossed_after_first = crossed.iter().skip(4).fold(0, |m, &e| m | 1 << e);
    out
}

/// Segments of every face with their owning group and orientation, face by face, each face's in
/// canonical slot order.
fn oriented_segments(case: u8, conn: Connectivity, groups: &[u8]) -> Vec<Segment> {
    let inside = |c: u8| (case >> c) & 1 == 1;
    let mut segs = Vec::new();
    for f in 0..6 {
        let (pairs, n) = face_segments(face_states(case, f), conn);
        for (slot, &(k0, k1)) in pairs.iter().take(n).enumerate() {
            let (side_a, side_b) = segment_sides(f, k0, k1, n);
            let (inside_side, outside_side) = if inside(side_a[0]) {
                (&side_a, &side_b)
            } else {
                (&side_b, &side_a)
            };
            let group_side = if conn.group_state() {
                inside_side
            } else {
                outside_side
            };
            let owner_corner = group_side[0];
            let group = groups
                .iter()
                .position(|&m| m & (1 << owner_corner) != 0)
                .unwrap();
            let (from, to) = segment_direction(f, k0, k1, inside_side, outside_side);
            segs.push(Segment {
                group,
                face: f,
                slot,
                from,
                to,
            });
        }
    }
    segs
}

/// The corners on each side of segment `(k0, k1)` (local edges) of face `f`, next to it; `n` is
/// the face's number of segments.
///
/// ```text
///   3 --2-- 2      local corner k sits between local edges k-1 and k;
///   |       |      local edge k joins local corners k and k+1 (mod 4)
///   3       1
///   |       |
///   0 --0-- 1
/// ```
///
/// With two crossing edges the segment splits the face into two runs of corners, each of one
/// state. With four, each segment cuts off one corner; its other side holds that corner's two
/// neighbours (the middle region).
fn segment_sides(f: usize, k0: u8, k1: u8, n: usize) -> (Vec<u8>, Vec<u8>) {
    let corner = |k: u8| FACE_CORNERS[f][k as usize % 4];
    if n == 1 {
        (
            (k0 + 1..=k1).map(corner).collect(),
            (k1 + 1..k0 + 5).map(corner).collect(),
        )
    } else {
        // Segment (k0, k1) with k1 = k0 + 1 cuts off local corner k1; (0, 3) cuts off 0.
        let cut = if k1 == k0 + 1 { k1 } else { 0 };
        (vec![corner(cut)], vec![corner(cut + 1), corner(cut + 3)])
    }
}

/// Segment `(k0, k1)` of face `f` as (from, to) cube edges, in its piece's loop direction.
///
/// With d pointing from the inside corners toward the outside ones, walking from P to Q keeps the
/// piece on the left seen from outside when (d × (Q - P)) · n_face < 0.
fn segment_direction(
    f: usize,
    k0: u8,
    k1: u8,
    inside_side: &[u8],
    outside_side: &[u8],
) -> (u8, u8) {
    let (e0, e1) = (FACE_EDGES[f][k0 as usize], FACE_EDGES[f][k1 as usize]);
    let (p, q) = (edge_midpoint(e0), edge_midpoint(e1));
    let d = sub(centroid(outside_side), centroid(inside_side));
    let forward = dot(cross(d, sub(q, p)), face_normal(f)) < 0.0;
    if forward {
        (e0, e1)
    } else {
        (e1, e0)
    }
}

/// Mean position of some cube corners.
fn centroid(cs: &[u8]) -> [f64; 3] {
    let mut c = [0.0; 3];
    for &x in cs {
        let pos = corner_pos(x);
        for i in 0..3 {
            c[i] += pos[i] / cs.len() as f64;
        }
    }
    c
}

/// The piece of the group with corners `mask`, bounded by the segments `mine`: its loops,
/// triangles and shares of the Euler characteristics (see [`Piece`]).
fn make_piece(mask: u8, mine: &[&Segment]) -> Piece {
    let loops = chain_loops(mine);
    let nseg = mine.len() as i32;
    let z_face = mine.iter().filter(|s| s.face >= 4).count() as i32;
    let side = nseg - z_face;
    let points: Vec<u8> = loops.iter().flatten().copied().collect();
    let z_points = points
        .iter()
        .filter(|&&e| EDGE_AXIS[e as usize] == 2)
        .count() as i32;
    let plane_points = points.len() as i32 - z_points;
    let k = loops.len() as i32;
    Piece {
        corners: mask,
        triangles: triangulate(&loops),
        chi4: (8 - 4 * k - nseg) as i8,
        ribbon_chi4: (8 - 4 * k - 2 * side - 4 * z_face + z_points + 2 * plane_points) as i8,
        z_face_segments: z_face as u8,
        loops,
    }
}

/// Chains a piece's segments into loops: each crossing point starts exactly one of them.
fn chain_loops(mine: &[&Segment]) -> Vec<Vec<u8>> {
    let mut next = [NONE; 12];
    for s in mine {
        next[s.from as usize] = s.to;
    }
    let mut seen = [false; 12];
    let mut loops = Vec::new();
    for s in mine {
        if seen[s.from as usize] {
            continue;
        }
        let mut lp = Vec::new();
        let mut e = s.from;
        while !seen[e as usize] {
            seen[e as usize] = true;
            lp.push(e);
            e = next[e as usize];
        }
        loops.push(lp);
    }
    loops
}

/// Copies `piece`, the next piece of case `case`, into `out`'s compact tables that the per-cube
/// loops read (the piece itself is pushed by the caller).
fn record_piece(out: &mut Case, case: u8, piece: &Piece, mine: &[&Segment]) {
    let piece_index = out.pieces.len() as u8;
    let k = piece_index as usize;
    for s in mine {
        out.face_owner[s.face][s.slot] = piece_index;
        out.face_segment[s.face][s.slot] = (s.from, s.to);
        match s.face {
            4 => out.bottom_segments[k] += 1,
            5 => out.top_segments[k] += 1,
            _ => {}
        }
    }
    let points = || piece.loops.iter().flatten();
    for &e in points() {
        out.edge_owner[e as usize] = piece_index;
    }
    out.chi4[k] = piece.chi4;
    out.ribbon_chi4[k] = piece.ribbon_chi4;
    out.z_upper[k] = points()
        .find(|&&e| EDGE_AXIS[e as usize] == 2)
        .map(|&e| EDGE_CORNERS[e as usize].1)
        .unwrap_or(NONE);
    for t in &piece.triangles {
        let n = out.n_triangles as usize;
        assert!(
            n < MAX_TRIANGLES,
            "case {case:#010b} has more than {MAX_TRIANGLES} triangles"
        );
        out.triangles[n] = *t;
        out.triangle_piece[n] = piece_index;
        out.n_triangles += 1;
    }
}

/// Do two cube edges lie on a common face? A triangle edge between their crossing points would
/// run inside that face, where the neighbouring cube's triangles can meet it too.
fn share_face(a: u8, b: u8) -> bool {
    FACE_EDGES.iter().any(|f| f.contains(&a) && f.contains(&b))
}

/// Triangles for a piece: for a disk, the polygon triangulation (dynamic programming over
/// diagonals) that uses no diagonal across a cube face and maximises the worst alignment of
/// triangle normals with the loop's normal; for a tube, a strip. Vertices are edge midpoints.
fn triangulate(loops: &[Vec<u8>]) -> Vec<[u8; 3]> {
    match loops.len() {
        1 => triangulate_disk(&loops[0]),
        2 => triangulate_tube(&loops[0], &loops[1]),
        _ => unreachable!("pieces are disks or tubes"),
    }
}

/// A disk's triangles, read back from the split table of [`disk_splits`] (root chord (0, n-1)).
fn triangulate_disk(lp: &[u8]) -> Vec<[u8; 3]> {
    let n = lp.len();
    let split = disk_splits(lp);
    assert!(
        split[0][n - 1] != usize::MAX,
        "no triangulation of loop {lp:?} avoids face diagonals"
    );
    let mut tris = Vec::new();
    let mut stack = vec![(0, n - 1)];
    while let Some((i, j)) = stack.pop() {
        if j < i + 2 {
            continue;
        }
        let k = split[i][j];
        tris.push([lp[i], lp[k], lp[j]]);
        stack.push((i, k));
        stack.push((k, j));
    }
    tris
}

/// Newell normal of a loop of edge midpoints.
fn newell_normal(lp: &[u8]) -> [f64; 3] {
    let n = lp.len();
    let mut nrm = [0.0; 3];
    for i in 0..n {
        let (a, b) = (edge_midpoint(lp[i]), edge_midpoint(lp[(i + 1) % n]));
        nrm[0] += (a[1] - b[1]) * (a[2] + b[2]);
        nrm[1] += (a[2] - b[2]) * (a[0] + b[0]);
        nrm[2] += (a[0] - b[0]) * (a[1] + b[1]);
    }
    nrm
}

/// The dynamic programme over the sub-polygons `i..=j` of a disk's loop `lp`: `split[i][j]` is
/// the apex `k` of the triangle on chord (i, j) in the triangulation of `i..=j` whose worst
/// triangle is best aligned with the loop's normal, among those using no chord that runs inside
/// a cube face; `usize::MAX` where there is none.
///
/// ```text
///        k
///       / \        triangle (i, k, j), then the best of i..=k and of k..=j
///      i---j
/// ```
fn disk_splits(lp: &[u8]) -> Vec<Vec<usize>> {
    let n = lp.len();
    let pos = |e: u8| edge_midpoint(e);
    let nrm = newell_normal(lp);
    let quality = |i: usize, j: usize, k: usize| {
        let (a, b, c) = (pos(lp[i]), pos(lp[j]), pos(lp[k]));
        let t = cross(sub(b, a), sub(c, a));
        dot(t, nrm) / dot(t, t).sqrt().max(1e-12)
    };
    let allowed =
        |i: usize, j: usize| j == i + 1 || (i == 0 && j == n - 1) || !share_face(lp[i], lp[j]);
    // best[i][j]: the best worst-quality triangulating the sub-polygon i..=j.
    let mut best = vec![vec![f64::INFINITY; n]; n];
    let mut split = vec![vec![usize::MAX; n]; n];
    for len in 2..n {
        for i in 0..n - len {
            let j = i + len;
            best[i][j] = f64::NEG_INFINITY;
            if !allowed(i, j) {
                continue;
            }
            for k in i + 1..j {
                if !allowed(i, k) || !allowed(k, j) {
                    continue;
                }
                let left = if k == i + 1 {
                    f64::INFINITY
                } else {
                    best[i][k]
                };
                let right = if j == k + 1 {
                    f64::INFINITY
                } else {
                    best[k][j]
                };
                let q = quality(i, k, j).min(left).min(right);
                if q > best[i][j] {
                    best[i][j] = q;
                    split[i][j] = k;
                }
            }
        }
    }
    split
}

/// A tube's strip between its two triangular loops, rung `i` joining `a[i]` to `b'(i)`:
///
/// ```text
///    a[i] ----- a[i+1]     triangles (a[i], a[i+1], b'(i)) and (b'(i+1), b'(i), a[i+1]),
///     |        /  |        b'(i) = b[(s - i) mod 3], with the offset s whose rungs are
///     |      /    |        shortest in total
///   b'(i) ----- b'(i+1)
/// ```
fn triangulate_tube(a: &[u8], b: &[u8]) -> Vec<[u8; 3]> {
    assert!(a.len() == 3 && b.len() == 3, "tubes join two triangles");
    let pos = |e: u8| edge_midpoint(e);
    // Walk `a` forward and `b` backward (boundary loops of an annulus run opposite ways).
    let dist = |p: [f64; 3], q: [f64; 3]| dot(sub(p, q), sub(p, q)).sqrt();
    let best_s = (0..3)
        .min_by(|&s1, &s2| {
            let cost = |s: usize| {
                (0..3)
                    .map(|i| dist(pos(a[i]), pos(b[(s + 3 - i) % 3])))
                    .sum::<f64>()
            };
            cost(s1).partial_cmp(&cost(s2)).unwrap()
        })
        .unwrap();
    let bb = |i: usize| b[(best_s + 3 - i % 3) % 3];
    let mut tris = Vec::new();
    for i in 0..3 {
        tris.push([a[i], a[(i + 1) % 3], bb(i)]);
        tris.push([bb(i + 1), bb(i), a[(i + 1) % 3]]);
    }
    tris
}

/// For each case: is its cube cut into the same pieces, in the same order, with the same face
/// segments and Euler characteristic shares, under both connectivities? All but the cases with
/// a face whose inside corners are diagonal or with two opposite corners alone are.
pub fn cut_alike() -> &'static [bool; 256] {
    static ALIKE: OnceLock<[bool; 256]> = OnceLock::new();
    ALIKE.get_or_init(|| {
        let (six, twenty_six) = (cases(Connectivity::Six), cases(Connectivity::TwentySix));
        std::array::from_fn(|c| {
            let (a, b) = (&six[c], &twenty_six[c]);
            a.n_pieces == b.n_pieces
                && a.chi4 == b.chi4
                && a.ribbon_chi4 == b.ribbon_chi4
                && a.z_upper == b.z_upper
                && a.face_owner == b.face_owner
        })
    })
}

/// The 256 cases for each connectivity, derived once.
pub fn cases(conn: Connectivity) -> &'static [Case; 256] {
    static SIX: OnceLock<Box<[Case; 256]>> = OnceLock::new();
    static TWENTY_SIX: OnceLock<Box<[Case; 256]>> = OnceLock::new();
    let cell = match conn {
        Connectivity::Six => &SIX,
        Connectivity::TwentySix => &TWENTY_SIX,
    };
    cell.get_or_init(|| {
        let v: Vec<Case> = (0..=255u8).map(|c| derive_case(c, conn)).collect();
        v.try_into().map_err(|_| ()).expect("256 cases")
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const BOTH: [Connectivity; 2] = [Connectivity::Six, Connectivity::TwentySix];

    /// Exactly the cubes without a critical face or corner pair are cut alike: the genus pass
    /// takes their pieces under one connectivity for the other's.
    #[test]
    fn cubes_are_cut_alike_under_both_connectivities_unless_critical() {
        let alike = cut_alike();
        for c in 0..=255u8 {
            let diagonal_face = (0..6).any(|f| matches!(face_states(c, f), 0b0101 | 0b1010));
            let critical = diagonal_face || crate::topology::critical::critical_cube(c);
            assert_eq!(alike[c as usize], !critical, "case {c:#010b}");
        }
        // 128 of the 256 cases have a critical face or corner pair (counted by a separate script).
        assert_eq!(alike.iter().filter(|&&a| a).count(), 128);
    }

    /// Body-diagonal corner pairs.
    fn body_diagonal(a: u8, b: u8) -> bool {
        a ^ b == 7
    }

    /// Where a cube has no face with one diagonal and is not two opposite corners alone, both
    /// connectivities cut the same surface: one piece with the same loops (the genus pass
    /// copies the chosen connectivity's slices for the other's where no cube is critical).
    #[test]
    fn cubes_without_critical_patterns_have_one_surface_under_both() {
        // Each face's corners as two diagonals (a, d) and (b, c).
        const FACES: [[u8; 4]; 6] = [
            [0, 6, 2, 4],
            [1, 7, 3, 5],
            [0, 5, 1, 4],
            [2, 7, 3, 6],
            [0, 3, 1, 2],
            [4, 7, 5, 6],
        ];
        let mut compared = 0;
        for case in 0..=255u8 {
            let at = |k: u8| (case >> k) & 1;
            let diagonal = FACES
                .iter()
                .any(|f| at(f[0]) == at(f[1]) && at(f[2]) == at(f[3]) && at(f[0]) != at(f[2]));
            let ones = case.count_ones();
            let lone = if ones == 6 { !case } else { case };
            let opposite =
                (ones == 2 || ones == 6) && (0..4).any(|k| lone == (1 << k) | (1 << (7 - k)));
            if diagonal || opposite {
                continue;
            }
            let [six, twenty_six] = BOTH.map(|conn| &cases(conn)[case as usize]);
            assert_eq!(six.pieces.len(), twenty_six.pieces.len(), "{case:#010b}");
            assert!(six.pieces.len() <= 1, "{case:#010b}");
            // What the slices and the tracker read of a case.
            let read = |c: &Case| {
                (
                    c.n_pieces,
                    c.chi4,
                    c.ribbon_chi4,
                    c.z_upper,
                    c.face_owner,
                    c.face_segment,
                    c.edge_owner,
                )
            };
            assert_eq!(read(six), read(twenty_six), "{case:#010b}");
            for (a, b) in six.pieces.iter().zip(&twenty_six.pieces) {
                assert_eq!(
                    (&a.loops, a.chi4, a.ribbon_chi4, a.z_face_segments),
                    (&b.loops, b.chi4, b.ribbon_chi4, b.z_face_segments),
                    "{case:#010b}"
                );
                compared += 1;
            }
        }
        assert!(compared > 100, "{compared}");
    }

    #[test]
    fn pieces_follow_the_rule() {
        for conn in BOTH {
            for case in 0..=255u8 {
                let c = &cases(conn)[case as usize];
                let group_mask = if conn.group_state() { case } else { !case };
                let groups = groups(case, conn);
                let expected_pieces = if group_mask == 0xff { 0 } else { groups.len() };
                assert_eq!(
                    c.pieces.len(),
                    expected_pieces,
                    "case {case:#010b} conn {}",
                    conn.number()
                );
                for p in &c.pieces {
                    assert!(
                        groups.contains(&p.corners),
                        "case {case:#010b}: piece corners not a group"
                    );
                    // A tube exactly when the other corners are two body-diagonal ones.
                    let others: Vec<u8> = (0..8).filter(|&k| group_mask & (1 << k) == 0).collect();
                    let tube = others.len() == 2 && body_diagonal(others[0], others[1]);
                    assert_eq!(
                        p.loops.len(),
                        if tube { 2 } else { 1 },
                        "case {case:#010b} conn {}",
                        conn.number()
                    );
                    // Disk: chi 1; tube: chi 0. Sum of shares: chi - segments/2 + points/4.
                    let segs: usize = p.loops.iter().map(Vec::len).sum();
                    assert_eq!(p.chi4 as i32, 8 - 4 * p.loops.len() as i32 - segs as i32);
                }
            }
        }
    }

    #[test]
    fn the_crossed_edges_are_those_whose_corners_differ() {
        for conn in BOTH {
            for case in 0..=255u8 {
                let c = &cases(conn)[case as usize];
                let inside = |corner: u8| (case >> corner) & 1;
                let expected: Vec<u8> = (0..12u8)
                    .filter(|&e| {
                        let (a, b) = EDGE_CORNERS[e as usize];
                        inside(a) != inside(b)
                    })
                    .collect();
                let mut listed: Vec<u8> = c.first_crossed.to_vec();
                listed.extend((0..12u8).filter(|&e| c.crossed_after_first >> e & 1 == 1));
                listed.sort_unstable();
                listed.dedup();
                let why = format!("case {case:#010b} conn {}", conn.number());
                match expected.is_empty() {
                    true => assert_eq!(c.crossed_after_first, 0, "{why}"),
                    false => assert_eq!(listed, expected, "{why}"),
                }
                // The first four in order, repeating the first where fewer are crossed.
                let first: Vec<u8> = (0..4)
                    .map(|k| *expected.get(k).or(expected.first()).unwrap_or(&0))
                    .collect();
                assert_eq!(c.first_crossed.to_vec(), first, "{why}");
            }
        }
    }

    #[test]
    fn each_pieces_z_face_segments_are_those_of_its_loops() {
        // A piece's segment on a face joins two consecutive points of one of its loops, both
        // on that face's edges (read from the loops, not from the face owners the counts
        // were made from).
        let on_face = |p: &Piece, face: usize| -> u8 {
            let edges = &FACE_EDGES[face];
            let pairs = p
                .loops
                .iter()
                .flat_map(|lp| (0..lp.len()).map(move |i| (lp[i], lp[(i + 1) % lp.len()])));
            pairs
                .filter(|(a, b)| edges.contains(a) && edges.contains(b))
                .count() as u8
        };
        for conn in BOTH {
            for case in 0..=255u8 {
                let c = &cases(conn)[case as usize];
                for (k, p) in c.pieces.iter().enumerate() {
                    let why = format!("case {case:#010b} conn {} piece {k}", conn.number());
                    assert_eq!(c.bottom_segments[k], on_face(p, 4), "{why}");
                    assert_eq!(c.top_segments[k], on_face(p, 5), "{why}");
                    assert_eq!(
                        c.bottom_segments[k] + c.top_segments[k],
                        p.z_face_segments,
                        "{why}"
                    );
                }
            }
        }
    }

    #[test]
    fn diagonal_corners_give_two_disks_under_6_and_a_tube_under_26() {
        let case = 0b1000_0001; // corners 0 and 7 inside
        let six = &cases(Connectivity::Six)[case];
        assert_eq!(six.pieces.len(), 2);
        assert!(six
            .pieces
            .iter()
            .all(|p| p.loops.len() == 1 && p.loops[0].len() == 3));
        let tw = &cases(Connectivity::TwentySix)[case];
        assert_eq!(tw.pieces.len(), 1);
        assert_eq!(tw.pieces[0].loops.len(), 2);
        assert_eq!(tw.pieces[0].triangles.len(), 6);
    }

    /// The two cubes sharing a face see the same segments and run them in opposite directions.
    #[test]
    fn shared_faces_agree_and_are_oppositely_oriented() {
        let local = |f: usize, e: u8| FACE_EDGES[f].iter().position(|&x| x == e).unwrap();
        for conn in BOTH {
            let t = cases(conn);
            for axis in 0..3 {
                let (fa, fb) = (2 * axis + 1, 2 * axis); // +face of cube A = -face of cube B
                for a in 0..=255u8 {
                    for b in 0..=255u8 {
                        if face_states(a, fa) != face_states(b, fb) {
                            continue;
                        }
                        let (ca, cb) = (&t[a as usize], &t[b as usize]);
                        for slot in 0..2 {
                            assert_eq!(
                                ca.face_owner[fa][slot] == NONE,
                                cb.face_owner[fb][slot] == NONE
                            );
                            if ca.face_owner[fa][slot] == NONE {
                                continue;
                            }
                            let (p, q) = ca.face_segment[fa][slot];
                            let (r, s) = cb.face_segment[fb][slot];
                            assert_eq!(
                                (local(fa, p), local(fa, q)),
                                (local(fb, s), local(fb, r)),
                                "cases {a} {b} axis {axis} slot {slot}"
                            );
                        }
                    }
                }
            }
        }
    }

    /// Each piece's triangles form an oriented surface whose boundary is exactly its loops.
    #[test]
    fn triangles_bound_the_loops_and_face_outward() {
        for conn in BOTH {
            for case in 0..=255u8 {
                let c = &cases(conn)[case as usize];
                for p in &c.pieces {
                    let mut directed: std::collections::HashMap<(u8, u8), i32> = Default::default();
                    for t in &p.triangles {
                        for k in 0..3 {
                            let (a, b) = (t[k], t[(k + 1) % 3]);
                            *directed.entry((a, b)).or_default() += 1;
                            *directed.entry((b, a)).or_default() -= 1;
                        }
                    }
                    let mut boundary: Vec<(u8, u8)> = directed
                        .iter()
                        .filter(|(_, &v)| v > 0)
                        .map(|(&k, _)| k)
                        .collect();
                    boundary.sort();
                    let mut want: Vec<(u8, u8)> = p
                        .loops
                        .iter()
                        .flat_map(|l| (0..l.len()).map(move |k| (l[k], l[(k + 1) % l.len()])))
                        .collect();
                    want.sort();
                    assert_eq!(boundary, want, "case {case:#010b} conn {}", conn.number());
                    assert!(directed.values().all(|&v| v.abs() <= 1));
                    // Outward: summed over the piece, triangle normals point down the gradient
                    // of the trilinear interpolant of the corner states (1 inside, 0 outside).
                    let mut outward = 0.0;
                    for t in &p.triangles {
                        let (a, b, cc) = (
                            edge_midpoint(t[0]),
                            edge_midpoint(t[1]),
                            edge_midpoint(t[2]),
                        );
                        let n = cross(sub(b, a), sub(cc, a));
                        let m = [
                            (a[0] + b[0] + cc[0]) / 3.0,
                            (a[1] + b[1] + cc[1]) / 3.0,
                            (a[2] + b[2] + cc[2]) / 3.0,
                        ];
                        let mut grad = [0.0; 3];
                        for k in 0..8u8 {
                            if case & (1 << k) == 0 {
                                continue;
                            }
                            let c = corner_pos(k);
                            let w = |axis: usize| {
                                if c[axis] == 1.0 {
                                    m[axis]
                                } else {
                                    1.0 - m[axis]
                                }
                            };
                            let sgn = |axis: usize| if c[axis] == 1.0 { 1.0 } else { -1.0 };
                            grad[0] += sgn(0) * w(1) * w(2);
                            grad[1] += sgn(1) * w(0) * w(2);
                            grad[2] += sgn(2) * w(0) * w(1);
                        }
                        outward -= dot(n, grad);
                    }
                    assert!(
                        outward > 0.0,
                        "case {case:#010b} conn {}: piece faces inward",
                        conn.number()
                    );
                }
            }
        }
    }
}
