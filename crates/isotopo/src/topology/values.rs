//! Sample values around a cube, and where the isosurface crosses each cube edge.

use super::cases::EDGE_CORNERS;
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

/// Position of the crossing on edge `e`, relative to the cube's lower corner, in voxel units.
#[inline]
pub fn edge_point(values: &[f64; 8], e: u8, iso: f64) -> [f64; 3] {
    let (a, b) = EDGE_CORNERS[e as usize];
    let t = crossing(values, e, iso);
    let pa = [(a & 1) as f64, ((a >> 1) & 1) as f64, ((a >> 2) & 1) as f64];
    let pb = [(b & 1) as f64, ((b >> 1) & 1) as f64, ((b >> 2) & 1) as f64];
    [
        pa[0] + t * (pb[0] - pa[0]),
        pa[1] + t * (pb[1] - pa[1]),
        pa[2] + t * (pb[2] - pa[2]),
    ]
}
