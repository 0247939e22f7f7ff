//! Sample values around a cube, and where the isosurface crosses each cube edge.

use super::cases::{EDGE_AXIS, EDGE_CORNERS};
use crate::volume::{Samples, Scaling};

/// Read access to the values of the two planes of a slice (either may be a padding plane).
pub struct SliceValues<'a> {
    /// Raw samples of plane z (`nx·ny`, x fastest), or `None` for the padding plane z = -1.
    pub lower: Option<&'a Samples>,
    /// Raw samples of plane z + 1, or `None` for the padding plane z = nz.
    pub upper: Option<&'a Samples>,
    /// Samples along x (without padding).
    pub nx: usize,
    /// Samples along y (without padding).
    pub ny: usize,
    /// The header's scaling from raw samples to values.
    pub scaling: Scaling,
}

impl SliceValues<'_> {
    /// Values (after scaling) at the 8 corners of the cube at padded (i, j); NaN for padding.
    #[inline]
    pub fn corners(&self, i: u32, j: u32) -> [f64; 8] {
        let mut out = [f64::NAN; 8];
        for c in 0..8 {
            let x = i as isize - 1 + (c & 1) as isize;
            let y = j as isize - 1 + ((c >> 1) & 1) as isize;
            if x < 0 || y < 0 || x >= self.nx as isize || y >= self.ny as isize {
                continue;
            }
            let plane = if c & 4 == 0 { self.lower } else { self.upper };
            if let Some(p) = plane {
                out[c] = self
                    .scaling
                    .apply(p.get_f64(y as usize * self.nx + x as usize));
            }
        }
        out
    }
}

/// Fraction along edge `e` (from its lower corner) where the linear interpolant reaches `iso`.
/// Padding and NaN samples put the crossing at the middle. Kept inside [0.001, 0.999] so that
/// vertices never land exactly on samples (which would make degenerate triangles).
#[inline]
pub fn crossing(values: &[f64; 8], e: u8, iso: f64) -> f64 {
    let (a, b) = EDGE_CORNERS[e as usize];
    let (va, vb) = (values[a as usize], values[b as usize]);
    let t = (iso - va) / (vb - va);
    if t.is_finite() {
        t.clamp(0.001, 0.999)
    } else {
        0.5
    }
}

/// Lower corner of each edge and its direction (a unit vector along [`EDGE_AXIS`]), relative to
/// the cube's lower corner: corner `c` is at `(c & 1, c >> 1 & 1, c >> 2 & 1)`.
const EDGE_START_AND_DIRECTION: [[[f64; 3]; 2]; 12] = {
    let mut out = [[[0.0; 3]; 2]; 12];
    let mut e = 0;
    while e < 12 {
        let a = EDGE_CORNERS[e].0;
        out[e][0] = [(a & 1) as f64, (a >> 1 & 1) as f64, (a >> 2 & 1) as f64];
        out[e][1][EDGE_AXIS[e] as usize] = 1.0;
        e += 1;
    }
    out
};

/// Position of the crossing on edge `e`, relative to the cube's lower corner, in voxel units.
#[inline]
pub fn edge_point(values: &[f64; 8], e: u8, iso: f64) -> [f64; 3] {
    // A table, not the corners' bits: converting them to floats for every crossing was a
    // tenth of the areas' time. (Storing `t` into the start's axis instead made a narrow
    // store followed by a wide load, which the processor cannot forward: slower.)
    let [a, d] = EDGE_START_AND_DIRECTION[e as usize];
    let t = crossing(values, e, iso);
    [a[0] + t * d[0], a[1] + t * d[1], a[2] + t * d[2]]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Corner `c` of the unit cube, as a point.
    fn corner(c: u8) -> [f64; 3] {
        [(c & 1) as f64, (c >> 1 & 1) as f64, (c >> 2 & 1) as f64]
    }

    #[test]
    fn crossing_points_lie_on_their_edge_where_the_values_reach_the_isovalue() {
        for e in 0..12u8 {
            let (a, b) = EDGE_CORNERS[e as usize];
            let mut values = [0.0; 8];
            (values[a as usize], values[b as usize]) = (10.0, 20.0);
            let p = edge_point(&values, e, 13.0);
            let (pa, pb) = (corner(a), corner(b));
            for k in 0..3 {
                let want = pa[k] + 0.3 * (pb[k] - pa[k]);
                assert!((p[k] - want).abs() < 1e-12, "edge {e}: {p:?}");
            }
        }
    }
}
