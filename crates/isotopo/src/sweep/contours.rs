//! Contours: the closed curves where the isosurface meets a plane. A contour is a connected set
//! of the segments the surface leaves on the plane's squares; two segments connect where they
//! share a crossing point on a plane edge, which always lies between two neighbouring squares:
//!
//! ```text
//!        (i, j+1)
//!   +------x------+          a segment in square (i, j) ending on its -x edge continues in
//!   |      :      |          square (i-1, j), on that square's +x edge; one ending on its -y
//!   x......+      |          edge continues in (i, j-1).
//!   |(i, j)       |
//!   +-------------+
//! ```
//!
//! The squares come from a slice's list of cubes whose lower (or upper) face the surface crosses.

use crate::topology::cases::{Case, NONE};
use crate::topology::slice::SliceSurfels;
use crate::unionfind::UnionFind;

/// Contours of one plane.
#[derive(Clone, Debug, Default)]
pub struct PlaneContours {
    /// Contour of each segment; segment `2k + slot` is slot `slot` of the k-th square of the list.
    pub of_segment: Vec<u32>,
    /// Number of segments of each contour.
    pub length: Vec<u32>,
}

impl PlaneContours {
    /// How many contours the plane has.
    pub fn count(&self) -> usize {
        self.length.len()
    }
}

/// The face's edges seen from the square: for face 4 (-z, lower plane) and 5 (+z, upper plane),
/// the cube edges on its -y side, +y side, -x side, +x side.
fn square_edges(face: usize) -> [u8; 4] {
    if face == 4 {
        [0, 1, 4, 5]
    } else {
        [2, 3, 6, 7]
    }
}

/// The slot of the segment of `face` of `case` that ends at cube edge `e`, if any.
#[inline]
fn slot_with_edge(case: &Case, face: usize, e: u8) -> Option<usize> {
    (0..2).find(|&s| {
        case.face_owner[face][s] != NONE && {
            let (a, b) = case.face_segment[face][s];
            a == e || b == e
        }
    })
}

/// Labels the contours on the lower (`face` 4, plane `z`) or upper (`face` 5, plane `z + 1`)
/// plane of a slice.
pub fn label(
    s: &SliceSurfels,
    face: usize,
    table: &[Case; 256],
    uf: &mut UnionFind,
) -> PlaneContours {
    let list = if face == 4 { &s.bottom } else { &s.top };
    let [lo_y, hi_y, lo_x, hi_x] = square_edges(face);
    uf.clear(2 * list.len());
    // Walk the previous row of squares alongside the current one.
    let mut row_begin = 0usize; // first square of the current row in `list`
    let mut prev_row = (0usize, 0usize); // [begin, end) of the previous row
    let mut ptr = 0usize;
    for k in 0..list.len() {
        let cube = s.cubes[list[k] as usize];
        if k > 0 {
            let before = s.cubes[list[k - 1] as usize];
            if before.j != cube.j {
                prev_row = if before.j + 1 == cube.j {
                    (row_begin, k)
                } else {
                    (k, k)
                };
                row_begin = k;
                ptr = prev_row.0;
            }
        }
        let case = &table[cube.case as usize];
        // -x neighbour: the previous square of the row, if adjacent.
        if k > row_begin {
            let left = s.cubes[list[k - 1] as usize];
            if left.i + 1 == cube.i {
                if let (Some(a), Some(b)) = (
                    slot_with_edge(case, face, lo_x),
                    slot_with_edge(&table[left.case as usize], face, hi_x),
                ) {
                    uf.union((2 * k + a) as u32, (2 * (k - 1) + b) as u32);
                }
            }
        }
        // -y neighbour in the previous row.
        while ptr < prev_row.1 && s.cubes[list[ptr] as usize].i < cube.i {
            ptr += 1;
        }
        if ptr < prev_row.1 {
            let below = s.cubes[list[ptr] as usize];
            if below.i == cube.i {
                if let (Some(a), Some(b)) = (
                    slot_with_edge(case, face, lo_y),
                    slot_with_edge(&table[below.case as usize], face, hi_y),
                ) {
                    uf.union((2 * k + a) as u32, (2 * ptr + b) as u32);
                }
            }
        }
    }
    // Labels for real segments only (slot 1 of one-segment squares does not exist).
    let mut of_segment = vec![u32::MAX; 2 * list.len()];
    let mut root_label = vec![u32::MAX; 2 * list.len()];
    let mut length: Vec<u32> = Vec::new();
    for k in 0..list.len() {
        let case = &table[s.cubes[list[k] as usize].case as usize];
        for slot in 0..2 {
            if case.face_owner[face][slot] == NONE {
                continue;
            }
            let seg = 2 * k + slot;
            let r = uf.find(seg as u32) as usize;
            if root_label[r] == u32::MAX {
                root_label[r] = length.len() as u32;
                length.push(0);
            }
            of_segment[seg] = root_label[r];
            length[root_label[r] as usize] += 1;
        }
    }
    PlaneContours { of_segment, length }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::{Frame, MaskVolume};
    use crate::topology::cases::{cases, Connectivity};

    /// Connected pieces of the samples of a plane equal to `side`, the plane padded with one
    /// ring of outside samples; neighbours along edges only (`diagonal` false) or also across
    /// corners.
    fn pieces(plane: &[Vec<bool>], side: bool, diagonal: bool) -> usize {
        let (ny, nx) = (plane.len() as i64, plane[0].len() as i64);
        let at = |x: i64, y: i64| {
            let inner = (0..nx).contains(&x) && (0..ny).contains(&y);
            inner && plane[y as usize][x as usize]
        };
        let mut seen = std::collections::HashSet::new();
        let mut count = 0;
        for start in (-1..=ny).flat_map(|y| (-1..=nx).map(move |x| (x, y))) {
            if at(start.0, start.1) != side || !seen.insert(start) {
                continue;
            }
            count += 1;
            let mut stack = vec![start];
            while let Some((x, y)) = stack.pop() {
                for (dx, dy) in (-1..=1).flat_map(|dy| (-1..=1).map(move |dx| (dx, dy))) {
                    let n = (x + dx, y + dy);
                    let step = (dx != 0) as u8 + (dy != 0) as u8;
                    let inner = (-1..=nx).contains(&n.0) && (-1..=ny).contains(&n.1);
                    if step == 0 || (step == 2 && !diagonal) || !inner || at(n.0, n.1) != side {
                        continue;
                    }
                    if seen.insert(n) {
                        stack.push(n);
                    }
                }
            }
        }
        count
    }

    /// The contours of random planes, lower and upper, are as many as the boundaries between
    /// their pieces: in a plane the pieces of the two sides, each touching the next, make a
    /// tree, whose edges are the contours (inside pieces + outside pieces - 1). Under
    /// connectivity 6 the inside joins along edges only (two inside samples across a square's
    /// diagonal are two contours), under 26 across corners too. Each contour goes round at least
    /// one sample: four segments or more.
    #[test]
    fn contours_are_the_boundaries_between_a_planes_pieces() {
        let mut rng = crate::test_rng::Rng(0x2545_f491_4f6c_dd1d);
        let mut random = || rng.next_u64();
        let (nx, ny) = (9, 8);
        let mut uf = UnionFind::new(0);
        for round in 0..200 {
            let density = [30, 50, 70][round % 3];
            let mut vol = MaskVolume::new([nx, ny, 2], Frame::identity());
            let mut planes = vec![vec![vec![false; nx]; ny]; 2];
            for (z, plane) in planes.iter_mut().enumerate() {
                for (y, row) in plane.iter_mut().enumerate() {
                    for (x, sample) in row.iter_mut().enumerate() {
                        *sample = random() % 100 < density;
                        vol.set(x, y, z, *sample);
                    }
                }
            }
            for conn in [Connectivity::Six, Connectivity::TwentySix] {
                let six = conn == Connectivity::Six;
                let sl = SliceSurfels::build(vol.plane(0), vol.plane(1), 0, conn);
                for (face, plane) in [(4, &planes[0]), (5, &planes[1])] {
                    let c = label(&sl, face, cases(conn), &mut uf);
                    let want = pieces(plane, true, !six) + pieces(plane, false, six) - 1;
                    assert_eq!(c.count(), want, "round {round} {conn:?} face {face}");
                    assert!(c.length.iter().all(|&n| n >= 4), "{:?}", c.length);
                }
            }
        }
    }
}
