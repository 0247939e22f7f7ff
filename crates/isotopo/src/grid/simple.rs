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
    /// Face neighbours (6-adjacent to the centre).
    pub(crate) face: [bool; 26],
    /// In the 18-neighbourhood (not a corner).
    pub(crate) in18: [bool; 26],
    /// Neighbours k, j that are 6-adjacent / 26-adjacent to each other: bit `j` of `adj6[k]`.
    adj6: [u32; 26],
    adj26: [u32; 26],
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
        let face = std::array::from_fn(|k| l1(offsets[k]) == 1);
        let in18 = std::array::from_fn(|k| l1(offsets[k]) <= 2);
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
            face,
            in18,
            adj6: adj(true),
            adj26: adj(false),
        }
    })
}

/// Components of the samples `member` of the neighbourhood: with 6-adjacency, those of the
/// 18-neighbourhood that touch a face neighbour (the geodesic count); with 26, all.
fn components(member: &[bool; 26], six: bool) -> usize {
    label_pieces(member, six, |_, _| {})
}

/// Walks the components counted by [`components`], calling `each(piece, k)` for every neighbour
/// `k` (an index into the offsets) of each; returns how many there are. Each piece grows as a
/// bit mask of the 26 neighbours (this runs for every flip tried).
pub(crate) fn label_pieces(
    member: &[bool; 26],
    six: bool,
    mut each: impl FnMut(usize, usize),
) -> usize {
    let nb = neighbourhood();
    let of = |pick: &dyn Fn(usize) -> bool| (0..26).fold(0u32, |m, k| m | u32::from(pick(k)) << k);
    let allowed = of(&|k| member[k] && (!six || nb.in18[k]));
    let mut starts = if six {
        allowed & of(&|k| nb.face[k])
    } else {
        allowed
    };
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

/// The topological numbers of sample `q`: the pieces of the inside and of the outside in its
/// neighbourhood that touch it (each with its own adjacency). Flipping `q` changes no topology
/// exactly when both are 1.
pub(crate) fn topological_numbers(
    vol: &MaskVolume,
    q: [i64; 3],
    conn: Connectivity,
) -> (usize, usize) {
    let nb = neighbourhood();
    let dims = vol.dims.map(|n| n as i64);
    let mut inside = [false; 26];
    for (k, d) in nb.offsets.iter().enumerate() {
        let r = [q[0] + d[0], q[1] + d[1], q[2] + d[2]];
        let within = (0..3).all(|c| r[c] >= 0 && r[c] < dims[c]);
        inside[k] = within && vol.get(r[0], r[1], r[2]);
    }
    let outside: [bool; 26] = std::array::from_fn(|k| !inside[k]);
    let six_inside = conn == Connectivity::Six;
    (
        components(&inside, six_inside),
        components(&outside, !six_inside),
    )
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
    let dims = vol.dims.map(|n| n as i64);
    let mut member = [false; 26];
    let (mut ka, mut kb) = (None, None);
    for (k, d) in nb.offsets.iter().enumerate() {
        let r = [q[0] + d[0], q[1] + d[1], q[2] + d[2]];
        let within = (0..3).all(|c| r[c] >= 0 && r[c] < dims[c]);
        member[k] = (within && vol.get(r[0], r[1], r[2])) == side;
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
    /// The numbers of `cells`' samples on its outer layer.
    shell: Vec<u32>,
    before: BoxShape,
}

impl SetTest {
    pub(crate) fn new(vol: &MaskVolume, lo: [i64; 3], hi: [i64; 3], conn: Connectivity) -> Self {
        let cells = BoxCells::new(lo.map(|c| c - SET_MARGIN), hi.map(|c| c + SET_MARGIN));
        let dims = vol.dims.map(|n| n as i64);
        let inside: Vec<bool> = (0..cells.len())
            .map(|c| {
                let q = cells.sample(c);
                (0..3).all(|k| q[k] >= 0 && q[k] < dims[k]) && vol.get(q[0], q[1], q[2])
            })
            .collect();
        let shell: Vec<u32> = (0..cells.len())
            .filter(|&c| cells.on_shell(c))
            .map(|c| c as u32)
            .collect();
        let before = BoxShape::of(&cells, &shell, &inside, conn);
        SetTest {
            region: BoxCells::new(lo, hi),
            cells,
            conn,
            inside,
            shell,
            before,
        }
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
        // costs a few dozen samples against the whole box's pieces.
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
        let keeps = euler_6(&self.cells, &self.inside, six_side, &lowest) == euler_before
            && self
                .before
                .is_of(&self.cells, &self.shell, &self.inside, self.conn);
        toggle(&mut self.inside);
        keeps
    }
}

/// What [`SetTest`] compares: for each side, how its pieces in the box join the shell's
/// samples (each shell sample of that side numbered by its piece, in order of first meeting)
/// and how many pieces do not reach the shell. (The Euler characteristic, of the 6-connected side,
/// is compared round the flips alone: by Alexander duality the other side's changes the same.)
struct BoxShape {
    shell: [Vec<u32>; 2],
    enclosed: [usize; 2],
}

impl BoxShape {
    /// `shell`: the numbers of the box's samples on its outer layer, in order.
    fn of(cells: &BoxCells, shell: &[u32], inside: &[bool], conn: Connectivity) -> BoxShape {
        let side = |s: usize| Self::side(cells, shell, inside, conn, s);
        let ((inside_shell, inside_enclosed), (outside_shell, outside_enclosed)) =
            (side(0), side(1));
        BoxShape {
            shell: [inside_shell, outside_shell],
            enclosed: [inside_enclosed, outside_enclosed],
        }
    }

    /// Whether the box's shape is this one; the outside is labelled only if the inside agrees.
    fn is_of(&self, cells: &BoxCells, shell: &[u32], inside: &[bool], conn: Connectivity) -> bool {
        (0..2).all(|s| {
            let (numbers, enclosed) = Self::side(cells, shell, inside, conn, s);
            numbers == self.shell[s] && enclosed == self.enclosed[s]
        })
    }

    /// Side `s` (0 the inside, 1 the outside): its shell samples numbered by piece, and how
    /// many pieces do not reach the shell.
    fn side(
        cells: &BoxCells,
        shell: &[u32],
        inside: &[bool],
        conn: Connectivity,
        s: usize,
    ) -> (Vec<u32>, usize) {
        let side = s == 0;
        let six = side == (conn == Connectivity::Six);
        let (pieces, piece) = label(cells, inside, side, six);
        let mut number = vec![u32::MAX; pieces];
        let mut numbers = Vec::new();
        let mut reaching = 0;
        for &c in shell {
            let p = piece[c as usize];
            if p == u32::MAX {
                continue;
            }
            if number[p as usize] == u32::MAX {
                number[p as usize] = reaching;
                reaching += 1;
            }
            numbers.push(number[p as usize]);
        }
        (numbers, pieces - reaching as usize)
    }
}

/// The pieces of `side` in the box (6- or 26-adjacent samples): how many, and each sample's
/// piece (`u32::MAX` for the other side), numbered by their first sample. One scan, x fastest,
/// joins each sample to its neighbours met before it (union-find, the lower root kept).
fn label(cells: &BoxCells, inside: &[bool], side: bool, six: bool) -> (usize, Vec<u32>) {
    let size = cells.size.map(|n| n as i64);
    let earlier: Vec<[i64; 3]> = neighbourhood()
        .offsets
        .into_iter()
        .filter(|d| (d[2], d[1], d[0]) < (0, 0, 0))
        .filter(|d| !six || d.iter().map(|c| c.abs()).sum::<i64>() == 1)
        .collect();
    let step: Vec<usize> = earlier
        .iter()
        .map(|d| (-((d[2] * size[1] + d[1]) * size[0] + d[0])) as usize)
        .collect();
    let mut root = vec![u32::MAX; inside.len()];
    let mut c = 0;
    for z in 0..size[2] {
        for y in 0..size[1] {
            for x in 0..size[0] {
                if inside[c] == side {
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
                            if inside[n] == side && root[n] != root[c] {
                                join(&mut root, c, n);
                            }
                        }
                    }
                }
                c += 1;
            }
        }
    }
    let mut piece = vec![u32::MAX; inside.len()];
    let mut pieces = 0;
    for c in 0..inside.len() {
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

/// Joins the sets of `a` and `b` under the lower root.
fn join(root: &mut [u32], a: usize, b: usize) {
    let (ra, rb) = (find(root, a), find(root, b));
    let (lo, hi) = (ra.min(rb), ra.max(rb));
    root[hi] = lo as u32;
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
    use crate::grid::Frame;

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

    /// On random volumes: every simple flip (Bertrand and Malandain's numbers, an independent
    /// test) is accepted, and every flip or set of two or three flips the test accepts keeps the
    /// Betti numbers of the whole volume (the genus pass, the oracle).
    #[test]
    fn the_set_test_agrees_with_simple_samples_and_with_the_genus_pass() {
        let mut rng = crate::test_rng::Rng(0x9e37_79b9_7f4a_7c15);
        let mut random = |n: u64| rng.below(n);
        let (mut accepted, mut refused) = (0, 0);
        for round in 0..8 {
            let n = 12;
            let mut vol = MaskVolume::new([n, n, n], Frame::identity());
            let density = [35, 50, 65][round % 3];
            for z in 0..n {
                for y in 0..n {
                    for x in 0..n {
                        vol.set(x, y, z, random(100) < density);
                    }
                }
            }
            let conn = BOTH[round % 2];
            let betti_before = betti(&vol, conn);
            for _ in 0..300 {
                let p = [0, 1, 2].map(|_| random(n as u64) as i64);
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
                let k = 2 + random(2) as usize;
                let mut set = vec![p];
                while set.len() < k {
                    let q: [i64; 3] = std::array::from_fn(|c| {
                        (p[c] + random(3) as i64 - 1).clamp(0, n as i64 - 1)
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
