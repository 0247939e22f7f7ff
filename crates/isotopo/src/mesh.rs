//! Mesh extraction with the same cube cases as the genus pass, so the mesh's Euler
//! characteristic is exactly `2·(b0 + b2) - 2·b1`.
//!
//! Vertices sit where the isosurface crosses grid edges (linear interpolation of the samples),
//! one per crossing edge, shared by every triangle around it. Vertex numbers come from ranks in
//! the bit masks: the crossing x-edges of a plane are the set bits of `row ^ (row >> 1)`, so the
//! k-th set bit is vertex k, with no hash map and nothing to clear between slices.
//!
//! ```text
//!   plane p:   x-edges (row j, columns i..i+1)   y-edges (rows j..j+1, column i)
//!   slice p:   z-edges between planes p and p+1
//! ```

use crate::error::{Error, Result};
use crate::progress::Progress;
use crate::topology::cases::cases;
use crate::topology::genus::SurfaceTracker;
use crate::topology::mask::PlaneMask;
use crate::topology::slice::SliceSurfels;
use crate::topology::values::{crossing, SliceValues};
use crate::topology::SurfaceOptions;
use crate::volume::{AtomicOutput, Compression, Samples, SliceReader, VolumeInfo};
use rayon::prelude::*;
use std::path::Path;

/// An indexed triangle mesh in world millimetres, triangles facing out of the solid.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    pub vertices: Vec<[f32; 3]>,
    pub triangles: Vec<[u32; 3]>,
}

/// Crossing edges of one bit-row set, with running counts for ranks.
#[derive(Default)]
struct EdgeSet {
    words: usize,
    bits: Vec<u64>,
    /// Set bits before each word.
    before: Vec<u32>,
    count: u32,
}

impl EdgeSet {
    fn finish(&mut self) {
        self.before.clear();
        let mut n = 0u32;
        for &w in &self.bits {
            self.before.push(n);
            n += w.count_ones();
        }
        self.count = n;
    }

    /// Rank of bit `i` of row `j` among all set bits (the bit must be set).
    #[inline]
    fn rank(&self, j: usize, i: usize) -> u32 {
        let w = j * self.words + i / 64;
        self.before[w] + (self.bits[w] & ((1u64 << (i % 64)) - 1)).count_ones()
    }

    fn for_each(&self, mut f: impl FnMut(usize, usize)) {
        for (w, &word) in self.bits.iter().enumerate() {
            let mut b = word;
            while b != 0 {
                let i = (w % self.words) * 64 + b.trailing_zeros() as usize;
                b &= b - 1;
                f(w / self.words, i);
            }
        }
    }
}

/// Crossing x- and y-edges of a plane (vertices shared by the slices below and above it).
struct PlaneEdges {
    x: EdgeSet,
    y: EdgeSet,
}

fn plane_edges(p: &PlaneMask) -> PlaneEdges {
    let w = p.words;
    let rows = p.ny + 2;
    let mut x = EdgeSet {
        words: w,
        bits: vec![0; w * rows],
        ..Default::default()
    };
    let mut y = EdgeSet {
        words: w,
        bits: vec![0; w * rows],
        ..Default::default()
    };
    for j in 0..rows {
        let r = p.row(j);
        for k in 0..w {
            let next = if k + 1 < w { r[k + 1] } else { 0 };
            x.bits[j * w + k] = r[k] ^ ((r[k] >> 1) | (next << 63));
            if j + 1 < rows {
                y.bits[j * w + k] = r[k] ^ p.row(j + 1)[k];
            }
        }
    }
    // Bits beyond the padded width would pair the last pad column with nothing.
    let width = p.nx + 2;
    for j in 0..rows {
        for i in width - 1..w * 64 {
            x.bits[j * w + i / 64] &= !(1u64 << (i % 64));
        }
    }
    x.finish();
    y.finish();
    PlaneEdges { x, y }
}

fn z_edges(lower: &PlaneMask, upper: &PlaneMask) -> EdgeSet {
    let mut z = EdgeSet {
        words: lower.words,
        bits: lower
            .bits
            .iter()
            .zip(&upper.bits)
            .map(|(a, b)| a ^ b)
            .collect(),
        ..Default::default()
    };
    z.finish();
    z
}

/// Vertex positions (voxel coordinates) of the crossings of a plane's edges.
fn plane_vertices(
    e: &PlaneEdges,
    values: Option<&Samples>,
    z: f64,
    nx: usize,
    ny: usize,
    opts: &SurfaceOptions,
    info: &VolumeInfo,
) -> Vec<[f64; 3]> {
    let mut out = Vec::with_capacity((e.x.count + e.y.count) as usize);
    let val = |i: isize, j: isize| -> f64 {
        let (x, y) = (i - 1, j - 1);
        match values {
            Some(v) if x >= 0 && y >= 0 && (x as usize) < nx && (y as usize) < ny => {
                info.scaling.apply(v.get_f64(y as usize * nx + x as usize))
            }
            _ => f64::NAN,
        }
    };
    let t_of = |a: f64, b: f64| {
        let mut c = [f64::NAN; 8];
        c[0] = a;
        c[1] = b;
        crossing(&c, 0, opts.iso)
    };
    e.x.for_each(|j, i| {
        let t = t_of(val(i as isize, j as isize), val(i as isize + 1, j as isize));
        out.push([i as f64 - 1.0 + t, j as f64 - 1.0, z]);
    });
    e.y.for_each(|j, i| {
        let t = t_of(val(i as isize, j as isize), val(i as isize, j as isize + 1));
        out.push([i as f64 - 1.0, j as f64 - 1.0 + t, z]);
    });
    out
}

/// Vertex reference kinds, packed in the top two bits until global numbers are known.
const LOWER: u32 = 0;
const UPPER: u32 = 1 << 30;
const ZEDGE: u32 = 2 << 30;
const KIND: u32 = 3 << 30;

/// One slice's share of the mesh, with vertex references still local.
struct SliceMesh {
    surfels: SliceSurfels,
    z_vertices: Vec<[f64; 3]>,
    upper_vertices: Vec<[f64; 3]>,
    upper_count: u32,
    triangles: Vec<[u32; 3]>,
    /// Ribbon of each triangle.
    ribbon: Vec<u32>,
    areas: Vec<f64>,
}

#[allow(clippy::too_many_arguments)]
fn slice_mesh(
    lower: &PlaneMask,
    upper: &PlaneMask,
    lower_edges: &PlaneEdges,
    upper_edges: &PlaneEdges,
    lower_v: Option<&Samples>,
    upper_v: Option<&Samples>,
    z: i32,
    opts: &SurfaceOptions,
    info: &VolumeInfo,
) -> SliceMesh {
    let (nx, ny) = (lower.nx, lower.ny);
    let conn = opts.connectivity;
    let table = cases(conn);
    let surfels = SliceSurfels::build(lower, upper, z, conn);
    let ze = z_edges(lower, upper);
    let sv = SliceValues {
        lower: lower_v,
        upper: upper_v,
        nx,
        ny,
        scaling: info.scaling,
    };
    let mut z_vertices = Vec::with_capacity(ze.count as usize);
    ze.for_each(|j, i| {
        let mut c = [f64::NAN; 8];
        let v = sv.corners(i as u32, j as u32);
        c[0] = v[0];
        c[4] = v[4];
        let t = crossing(&c, 8, opts.iso);
        z_vertices.push([i as f64 - 1.0, j as f64 - 1.0, z as f64 + t]);
    });
    let upper_vertices = plane_vertices(upper_edges, upper_v, z as f64 + 1.0, nx, ny, opts, info);
    let mut triangles = Vec::new();
    let mut ribbon = Vec::new();
    let (lx, ux) = (lower_edges.x.count, upper_edges.x.count);
    for cube in &surfels.cubes {
        let (i, j) = (cube.i as usize, cube.j as usize);
        let case = &table[cube.case as usize];
        let vid = |e: u8| -> u32 {
            match e {
                0 => LOWER | lower_edges.x.rank(j, i),
                1 => LOWER | lower_edges.x.rank(j + 1, i),
                2 => UPPER | upper_edges.x.rank(j, i),
                3 => UPPER | upper_edges.x.rank(j + 1, i),
                4 => LOWER | (lx + lower_edges.y.rank(j, i)),
                5 => LOWER | (lx + lower_edges.y.rank(j, i + 1)),
                6 => UPPER | (ux + upper_edges.y.rank(j, i)),
                7 => UPPER | (ux + upper_edges.y.rank(j, i + 1)),
                8 => ZEDGE | ze.rank(j, i),
                9 => ZEDGE | ze.rank(j, i + 1),
                10 => ZEDGE | ze.rank(j + 1, i),
                _ => ZEDGE | ze.rank(j + 1, i + 1),
            }
        };
        for (k, piece) in case.pieces.iter().enumerate() {
            let r = surfels.piece_ribbon[cube.first_piece as usize + k];
            for t in &piece.triangles {
                triangles.push([vid(t[0]), vid(t[1]), vid(t[2])]);
                ribbon.push(r);
            }
        }
    }
    let areas = crate::topology::genus::ribbon_areas(&surfels, &sv, opts.iso, &info.affine, conn);
    SliceMesh {
        surfels,
        z_vertices,
        upper_count: upper_vertices.len() as u32,
        upper_vertices,
        triangles,
        ribbon,
        areas,
    }
}

const BATCH: usize = 16;

/// Extracts the isosurface as a mesh; with `largest`, only the surface of largest area.
pub fn extract(
    reader: &mut dyn SliceReader,
    opts: &SurfaceOptions,
    largest: bool,
    progress: &dyn Progress,
) -> Result<Mesh> {
    let info = reader.info().clone();
    let [nx, ny, nz] = info.dims;
    let classifier = opts.classifier(&info);
    let affine = info.affine;
    let flip = affine.determinant() < 0.0;
    let mut mesh = Mesh::default();
    let mut tri_ribbon: Vec<u32> = Vec::new();
    let mut tracker = SurfaceTracker::default();
    let to_world = |p: [f64; 3]| {
        let w = affine.apply(p);
        [w[0] as f32, w[1] as f32, w[2] as f32]
    };
    progress.start("mesh", nz as u64 + 1);
    let mut lower_plane = PlaneMask::empty(nx, ny);
    let mut lower_edges = plane_edges(&lower_plane);
    let mut lower_values: Option<Samples> = None;
    let mut lower_base = 0u32; // first vertex of the lower plane's x/y crossings
    let mut prev: Option<(SliceSurfels, u32)> = None;
    let mut z0: i32 = -1;
    while z0 < nz as i32 {
        let z1 = (z0 + BATCH as i32).min(nz as i32);
        let mut values = Vec::new();
        for p in z0 + 1..=z1 {
            values.push(if p < nz as i32 {
                let mut s = Samples::new(info.dtype);
                reader.read_slice(&mut s)?;
                Some(s)
            } else {
                None
            });
        }
        let planes: Vec<(PlaneMask, PlaneEdges)> = values
            .par_iter()
            .map(|v| {
                let mut p = PlaneMask::empty(nx, ny);
                if let Some(v) = v {
                    p.fill(v, &classifier);
                }
                let e = plane_edges(&p);
                (p, e)
            })
            .collect();
        let built: Vec<SliceMesh> = (0..planes.len())
            .into_par_iter()
            .map(|k| {
                let (lo, lo_e, lo_v) = if k == 0 {
                    (&lower_plane, &lower_edges, lower_values.as_ref())
                } else {
                    (&planes[k - 1].0, &planes[k - 1].1, values[k - 1].as_ref())
                };
                slice_mesh(
                    lo,
                    &planes[k].0,
                    lo_e,
                    &planes[k].1,
                    lo_v,
                    values[k].as_ref(),
                    z0 + k as i32,
                    opts,
                    &info,
                )
            })
            .collect();
        for sm in built {
            // Global numbers: the lower plane's block exists; the z-edges come next, then the
            // upper plane's block.
            let z_base = mesh.vertices.len() as u32;
            mesh.vertices
                .extend(sm.z_vertices.iter().map(|&p| to_world(p)));
            let upper_base = mesh.vertices.len() as u32;
            mesh.vertices
                .extend(sm.upper_vertices.iter().map(|&p| to_world(p)));
            let _ = sm.upper_count;
            let base = tracker.add_slice(
                &sm.surfels,
                &sm.areas,
                prev.as_ref().map(|(p, b)| (p, *b)),
                opts.connectivity,
            )?;
            let map = |v: u32| -> u32 {
                let local = v & !KIND;
                match v & KIND {
                    LOWER => lower_base + local,
                    UPPER => upper_base + local,
                    _ => z_base + local,
                }
            };
            for (t, &r) in sm.triangles.iter().zip(&sm.ribbon) {
                let mut tri = [map(t[0]), map(t[1]), map(t[2])];
                if flip {
                    tri.swap(1, 2);
                }
                mesh.triangles.push(tri);
                tri_ribbon.push(base + r);
            }
            lower_base = upper_base;
            prev = Some((sm.surfels, base));
            progress.advance(1);
        }
        let (lp, le) = planes.into_iter().last().expect("a batch has a plane");
        lower_plane = lp;
        lower_edges = le;
        lower_values = values.pop().flatten();
        z0 = z1;
    }
    progress.finish();
    if mesh.vertices.len() > u32::MAX as usize / 4 {
        return Err(Error::Internal(
            "mesh too large for 32-bit vertex numbers".into(),
        ));
    }
    if largest {
        keep_largest(&mut mesh, &tri_ribbon, &mut tracker);
    }
    Ok(mesh)
}

/// Keeps the triangles of the surface with the largest area and the vertices they use.
fn keep_largest(mesh: &mut Mesh, tri_ribbon: &[u32], tracker: &mut SurfaceTracker) {
    let n = tracker.ribbons.len();
    let mut area = vec![0.0f64; n];
    for r in 0..n {
        let root = tracker.uf.find(r as u32) as usize;
        area[root] += tracker.ribbons[r].area;
    }
    let Some(best) = (0..n).max_by(|&a, &b| area[a].partial_cmp(&area[b]).unwrap()) else {
        return;
    };
    let mut used = vec![u32::MAX; mesh.vertices.len()];
    let mut vertices = Vec::new();
    let mut triangles = Vec::new();
    for (t, &r) in mesh.triangles.iter().zip(tri_ribbon) {
        if tracker.uf.find(r) as usize != best {
            continue;
        }
        let mut nt = [0u32; 3];
        for k in 0..3 {
            let v = t[k] as usize;
            if used[v] == u32::MAX {
                used[v] = vertices.len() as u32;
                vertices.push(mesh.vertices[v]);
            }
            nt[k] = used[v];
        }
        triangles.push(nt);
    }
    mesh.vertices = vertices;
    mesh.triangles = triangles;
}

impl Mesh {
    /// Euler characteristic V - E + F (edges counted from the triangles).
    pub fn euler_characteristic(&self) -> i64 {
        let mut edges: Vec<(u32, u32)> = self
            .triangles
            .iter()
            .flat_map(|t| (0..3).map(move |k| (t[k].min(t[(k + 1) % 3]), t[k].max(t[(k + 1) % 3]))))
            .collect();
        edges.sort_unstable();
        edges.dedup();
        self.vertices.len() as i64 - edges.len() as i64 + self.triangles.len() as i64
    }

    /// Writes the mesh; the format follows the extension: `.ply` (binary), `.obj` or `.stl`.
    pub fn write(&self, path: &Path) -> Result<()> {
        let ext = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
            .unwrap_or_default();
        let mut out = AtomicOutput::create(path, Compression::None)?;
        match ext.as_str() {
            "ply" => self.write_ply(&mut out)?,
            "obj" => self.write_obj(&mut out)?,
            "stl" => self.write_stl(&mut out)?,
            _ => {
                return Err(Error::usage(format!(
                    "{}: unknown mesh format; use .ply, .obj or .stl",
                    path.display()
                )));
            }
        }
        out.commit()
    }

    fn write_ply(&self, out: &mut AtomicOutput) -> Result<()> {
        let header = format!(
            "ply\nformat binary_little_endian 1.0\ncomment isotopo isosurface, world coordinates in mm (RAS)\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
            self.vertices.len(),
            self.triangles.len()
        );
        out.write_all(header.as_bytes())?;
        let mut buf = Vec::with_capacity(1 << 20);
        for v in &self.vertices {
            for c in v {
                buf.extend_from_slice(&c.to_le_bytes());
            }
            if buf.len() > (1 << 20) - 64 {
                out.write_all(&buf)?;
                buf.clear();
            }
        }
        for t in &self.triangles {
            buf.push(3);
            for c in t {
                buf.extend_from_slice(&(*c as i32).to_le_bytes());
            }
            if buf.len() > (1 << 20) - 64 {
                out.write_all(&buf)?;
                buf.clear();
            }
        }
        out.write_all(&buf)
    }

    fn write_obj(&self, out: &mut AtomicOutput) -> Result<()> {
        use std::fmt::Write;
        let mut s = String::from("# isotopo isosurface, world coordinates in mm (RAS)\n");
        for v in &self.vertices {
            let _ = writeln!(s, "v {} {} {}", v[0], v[1], v[2]);
            if s.len() > 1 << 20 {
                out.write_all(s.as_bytes())?;
                s.clear();
            }
        }
        for t in &self.triangles {
            let _ = writeln!(s, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1);
            if s.len() > 1 << 20 {
                out.write_all(s.as_bytes())?;
                s.clear();
            }
        }
        out.write_all(s.as_bytes())
    }

    fn write_stl(&self, out: &mut AtomicOutput) -> Result<()> {
        let mut head = [0u8; 80];
        let title = b"isotopo isosurface (mm)";
        head[..title.len()].copy_from_slice(title);
        out.write_all(&head)?;
        out.write_all(&(self.triangles.len() as u32).to_le_bytes())?;
        let mut buf = Vec::with_capacity(1 << 20);
        for t in &self.triangles {
            let p = t.map(|i| self.vertices[i as usize]);
            let u = [p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]];
            let w = [p[2][0] - p[0][0], p[2][1] - p[0][1], p[2][2] - p[0][2]];
            let mut n = [
                u[1] * w[2] - u[2] * w[1],
                u[2] * w[0] - u[0] * w[2],
                u[0] * w[1] - u[1] * w[0],
            ];
            let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            if l > 0.0 {
                n = n.map(|c| c / l);
            }
            for c in n.iter().chain(p.iter().flatten()) {
                buf.extend_from_slice(&c.to_le_bytes());
            }
            buf.extend_from_slice(&[0, 0]);
            if buf.len() > (1 << 20) - 64 {
                out.write_all(&buf)?;
                buf.clear();
            }
        }
        out.write_all(&buf)
    }
}
