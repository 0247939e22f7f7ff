//! Critical configurations: where the inside/outside pattern lets meshers disagree.
//!
//! A set of samples is *well-composed* (Latecki) when no unit face and no unit cube of the grid
//! holds one of these patterns (`#` inside, `.` outside, or the other way round):
//!
//! ```text
//!   face: one diagonal            cube: two opposite corners alone
//!      # .                            .-------#
//!      . #                           /|      /|     (the other six corners
//!                                   . -----. |      on the other side)
//!                                   | .----|-.
//!                                   |/     |/
//!                                   #------.
//! ```
//!
//! There the surface may pass either way: connectivity 6 separates the two corners,
//! connectivity 26 joins them, VTK's case table and scikit-image's asymptotic decider choose
//! by case or by value. Without them every rule gives the same surface, so the Betti numbers
//! under connectivity 6 and 26 agree.
//!
//! Cells are named by their lowest corner in padded coordinates (-1 ..= n - 1 on each axis); a
//! cube owns the three faces through that corner.

use super::mask::PlaneMask;

/// A unit face or cube of the grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum CellKind {
    /// The face normal to x through the corner (corners differ in y and z).
    FaceX,
    /// The face normal to y (corners differ in x and z).
    FaceY,
    /// The face normal to z (corners differ in x and y).
    FaceZ,
    /// The unit cube.
    Cube,
}

/// The eight corner bits of a cube: bit `dx + 2 dy + 4 dz` is the corner at `+ (dx, dy, dz)`.
pub type CubeBits = u8;

/// The corners of each owned face of a cube, as two diagonals (`a`, `d`) and (`b`, `c`).
const FACES: [(CellKind, [u8; 4]); 3] = [
    (CellKind::FaceX, [0, 6, 2, 4]),
    (CellKind::FaceY, [0, 5, 1, 4]),
    (CellKind::FaceZ, [0, 3, 1, 2]),
];

/// Whether a face whose corners are the bits `[a, d, b, c]` of `bits` shows one diagonal.
#[inline]
fn diagonal(bits: CubeBits, c: [u8; 4]) -> bool {
    let at = |k: u8| (bits >> k) & 1;
    at(c[0]) == at(c[1]) && at(c[2]) == at(c[3]) && at(c[0]) != at(c[2])
}

/// Whether the cube shows two opposite corners alone (inside or outside).
#[inline]
pub fn critical_cube(bits: CubeBits) -> bool {
    let lone = match bits.count_ones() {
        2 => bits,
        6 => !bits,
        _ => return false,
    };
    (0..4).any(|k| lone == (1 << k) | (1 << (7 - k)))
}

/// Whether `kind` of the cube with these corners is critical (a face: one of the three it owns).
#[inline]
pub fn critical(kind: CellKind, bits: CubeBits) -> bool {
    match kind {
        CellKind::Cube => critical_cube(bits),
        face => FACES
            .iter()
            .find(|(k, _)| *k == face)
            .is_some_and(|(_, c)| diagonal(bits, *c)),
    }
}

/// How many critical faces and cubes a pattern has.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct CriticalCounts {
    /// Unit faces with one diagonal inside.
    pub faces: u64,
    /// Unit cubes with two opposite corners alone.
    pub cubes: u64,
}

impl CriticalCounts {
    /// Faces and cubes together.
    pub fn total(&self) -> u64 {
        self.faces + self.cubes
    }

    /// The counts of two parts of a volume together.
    pub fn add(&mut self, other: CriticalCounts) {
        self.faces += other.faces;
        self.cubes += other.cubes;
    }
}

/// The corner bits of the cube between planes `lower` and `upper` with lowest corner at padded
/// column `i`, row `j` (each from 0 to n, padding included).
#[inline]
pub fn cube_bits(lower: &PlaneMask, upper: &PlaneMask, i: usize, j: usize) -> CubeBits {
    let mut bits = 0u8;
    for (dz, plane) in [lower, upper].into_iter().enumerate() {
        for dy in 0..2 {
            for dx in 0..2 {
                if plane.get_padded(i + dx, j + dy) {
                    bits |= 1 << (dx + 2 * dy + 4 * dz);
                }
            }
        }
    }
    bits
}

/// Calls `each(i, j, kind)` for every critical cell owned by the cubes between two planes,
/// `(i, j)` the cube's lowest corner in padded columns and rows.
pub fn each_critical(
    lower: &PlaneMask,
    upper: &PlaneMask,
    mut each: impl FnMut(usize, usize, CellKind),
) {
    let words = lower.words;
    for j in 0..=lower.ny {
        let rows = [
            lower.row(j),
            lower.row(j + 1),
            upper.row(j),
            upper.row(j + 1),
        ];
        for w in 0..words {
            // A cube whose eight corners agree is never critical: skip runs of 64 such cubes
            // (the next word's first bit is the corner past the last column of this one).
            let carry = |r: &[u64]| r.get(w + 1).map_or(0, |x| x & 1);
            let all_in = rows.iter().all(|r| r[w] == u64::MAX && carry(r) == 1);
            let all_out = rows.iter().all(|r| r[w] == 0 && carry(r) == 0);
            if all_in || all_out {
                continue;
            }
            for b in 0..64 {
                let i = w * 64 + b;
                if i > lower.nx {
                    break;
                }
                let bits = cube_bits(lower, upper, i, j);
                if bits == 0 || bits == u8::MAX {
                    continue;
                }
                for kind in [
                    CellKind::FaceX,
                    CellKind::FaceY,
                    CellKind::FaceZ,
                    CellKind::Cube,
                ] {
                    if critical(kind, bits) {
                        each(i, j, kind);
                    }
                }
            }
        }
    }
}

/// For each pair of opposite corners (k, 7 - k), k < 4, the other six.
const OTHERS: [[usize; 6]; 4] = [
    [1, 2, 3, 4, 5, 6],
    [0, 2, 3, 4, 5, 7],
    [0, 1, 3, 4, 6, 7],
    [0, 1, 2, 5, 6, 7],
];

/// The critical faces and cubes owned by the cubes between two planes, 64 cubes at a time:
/// word `w` of `c[k]` holds corner `k` of the cubes of columns `64 w ..`, and each pattern is
/// a few bitwise operations on those words (the genus pass counts every slice of a volume).
pub fn count_critical(lower: &PlaneMask, upper: &PlaneMask) -> CriticalCounts {
    // Each bit's right neighbour: the word shifted, with the next word's first bit on top.
    let next = |r: &[u64], w: usize| (r[w] >> 1) | r.get(w + 1).map_or(0, |x| x << 63);
    let mut counts = CriticalCounts::default();
    for j in 0..=lower.ny {
        let rows = [
            lower.row(j),
            lower.row(j + 1),
            upper.row(j),
            upper.row(j + 1),
        ];
        for w in 0..lower.words {
            // Corner k = dx + 2 dy + 4 dz: row (dy, dz), shifted by dx.
            let c: [u64; 8] = std::array::from_fn(|k| {
                let r = rows[(k >> 1) & 3];
                if k & 1 == 0 {
                    r[w]
                } else {
                    next(r, w)
                }
            });
            // Most words of a scan lie wholly inside or outside: nothing there is critical.
            if c.iter().all(|&x| x == c[0]) {
                continue;
            }
            let same = |a: usize, b: usize| !(c[a] ^ c[b]);
            for [a, d, b, e] in FACES.map(|(_, f)| f.map(usize::from)) {
                let diagonal = same(a, d) & same(b, e) & (c[a] ^ c[b]);
                counts.faces += u64::from(diagonal.count_ones());
            }
            // Two opposite corners alone: they agree, differ from a third, and the other five
            // agree with that third.
            for (k, others) in OTHERS.iter().enumerate() {
                let lone = others[1..]
                    .iter()
                    .fold(same(k, 7 - k) & (c[k] ^ c[others[0]]), |m, &q| {
                        m & same(others[0], q)
                    });
                counts.cubes += u64::from(lone.count_ones());
            }
        }
    }
    counts
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bits of a cube whose inside corners are `corners`.
    fn bits(corners: &[[u8; 3]]) -> CubeBits {
        corners
            .iter()
            .map(|c| 1u8 << (c[0] + 2 * c[1] + 4 * c[2]))
            .sum()
    }

    #[test]
    fn the_critical_patterns_and_no_others() {
        // Every cube: count its critical owned faces and itself by brute force on corners.
        for b in 0..=255u8 {
            let at = |x: u8, y: u8, z: u8| (b >> (x + 2 * y + 4 * z)) & 1 == 1;
            let face_x = at(0, 0, 0) == at(0, 1, 1)
                && at(0, 1, 0) == at(0, 0, 1)
                && at(0, 0, 0) != at(0, 1, 0);
            let face_y = at(0, 0, 0) == at(1, 0, 1)
                && at(1, 0, 0) == at(0, 0, 1)
                && at(0, 0, 0) != at(1, 0, 0);
            let face_z = at(0, 0, 0) == at(1, 1, 0)
                && at(1, 0, 0) == at(0, 1, 0)
                && at(0, 0, 0) != at(1, 0, 0);
            assert_eq!(critical(CellKind::FaceX, b), face_x, "{b:08b}");
            assert_eq!(critical(CellKind::FaceY, b), face_y, "{b:08b}");
            assert_eq!(critical(CellKind::FaceZ, b), face_z, "{b:08b}");
            let ones: Vec<u8> = (0..8).filter(|k| (b >> k) & 1 == 1).collect();
            let zeros: Vec<u8> = (0..8).filter(|k| (b >> k) & 1 == 0).collect();
            let antipodal = |v: &Vec<u8>| v.len() == 2 && v[0] ^ v[1] == 7;
            assert_eq!(
                critical_cube(b),
                antipodal(&ones) || antipodal(&zeros),
                "{b:08b}"
            );
        }
        assert!(critical_cube(bits(&[[0, 0, 0], [1, 1, 1]])));
        assert!(critical_cube(!bits(&[[1, 0, 0], [0, 1, 1]])));
        assert!(!critical_cube(bits(&[[0, 0, 0], [1, 1, 0]])));
    }

    /// The word-wise count equals the cube-by-cube one (`each_critical`), on random planes of
    /// widths across a word's edge and densities from sparse to dense.
    #[test]
    fn counts_word_by_word_as_cube_by_cube() {
        let mut rng = crate::test_rng::Rng(0x9e37_79b9_7f4a_7c15);
        let mut random = || rng.next_u64();
        let mut total = CriticalCounts::default();
        for round in 0..300 {
            let (nx, ny) = (1 + round % 131, 1 + round % 4);
            let density = 1 + round % 9;
            let mut planes = [PlaneMask::empty(nx, ny), PlaneMask::empty(nx, ny)];
            for p in &mut planes {
                for y in 0..ny {
                    for x in 0..nx {
                        p.set(x, y, random() % 10 < density as u64);
                    }
                }
            }
            let mut expected = CriticalCounts::default();
            each_critical(&planes[0], &planes[1], |_, _, kind| match kind {
                CellKind::Cube => expected.cubes += 1,
                _ => expected.faces += 1,
            });
            assert_eq!(
                count_critical(&planes[0], &planes[1]),
                expected,
                "round {round}"
            );
            total.add(expected);
        }
        assert!(total.faces > 1000 && total.cubes > 100, "{total:?}");
    }

    #[test]
    fn counts_on_two_planes() {
        // Two samples touching along an edge (a diagonal of a z-face) and a third touching the
        // second at a corner only.
        let mut lower = PlaneMask::empty(4, 4);
        let mut upper = PlaneMask::empty(4, 4);
        lower.set(0, 0, true);
        lower.set(1, 1, true);
        upper.set(2, 2, true);
        // The cubes between the planes own the z-faces of the lower one: (0,0)-(1,1) is a
        // diagonal; the cube (1,1,0)-(2,2,1) has two opposite corners alone.
        let c = count_critical(&lower, &upper);
        assert_eq!((c.faces, c.cubes), (1, 1));
        // Below the lower plane: no diagonal face, and the cube (0,0,-1)-(1,1,0) has its two
        // inside corners on one face, not opposite.
        let below = PlaneMask::empty(4, 4);
        assert_eq!(count_critical(&below, &lower).total(), 0);
    }
}
