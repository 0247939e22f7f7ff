//! Surfels of one slice: the surface pieces in the cubes between two z-planes, their adjacency
//! across the cubes' side faces, and the ribbons (connected pieces within the slice) they form.
//!
//! ```text
//!   plane z+1  o-----o-----o        a cube (i, j) spans padded columns i, i+1 and rows j, j+1
//!              |     |     |        of both planes; only "mixed" cubes (corners not all the
//!   plane z    o-----o-----o        same) hold pieces, so only those are listed.
//! ```
//!
//! Pieces are numbered per slice: cube `q` owns pieces `first_piece .. first_piece + n`.

use super::cases::{cases, cut_alike, Case, Connectivity, NONE};
use super::mask::PlaneMask;
use crate::unionfind::UnionFind;

/// A cube with pieces.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Cube {
    /// Padded column (sample x of its lower corners + 1), 0 ..= nx.
    pub i: u32,
    /// Padded row, 0 ..= ny.
    pub j: u32,
    /// Cube case: bit `b` says corner `b = x + 2y + 4z` is inside (see [`super::cases`]).
    pub case: u8,
    /// Slice-wide number of its first piece; its pieces are numbered consecutively from it.
    pub first_piece: u32,
}

/// A connected piece of surface within one slice.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Ribbon {
    /// 4 × Euler characteristic of the ribbon as a surface with boundary.
    pub chi4: i32,
    /// 4 × its share of its closed surface's Euler characteristic.
    pub surface_chi4: i32,
    /// Number of cube pieces it is made of.
    pub pieces: u32,
    /// Segments on the lower plane (its boundary contours there).
    pub bottom_segments: u32,
    /// Segments on the upper plane (its boundary contours there).
    pub top_segments: u32,
    /// Bounding box in padded cube indices: [min i, min j].
    pub min: [u32; 2],
    /// Bounding box in padded cube indices: [max i, max j] (inclusive).
    pub max: [u32; 2],
    /// For a crossing on a vertical (z) edge of this ribbon: is the edge's upper sample inside?
    /// In the lowest slice of a surface this tells whether the surface encloses material.
    pub upper_inside: Option<bool>,
    /// First cube (index into `cubes`) holding one of its pieces.
    pub first_cube: u32,
}

impl Ribbon {
    /// Adds piece `k` of `cube` (index `q` into the slice's cubes), whose case is `case`.
    #[inline]
    fn add_piece(&mut self, case: &Case, k: usize, cube: &Cube, q: u32) {
        self.chi4 += case.ribbon_chi4[k] as i32;
        self.surface_chi4 += case.chi4[k] as i32;
        self.pieces += 1;
        self.min = [self.min[0].min(cube.i), self.min[1].min(cube.j)];
        self.max = [self.max[0].max(cube.i), self.max[1].max(cube.j)];
        if self.first_cube == u32::MAX {
            self.first_cube = q;
        }
        self.bottom_segments += case.bottom_segments[k] as u32;
        self.top_segments += case.top_segments[k] as u32;
        if self.upper_inside.is_none() && case.z_upper[k] != NONE {
            self.upper_inside = Some((cube.case >> case.z_upper[k]) & 1 == 1);
        }
    }
}

/// Surfels of the slice between planes `z` and `z + 1`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SliceSurfels {
    /// Lower plane (-1 ..= nz - 1).
    pub z: i32,
    /// Samples along x of the volume (without padding).
    pub nx: usize,
    /// Samples along y of the volume (without padding).
    pub ny: usize,
    /// The mixed cubes, row by row (by `j`, then `i`).
    pub cubes: Vec<Cube>,
    /// `cubes[row_start[j] .. row_start[j + 1]]` are the cubes of row `j`, by increasing `i`.
    pub row_start: Vec<u32>,
    /// Ribbon of each piece.
    pub piece_ribbon: Vec<u32>,
    /// The ribbons, indexed by the labels in `piece_ribbon`.
    pub ribbons: Vec<Ribbon>,
    /// Cubes whose lower (`-z`) face carries segments, in (j, i) order: the squares of plane `z`
    /// that the surface crosses.
    pub bottom: Vec<u32>,
    /// Cubes whose upper (`+z`) face carries segments, in (j, i) order: the squares of plane
    /// `z + 1` that the surface crosses.
    pub top: Vec<u32>,
}

#[inline]
fn bit(row: &[u64], i: usize) -> u8 {
    ((row[i / 64] >> (i % 64)) & 1) as u8
}

/// Cube case from the rows of its corners: `a`/`b` rows j, j+1 of the lower plane, `c`/`d` of
/// the upper plane.
#[inline]
pub fn case_at(a: &[u64], b: &[u64], c: &[u64], d: &[u64], i: usize) -> u8 {
    bit(a, i)
        | bit(a, i + 1) << 1
        | bit(b, i) << 2
        | bit(b, i + 1) << 3
        | bit(c, i) << 4
        | bit(c, i + 1) << 5
        | bit(d, i) << 6
        | bit(d, i + 1) << 7
}

/// Calls `f(i)` for every mixed cube of cube row `j` (rows j, j+1 of both planes), in order.
#[inline]
pub fn for_mixed_in_row(
    lower: &PlaneMask,
    upper: &PlaneMask,
    j: usize,
    mut f: impl FnMut(usize, u8),
) {
    let (a, b) = (lower.row(j), lower.row(j + 1));
    let (c, d) = (upper.row(j), upper.row(j + 1));
    let words = lower.words;
    let or_at = |w: usize| {
        if w < words {
            a[w] | b[w] | c[w] | d[w]
        } else {
            0
        }
    };
    let and_at = |w: usize| {
        if w < words {
            a[w] & b[w] & c[w] & d[w]
        } else {
            0
        }
    };
    let (mut or_w, mut and_w) = (or_at(0), and_at(0));
    for w in 0..words {
        let (or_n, and_n) = (or_at(w + 1), and_at(w + 1));
        // Bit i of the shifted words is column i + 1.
        let or_s = (or_w >> 1) | (or_n << 63);
        let and_s = (and_w >> 1) | (and_n << 63);
        let mut mixed = (or_w | or_s) & !(and_w & and_s);
        while mixed != 0 {
            let i = w * 64 + mixed.trailing_zeros() as usize;
            mixed &= mixed - 1;
            f(i, case_at(a, b, c, d, i));
        }
        or_w = or_n;
        and_w = and_n;
    }
}

impl SliceSurfels {
    /// Builds the surfels of the slice between `lower` (plane z) and `upper` (plane z+1).
    pub fn build(lower: &PlaneMask, upper: &PlaneMask, z: i32, conn: Connectivity) -> SliceSurfels {
        let mut s = SliceSurfels::default();
        s.rebuild(lower, upper, z, conn, &mut UnionFind::default());
        s
    }

    /// As [`SliceSurfels::build`], reusing this value's buffers and a scratch union-find.
    pub fn rebuild(
        &mut self,
        lower: &PlaneMask,
        upper: &PlaneMask,
        z: i32,
        conn: Connectivity,
        uf: &mut UnionFind,
    ) {
        let table = cases(conn);
        self.z = z;
        self.nx = lower.nx;
        self.ny = lower.ny;
        let pieces = self.list_mixed_cubes(lower, upper, table);
        uf.clear(pieces as usize);
        self.join_side_faces(table, uf, None);
        self.label_ribbons(table, uf);
    }

    /// Builds the surfels of the slice under `conn`, and under the other connectivity where
    /// they differ (`None`: no cube of the slice is cut differently, see [`cut_alike`]), in the
    /// buffers of `spare`, a slice no longer needed (fresh ones cost the allocator and a page
    /// fault every 4 KiB as they grow; `SliceSurfels::default()` for none).
    ///
    /// The other connectivity's slice is derived from this one: the side faces between cubes
    /// cut alike are joined once, for both; only those of the other cubes are joined again.
    pub fn build_both(
        mut s: SliceSurfels,
        lower: &PlaneMask,
        upper: &PlaneMask,
        z: i32,
        conn: Connectivity,
    ) -> (SliceSurfels, Option<SliceSurfels>) {
        let table = cases(conn);
        (s.z, s.nx, s.ny) = (z, lower.nx, lower.ny);
        let pieces = s.list_mixed_cubes(lower, upper, table);
        let mut uf = UnionFind::new(pieces as usize);
        let mut deferred = Vec::new();
        s.join_side_faces(table, &mut uf, Some(&mut deferred));
        let alike = cut_alike();
        let other = match s.cubes.iter().all(|c| alike[c.case as usize]) {
            true => None,
            false => Some(s.other_connectivity(&uf, &deferred, conn.other())),
        };
        for f in &deferred {
            let (a, b) = (s.cubes[f.a as usize], s.cubes[f.b as usize]);
            let (ca, cb) = (&table[a.case as usize], &table[b.case as usize]);
            join_face(&mut uf, ca, a.first_piece, f.fa, cb, b.first_piece, f.fb);
        }
        s.label_ribbons(table, &mut uf);
        (s, other)
    }

    /// The slice under connectivity `conn`, the other one: from this slice's cubes, and its
    /// pieces joined across every side face but the `deferred` ones (those of cubes not cut
    /// alike), in `fragments`. Its pieces and ribbons are numbered as a fresh build numbers them.
    fn other_connectivity(
        &self,
        fragments: &UnionFind,
        deferred: &[SideFace],
        conn: Connectivity,
    ) -> SliceSurfels {
        let table = cases(conn);
        let alike = cut_alike();
        let mut o = SliceSurfels {
            z: self.z,
            nx: self.nx,
            ny: self.ny,
            cubes: self.cubes.clone(),
            row_start: self.row_start.clone(),
            bottom: self.bottom.clone(),
            top: self.top.clone(),
            ..Default::default()
        };
        // Each cube's first node in the union-find: a cube cut alike keeps this slice's pieces;
        // the others' pieces are new nodes.
        let mut uf = fragments.clone();
        let mut node = Vec::with_capacity(o.cubes.len());
        let mut pieces = 0u32;
        for cube in &mut o.cubes {
            let n = table[cube.case as usize].n_pieces as u32;
            node.push(match alike[cube.case as usize] {
                true => cube.first_piece,
                false => {
                    let first = uf.len() as u32;
                    (0..n).for_each(|_| _ = uf.push());
                    first
                }
            });
            cube.first_piece = pieces;
            pieces += n;
        }
        for f in deferred {
            let (a, b) = (f.a as usize, f.b as usize);
            let ca = &table[o.cubes[a].case as usize];
            let cb = &table[o.cubes[b].case as usize];
            join_face(&mut uf, ca, node[a], f.fa, cb, node[b], f.fb);
        }
        // Ribbons labelled in order of their first piece, as a fresh build labels them.
        let nodes = o.cubes.iter().zip(&node).flat_map(|(cube, &first)| {
            (0..table[cube.case as usize].n_pieces as u32).map(move |k| first + k)
        });
        let (labels, n) = uf.labels_of(nodes);
        o.piece_ribbon = labels;
        o.sum_ribbons(table, n);
        o
    }

    /// Labels the ribbons the pieces joined in `uf` form, and sums them.
    fn label_ribbons(&mut self, table: &[Case; 256], uf: &mut UnionFind) {
        let (labels, n) = uf.labels();
        self.piece_ribbon = labels;
        self.sum_ribbons(table, n);
    }

    /// Lists the mixed cubes row by row, numbering their pieces; returns the number of pieces.
    fn list_mixed_cubes(
        &mut self,
        lower: &PlaneMask,
        upper: &PlaneMask,
        table: &[Case; 256],
    ) -> u32 {
        self.cubes.clear();
        self.row_start.clear();
        let mut pieces = 0u32;
        for j in 0..=self.ny {
            self.row_start.push(self.cubes.len() as u32);
            for_mixed_in_row(lower, upper, j, |i, case| {
                self.cubes.push(Cube {
                    i: i as u32,
                    j: j as u32,
                    case,
                    first_piece: pieces,
                });
                pieces += table[case as usize].n_pieces as u32;
            });
        }
        self.row_start.push(self.cubes.len() as u32);
        pieces
    }

    /// Joins pieces across the -x and -y faces of each cube (each side face is the -x or -y face
    /// of one of its two cubes), and lists the cubes whose -z / +z faces carry segments.
    ///
    /// ```text
    ///   row j     [q-1][ q ]     -x face: the previous cube of the row
    ///   row j-1        [ b ]     -y face: cube b, found by walking row j-1 alongside row j
    /// ```
    ///
    /// With `deferred`, the faces of cubes not [`cut_alike`] are listed there instead of joined.
    fn join_side_faces(
        &mut self,
        table: &[Case; 256],
        uf: &mut UnionFind,
        mut deferred: Option<&mut Vec<SideFace>>,
    ) {
        let alike = cut_alike();
        self.bottom.clear();
        self.top.clear();
        let mut below_row = 0usize; // walks row j-1 alongside row j
        for j in 0..=self.ny {
            let (r0, r1) = (self.row_start[j] as usize, self.row_start[j + 1] as usize);
            let (p0, p1) = if j > 0 {
                (self.row_start[j - 1] as usize, self.row_start[j] as usize)
            } else {
                (0, 0)
            };
            below_row = below_row.max(p0);
            for q in r0..r1 {
                let cube = self.cubes[q];
                let case = &table[cube.case as usize];
                let mut join = |b: usize, fa: usize, fb: usize| {
                    let nb = self.cubes[b];
                    match deferred.as_deref_mut() {
                        Some(d) if !alike[cube.case as usize] || !alike[nb.case as usize] => d
                            .push(SideFace {
                                a: q as u32,
                                fa,
                                b: b as u32,
                                fb,
                            }),
                        _ => {
                            let cb = &table[nb.case as usize];
                            join_face(uf, case, cube.first_piece, fa, cb, nb.first_piece, fb)
                        }
                    }
                };
                if case.face_owner[0][0] != NONE {
                    debug_assert!(self.cubes[q - 1].i + 1 == cube.i);
                    join(q - 1, 0, 1);
                }
                if case.face_owner[2][0] != NONE {
                    while below_row < p1 && self.cubes[below_row].i < cube.i {
                        below_row += 1;
                    }
                    debug_assert!(self.cubes[below_row].i == cube.i);
                    join(below_row, 2, 3);
                }
                if case.face_owner[4][0] != NONE {
                    self.bottom.push(q as u32);
                }
                if case.face_owner[5][0] != NONE {
                    self.top.push(q as u32);
                }
            }
        }
    }

    /// Sums the pieces of each of the `n` ribbons (labelled in `piece_ribbon`), and counts their
    /// segments on the lower and upper planes.
    fn sum_ribbons(&mut self, table: &[Case; 256], n: usize) {
        self.ribbons.clear();
        self.ribbons.resize(
            n,
            Ribbon {
                min: [u32::MAX; 2],
                first_cube: u32::MAX,
                ..Default::default()
            },
        );
        for (q, cube) in self.cubes.iter().enumerate() {
            let case = &table[cube.case as usize];
            for k in 0..case.n_pieces as usize {
                let r =
                    &mut self.ribbons[self.piece_ribbon[cube.first_piece as usize + k] as usize];
                r.add_piece(case, k, cube, q as u32);
            }
        }
    }

    /// Index into `cubes` of the cube at padded (i, j), if it is mixed.
    pub fn find_cube(&self, i: u32, j: u32) -> Option<usize> {
        if j as usize + 1 >= self.row_start.len() {
            return None;
        }
        let (r0, r1) = (
            self.row_start[j as usize] as usize,
            self.row_start[j as usize + 1] as usize,
        );
        self.cubes[r0..r1]
            .binary_search_by_key(&i, |c| c.i)
            .ok()
            .map(|k| r0 + k)
    }

    /// Ribbon of the piece owning segment `slot` of face `face` of cube `q`.
    #[inline]
    pub fn face_ribbon(&self, table: &[Case; 256], q: usize, face: usize, slot: usize) -> u32 {
        let cube = self.cubes[q];
        let o = table[cube.case as usize].face_owner[face][slot];
        self.piece_ribbon[(cube.first_piece + o as u32) as usize]
    }
}

/// A side face shared by two cubes of a slice: face `fa` of cube `a`, face `fb` of cube `b`
/// (indices into the slice's cubes).
#[derive(Clone, Copy, Debug)]
struct SideFace {
    a: u32,
    fa: usize,
    b: u32,
    fb: usize,
}

/// Unites the pieces on either side of a shared face: face `fa` of a cube of case `ca` whose
/// first piece is node `a`, face `fb` of one of case `cb` whose first piece is node `b`.
#[inline]
fn join_face(uf: &mut UnionFind, ca: &Case, a: u32, fa: usize, cb: &Case, b: u32, fb: usize) {
    for slot in 0..2 {
        let (oa, ob) = (ca.face_owner[fa][slot], cb.face_owner[fb][slot]);
        if oa == NONE {
            break;
        }
        debug_assert!(
            ob != NONE,
            "a shared face has the same segments on both sides"
        );
        uf.union(a + oa as u32, b + ob as u32);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A random plane: each sample inside with probability `density` (in 256ths).
    fn random_plane(
        rng: &mut crate::test_rng::Rng,
        nx: usize,
        ny: usize,
        density: u64,
    ) -> PlaneMask {
        let mut p = PlaneMask::empty(nx, ny);
        for y in 0..ny {
            for x in 0..nx {
                p.set(x, y, rng.below(256) < density);
            }
        }
        p
    }

    /// Both slices of `build_both` are those two fresh builds make, field by field, on random
    /// planes of every density (sparse ones have no critical cube, dense noise many), both
    /// connectivities, each built in the buffers of the round before (another size and
    /// density); and the other connectivity's is `None` exactly where every cube is cut alike.
    #[test]
    fn both_connectivities_built_at_once_are_built_as_each_alone() {
        let mut rng = crate::test_rng::Rng(0x51ce_5eed_0dd5_1ce5);
        let (mut shared, mut derived) = (0, 0);
        let mut spare = SliceSurfels::default();
        for round in 0..400 {
            let (nx, ny) = (1 + rng.below(70) as usize, 1 + rng.below(9) as usize);
            let density = [4, 40, 128, 200, 250][round % 5];
            let lower = random_plane(&mut rng, nx, ny, density);
            let upper = random_plane(&mut rng, nx, ny, density);
            for conn in [Connectivity::Six, Connectivity::TwentySix] {
                let (s, other) = SliceSurfels::build_both(spare, &lower, &upper, 3, conn);
                assert_eq!(
                    s,
                    SliceSurfels::build(&lower, &upper, 3, conn),
                    "round {round}"
                );
                let fresh = SliceSurfels::build(&lower, &upper, 3, conn.other());
                let alike = s.cubes.iter().all(|c| cut_alike()[c.case as usize]);
                assert_eq!(other.is_none(), alike, "round {round}");
                match other {
                    Some(o) => {
                        assert_eq!(o, fresh, "round {round} {conn:?}");
                        derived += 1;
                    }
                    // The other connectivity's tracker reads these with its own table.
                    None => {
                        assert_eq!(s.cubes, fresh.cubes, "round {round}");
                        assert_eq!(s.piece_ribbon, fresh.piece_ribbon, "round {round}");
                        assert_eq!(s.ribbons, fresh.ribbons, "round {round}");
                        shared += 1;
                    }
                }
                spare = s;
            }
        }
        assert!(
            shared > 100 && derived > 300,
            "{shared} shared, {derived} derived"
        );
    }
}
