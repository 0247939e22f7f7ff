//! Simple samples: those whose flip changes no topology of the solid or of its complement
//! (Bertrand and Malandain's topological numbers, each side with its own adjacency, in the
//! sample's 26-neighbourhood, are both 1). Thinning walls (`closure::peel`) and making the
//! output well-composed (`compose`) flip only such samples.

use crate::grid::MaskVolume;
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
    /// Neighbours k, j that are 6-adjacent / 26-adjacent to each other.
    pub(crate) adj6: [Vec<u8>; 26],
    pub(crate) adj26: [Vec<u8>; 26],
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
        let adj = |six: bool| -> [Vec<u8>; 26] {
            std::array::from_fn(|k| {
                (0..26u8)
                    .filter(|&j| {
                        let d: [i64; 3] =
                            std::array::from_fn(|c| offsets[k][c] - offsets[j as usize][c]);
                        let m = d.iter().map(|x| x.abs()).max().unwrap_or(0);
                        j as usize != k && m == 1 && (!six || l1(d) == 1)
                    })
                    .collect()
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
/// `k` (an index into the offsets) of each; returns how many there are.
pub(crate) fn label_pieces(
    member: &[bool; 26],
    six: bool,
    mut each: impl FnMut(usize, usize),
) -> usize {
    let nb = neighbourhood();
    let allowed = |k: usize| member[k] && (!six || nb.in18[k]);
    let mut seen = [false; 26];
    let mut stack = [0u8; 26];
    let mut count = 0;
    for start in 0..26 {
        if seen[start] || !allowed(start) || (six && !nb.face[start]) {
            continue;
        }
        seen[start] = true;
        stack[0] = start as u8;
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let k = stack[top] as usize;
            each(count, k);
            let adj = if six { &nb.adj6[k] } else { &nb.adj26[k] };
            for &j in adj {
                let j = j as usize;
                if !seen[j] && allowed(j) {
                    seen[j] = true;
                    stack[top] = j as u8;
                    top += 1;
                }
            }
        }
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
