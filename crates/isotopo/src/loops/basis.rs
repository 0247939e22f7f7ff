//! Does a set of closed curves span the surface's first homology? The check behind simplify's
//! promise that no loop shorter than tau is left.
//!
//! On a closed orientable surface of genus g, a loop is non-separating exactly when its class in
//! H1 (mod 2) is not zero, and the intersection form is non-degenerate: a non-zero class crosses
//! some member of any basis an odd number of times. So if closed curves c_1 … c_n span H1 and no
//! loop shorter than tau crosses any of them an odd number of times, no non-separating loop is
//! shorter than tau. Curves span H1 exactly when their matrix of crossing parities c_i · c_j has
//! rank 2g (the rank of the form restricted to their span is at most its dimension, and is 2g
//! on all of H1).

use crate::surface::search::{crossing_parity, FastMap, Graph};
use crate::surface::Vertex;

/// Rank (mod 2) of the matrix of crossing parities of the closed curves. Curves that share no
/// vertex do not cross, so the matrix is taken apart into groups of curves joined by shared
/// vertices, each eliminated on its own. `None` if a curve is not a closed walk on the surface.
pub fn crossing_rank(g: &mut Graph, curves: &[Vec<Vertex>]) -> Option<usize> {
    let n = curves.len();
    // Curves through each vertex.
    let mut through: FastMap<u64, Vec<u32>> = FastMap::default();
    for (i, c) in curves.iter().enumerate() {
        for v in c {
            let list = through.entry(v.key()).or_default();
            if list.last() != Some(&(i as u32)) {
                list.push(i as u32);
            }
        }
    }
    // Neighbours (curves sharing a vertex), and the groups they make.
    let mut touching: Vec<Vec<u32>> = vec![Vec::new(); n];
    let mut group = crate::unionfind::UnionFind::new(n);
    for list in through.values() {
        for &a in list {
            for &b in list {
                if a < b {
                    touching[a as usize].push(b);
                    group.union(a, b);
                }
            }
        }
    }
    for t in &mut touching {
        t.sort_unstable();
        t.dedup();
    }
    let mut members: FastMap<u32, Vec<usize>> = FastMap::default();
    for i in 0..n {
        members.entry(group.find(i as u32)).or_default().push(i);
    }
    let mut rank = 0;
    for list in members.values() {
        let pos: FastMap<usize, usize> = list.iter().enumerate().map(|(k, &i)| (i, k)).collect();
        let words = list.len().div_ceil(64);
        let mut rows = vec![vec![0u64; words]; list.len()];
        for (ka, &a) in list.iter().enumerate() {
            // A curve crosses itself an even number of times: the diagonal is zero.
            for &b in &touching[a] {
                if crossing_parity(g, &curves[a], &curves[b as usize])? == 1 {
                    let kb = pos[&(b as usize)];
                    rows[ka][kb / 64] |= 1 << (kb % 64);
                    rows[kb][ka / 64] |= 1 << (ka % 64);
                }
            }
        }
        rank += rank_mod2(&mut rows);
    }
    Some(rank)
}

/// Rank over the integers mod 2 of the rows (bit sets), by elimination in place.
fn rank_mod2(rows: &mut [Vec<u64>]) -> usize {
    let bits = rows.first().map_or(0, |r| r.len() * 64);
    let mut rank = 0;
    for col in 0..bits {
        let (w, b) = (col / 64, 1u64 << (col % 64));
        let Some(p) = (rank..rows.len()).find(|&r| rows[r][w] & b != 0) else {
            continue;
        };
        rows.swap(rank, p);
        let pivot = rows[rank].clone();
        for (r, row) in rows.iter_mut().enumerate() {
            if r != rank && row[w] & b != 0 {
                row.iter_mut().zip(&pivot).for_each(|(x, y)| *x ^= y);
            }
        }
        rank += 1;
    }
    rank
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rank_of_small_matrices() {
        let mut m = vec![vec![0b01u64], vec![0b10u64]];
        assert_eq!(rank_mod2(&mut m), 2);
        let mut m = vec![vec![0b11u64], vec![0b11u64]];
        assert_eq!(rank_mod2(&mut m), 1);
        let mut m: Vec<Vec<u64>> = vec![vec![0], vec![0]];
        assert_eq!(rank_mod2(&mut m), 0);
        // Three rows, the third the sum of the first two.
        let mut m = vec![vec![0b011u64], vec![0b110u64], vec![0b101u64]];
        assert_eq!(rank_mod2(&mut m), 2);
    }
}
