//! The meshes a report shows, gathered in one pass over the slices (out of core like the rest):
//! the isosurface in each brick round the handles shown in 3D (before and, for `simplify`,
//! after the edits), and the whole surface coarsened for the overview.
//!
//! ```text
//!   volume ──slice z──▶ every brick that spans z copies its rows (samples of the bricks)
//!                   └─▶ the coarse grid adds the slice's samples (f×f×f blocks, averaged)
//! ```
//!
//! A brick is meshed with the same cube cases as the genus pass. Beyond the box the mesher sees
//! outside, which closes the surface with caps at its sides; the triangles of those caps are
//! dropped, so what shows is the surface as it is, cut open at the box.

use super::blob::Blob;
use crate::error::Result;
use crate::mesh;
use crate::progress::NoProgress;
use crate::topology::SurfaceOptions;
use crate::volume::{DType, InMemoryVolume, Samples, Scaling, VolumeInfo};

/// A box of samples (voxel indices `min .. min + dims`), as values (the header's scaling applied).
pub(crate) struct Crop {
    pub min: [usize; 3],
    pub dims: [usize; 3],
    pub before: Vec<f32>,
    pub after: Option<Vec<f32>>,
}

impl Crop {
    pub fn new(min: [usize; 3], dims: [usize; 3], with_after: bool) -> Crop {
        let n = dims.iter().product();
        Crop {
            min,
            dims,
            before: vec![0.0; n],
            after: with_after.then(|| vec![0.0; n]),
        }
    }

    fn spans(&self, z: usize) -> bool {
        z >= self.min[2] && z < self.min[2] + self.dims[2]
    }

    /// Copies this box's rows of slice `z` (`nx` samples a row).
    fn take(&mut self, z: usize, nx: usize, before: &[f32], after: Option<&[f32]>) {
        let [dx, dy, _] = self.dims;
        let base = (z - self.min[2]) * dx * dy;
        for y in 0..dy {
            let from = (self.min[1] + y) * nx + self.min[0];
            let to = base + y * dx;
            self.before[to..to + dx].copy_from_slice(&before[from..from + dx]);
            if let (Some(out), Some(src)) = (&mut self.after, after) {
                out[to..to + dx].copy_from_slice(&src[from..from + dx]);
            }
        }
    }
}

/// The whole volume averaged over blocks of `factor`³ samples.
pub(crate) struct Coarse {
    pub factor: usize,
    pub dims: [usize; 3],
    sums: [Vec<f32>; 2],
    counts: Vec<u32>,
    with_after: bool,
}

impl Coarse {
    /// The coarsening of a volume of `dims` whose largest side is at most `side` samples.
    pub fn new(dims: [usize; 3], side: usize, with_after: bool) -> Coarse {
        let largest = dims.iter().copied().max().unwrap_or(1);
        let factor = largest.div_ceil(side.max(2)).max(1);
        let cd = dims.map(|d| d.div_ceil(factor));
        let n = cd.iter().product();
        Coarse {
            factor,
            dims: cd,
            sums: [vec![0.0; n], if with_after { vec![0.0; n] } else { vec![] }],
            counts: vec![0; n],
            with_after,
        }
    }

    fn take(&mut self, z: usize, nx: usize, before: &[f32], after: Option<&[f32]>) {
        let f = self.factor;
        let [cx, cy, _] = self.dims;
        let plane = (z / f) * cx * cy;
        for (i, &v) in before.iter().enumerate() {
            let (x, y) = (i % nx, i / nx);
            let c = plane + (y / f) * cx + x / f;
            self.sums[0][c] += v;
            self.counts[c] += 1;
            if let Some(a) = after {
                self.sums[1][c] += a[i];
            }
        }
    }

    /// Twice as coarse: blocks of 2×2×2 of these merged.
    pub fn halve(&mut self) {
        let [cx, cy, cz] = self.dims;
        let nd = self.dims.map(|d| d.div_ceil(2));
        let n = nd.iter().product();
        let mut sums = [vec![0.0; n], vec![0.0; if self.with_after { n } else { 0 }]];
        let mut counts = vec![0; n];
        for z in 0..cz {
            for y in 0..cy {
                for x in 0..cx {
                    let from = (z * cy + y) * cx + x;
                    let to = ((z / 2) * nd[1] + y / 2) * nd[0] + x / 2;
                    counts[to] += self.counts[from];
                    for w in 0..if self.with_after { 2 } else { 1 } {
                        sums[w][to] += self.sums[w][from];
                    }
                }
            }
        }
        self.sums = sums;
        self.counts = counts;
        self.dims = nd;
        self.factor *= 2;
    }

    /// The averages, before (`which` 0) or after (1).
    fn values(&self, which: usize) -> Vec<f32> {
        self.sums[which]
            .iter()
            .zip(&self.counts)
            .map(|(&s, &n)| s / n.max(1) as f32)
            .collect()
    }
}

/// Everything one pass over the slices fills.
pub(crate) struct Gather {
    pub dims: [usize; 3],
    pub crops: Vec<Crop>,
    pub coarse: Coarse,
    scaling: Scaling,
    row: [Vec<f32>; 2],
}

impl Gather {
    pub fn new(dims: [usize; 3], crops: Vec<Crop>, coarse: Coarse, scaling: Scaling) -> Gather {
        Gather {
            dims,
            crops,
            coarse,
            scaling,
            row: [Vec::new(), Vec::new()],
        }
    }

    /// Takes slice `z` of the input, and of the edited volume when there is one.
    pub fn add_slice(&mut self, z: usize, before: &Samples, after: Option<&Samples>) {
        let nx = self.dims[0];
        let [b, a] = &mut self.row;
        values(before, self.scaling, b);
        if let Some(s) = after {
            values(s, self.scaling, a);
        }
        let after = after.map(|_| a.as_slice());
        for c in self.crops.iter_mut().filter(|c| c.spans(z)) {
            c.take(z, nx, b, after);
        }
        self.coarse
            .take(z, nx, b, after.filter(|_| self.coarse.with_after));
    }
}

fn values(s: &Samples, scaling: Scaling, out: &mut Vec<f32>) {
    out.clear();
    out.extend((0..s.len()).map(|i| scaling.apply(s.get_f64(i)) as f32));
}

/// A mesh in the report's binary blob (delta-coded, see [`Blob::push_mesh`]): vertex `k` is at
/// voxel coordinates `origin + scale · q[k]` (`q` three u16 per vertex).
#[derive(serde::Serialize)]
pub(crate) struct MeshRef {
    /// Byte offset of the vertices, and their count.
    pub v: [usize; 2],
    /// Byte offset of the triangles, and their count.
    pub t: [usize; 2],
    /// Bytes per index: 2, or 4 above 65,536 vertices.
    pub w: usize,
    pub origin: [f32; 3],
    pub scale: f32,
    /// Sums (wrapping, u32) of the vertex codes and of the indices: the page checks what it
    /// decodes against them and says so if the report is damaged.
    pub sum: [u32; 2],
}

/// Which sides of a box (low, high along x, y, z) lie inside the volume: there the mesh is cut
/// open; at the volume's own sides the surface closes, as everywhere in isotopo.
pub(crate) type OpenSides = [[bool; 2]; 3];

impl Crop {
    /// The sides of this box that lie inside a volume of `dims`.
    pub fn open_sides(&self, dims: [usize; 3]) -> OpenSides {
        [0, 1, 2].map(|a| [self.min[a] > 0, self.min[a] + self.dims[a] < dims[a]])
    }
}

/// The isosurface of `values` (a box of `dims` samples whose first sample is at voxel
/// `offset`, samples `step` voxels apart), cut open at its `open` sides, into `blob`.
pub(crate) fn mesh_box(
    values: &[f32],
    dims: [usize; 3],
    offset: [f32; 3],
    step: f32,
    open: OpenSides,
    opts: &SurfaceOptions,
    blob: &mut Blob,
) -> Result<MeshRef> {
    let [nx, ny, nz] = dims;
    let slices = values
        .chunks(nx * ny)
        .map(|c| Samples::F32(c.to_vec()))
        .collect();
    let mut info = VolumeInfo::synthetic(dims, DType::F32);
    info.path = "<report box>".into();
    let mut vol = InMemoryVolume::new(info, slices);
    let m = mesh::extract(&mut vol, opts, false, &NoProgress)?;
    // Caps: triangles with a vertex beyond the box's outer samples, on an open side.
    let limit = [nx, ny, nz].map(|d| d as f32 - 1.0);
    let inside = |p: &[f32; 3]| {
        let beyond = |a: usize| (open[a][0] && p[a] < 0.0) || (open[a][1] && p[a] > limit[a]);
        !(0..3).any(beyond)
    };
    let mut keep = vec![u32::MAX; m.vertices.len()];
    let mut vertices = Vec::new();
    let mut triangles = Vec::new();
    for t in &m.triangles {
        if !t.iter().all(|&k| inside(&m.vertices[k as usize])) {
            continue;
        }
        let mut out = [0u32; 3];
        for (o, &k) in out.iter_mut().zip(t) {
            if keep[k as usize] == u32::MAX {
                keep[k as usize] = vertices.len() as u32;
                vertices.push(m.vertices[k as usize]);
            }
            *o = keep[k as usize];
        }
        triangles.push(out);
    }
    Ok(encode(&vertices, &triangles, offset, step, blob))
}

/// Quantizes the vertices (box coordinates) to u16 over the box and appends both arrays.
fn encode(
    vertices: &[[f32; 3]],
    triangles: &[[u32; 3]],
    offset: [f32; 3],
    step: f32,
    blob: &mut Blob,
) -> MeshRef {
    let mut lo = [f32::MAX; 3];
    let mut hi = [f32::MIN; 3];
    for p in vertices {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    let range = (0..3).map(|a| hi[a] - lo[a]).fold(0.0f32, f32::max);
    let q = if range > 0.0 { 65535.0 / range } else { 1.0 };
    let codes: Vec<u16> = vertices
        .iter()
        .flat_map(|p| (0..3).map(move |a| ((p[a] - lo[a]) * q).round() as u16))
        .collect();
    let flat: Vec<u32> = triangles.iter().flatten().copied().collect();
    let (v, t, w) = blob.push_mesh(&codes, &flat);
    let sum_codes = codes.iter().fold(0u32, |s, &c| s.wrapping_add(c as u32));
    let sum_indices = flat.iter().fold(0u32, |s, &i| s.wrapping_add(i));
    let lo = if vertices.is_empty() { [0.0; 3] } else { lo };
    MeshRef {
        v: [v, vertices.len()],
        t: [t, triangles.len()],
        w,
        origin: [0, 1, 2].map(|a| offset[a] + lo[a] * step),
        scale: step / q,
        sum: [sum_codes, sum_indices],
    }
}

/// The coarse surface (before: `which` 0, after: 1) into `blob`.
pub(crate) fn mesh_coarse(
    coarse: &Coarse,
    which: usize,
    opts: &SurfaceOptions,
    blob: &mut Blob,
) -> Result<MeshRef> {
    let f = coarse.factor as f32;
    // A block's average sits at its centre, (f - 1) / 2 voxels from its first sample.
    let offset = [(f - 1.0) / 2.0; 3];
    let closed = [[false; 2]; 3];
    mesh_box(
        &coarse.values(which),
        coarse.dims,
        offset,
        f,
        closed,
        opts,
        blob,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A ball of radius 5 in a 16³ volume: its box round the centre is cut open (no caps), the
    /// whole-box mesh is closed (every edge in two triangles).
    #[test]
    fn a_box_is_cut_open_and_the_whole_is_closed() {
        let ball = |x: usize, y: usize, z: usize| {
            let d = |a: usize| a as f32 - 7.5;
            5.0 - (d(x).powi(2) + d(y).powi(2) + d(z).powi(2)).sqrt()
        };
        let dims = [16, 16, 16];
        let all: Vec<f32> = (0..16 * 16 * 16)
            .map(|i| ball(i % 16, (i / 16) % 16, i / 256))
            .collect();
        let mut blob = Blob::default();
        let opts = SurfaceOptions::default();
        let open = [[true; 2]; 3];
        let whole = mesh_box(&all, dims, [0.0; 3], 1.0, open, &opts, &mut blob).unwrap();
        assert!(whole.t[1] > 100);
        let edges = |t: &[u32]| {
            let mut count = std::collections::HashMap::new();
            for tri in t.chunks(3) {
                for k in 0..3 {
                    let (a, b) = (tri[k], tri[(k + 1) % 3]);
                    *count.entry((a.min(b), a.max(b))).or_insert(0) += 1;
                }
            }
            count
        };
        let tris = blob.mesh(whole.v[0], whole.v[1], whole.t[0], whole.t[1]).1;
        assert!(edges(&tris).values().all(|&n| n == 2), "whole ball closed");
        // The half z < 8: a bowl, open along its rim.
        let half: Vec<f32> = all[..16 * 16 * 8].to_vec();
        let bowl = mesh_box(&half, [16, 16, 8], [0.0; 3], 1.0, open, &opts, &mut blob).unwrap();
        let (codes, tris) = blob.mesh(bowl.v[0], bowl.v[1], bowl.t[0], bowl.t[1]);
        let e = edges(&tris);
        assert!(e.values().any(|&n| n == 1), "the bowl has a rim");
        assert!(bowl.t[1] < whole.t[1] && bowl.t[1] > whole.t[1] / 3);
        // No vertex beyond the box's last plane of samples (z = 7).
        let top = codes
            .chunks(3)
            .map(|c| bowl.origin[2] + bowl.scale * c[2] as f32)
            .fold(f32::MIN, f32::max);
        assert!(top <= 7.0 + 1e-3, "top {top}");
        // At the volume's own side (closed), the cap stays: the half ball is closed.
        let mut closed = open;
        closed[2][1] = false;
        let cup = mesh_box(&half, [16, 16, 8], [0.0; 3], 1.0, closed, &opts, &mut blob).unwrap();
        let tris = blob.mesh(cup.v[0], cup.v[1], cup.t[0], cup.t[1]).1;
        assert!(edges(&tris).values().all(|&n| n == 2), "closed half ball");
    }

    #[test]
    fn the_coarse_grid_averages_blocks() {
        let mut c = Coarse::new([5, 4, 3], 2, false);
        assert_eq!(c.factor, 3);
        assert_eq!(c.dims, [2, 2, 1]);
        for z in 0..3 {
            let slice: Vec<f32> = (0..20).map(|i| (i % 5) as f32).collect();
            c.take(z, 5, &slice, None);
        }
        // Block x 0..3 averages 0, 1, 2; block x 3..5 averages 3, 4.
        assert_eq!(c.values(0), vec![1.0, 3.5, 1.0, 3.5]);
        // Halved: one block of everything, weighted by the samples in each.
        c.halve();
        assert_eq!((c.factor, c.dims), (6, [1, 1, 1]));
        assert_eq!(c.values(0), vec![2.0]);
    }
}
