//! Mini-volumes for handles inside a single slice (intra-ribbon handles, paper §2.1).
//!
//! A ribbon whose surface, closed by a cap on each of its contours, has genus `g > 0` hides `g`
//! handles that no cycle of the z Reeb graph sees. The mini-volume holds just that slice (its
//! two planes, cropped to the ribbon), closed by caps below and above, and is swept along the
//! slice's own u axis, where those handles show up as cycles.
//!
//! Each contour must be capped by its own disk, also when contours are nested. A plane's
//! contours bound regions nested like a tree (background, inside regions, holes in them, islands
//! in the holes…); a point's *depth* is how many contours enclose it, odd inside. With `D` the
//! largest depth, layer `j` below the plane keeps depth `min(depth, D - j)`: the innermost
//! regions are filled in first, so each contour goes down as a wall and is closed by a flat
//! disk one layer lower than the contour around it:
//!
//! ```text
//!   plane s      . ##### . ##### .      depth 0 1 2 1 0 …   (# inside)
//!   layer s-1    . ############# .      the hole (depth 2) closed: merged into its parent
//!   layer s-2    . . . . . . . . .      all outside: the outer contour closed
//! ```

use crate::grid::{Frame, MaskVolume};
use crate::topology::Connectivity;

/// Nesting depth of every sample of a 2-D inside grid (`nu × nv`, u fastest), whose border is
/// outside. Inside samples are 4-adjacent under connectivity 6 (outside 8-adjacent), the reverse
/// under 26, as in a grid plane of the volume.
pub fn nesting_depth(inside: &[bool], nu: usize, nv: usize, conn: Connectivity) -> Vec<u32> {
    const FOUR: [(isize, isize); 4] = [(-1, 0), (0, -1), (1, 0), (0, 1)];
    const EIGHT: [(isize, isize); 8] = [
        (-1, -1),
        (0, -1),
        (1, -1),
        (-1, 0),
        (1, 0),
        (-1, 1),
        (0, 1),
        (1, 1),
    ];
    // Samples as (x, y): no division per neighbour.
    let within = |(x, y): (usize, usize), (dx, dy): (isize, isize)| -> Option<(usize, usize)> {
        let (a, b) = (x.wrapping_add_signed(dx), y.wrapping_add_signed(dy));
        (a < nu && b < nv).then_some((a, b))
    };
    // Components of each state. Under 6, inside is 4-connected; under 26, 8-connected. Outside
    // takes the other.
    let inside_eight = conn == Connectivity::TwentySix;
    let mut comp = vec![u32::MAX; nu * nv];
    let mut n = 0u32;
    let mut stack = Vec::new();
    for start in 0..nu * nv {
        if comp[start] != u32::MAX {
            continue;
        }
        let state = inside[start];
        let steps: &[(isize, isize)] = if state == inside_eight { &EIGHT } else { &FOUR };
        comp[start] = n;
        stack.push((start % nu, start / nu));
        while let Some(p) = stack.pop() {
            for (a, b) in steps.iter().filter_map(|&d| within(p, d)) {
                let q = b * nu + a;
                if comp[q] == u32::MAX && inside[q] == state {
                    comp[q] = n;
                    stack.push((a, b));
                }
            }
        }
        n += 1;
    }
    // Adjacent components (4-adjacency between samples of different states suffices: a region
    // of one state is surrounded 4-wise by its enclosing region). Depth by breadth-first search
    // from the background, which holds the border.
    let mut adj = vec![Vec::new(); n as usize];
    for y in 0..nv {
        for x in 0..nu {
            let a = comp[y * nu + x];
            for (p, q) in [(1, 0), (0, 1)]
                .into_iter()
                .filter_map(|d| within((x, y), d))
            {
                let b = comp[q * nu + p];
                if a != b {
                    adj[a as usize].push(b);
                    adj[b as usize].push(a);
                }
            }
        }
    }
    let mut depth = vec![u32::MAX; n as usize];
    let background = comp[0];
    depth[background as usize] = 0;
    let mut queue = std::collections::VecDeque::from([background]);
    while let Some(c) = queue.pop_front() {
        for &d in &adj[c as usize] {
            if depth[d as usize] == u32::MAX {
                depth[d as usize] = depth[c as usize] + 1;
                queue.push_back(d);
            }
        }
    }
    comp.iter().map(|&c| depth[c as usize]).collect()
}

/// A mini-volume ready to sweep, and where its original slice lies.
pub struct MiniVolume {
    /// Rotated so that its sweep runs along the parent's u axis.
    pub volume: MaskVolume,
    /// Parent-local position of the mini-volume's corner (before rotation): (u, v, w).
    pub origin: [i64; 3],
    /// Caps below the slice (number of layers).
    pub below: usize,
}

/// Builds the mini-volume of the slice between planes `s` and `s + 1` of `vol`, cropped to the
/// samples `u0..=u1`, `v0..=v1` (parent-local, may include the padding at -1 and n).
pub fn build(
    vol: &MaskVolume,
    s: i64,
    u: (i64, i64),
    v: (i64, i64),
    conn: Connectivity,
) -> MiniVolume {
    let (nu, nv) = ((u.1 - u.0 + 1) as usize, (v.1 - v.0 + 1) as usize);
    // Each data plane with a ring of outside around it, so the border is background.
    let grid = |w: i64| -> Vec<bool> {
        let plane = vol.plane(w);
        let mut g = vec![false; (nu + 2) * (nv + 2)];
        for b in 0..nv {
            for a in 0..nu {
                g[(b + 1) * (nu + 2) + a + 1] =
                    plane.get((u.0 + a as i64) as isize, (v.0 + b as i64) as isize);
            }
        }
        g
    };
    let caps = |plane: &[bool]| -> Vec<Vec<bool>> {
        let depth = nesting_depth(plane, nu + 2, nv + 2, conn);
        let d_max = depth.iter().copied().max().unwrap_or(0);
        // Layers j = 1 .. d_max - 1 away from the plane; layer d_max is all outside (padding).
        (1..d_max)
            .map(|j| {
                let keep = d_max - j;
                depth.iter().map(|&d| d.min(keep) % 2 == 1).collect()
            })
            .collect()
    };
    let lower = grid(s);
    let upper = grid(s + 1);
    let below = caps(&lower);
    let above = caps(&upper);
    // Layers along w: below caps (farthest first), the two planes, above caps (nearest first).
    let mut layers: Vec<&Vec<bool>> = below.iter().rev().collect();
    layers.push(&lower);
    layers.push(&upper);
    layers.extend(above.iter());
    let origin = [u.0, v.0, s - below.len() as i64];
    let frame = Frame {
        uvw: vol.frame.uvw,
        offset: vol.frame.to_original_i(origin),
    };
    // Written straight into the rotated volume: (u', v', w') = (v, w, u).
    let mut rotated = MaskVolume::new([nv, layers.len(), nu], frame.rotated([0, 0, 0]));
    for (w, layer) in layers.iter().enumerate() {
        for b in 0..nv {
            for a in 0..nu {
                if layer[(b + 1) * (nu + 2) + a + 1] {
                    rotated.set(b, w, a, true);
                }
            }
        }
    }
    MiniVolume {
        volume: rotated,
        origin,
        below: below.len(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(rows: &[&str]) -> (Vec<bool>, usize, usize) {
        let nv = rows.len();
        let nu = rows[0].len();
        (
            rows.iter()
                .flat_map(|r| r.chars().map(|c| c == '#'))
                .collect(),
            nu,
            nv,
        )
    }

    #[test]
    fn depth_counts_nested_contours() {
        let (g, nu, nv) = grid(&[
            ".........", //
            ".#######.",
            ".#.....#.",
            ".#.###.#.",
            ".#.#.#.#.",
            ".#.###.#.",
            ".#.....#.",
            ".#######.",
            ".........",
        ]);
        let d = nesting_depth(&g, nu, nv, Connectivity::Six);
        assert_eq!(d[0], 0);
        assert_eq!(d[nu + 1], 1); // outer ring
        assert_eq!(d[2 * nu + 2], 2); // hole
        assert_eq!(d[3 * nu + 3], 3); // island
        assert_eq!(d[4 * nu + 4], 4); // hole in the island
    }

    #[test]
    fn diagonal_gaps_follow_the_connectivity() {
        // A ring closed only through a diagonal step: under 6 (inside 4-connected, outside
        // 8-connected) the centre leaks out, under 26 it is a hole.
        let (g, nu, nv) = grid(&[
            "......", //
            ".###..", ".#..#.", ".#..#.", ".####.", "......",
        ]);
        let d6 = nesting_depth(&g, nu, nv, Connectivity::Six);
        let d26 = nesting_depth(&g, nu, nv, Connectivity::TwentySix);
        assert_eq!(d6[2 * nu + 2], 0);
        assert_eq!(d26[2 * nu + 2], 2);
    }
}
