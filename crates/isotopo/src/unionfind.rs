//! Disjoint sets (union-find) with path halving and union by size.

#[derive(Clone, Debug, Default)]
pub struct UnionFind {
    parent: Vec<u32>,
    size: Vec<u32>,
}

impl UnionFind {
    pub fn new(n: usize) -> UnionFind {
        UnionFind {
            parent: (0..n as u32).collect(),
            size: vec![1; n],
        }
    }

    pub fn len(&self) -> usize {
        self.parent.len()
    }

    pub fn is_empty(&self) -> bool {
        self.parent.is_empty()
    }

    /// Adds a new singleton set and returns its element.
    pub fn push(&mut self) -> u32 {
        let i = self.parent.len() as u32;
        self.parent.push(i);
        self.size.push(1);
        i
    }

    pub fn clear(&mut self, n: usize) {
        self.parent.clear();
        self.parent.extend(0..n as u32);
        self.size.clear();
        self.size.resize(n, 1);
    }

    #[inline]
    pub fn find(&mut self, mut x: u32) -> u32 {
        while self.parent[x as usize] != x {
            let p = self.parent[x as usize];
            self.parent[x as usize] = self.parent[p as usize];
            x = self.parent[x as usize];
        }
        x
    }

    /// Joins the sets of `a` and `b`; returns false if they were already one set.
    #[inline]
    pub fn union(&mut self, a: u32, b: u32) -> bool {
        let (mut ra, mut rb) = (self.find(a), self.find(b));
        if ra == rb {
            return false;
        }
        if self.size[ra as usize] < self.size[rb as usize] {
            std::mem::swap(&mut ra, &mut rb);
        }
        self.parent[rb as usize] = ra;
        self.size[ra as usize] += self.size[rb as usize];
        true
    }

    /// Labels `0..k` for the sets, in order of each set's first element; returns (labels, k).
    pub fn labels(&mut self) -> (Vec<u32>, usize) {
        self.labels_of(0..self.parent.len() as u32)
    }

    /// Labels `0..k` for the sets of the given elements, in order of each set's first element
    /// among them: the label of each element, in their order, and k.
    pub fn labels_of(&mut self, elements: impl Iterator<Item = u32>) -> (Vec<u32>, usize) {
        let mut label = vec![u32::MAX; self.parent.len()];
        let mut out = Vec::with_capacity(elements.size_hint().0);
        let mut k = 0u32;
        for i in elements {
            let r = self.find(i) as usize;
            if label[r] == u32::MAX {
                label[r] = k;
                k += 1;
            }
            out.push(label[r]);
        }
        (out, k as usize)
    }
}
