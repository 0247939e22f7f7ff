//! Where the isosurface crosses the grid, for lengths in millimetres that follow the surface.
//!
//! The surface graph's vertices are grid edges; for lengths in voxel edges that is all a loop
//! needs. For lengths in millimetres each vertex sits where the linear interpolant of the two
//! samples reaches the isovalue (as the mesh's vertices do), mapped through the file's affine
//! (spacing and direction). The fractions along the crossing edges are read once, with the
//! samples, and kept compactly: two bytes each, per plane sorted by edge.
//!
//! ```text
//!    a = 10 ---------x------ b = 30      iso 15: x at t = (15 - 10) / (30 - 10) = 0.25
//!                    t
//! ```

use crate::topology::mask::{Classifier, PlaneMask};
use crate::topology::values::crossing;
use crate::volume::Samples;

/// The fractions along the crossing edges of a volume whose two samples are both in the volume
/// (edges to the padding cross at their middle).
#[derive(Clone, Debug, Default)]
pub struct EdgeFractions {
    nx: usize,
    /// Per plane z: the edges whose lower end lies in it (x and y edges in the plane, z edges to
    /// the plane above), keyed `axis << 60 | y · nx + x`, sorted, with their fractions (/ 65535).
    planes: Vec<(Vec<u64>, Vec<u16>)>,
}

impl EdgeFractions {
    /// No fractions yet, for a volume of `dims` samples.
    pub fn new(dims: [usize; 3]) -> EdgeFractions {
        EdgeFractions {
            nx: dims[0],
            planes: vec![(Vec::new(), Vec::new()); dims[2]],
        }
    }

    /// Records the crossings of plane `z` (`values`, classified as `mask`): its x and y edges,
    /// and the z edges from the plane below (`below`, the plane z - 1, if any).
    pub fn add_plane(
        &mut self,
        z: usize,
        values: &Samples,
        mask: &PlaneMask,
        below: Option<(&Samples, &PlaneMask)>,
        classifier: &Classifier,
    ) {
        let (nx, ny) = (mask.nx, mask.ny);
        let value =
            |s: &Samples, x: usize, y: usize| classifier.scaling.apply(s.get_f64(y * nx + x));
        let iso = classifier.iso;
        let fraction = |a: f64, b: f64| {
            let mut c = [f64::NAN; 8];
            (c[0], c[1]) = (a, b);
            (crossing(&c, 0, iso) * 65535.0).round() as u16
        };
        let mut here: Vec<(u64, u16)> = Vec::new();
        for y in 0..ny {
            for x in 0..nx {
                let inside = mask.get(x as isize, y as isize);
                let key = (y * nx + x) as u64;
                let v = value(values, x, y);
                if x + 1 < nx && mask.get(x as isize + 1, y as isize) != inside {
                    here.push((key, fraction(v, value(values, x + 1, y))));
                }
                if y + 1 < ny && mask.get(x as isize, y as isize + 1) != inside {
                    here.push((1 << 60 | key, fraction(v, value(values, x, y + 1))));
                }
            }
        }
        self.store(z, here, 0..2);
        if let (Some((bv, bm)), Some(zb)) = (below, z.checked_sub(1)) {
            let mut down: Vec<(u64, u16)> = Vec::new();
            for y in 0..ny {
                for x in 0..nx {
                    if bm.get(x as isize, y as isize) != mask.get(x as isize, y as isize) {
                        let t = fraction(value(bv, x, y), value(values, x, y));
                        down.push((2 << 60 | (y * nx + x) as u64, t));
                    }
                }
            }
            self.store(zb, down, 2..3);
        }
    }

    /// Merges the edges of the given axes into plane `z`'s list, keeping it sorted.
    fn store(&mut self, z: usize, mut edges: Vec<(u64, u16)>, axes: std::ops::Range<u64>) {
        let (keys, t) = &mut self.planes[z];
        let old: Vec<(u64, u16)> = keys
            .iter()
            .copied()
            .zip(t.iter().copied())
            .filter(|(k, _)| !axes.contains(&(k >> 60)))
            .collect();
        edges.extend(old);
        edges.sort_unstable_by_key(|e| e.0);
        (*keys, *t) = edges.into_iter().unzip();
    }

    /// Fraction along the edge from `p` to `p + e[axis]` (original voxel coordinates) where the
    /// surface crosses it: recorded, else the middle (edges to the padding, and edges that a
    /// closure made cross).
    pub fn get(&self, p: [i64; 3], axis: u8) -> f64 {
        let inside = p[0] >= 0 && p[1] >= 0 && p[2] >= 0 && (p[0] as usize) < self.nx;
        let plane = inside.then(|| self.planes.get(p[2] as usize)).flatten();
        let Some((keys, t)) = plane else {
            return 0.5;
        };
        let key = (axis as u64) << 60 | (p[1] as u64 * self.nx as u64 + p[0] as u64);
        match keys.binary_search(&key) {
            Ok(i) => t[i] as f64 / 65535.0,
            Err(_) => 0.5,
        }
    }

    /// Crossing edges recorded.
    pub fn len(&self) -> usize {
        self.planes.iter().map(|p| p.0.len()).sum()
    }

    /// Whether no fraction was recorded.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::topology::mask::Inside;
    use crate::volume::{DType, Scaling};

    #[test]
    fn fractions_of_a_ramp() {
        // Values x + 10 y + 100 z on a 4×3×2 grid, iso 12.5.
        let (nx, ny, nz) = (4usize, 3usize, 2usize);
        let c = Classifier {
            iso: 12.5,
            inside: Inside::Above,
            scaling: Scaling::IDENTITY,
        };
        let mut f = EdgeFractions::new([nx, ny, nz]);
        let mut prev: Option<(Samples, PlaneMask)> = None;
        for z in 0..nz {
            let mut s = Samples::zeros(DType::F32, nx * ny);
            for y in 0..ny {
                for x in 0..nx {
                    s.set_f64(y * nx + x, (x + 10 * y + 100 * z) as f64);
                }
            }
            let mut m = PlaneMask::empty(nx, ny);
            m.fill(&s, &c);
            f.add_plane(z, &s, &m, prev.as_ref().map(|(a, b)| (a, b)), &c);
            prev = Some((s, m));
        }
        // y-edges from y = 0 to 1 at x = 2 (values 2 -> 12: not crossing), x = 3 (3 -> 13).
        assert!((f.get([3, 0, 0], 1) - 0.95).abs() < 0.01);
        // z-edges: 2 -> 102 at (2, 0): crossing at t = 10.5 / 100.
        assert!((f.get([2, 0, 0], 2) - 0.105).abs() < 0.01);
        // An edge that does not cross, and one to the padding: the middle.
        assert_eq!(f.get([0, 0, 1], 0), 0.5);
        assert_eq!(f.get([-1, 0, 0], 0), 0.5);
    }
}
