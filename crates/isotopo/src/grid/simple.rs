//! Simple samples: those whose flip changes no topology of the solid or of its complement
//! (Bertrand and Malandain's topological numbers, each side with its own adjacency, in the
//! sample's 26-neighbourhood, are both 1). Thinning walls (`closure::peel`) flips only such
//! samples; making the output well-composed (`compose`) flips them first, and as a last
//! resort sets of samples that keep the topology together ([`SetTest`]).

use crate::grid::{BoxCells, MaskVolume};
use crate::topology::cases::Connectivity;

/// The six face neighbours' offsets.
pub(crate) const FACES: [[i64; 3]; 6] = [
    [-1, 0, 0],
    [1, 0, 0],
    [0, -1, 0],
    [0, 1, 0],
    [0, 0, -1],
    [0, 0, 1],
];

/// The 26 neighbours of a sample, and for each its adjacencies within the neighbourhood.
pub(crate) struct Neighbourhood {
    pub(crate) offsets: [[i64; 3]; 26],
    /// Neighbours k, j that are 6-adjacent / 26-adjacent to each other: bit `j` of `adj6[k]`.
    adj6: [u32; 26],
    adj26: [u32; 26],
    /// Face neighbours (6-adjacent to the centre), and those of the 18-neighbourhood (not a
    /// corner): bit `k` for neighbour `k`.
    face: u32,
    in18: u32,
}

pub(crate) fn neighbourhood() -> &'static Neighbourhood {
    static N: std::sync::OnceLock<Neighbourhood> = std::sync::OnceLock::new();
    N.get_or_init(|| {
        let mut offsets = [[0i64; 3]; 26];
        let mut n = 0;
        for z in -1..=1 {
            for y in -1..=1 {
                for x in -1..=1 {
                    if (x, y, z) != (0, 0, 0) {
                        offsets[n] = [x, y, z];
                        n += 1;
                    }
                }
            }
        }
        let l1 = |d: [i64; 3]| d[0].abs() + d[1].abs() + d[2].abs();
        let face: [bool; 26] = std::array::from_fn(|k| l1(offsets[k]) == 1);
        let in18: [bool; 26] = std::array::from_fn(|k| l1(offsets[k]) <= 2);
        let adj = |six: bool| -> [u32; 26] {
            std::array::from_fn(|k| {
                (0..26).fold(0, |bits, j| {
                    let d: [i64; 3] = std::array::from_fn(|c| offsets[k][c] - offsets[j][c]);
                    let m = d.iter().map(|x| x.abs()).max().unwrap_or(0);
                    let adjacent = j != k && m == 1 && (!six || l1(d) == 1);
                    bits | u32::from(adjacent) << j
                })
            })
        };
        Neighbourhood {
            offsets,
            adj6: adj(true),
            adj26: adj(false),
            face: bits_of(&face),
            in18: bits_of(&in18),
        }
    })
}

/// The neighbours flagged, as bit `k` for neighbour `k`.
fn bits_of(flags: &[bool; 26]) -> u32 {
    (0..26).fold(0, |m, k| m | u32::from(flags[k]) << k)
}

/// All 26 neighbours' bits.
const ALL: u32 = (1 << 26) - 1;

/// Components of the samples `member` of the neighbourhood (bit `k` for neighbour `k`): with
/// 6-adjacency, those of the 18-neighbourhood that touch a face neighbour (the geodesic count);
/// with 26, all.
fn components(member: u32, six: bool) -> usize {
    pieces_of(member, six, |_, _| {})
}

/// Walks the components counted by [`components`], calling `each(piece, k)` for every neighbour
/// `k` (an index into the offsets) of each; returns how many there are. Each piece grows as a
/// bit mask of the 26 neighbours (this runs for every flip tried).
pub(crate) fn label_pieces(
    member: &[bool; 26],
    six: bool,
    each: impl FnMut(usize, usize),
) -> usize {
    pieces_of(bits_of(member), six, each)
}

/// [`label_pieces`] of the neighbours whose bits are set in `member`.
fn pieces_of(member: u32, six: bool, mut each: impl FnMut(usize, usize)) -> usize {
    let nb = neighbourhood();
    let allowed = if six { member & nb.in18 } else { member };
    let mut starts = if six { allowed & nb.face } else { allowed };
    let adj = if six { &nb.adj6 } else { &nb.adj26 };
    let mut count = 0;
    while starts != 0 {
        let mut piece = 1u32 << starts.trailing_zeros();
        let mut frontier = piece;
        while frontier != 0 {
            let k = frontier.trailing_zeros() as usize;
            frontier &= frontier - 1;
            let new = adj[k] & allowed & !piece;
            piece |= new;
            frontier |= new;
        }
        let mut walk = piece;
        while walk != 0 {
            each(count, walk.trailing_zeros() as usize);
            walk &= walk - 1;
        }
        starts &= !piece;
        count += 1;
    }
    count
}

/// [`label_pieces`] of the neighbours of `q` on `side` (read as [`topological_numbers`] reads
/// them).
pub(crate) fn label_side_pieces(
    vol: &MaskVolume,
    q: [i64; 3],
    side: bool,
    six: bool,
    each: impl FnMut(usize, usize),
) -> usize {
    let inside = neighbours(vol, q);
    pieces_of(if side { inside } else { !inside & ALL }, six, each)
}

/// The inside samples of the 26-neighbourhood of `q` (bit `k` for neighbour `k`).
fn neighbours(vol: &MaskVolume, q: [i64; 3]) -> u32 {
    if vol.contains(q) {
        // The neighbours are numbered as the block's bits, less the centre's (bit 13).
        let block = vol.block(q);
        return block & ((1 << 13) - 1) | (block >> 14) << 13;
    }
    let nb = neighbourhood();
    (0..26).fold(0, |m, k| {
        let r = super::shift(q, nb.offsets[k]);
        m | u32::from(vol.get(r[0], r[1], r[2])) << k
    })
}

/// The topological numbers of sample `q`: the pieces of the inside and of the outside in its
/// neighbourhood that touch it (each with its own adjacency). Flipping `q` changes no topology
/// exactly when both are 1.
pub(crate) fn topological_numbers(
    vol: &MaskVolume,
    q: [i64; 3],
    conn: Connectivity,
) -> (usize, usize) {
    let inside = neighbours(vol, q);
    let six_inside = conn == Connectivity::Six;
    (
        components(inside, six_inside),
        components(!inside & ALL, !six_inside),
    )
}

/// Whether flipping sample `q` changes no topology: [`topological_numbers`] both 1. The side
/// with fewer samples round `q` is labelled first, and the other only if that gave one piece:
/// a sample with none of the other side round it (inside a thick region being thinned) is
/// answered without labelling its own side.
pub(crate) fn is_simple(vol: &MaskVolume, q: [i64; 3], conn: Connectivity) -> bool {
    let inside = neighbours(vol, q);
    let outside = !inside & ALL;
    let six_inside = conn == Connectivity::Six;
    let ((a, six_a), (b, six_b)) = match inside.count_ones() <= outside.count_ones() {
        true => ((inside, six_inside), (outside, !six_inside)),
        false => ((outside, !six_inside), (inside, six_inside)),
    };
    components(a, six_a) == 1 && components(b, six_b) == 1
}

/// Whether the face neighbours `a` and `b` of sample `q` lie in one piece of `side` within its
/// neighbourhood (6-adjacent pieces in the 18-neighbourhood: `side` is the 6-connected side).
pub(crate) fn same_piece(
    vol: &MaskVolume,
    q: [i64; 3],
    side: bool,
    a: [i64; 3],
    b: [i64; 3],
) -> bool {
    let nb = neighbourhood();
    let mut member = [false; 26];
    let (mut ka, mut kb) = (None, None);
    for (k, d) in nb.offsets.iter().enumerate() {
        let r = super::shift(q, *d);
        member[k] = vol.get(r[0], r[1], r[2]) == side;
        if r == a {
            ka = Some(k);
        }
        if r == b {
            kb = Some(k);
        }
    }
    let mut piece = [usize::MAX; 26];
    label_pieces(&member, true, |p, k| piece[k] = p);
    matches!((ka, kb), (Some(x), Some(y)) if piece[x] != usize::MAX && piece[x] == piece[y])
}

/// How far round a set of flips [`SetTest`] looks: pieces joined within this many samples of
/// the region where flips may be are seen joined.
const SET_MARGIN: i64 = 3;

/// Whether flipping a set of samples together keeps the number of components, handles and
/// cavities of either side, though each flip alone may not (a tunnel punched and another sealed
/// beside it). A handle may move, as with `compose`'s swaps: one made and one undone at once. Sets of
/// flips within a region `lo ..= hi` are checked in a box round it, [`SET_MARGIN`] samples
/// wider: the pieces of each side that reach the box's shell are joined the same way within
/// it, as many pieces lie wholly inside, and the Euler characteristic is the same. The world
/// beyond the box is unchanged and meets it only at its shell, so the components of both
/// sides are kept, hence the cavities (the other side's components but the outermost); with
/// those and the Euler characteristic kept, so is the number of handles. Pieces joined only beyond the box count as apart, so the test may refuse a set
/// that keeps the topology, never accept one that does not.
///
/// ```text
///   +-------------+   shell: the box's outer layer, never flipped
///   |  . . . . .  |
///   |  . f f f .  |   f: where flips may be, SET_MARGIN samples inside the shell
///   |  . f f f .  |
///   |  . . . . .  |
///   +-------------+
/// ```
pub(crate) struct SetTest {
    /// Where flips may be.
    region: BoxCells,
    cells: BoxCells,
    conn: Connectivity,
    inside: Vec<bool>,
    /// Each region sample's number in `cells`.
    region_cells: Vec<u32>,
    /// The inside's pieces beyond the region, then the outside's.
    sides: [Exterior; 2],
    /// Room for the union-find of one side's pieces (reused by every set).
    root: Vec<u32>,
}

impl SetTest {
    pub(crate) fn new(vol: &MaskVolume, lo: [i64; 3], hi: [i64; 3], conn: Connectivity) -> Self {
        let cells = BoxCells::new(lo.map(|c| c - SET_MARGIN), hi.map(|c| c + SET_MARGIN));
        let region = BoxCells::new(lo, hi);
        let inside: Vec<bool> = (0..cells.len())
            .map(|c| {
                let q = cells.sample(c);
                vol.get(q[0], q[1], q[2])
            })
            .collect();
        let region_cells: Vec<u32> = (0..region.len())
            .filter_map(|r| cells.index(region.sample(r)))
            .map(|c| c as u32)
            .collect();
        let shell: Vec<u32> = (0..cells.len())
            .filter(|&c| cells.on_shell(c))
            .map(|c| c as u32)
            .collect();
        let side = |s: usize| {
            let six = (s == 0) == (conn == Connectivity::Six);
            Exterior::new(&cells, &region, &region_cells, &shell, &inside, s == 0, six)
        };
        let sides = [side(0), side(1)];
        let mut test = SetTest {
            region,
            cells,
            conn,
            inside,
            region_cells,
            sides,
            root: Vec::new(),
        };
        // The shape before: the same count with nothing flipped.
        for s in 0..2 {
            let (numbers, enclosed) = test.shape(s);
            test.sides[s].before = numbers;
            test.sides[s].enclosed = enclosed;
        }
        test
    }

    /// Whether flipping all of `flips` (samples of the region) keeps the topology.
    pub(crate) fn keeps(&mut self, flips: &[[i64; 3]]) -> bool {
        // A flip nearer the shell than the margin would break the argument above.
        if flips.iter().any(|&p| self.region.index(p).is_none()) {
            debug_assert!(false, "a flip outside the region: {flips:?}");
            return false;
        }
        let six_side = self.conn == Connectivity::Six;
        let index: Vec<usize> = flips.iter().filter_map(|&p| self.cells.index(p)).collect();
        // The Euler characteristic first, from the cells that have a flip as a corner alone
        // (their lowest corners within a sample below each flip): most sets fail there, and it
        // costs a few dozen samples against the box's pieces. (That of the 6-connected side:
        // by Alexander duality the other side's changes the same.)
        let mut lowest: Vec<[i64; 3]> = flips
            .iter()
            .flat_map(|p| {
                (0..8).map(move |k| [p[0] - (k & 1), p[1] - (k >> 1 & 1), p[2] - (k >> 2)])
            })
            .collect();
        lowest.sort_unstable();
        lowest.dedup();
        let euler_before = euler_6(&self.cells, &self.inside, six_side, &lowest);
        let toggle = |inside: &mut Vec<bool>| index.iter().for_each(|&c| inside[c] = !inside[c]);
        toggle(&mut self.inside);
        // The outside is counted only if the inside agrees.
        let keeps = euler_6(&self.cells, &self.inside, six_side, &lowest) == euler_before
            && (0..2).all(|s| {
                let (numbers, enclosed) = self.shape(s);
                numbers == self.sides[s].before && enclosed == self.sides[s].enclosed
            });
        toggle(&mut self.inside);
        keeps
    }

    /// Side `s`'s shape in the box as it is (0 the inside, 1 the outside): the pieces beyond
    /// the region that reach the shell, numbered by the piece of the box they lie in (in order
    /// of first meeting), and how many pieces of the box do not reach the shell. The pieces
    /// beyond the region were labelled once; only the region's samples are joined here, to
    /// each other and to the pieces they touch.
    fn shape(&mut self, s: usize) -> (Vec<u32>, usize) {
        let side = s == 0;
        let ext = &self.sides[s];
        let nodes = ext.pieces + self.region_cells.len();
        self.root.clear();
        self.root.extend(0..nodes as u32);
        let root = &mut self.root;
        let (inside, region_cells) = (&self.inside, &self.region_cells);
        let of_side = |r: usize| inside[region_cells[r] as usize] == side;
        // Nodes: the pieces beyond the region, then the region's samples.
        let mut pieces = ext.pieces;
        for r in 0..region_cells.len() {
            if !of_side(r) {
                continue;
            }
            pieces += 1;
            let node = ext.pieces + r;
            for &n in ext.links(r) {
                let n = n as usize;
                if n < ext.pieces || of_side(n - ext.pieces) {
                    pieces -= usize::from(join(root, node, n));
                }
            }
        }
        let mut number = vec![u32::MAX; nodes];
        let mut reaching = 0;
        let numbers = ext
            .on_shell
            .iter()
            .map(|&e| {
                let r = find(root, e as usize);
                if number[r] == u32::MAX {
                    number[r] = reaching;
                    reaching += 1;
                }
                number[r]
            })
            .collect();
        (numbers, pieces - reaching as usize)
    }
}

/// One side's pieces in [`SetTest`]'s box beyond the region where flips may be: flips change
/// only the region, so these are labelled once and each set joins the region's samples to them.
///
/// ```text
///   +-------------+   shell
///   |  a a . . b  |   a, b: pieces beyond the region, labelled once (a and b may be one
///   |  a f f f b  |         piece of the box once the region's samples join them)
///   |  . f f f b  |   f: the region, where flips may be
///   +-------------+
/// ```
struct Exterior {
    /// How many pieces.
    pieces: usize,
    /// The pieces the shell's samples of the side lie in, each once, in order of first meeting.
    on_shell: Vec<u32>,
    /// For region sample `r`, the nodes it is joined to are `links[start[r]..start[r + 1]]`:
    /// pieces (numbers below `pieces`) and region samples met before it (`pieces` + their
    /// number in the region).
    start: Vec<u32>,
    links: Vec<u32>,
    /// The shape before any flip (see [`SetTest::shape`]).
    before: Vec<u32>,
    enclosed: usize,
}

impl Exterior {
    fn new(
        cells: &BoxCells,
        region: &BoxCells,
        region_cells: &[u32],
        shell: &[u32],
        inside: &[bool],
        side: bool,
        six: bool,
    ) -> Exterior {
        let mut in_region = vec![false; cells.len()];
        region_cells
            .iter()
            .for_each(|&c| in_region[c as usize] = true);
        let (pieces, piece) = label(cells, six, |c| !in_region[c] && inside[c] == side);
        let mut on_shell = Vec::new();
        let mut met = vec![false; pieces];
        for &c in shell {
            let p = piece[c as usize];
            if p != u32::MAX && !met[p as usize] {
                met[p as usize] = true;
                on_shell.push(p);
            }
        }
        // What each region sample is joined to when it is of the side: the pieces it touches,
        // always, and the region samples met before it in a scan, if they are of the side too.
        // (A region sample's neighbours all lie in the box: the margin is wider than one.)
        let offsets = neighbourhood().offsets.into_iter();
        let adjacent: Vec<i64> = offsets
            .filter(|d| !six || l1(*d) == 1)
            .map(|d| cells.offset(d))
            .collect();
        let (mut start, mut links) = (vec![0], Vec::new());
        for (r, &c) in region_cells.iter().enumerate() {
            let first = links.len();
            for &d in &adjacent {
                let p = piece[(c as i64 + d) as usize];
                if p != u32::MAX && !links[first..].contains(&p) {
                    links.push(p);
                }
            }
            let q = region.sample(r);
            for d in earlier_offsets(six) {
                let n = super::shift(q, *d);
                if let Some(m) = region.index(n) {
                    links.push((pieces + m) as u32);
                }
            }
            start.push(links.len() as u32);
        }
        Exterior {
            pieces,
            on_shell,
            start,
            links,
            before: Vec::new(),
            enclosed: 0,
        }
    }

    /// The nodes region sample `r` is joined to (see [`SetTest::shape`]).
    fn links(&self, r: usize) -> &[u32] {
        &self.links[self.start[r] as usize..self.start[r + 1] as usize]
    }
}

fn l1(d: [i64; 3]) -> i64 {
    d.iter().map(|c| c.abs()).sum()
}

/// The neighbours met before a sample in a scan x fastest, then y, then z: its face
/// neighbours (6-adjacency) or all 26.
fn earlier_offsets(six: bool) -> &'static [[i64; 3]] {
    static EARLIER: std::sync::OnceLock<[Vec<[i64; 3]>; 2]> = std::sync::OnceLock::new();
    let both = EARLIER.get_or_init(|| {
        let of = |six: bool| -> Vec<[i64; 3]> {
            neighbourhood()
                .offsets
                .into_iter()
                .filter(|d| (d[2], d[1], d[0]) < (0, 0, 0))
                .filter(|d| !six || l1(*d) == 1)
                .collect()
        };
        [of(false), of(true)]
    });
    &both[usize::from(six)]
}

/// The pieces of the box's samples that are `member`s (6- or 26-adjacent samples): how many,
/// and each sample's piece (`u32::MAX` for others), numbered by their first sample. One scan,
/// x fastest, joins each sample to its neighbours met before it (union-find, the lower root
/// kept).
fn label(cells: &BoxCells, six: bool, member: impl Fn(usize) -> bool) -> (usize, Vec<u32>) {
    let size = cells.size.map(|n| n as i64);
    let earlier = earlier_offsets(six);
    let step: Vec<usize> = earlier.iter().map(|&d| -cells.offset(d) as usize).collect();
    let mut root = vec![u32::MAX; cells.len()];
    let mut c = 0;
    for z in 0..size[2] {
        for y in 0..size[1] {
            for x in 0..size[0] {
                if member(c) {
                    root[c] = c as u32;
                    // Away from the box's faces every earlier neighbour is in it (+1 steps
                    // come with a -1 step along a slower axis).
                    let interior = z >= 1 && y >= 1 && y + 1 < size[1] && x >= 1 && x + 1 < size[0];
                    for (d, &back) in earlier.iter().zip(&step) {
                        let within = |v: i64, s: i64| (0..s).contains(&v);
                        if interior
                            || within(x + d[0], size[0])
                                && within(y + d[1], size[1])
                                && within(z + d[2], size[2])
                        {
                            let n = c - back;
                            if root[n] != u32::MAX && root[n] != root[c] {
                                join(&mut root, c, n);
                            }
                        }
                    }
                }
                c += 1;
            }
        }
    }
    let mut piece = vec![u32::MAX; cells.len()];
    let mut pieces = 0;
    for c in 0..cells.len() {
        if root[c] != u32::MAX {
            let r = find(&mut root, c);
            // The root is the piece's first sample, numbered already unless it is this one.
            piece[c] = if r == c { pieces } else { piece[r] };
            pieces += u32::from(r == c);
        }
    }
    (pieces as usize, piece)
}

/// The root of `c`'s set (halving the path on the way).
fn find(root: &mut [u32], mut c: usize) -> usize {
    while root[c] as usize != c {
        let up = root[root[c] as usize];
        root[c] = up;
        c = up as usize;
    }
    c
}

/// Joins the sets of `a` and `b` under the lower root; whether they were apart.
fn join(root: &mut [u32], a: usize, b: usize) -> bool {
    let (ra, rb) = (find(root, a), find(root, b));
    let (lo, hi) = (ra.min(rb), ra.max(rb));
    root[hi] = lo as u32;
    lo != hi
}

/// Euler characteristic of the cubical complex of `side` counted over the cells whose lowest
/// corner is one of `lowest`: its samples, minus the unit edges, plus the unit squares, minus
/// the unit cubes whose corners are all of `side` (samples beyond the box are not).
fn euler_6(cells: &BoxCells, inside: &[bool], side: bool, lowest: &[[i64; 3]]) -> i64 {
    let of_side = |q: [i64; 3]| cells.index(q).is_some_and(|c| inside[c] == side);
    let [nx, ny, _] = cells.size;
    let corner_step: [usize; 8] =
        std::array::from_fn(|k| (k & 1) + (k >> 1 & 1) * nx + (k >> 2) * nx * ny);
    let mut euler = 0;
    for &[x, y, z] in lowest {
        let Some(c) = cells.index([x, y, z]).filter(|&c| inside[c] == side) else {
            continue;
        };
        let bits = if cells.index([x + 1, y + 1, z + 1]).is_some() {
            (0..8).fold(0u8, |bits, k| {
                bits | u8::from(inside[c + corner_step[k]] == side) << k
            })
        } else {
            (0..8).fold(0u8, |bits, k| {
                let d = [k & 1, k >> 1 & 1, k >> 2 & 1];
                bits | u8::from(of_side([x + d[0], y + d[1], z + d[2]])) << k
            })
        };
        euler += euler_at_corner()[bits as usize];
    }
    euler
}

/// What the cells counted at a sample of the side add to the Euler characteristic, by the cube
/// above it (bit `k` = corner `x + 2y + 4z` of the side; corner 0, the sample, always is):
/// itself, minus its edges along +x, +y, +z, plus its three squares, minus the cube.
fn euler_at_corner() -> &'static [i64; 256] {
    static TABLE: std::sync::OnceLock<[i64; 256]> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| {
        std::array::from_fn(|bits| {
            let all = |corners: &[usize]| i64::from(corners.iter().all(|&k| bits >> k & 1 == 1));
            let edges = all(&[0, 1]) + all(&[0, 2]) + all(&[0, 4]);
            let squares = all(&[0, 1, 2, 3]) + all(&[0, 1, 4, 5]) + all(&[0, 2, 4, 6]);
            1 - edges + squares - all(&[0, 1, 2, 3, 4, 5, 6, 7])
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::{shift, Frame};

    const BOTH: [Connectivity; 2] = [Connectivity::Six, Connectivity::TwentySix];

    fn betti(vol: &MaskVolume, conn: Connectivity) -> (u64, u64, u64) {
        let g = vol.genus(conn).unwrap();
        (g.b0, g.b1, g.b2)
    }

    fn toggle(vol: &mut MaskVolume, p: [i64; 3]) {
        let now = vol.get(p[0], p[1], p[2]);
        vol.set(p[0] as usize, p[1] as usize, p[2] as usize, !now);
    }

    fn test_round(vol: &MaskVolume, flips: &[[i64; 3]], conn: Connectivity) -> bool {
        let lo = std::array::from_fn(|c| flips.iter().map(|p| p[c]).min().unwrap());
        let hi = std::array::from_fn(|c| flips.iter().map(|p| p[c]).max().unwrap());
        SetTest::new(vol, lo, hi, conn).keeps(flips)
    }

    /// A sample's neighbours read as a block of rows are those read one by one: every sample
    /// of random volumes 130 samples wide (padded rows of three words, blocks straddling them)
    /// and 126 wide (padded rows filling two words to their last bit: a block at the end reads
    /// no word beyond), and samples just outside the volume (read one by one).
    #[test]
    fn neighbours_read_by_rows_are_those_read_one_by_one() {
        let mut rng = crate::test_rng::Rng(0xa54f_f53a_5f1d_36f1);
        for nx in [130, 126, 130, 126] {
            let dims = [nx, 4, 3];
            let mut vol = MaskVolume::new(dims, Frame::identity());
            for k in 0..dims.iter().product::<usize>() {
                vol.set(k % nx, k / nx % 4, k / (4 * nx), rng.below(2) == 1);
            }
            let nb = neighbourhood();
            for k in 0..(nx + 2) * 6 * 5 {
                let q = [k % (nx + 2), k / (nx + 2) % 6, k / (6 * (nx + 2))].map(|x| x as i64 - 1);
                let one_by_one = (0..26).fold(0, |m, j| {
                    let r = shift(q, nb.offsets[j]);
                    m | u32::from(vol.get(r[0], r[1], r[2])) << j
                });
                assert_eq!(neighbours(&vol, q), one_by_one, "{q:?}");
            }
        }
    }

    /// A plate one sample thick with a hole (a handle under either connectivity): sealing the
    /// hole and punching one beside it each change the topology, together they keep it.
    ///
    /// ```text
    ///   # # # # #        # # # # #
    ///   # h # p #   ->   # # # . #     h: the hole, p: its new place (plane z = 5)
    ///   # # # # #        # # # # #
    /// ```
    #[test]
    fn a_hole_sealed_and_punched_beside_it_keeps_the_topology() {
        let mut vol = MaskVolume::new([14, 14, 11], Frame::identity());
        for y in 2..=11 {
            for x in 2..=11 {
                vol.set(x, y, 5, true);
            }
        }
        let (h, p) = ([6, 6, 5], [8, 6, 5]);
        toggle(&mut vol, h);
        for conn in BOTH {
            assert!(!test_round(&vol, &[h], conn));
            assert!(!test_round(&vol, &[p], conn));
            assert!(test_round(&vol, &[h, p], conn));
            // Punched next to the hole, the sample only widens it.
            assert!(test_round(&vol, &[[7, 6, 5]], conn));
            // Two holes punched beside the first: a handle more.
            assert!(!test_round(&vol, &[p, [9, 6, 5]], conn));
        }
    }

    /// A rod cut (a component more) and a plate punched (a handle more) leave the Euler
    /// characteristic as it was: the pieces reaching the box's shell tell them apart.
    #[test]
    fn a_rod_cut_and_a_plate_punched_are_told_apart() {
        let mut vol = MaskVolume::new([16, 12, 12], Frame::identity());
        for x in 1..=14 {
            vol.set(x, 3, 3, true);
        }
        for y in 2..=10 {
            for x in 2..=12 {
                vol.set(x, y, 7, true);
            }
        }
        let conn = Connectivity::Six;
        let before = betti(&vol, conn);
        let flips = [[7, 3, 3], [7, 6, 7]];
        for &p in &flips {
            toggle(&mut vol, p);
        }
        let after = betti(&vol, conn);
        assert_eq!(
            (after.0, after.1),
            (before.0 + 1, before.1 + 1),
            "the case tested"
        );
        for &p in &flips {
            toggle(&mut vol, p);
        }
        assert!(!test_round(&vol, &flips, conn));
    }

    /// The whole box labelled, each side's shell samples numbered by piece (in order of first
    /// meeting), and the pieces not reaching the shell counted: what [`SetTest`] compares, the
    /// slow way (it labels the pieces beyond the region once and joins the region to them).
    fn whole_box_shape(test: &SetTest) -> [(Vec<u32>, usize); 2] {
        std::array::from_fn(|s| {
            let six = (s == 0) == (test.conn == Connectivity::Six);
            let (pieces, piece) = label(&test.cells, six, |c| test.inside[c] == (s == 0));
            let mut number = vec![u32::MAX; pieces];
            let (mut numbers, mut reaching) = (Vec::new(), 0);
            for c in (0..test.cells.len()).filter(|&c| test.cells.on_shell(c)) {
                let p = piece[c];
                if p != u32::MAX {
                    if number[p as usize] == u32::MAX {
                        number[p as usize] = reaching;
                        reaching += 1;
                    }
                    numbers.push(number[p as usize]);
                }
            }
            (numbers, pieces - reaching as usize)
        })
    }

    /// On random volumes, sets of one to three flips: [`SetTest`] accepts exactly the sets
    /// that keep the whole box's Euler characteristic and its shape labelled from scratch (each
    /// side's shell samples grouped the same, as many pieces enclosed).
    #[test]
    fn the_set_test_agrees_with_labelling_the_whole_box() {
        let mut rng = crate::test_rng::Rng(0x51ab_1e5e_7000_0001);
        let (mut accepted, mut refused) = (0, 0);
        for round in 0..16 {
            let n = 14;
            let vol = crate::grid::random_mask(&mut rng, n, [30, 45, 55, 70][round % 4]);
            let conn = BOTH[round % 2];
            let six_side = conn == Connectivity::Six;
            // A region like a rewrite's (six samples wide), some beyond the volume's faces.
            let c: [i64; 3] = std::array::from_fn(|_| rng.below(n as u64 - 3) as i64);
            let (lo, hi) = (c.map(|v| v - 1), c.map(|v| v + 4));
            let mut test = SetTest::new(&vol, lo, hi, conn);
            let every: Vec<[i64; 3]> = (0..test.cells.len())
                .map(|i| test.cells.sample(i))
                .collect();
            let shape_before = whole_box_shape(&test);
            let euler_before = euler_6(&test.cells, &test.inside, six_side, &every);
            for _ in 0..400 {
                let k = 1 + rng.below(3) as usize;
                let mut set: Vec<[i64; 3]> = Vec::new();
                while set.len() < k {
                    let q: [i64; 3] = std::array::from_fn(|i| lo[i] + rng.below(6) as i64);
                    if !set.contains(&q) {
                        set.push(q);
                    }
                }
                let got = test.keeps(&set);
                let index: Vec<usize> = set.iter().filter_map(|&p| test.cells.index(p)).collect();
                index.iter().for_each(|&i| test.inside[i] = !test.inside[i]);
                let want = euler_6(&test.cells, &test.inside, six_side, &every) == euler_before
                    && whole_box_shape(&test) == shape_before;
                index.iter().for_each(|&i| test.inside[i] = !test.inside[i]);
                assert_eq!(got, want, "round {round}: {set:?}");
                accepted += usize::from(got);
                refused += usize::from(!got);
            }
        }
        assert!(
            accepted > 300 && refused > 300,
            "{accepted} accepted, {refused} refused"
        );
    }

    /// The short-cut simplicity test answers as the topological numbers do, for every sample of
    /// random masks from sparse to dense (interior samples of both sides, and the padding round
    /// the volume), both connectivities.
    #[test]
    fn is_simple_answers_as_the_topological_numbers_do() {
        let mut rng = crate::test_rng::Rng(0xbb67_ae85_84ca_a73b);
        let (mut simple, mut not) = (0, 0);
        for round in 0..40 {
            let n = 9;
            let percent = [5, 30, 50, 70, 95][round % 5];
            let vol = crate::grid::random_mask(&mut rng, n, percent);
            let conn = BOTH[round % 2];
            for z in -1..=n as i64 {
                for y in -1..=n as i64 {
                    for x in -1..=n as i64 {
                        let want = topological_numbers(&vol, [x, y, z], conn) == (1, 1);
                        assert_eq!(is_simple(&vol, [x, y, z], conn), want, "{x} {y} {z}");
                        (simple, not) = (simple + usize::from(want), not + usize::from(!want));
                    }
                }
            }
        }
        assert!(simple > 5_000 && not > 5_000, "{simple} simple, {not} not");
    }

    /// On random volumes: every simple flip (Bertrand and Malandain's numbers, an independent
    /// test) is accepted, and every flip or set of two or three flips the test accepts keeps the
    /// Betti numbers of the whole volume (the genus pass, the oracle).
    #[test]
    fn the_set_test_agrees_with_simple_samples_and_with_the_genus_pass() {
        let mut rng = crate::test_rng::Rng(0x9e37_79b9_7f4a_7c15);
        let (mut accepted, mut refused) = (0, 0);
        for round in 0..8 {
            let n = 12;
            let mut vol = crate::grid::random_mask(&mut rng, n, [35, 50, 65][round % 3]);
            let conn = BOTH[round % 2];
            let betti_before = betti(&vol, conn);
            for _ in 0..300 {
                let p = [0, 1, 2].map(|_| rng.below(n as u64) as i64);
                // A simple flip is always accepted; a flip that is not may be too, when it
                // makes one handle and undoes another (numbers (2, 2)), checked below.
                let simple = topological_numbers(&vol, p, conn) == (1, 1);
                let keeps = test_round(&vol, &[p], conn);
                assert!(keeps || !simple, "{p:?} is simple");
                if keeps {
                    toggle(&mut vol, p);
                    assert_eq!(betti(&vol, conn), betti_before, "{p:?}");
                    toggle(&mut vol, p);
                }
                let k = 2 + rng.below(2) as usize;
                let mut set = vec![p];
                while set.len() < k {
                    let q: [i64; 3] = std::array::from_fn(|c| {
                        (p[c] + rng.below(3) as i64 - 1).clamp(0, n as i64 - 1)
                    });
                    if !set.contains(&q) {
                        set.push(q);
                    }
                }
                if !test_round(&vol, &set, conn) {
                    refused += 1;
                    continue;
                }
                accepted += 1;
                set.iter().for_each(|&q| toggle(&mut vol, q));
                assert_eq!(betti(&vol, conn), betti_before, "{set:?}");
                set.iter().for_each(|&q| toggle(&mut vol, q));
            }
        }
        // Both answers are common: the checks above ran on each.
        assert!(
            accepted > 100 && refused > 100,
            "{accepted} accepted, {refused} refused"
        );
    }
}
