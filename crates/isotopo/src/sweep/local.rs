//! Handles of a small piece of surface, found directly: homology generators α from a
//! tree–cotree decomposition, and for each the shortest loop β crossing it once (and every
//! earlier α an even number of times, so the handles are independent).
//!
//! The sweep uses this where the orthogonal sweep of a mini-volume leaves a handle inside one of
//! its slices (small handles whose loops run through the caps, or the tunnel inside one cube).
//! Such a ribbon of the mini-volume is small, so the direct search is cheap.

use crate::surface::search::{key, odd_loop_with_parities, FastMap, Graph, Region};
use crate::surface::{Around, PieceRef, Vertex};
use crate::unionfind::UnionFind;
use std::collections::VecDeque;

/// `h` handles of the surface region `region`, whose crossing points are `vertices` (a piece of
/// surface with boundary). Each handle is (α, β): β crosses α an odd number of times and every
/// earlier α an even number, so the matrix of crossings α_i·β_j is triangular with ones on the
/// diagonal: the handles are independent.
pub fn handles(
    g: &mut Graph,
    vertices: &[Vertex],
    region: &dyn Region,
    h: usize,
) -> Option<Vec<(Vec<Vertex>, Vec<Vertex>)>> {
    let cycles = generators(g, vertices, region)?;
    let mut out: Vec<(Vec<Vertex>, Vec<Vertex>)> = Vec::new();
    for cycle in cycles {
        if out.len() == h {
            break;
        }
        let earlier: Vec<&[Vertex]> = out.iter().map(|(a, _)| a.as_slice()).collect();
        if let Some(beta) = odd_loop_with_parities(g, &cycle, &earlier, region, usize::MAX).found {
            out.push((cycle, beta));
        }
    }
    (out.len() == h).then_some(out)
}

/// Is the edge to neighbour `k` usable in the region (a piece of the region on either side)?
#[inline]
fn usable(region: &dyn Region, a: &Around, k: usize) -> bool {
    let (l, r) = a.sides(k);
    region.allows(&l) || region.allows(&r)
}

/// Generators of the first homology of the region with its boundary curves capped, by a
/// tree–cotree decomposition: a breadth-first spanning forest T of the vertices, a spanning
/// forest C of the faces (pieces, and one cap per boundary curve) across edges not in T; each
/// edge in neither closes one generator with its path in T. Shortest first.
pub(crate) fn generators(
    g: &mut Graph,
    vertices: &[Vertex],
    region: &dyn Region,
) -> Option<Vec<Vec<Vertex>>> {
    let mut tree: FastMap<u64, (u32, u64)> = FastMap::default(); // key -> (depth, parent key)
    let mut vert: FastMap<u64, Vertex> = FastMap::default();
    // Every usable edge once: (v, w, left face, right face).
    let mut edges: Vec<(Vertex, Vertex, PieceRef, PieceRef)> = Vec::new();
    for &root in vertices {
        let kr = key(root);
        if tree.contains_key(&kr) {
            continue;
        }
        let a = g.around(root)?;
        if !(0..a.n()).any(|k| usable(region, &a, k)) {
            continue;
        }
        tree.insert(kr, (0, u64::MAX));
        vert.insert(kr, root);
        let mut queue = VecDeque::from([root]);
        while let Some(v) = queue.pop_front() {
            let a = g.around(v)?;
            let (kv, d) = (key(v), tree[&key(v)].0);
            for k in 0..a.n() {
                if !usable(region, &a, k) {
                    continue;
                }
                let w = a.nbr(k);
                let kw = key(w);
                if kv < kw {
                    let (l, r) = a.sides(k);
                    edges.push((v, w, l, r));
                }
                if let std::collections::hash_map::Entry::Vacant(e) = tree.entry(kw) {
                    e.insert((d + 1, kv));
                    vert.insert(kw, w);
                    queue.push_back(w);
                }
            }
        }
    }
    // Faces: the region's pieces, then one cap per boundary curve (boundary edges joined at
    // their ends).
    let mut face: FastMap<PieceRef, u32> = FastMap::default();
    for &(_, _, l, r) in &edges {
        for p in [l, r] {
            if region.allows(&p) {
                let n = face.len() as u32;
                face.entry(p).or_insert(n);
            }
        }
    }
    let vid: FastMap<u64, u32> = vert
        .keys()
        .enumerate()
        .map(|(i, &k)| (k, i as u32))
        .collect();
    let mut boundary = UnionFind::new(vid.len());
    for &(v, w, l, r) in &edges {
        if !(region.allows(&l) && region.allows(&r)) {
            boundary.union(vid[&key(v)], vid[&key(w)]);
        }
    }
    let caps = face.len() as u32;
    let face_of = |p: PieceRef, v: Vertex, boundary: &mut UnionFind| -> u32 {
        if region.allows(&p) {
            face[&p]
        } else {
            caps + boundary.find(vid[&key(v)])
        }
    };
    let mut dual = UnionFind::new(face.len() + vid.len());
    let mut out = Vec::new();
    for &(v, w, l, r) in &edges {
        let (kv, kw) = (key(v), key(w));
        if tree[&kw].1 == kv || tree[&kv].1 == kw {
            continue; // in T
        }
        let (fl, fr) = (face_of(l, v, &mut boundary), face_of(r, v, &mut boundary));
        if !dual.union(fl, fr) {
            out.push(tree_cycle(&tree, &vert, v, w));
        }
    }
    out.sort_by_key(|c| c.len());
    Some(out)
}

/// The cycle made by the tree paths from `a` and `b` to their lowest common ancestor, closed by
/// the edge from `b` back to `a`.
fn tree_cycle(
    tree: &FastMap<u64, (u32, u64)>,
    vert: &FastMap<u64, Vertex>,
    a: Vertex,
    b: Vertex,
) -> Vec<Vertex> {
    let (mut x, mut y) = (key(a), key(b));
    let mut left = vec![x];
    let mut right = vec![y];
    while x != y {
        if tree[&x].0 >= tree[&y].0 {
            x = tree[&x].1;
            left.push(x);
        } else {
            y = tree[&y].1;
            right.push(y);
        }
    }
    right.pop(); // the ancestor, already at the end of `left`
    right.reverse();
    left.into_iter().chain(right).map(|k| vert[&k]).collect()
}
