//! Where the surface graph's vertices lie: in voxels and in millimetres, interpolated along
//! their edges (see [`crate::grid::EdgeFractions`]) or at the edges' midpoints.

use super::Vertex;
use crate::grid::{EdgeFractions, Frame};
use crate::volume::Affine;

/// Positions of the surface graph's vertices in millimetres: interpolated along their edges when
/// the fractions are known, else at the edges' midpoints.
#[derive(Clone, Copy)]
pub struct Geometry<'a> {
    /// Voxel to millimetre coordinates.
    pub affine: &'a Affine,
    pub(crate) fractions: Option<&'a EdgeFractions>,
}

impl Geometry<'_> {
    /// The crossing point of vertex `v` of a volume in `frame`, in original voxel coordinates.
    pub fn voxel_position(&self, frame: &Frame, v: Vertex) -> [f64; 3] {
        let start = frame.to_original_i(v.p);
        let axis = frame.uvw[v.axis as usize];
        let t = self.fractions.map_or(0.5, |f| f.get(start, axis as u8));
        let mut p = start.map(|c| c as f64);
        p[axis] += t;
        p
    }

    /// The crossing point of vertex `v` in world millimetres.
    pub fn position(&self, frame: &Frame, v: Vertex) -> [f64; 3] {
        self.affine.apply(self.voxel_position(frame, v))
    }

    /// Length in millimetres of the closed polyline through the loop's crossing points.
    pub fn loop_mm(&self, frame: &Frame, lp: &[Vertex]) -> f64 {
        let n = lp.len();
        let pts: Vec<[f64; 3]> = lp.iter().map(|&v| self.position(frame, v)).collect();
        (0..n)
            .map(|i| {
                let (a, b) = (pts[i], pts[(i + 1) % n]);
                ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
            })
            .sum()
    }
}

/// The mean of the points: the apex of a loop's spanning fan.
pub fn centroid(points: &[[f64; 3]]) -> [f64; 3] {
    let n = points.len() as f64;
    points.iter().fold([0.0; 3], |s, p| {
        [s[0] + p[0] / n, s[1] + p[1] / n, s[2] + p[2] / n]
    })
}
