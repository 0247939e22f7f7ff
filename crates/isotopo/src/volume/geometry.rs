//! Voxel-to-world geometry.

/// Affine map from voxel indices `(i, j, k)` to world millimetres: `world = M·(i, j, k) + t`,
/// stored as the top three rows of the 4×4 matrix (`m[r] = [M[r][0], M[r][1], M[r][2], t[r]]`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Affine {
    /// Rows of `[M | t]`: `m[r][c]` for `c < 3` is `M[r][c]`, `m[r][3]` is `t[r]` (millimetres).
    pub m: [[f64; 4]; 3],
}

impl Affine {
    /// Voxel index = world millimetres: unit spacing along x, y, z, voxel (0,0,0) at the origin.
    pub const IDENTITY: Affine = Affine {
        m: [
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
        ],
    };

    /// Axis-aligned voxels of the given size with voxel (0,0,0) at `origin`.
    pub fn from_spacing(spacing: [f64; 3], origin: [f64; 3]) -> Affine {
        let mut a = Affine::IDENTITY;
        for r in 0..3 {
            a.m[r][r] = spacing[r];
            a.m[r][3] = origin[r];
        }
        a
    }

    /// From a direction matrix whose *columns* are the unit directions of i, j, k, the spacing,
    /// and the origin.
    pub fn from_parts(direction: [[f64; 3]; 3], spacing: [f64; 3], origin: [f64; 3]) -> Affine {
        let mut a = Affine::IDENTITY;
        for r in 0..3 {
            for c in 0..3 {
                a.m[r][c] = direction[r][c] * spacing[c];
            }
            a.m[r][3] = origin[r];
        }
        a
    }

    /// World position of a (possibly fractional) voxel index.
    #[inline]
    pub fn apply(&self, p: [f64; 3]) -> [f64; 3] {
        let m = &self.m;
        [
            m[0][0] * p[0] + m[0][1] * p[1] + m[0][2] * p[2] + m[0][3],
            m[1][0] * p[0] + m[1][1] * p[1] + m[1][2] * p[2] + m[1][3],
            m[2][0] * p[0] + m[2][1] * p[1] + m[2][2] * p[2] + m[2][3],
        ]
    }

    /// The linear part applied to a vector (no translation).
    #[inline]
    pub fn apply_vector(&self, v: [f64; 3]) -> [f64; 3] {
        let m = &self.m;
        [
            m[0][0] * v[0] + m[0][1] * v[1] + m[0][2] * v[2],
            m[1][0] * v[0] + m[1][1] * v[1] + m[1][2] * v[2],
            m[2][0] * v[0] + m[2][1] * v[1] + m[2][2] * v[2],
        ]
    }

    /// Length of each column: the voxel size along i, j, k in millimetres.
    pub fn spacing(&self) -> [f64; 3] {
        let mut s = [0.0; 3];
        for (c, sc) in s.iter_mut().enumerate() {
            *sc = (0..3)
                .map(|r| self.m[r][c] * self.m[r][c])
                .sum::<f64>()
                .sqrt();
        }
        s
    }

    /// Unit column directions (a column of zero length stays zero).
    pub fn direction(&self) -> [[f64; 3]; 3] {
        let s = self.spacing();
        let mut d = [[0.0; 3]; 3];
        for r in 0..3 {
            for c in 0..3 {
                d[r][c] = if s[c] > 0.0 { self.m[r][c] / s[c] } else { 0.0 };
            }
        }
        d
    }

    /// World position of voxel (0,0,0) in millimetres: the translation `t`.
    pub fn origin(&self) -> [f64; 3] {
        [self.m[0][3], self.m[1][3], self.m[2][3]]
    }

    /// Determinant of the linear part; negative for a left-handed voxel grid.
    pub fn determinant(&self) -> f64 {
        let m = &self.m;
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    }

    /// Flips world x and y: RAS+ ↔ LPS+ (the same map both ways).
    pub fn flip_xy(&self) -> Affine {
        let mut a = *self;
        for c in 0..4 {
            a.m[0][c] = -a.m[0][c];
            a.m[1][c] = -a.m[1][c];
        }
        a
    }

    /// True when every entry is finite and the linear part is invertible.
    pub fn is_valid(&self) -> bool {
        self.m.iter().flatten().all(|v| v.is_finite()) && self.determinant().abs() > 1e-12
    }

    /// Largest absolute difference between entries (for tests and round trips).
    pub fn max_diff(&self, other: &Affine) -> f64 {
        let mut d: f64 = 0.0;
        for r in 0..3 {
            for c in 0..4 {
                d = d.max((self.m[r][c] - other.m[r][c]).abs());
            }
        }
        d
    }
}

/// Inclusive bounds in voxel indices.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct BBox {
    /// Smallest x, y, z voxel index in the box.
    pub min: [i64; 3],
    /// Largest x, y, z voxel index in the box (inclusive).
    pub max: [i64; 3],
}

impl BBox {
    /// The box containing nothing (`min` > `max`), to grow with [`BBox::include`].
    pub const EMPTY: BBox = BBox {
        min: [i64::MAX; 3],
        max: [i64::MIN; 3],
    };
    /// Grows the box to contain voxel `p`.
    pub fn include(&mut self, p: [i64; 3]) {
        for a in 0..3 {
            self.min[a] = self.min[a].min(p[a]);
            self.max[a] = self.max[a].max(p[a]);
        }
    }
    /// Grows the box to contain `o` by including its two corners (`o` must not be empty).
    pub fn union(&mut self, o: &BBox) {
        self.include(o.min);
        self.include(o.max);
    }
    /// The centre of the box read as one of cubes by their lower corners (as a handle's
    /// cycle box is): the cubes `min..=max` span `min..=max + 1` along each axis.
    pub fn cube_centre(&self) -> [f64; 3] {
        std::array::from_fn(|k| (self.min[k] + self.max[k] + 1) as f64 / 2.0)
    }
    /// Corners in millimetres (the box of the transformed voxel box).
    pub fn to_mm(&self, affine: &Affine) -> [[f64; 3]; 2] {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for c in 0..8 {
            let p = [
                if c & 1 == 0 { self.min[0] } else { self.max[0] } as f64,
                if c & 2 == 0 { self.min[1] } else { self.max[1] } as f64,
                if c & 4 == 0 { self.min[2] } else { self.max[2] } as f64,
            ];
            let w = affine.apply(p);
            for a in 0..3 {
                lo[a] = lo[a].min(w[a]);
                hi[a] = hi[a].max(w[a]);
            }
        }
        [lo, hi]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A box of cubes is centred between its first cube's lower corner and its last cube's
    /// upper one: one cube at (2, 3, 4) has its centre at (2.5, 3.5, 4.5); cubes 0 to 3 along x
    /// span 0..4, centre 2.
    #[test]
    fn a_box_of_cubes_is_centred_on_their_span() {
        let mut one = BBox::EMPTY;
        one.include([2, 3, 4]);
        assert_eq!(one.cube_centre(), [2.5, 3.5, 4.5]);
        let mut row = BBox::EMPTY;
        row.include([0, -1, 7]);
        row.include([3, -1, 7]);
        assert_eq!(row.cube_centre(), [2.0, -0.5, 7.5]);
    }
}
