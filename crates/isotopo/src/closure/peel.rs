//! A wall grown one sample at a time, with the topology watched at each: for the loops no wall
//! of the fan or the minimum cut closes cleanly (round a long twisted loop both touch other
//! parts of the surface).
//!
//! Within a region across the loop (the samples near its spanning disk), the side a closure
//! changes is thinned by *simple* samples only: flipping a simple sample changes no topology
//! (Bertrand and Malandain's topological numbers, in its 26-neighbourhood, are both 1). What is
//! left of that side in the region is a skeleton; flipping one of its samples whose
//! neighbourhood holds two pieces of the side and one of the other is the single change that
//! cuts a bar (or, filling, closes a tunnel). Then every thinned sample whose flip back is
//! simple again is flipped back, so that the wall keeps only what the change needs.
//!
//! ```text
//!    bar across the region     thinned to a thread      cut at one sample, the rest put back
//!     # # # # # # #             # # # . # # #            # # # . # # #
//!     # # # # # # #      ->     . . . # . . .     ->     # # #   # # #
//!     # # # # # # #             # # # . # # #            # # # . # # #
//! ```
//!
//! The result is verified by [`super::close`] like any other wall.

use super::Operation;
use crate::loops::search::FastMap;
use crate::sweep::MaskVolume;
use crate::topology::cases::Connectivity;

/// The 26 neighbours of a sample, and for each its adjacencies within the neighbourhood.
struct Neighbourhood {
    offsets: [[i64; 3]; 26],
    /// Face neighbours (6-adjacent to the centre).
    face: [bool; 26],
    /// In the 18-neighbourhood (not a corner).
    in18: [bool; 26],
    /// Neighbours k, j that are 6-adjacent / 26-adjacent to each other.
    adj6: [Vec<u8>; 26],
    adj26: [Vec<u8>; 26],
}

fn neighbourhood() -> &'static Neighbourhood {
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
    let nb = neighbourhood();
    let mut seen = [false; 26];
    let mut count = 0;
    for start in 0..26 {
        let allowed = |k: usize| member[k] && (!six || nb.in18[k]);
        if seen[start] || !allowed(start) || (six && !nb.face[start]) {
            continue;
        }
        count += 1;
        let mut stack = vec![start];
        seen[start] = true;
        while let Some(k) = stack.pop() {
            let adj = if six { &nb.adj6[k] } else { &nb.adj26[k] };
            for &j in adj {
                let j = j as usize;
                if !seen[j] && allowed(j) {
                    seen[j] = true;
                    stack.push(j);
                }
            }
        }
    }
    count
}

/// The topological numbers of sample `q`: the pieces of the inside and of the outside in its
/// neighbourhood that touch it (each with its own adjacency). Flipping `q` changes no topology
/// exactly when both are 1.
pub fn topological_numbers(vol: &MaskVolume, q: [i64; 3], conn: Connectivity) -> (usize, usize) {
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

/// Walls for closing the loop by `op` within `region` (see the module notes), one per sample of
/// the thinned region whose flip cuts (or fills) it, nearest `centre` first, at most `most` of
/// them. The volume is left as it was.
pub fn peel_walls(
    vol: &mut MaskVolume,
    conn: Connectivity,
    region: &[[i64; 3]],
    centre: [f64; 3],
    op: Operation,
    most: usize,
) -> Vec<Vec<[i64; 3]>> {
    let dims = vol.dims.map(|n| n as i64);
    let side = !op.target();
    let mut cand: Vec<[i64; 3]> = region
        .iter()
        .copied()
        .filter(|q| (0..3).all(|c| q[c] >= 0 && q[c] < dims[c]))
        .filter(|q| vol.get(q[0], q[1], q[2]) == side)
        .collect();
    // Far from the centre first: the side is peeled from the loop inwards.
    let d2 = |q: &[i64; 3]| {
        (0..3)
            .map(|c| (q[c] as f64 - centre[c]).powi(2))
            .sum::<f64>()
    };
    cand.sort_by(|a, b| d2(b).total_cmp(&d2(a)));
    let set = |vol: &mut MaskVolume, q: [i64; 3], inside: bool| {
        vol.set(q[0] as usize, q[1] as usize, q[2] as usize, inside)
    };
    let thinned = thin(vol, conn, &cand, side);
    let is_thinned: FastMap<[i64; 3], ()> = thinned.iter().map(|&q| (q, ())).collect();
    // The single change: a sample whose neighbourhood holds two pieces of the side.
    let splits = |t: (usize, usize)| match op {
        Operation::Pinch => t == (2, 1),
        Operation::Collapse => t == (1, 2),
    };
    let cuts: Vec<[i64; 3]> = cand
        .iter()
        .rev()
        .copied()
        .filter(|q| !is_thinned.contains_key(q) && splits(topological_numbers(vol, *q, conn)))
        .take(most)
        .collect();
    let mut walls = Vec::new();
    for c in cuts {
        set(vol, c, !side);
        // Put back what is simple to put back.
        let mut kept: Vec<[i64; 3]> = thinned.clone();
        let mut back: Vec<[i64; 3]> = Vec::new();
        loop {
            let mut any = false;
            kept.retain(|&q| {
                let simple = topological_numbers(vol, q, conn) == (1, 1);
                if simple {
                    set(vol, q, side);
                    back.push(q);
                    any = true;
                }
                !simple
            });
            if !any {
                break;
            }
        }
        // Back to the thinned state for the next cut.
        for &q in &back {
            set(vol, q, !side);
        }
        set(vol, c, side);
        kept.push(c);
        walls.push(kept);
    }
    for &q in &thinned {
        set(vol, q, side);
    }
    walls
}

/// Flips the samples of `cand` (all of state `side`) that are simple, in turn, until none is
/// left; returns those flipped.
fn thin(vol: &mut MaskVolume, conn: Connectivity, cand: &[[i64; 3]], side: bool) -> Vec<[i64; 3]> {
    let mut flipped: Vec<[i64; 3]> = Vec::new();
    let mut done: FastMap<[i64; 3], ()> = FastMap::default();
    loop {
        let mut any = false;
        for &q in cand {
            if !done.contains_key(&q) && topological_numbers(vol, q, conn) == (1, 1) {
                vol.set(q[0] as usize, q[1] as usize, q[2] as usize, !side);
                flipped.push(q);
                done.insert(q, ());
                any = true;
            }
        }
        if !any {
            return flipped;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sweep::Frame;

    #[test]
    fn simple_samples_of_a_bar() {
        let mut vol = MaskVolume::new([7, 5, 5], Frame::identity());
        for x in 0..7 {
            vol.set(x, 2, 2, true);
        }
        for conn in [Connectivity::Six, Connectivity::TwentySix] {
            // The end of the bar is simple; a sample in its middle splits it in two.
            assert_eq!(topological_numbers(&vol, [0, 2, 2], conn), (1, 1));
            assert_eq!(topological_numbers(&vol, [3, 2, 2], conn), (2, 1));
            // An outside sample beside the bar: adding it changes nothing.
            assert_eq!(topological_numbers(&vol, [3, 1, 2], conn), (1, 1));
        }
    }

    /// A 3×3 bar, peeled within the slab x = 4 down to its centre and cut there: none of the
    /// peeled samples can go back without joining the two halves again.
    #[test]
    fn peeling_a_thick_bar_cuts_it() {
        let mut vol = MaskVolume::new([9, 7, 7], Frame::identity());
        for x in 0..9 {
            for y in 2..5 {
                for z in 2..5 {
                    vol.set(x, y, z, true);
                }
            }
        }
        let region: Vec<[i64; 3]> = (1..6)
            .flat_map(|y| (1..6).map(move |z| [4, y, z]))
            .collect();
        let walls = peel_walls(
            &mut vol,
            Connectivity::Six,
            &region,
            [4.0, 3.0, 3.0],
            Operation::Pinch,
            4,
        );
        let wall = walls.first().expect("a cut");
        // Unchanged volume.
        assert!((0..9).all(|x| vol.get(x, 3, 3)));
        // The wall is the whole cross-section (a 6-connected bar is only cut by all 9).
        assert_eq!(wall.len(), 9, "{wall:?}");
    }
}
