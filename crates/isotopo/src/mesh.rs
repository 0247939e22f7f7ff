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
use crate::topology::{Classifier, Connectivity, SurfaceOptions};
use crate::volume::{
    Affine, AtomicOutput, Compression, DType, Sample, Samples, Scaling, SliceReader, VolumeInfo,
};
use rayon::prelude::*;
use std::path::Path;

/// An indexed triangle mesh in world millimetres, triangles facing out of the solid.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    /// Vertex positions in world millimetres (RAS+, as the volume's affine maps them).
    pub vertices: Vec<[f32; 3]>,
    /// Indices into `vertices`, counter-clockwise seen from outside the solid.
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

/// Read access to one plane's values by padded (column, row); NaN on the padding.
struct PlaneValues<'a, T> {
    v: Option<&'a [T]>,
    nx: usize,
    ny: usize,
    scaling: Scaling,
}

impl<T: Sample> PlaneValues<'_, T> {
    #[inline]
    fn at(&self, i: usize, j: usize) -> f64 {
        match self.v {
            Some(v) if i >= 1 && j >= 1 && i <= self.nx && j <= self.ny => {
                self.scaling.apply(v[(j - 1) * self.nx + i - 1].to_f64())
            }
            _ => f64::NAN,
        }
    }
}

/// Where the isosurface crosses between values `a` and `b` (fraction from `a`).
#[inline]
fn fraction(a: f64, b: f64, iso: f64) -> f64 {
    let mut c = [f64::NAN; 8];
    c[0] = a;
    c[1] = b;
    crossing(&c, 0, iso)
}

/// World positions of the crossings of a plane's x- then y-edges.
fn plane_vertices<T: Sample>(
    e: &PlaneEdges,
    vals: &PlaneValues<T>,
    z: f64,
    iso: f64,
    affine: &Affine,
) -> Vec<[f32; 3]> {
    let mut out = Vec::with_capacity((e.x.count + e.y.count) as usize);
    e.x.for_each(|j, i| {
        let t = fraction(vals.at(i, j), vals.at(i + 1, j), iso);
        out.push(world(affine, [i as f64 - 1.0 + t, j as f64 - 1.0, z]));
    });
    e.y.for_each(|j, i| {
        let t = fraction(vals.at(i, j), vals.at(i, j + 1), iso);
        out.push(world(affine, [i as f64 - 1.0, j as f64 - 1.0 + t, z]));
    });
    out
}

/// World positions of the crossings of the z-edges between two planes.
fn z_vertices<T: Sample>(
    ze: &EdgeSet,
    lower: &PlaneValues<T>,
    upper: &PlaneValues<T>,
    z: f64,
    iso: f64,
    affine: &Affine,
) -> Vec<[f32; 3]> {
    let mut out = Vec::with_capacity(ze.count as usize);
    ze.for_each(|j, i| {
        let t = fraction(lower.at(i, j), upper.at(i, j), iso);
        out.push(world(affine, [i as f64 - 1.0, j as f64 - 1.0, z + t]));
    });
    out
}

#[inline]
fn world(affine: &Affine, p: [f64; 3]) -> [f32; 3] {
    let q = affine.apply(p);
    [q[0] as f32, q[1] as f32, q[2] as f32]
}

/// Vertex reference kinds, packed in the top two bits until global numbers are known.
const LOWER: u32 = 0;
const UPPER: u32 = 1 << 30;
const ZEDGE: u32 = 2 << 30;
const KIND: u32 = 3 << 30;

/// One slice's share of the mesh, with vertex references still local.
struct SliceMesh {
    surfels: SliceSurfels,
    z_vertices: Vec<[f32; 3]>,
    upper_vertices: Vec<[f32; 3]>,
    triangles: Vec<[u32; 3]>,
    /// Ribbon of each triangle.
    ribbon: Vec<u32>,
    /// Ribbon areas, when needed (to pick the largest surface).
    areas: Vec<f64>,
}

/// A plane ready for meshing: its mask, crossing edges, and samples (None for padding).
struct MeshPlane {
    mask: PlaneMask,
    edges: PlaneEdges,
    samples: Option<Samples>,
}

/// Runs `$body` with `$lo`/`$up` bound to typed [`PlaneValues`] of two planes of one type.
macro_rules! with_plane_values {
    ($lower:expr, $upper:expr, $info:expr, $lo:ident, $up:ident => $body:expr) => {{
        let dtype = $info.dtype;
        let (nx, ny, scaling) = ($info.dims[0], $info.dims[1], $info.scaling);
        $crate::volume::with_dtype!(dtype, T => {
            let $lo = PlaneValues::<T> {
                v: $lower.and_then(T::view),
                nx,
                ny,
                scaling,
            };
            let $up = PlaneValues::<T> {
                v: $upper.and_then(T::view),
                nx,
                ny,
                scaling,
            };
            $body
        })
    }};
}

fn slice_mesh(
    lower: &MeshPlane,
    upper: &MeshPlane,
    z: i32,
    opts: &SurfaceOptions,
    info: &VolumeInfo,
    want_areas: bool,
) -> SliceMesh {
    let (nx, ny) = (lower.mask.nx, lower.mask.ny);
    let conn = opts.connectivity;
    let table = cases(conn);
    let surfels = SliceSurfels::build(&lower.mask, &upper.mask, z, conn);
    let ze = z_edges(&lower.mask, &upper.mask);
    let (z_vertices, upper_vertices) = with_plane_values!(lower.samples.as_ref(), upper.samples.as_ref(), info, lo, up => (
        z_vertices(&ze, &lo, &up, z as f64, opts.iso, &info.affine),
        plane_vertices(&upper.edges, &up, z as f64 + 1.0, opts.iso, &info.affine),
    ));
    let mut triangles = Vec::new();
    let mut ribbon = Vec::new();
    let (le, ue) = (&lower.edges, &upper.edges);
    let (lx, ux) = (le.x.count, ue.x.count);
    for cube in &surfels.cubes {
        let (i, j) = (cube.i as usize, cube.j as usize);
        let case = &table[cube.case as usize];
        let vid = |e: u8| -> u32 {
            match e {
                0 => LOWER | le.x.rank(j, i),
                1 => LOWER | le.x.rank(j + 1, i),
                2 => UPPER | ue.x.rank(j, i),
                3 => UPPER | ue.x.rank(j + 1, i),
                4 => LOWER | (lx + le.y.rank(j, i)),
                5 => LOWER | (lx + le.y.rank(j, i + 1)),
                6 => UPPER | (ux + ue.y.rank(j, i)),
                7 => UPPER | (ux + ue.y.rank(j, i + 1)),
                8 => ZEDGE | ze.rank(j, i),
                9 => ZEDGE | ze.rank(j, i + 1),
                10 => ZEDGE | ze.rank(j + 1, i),
                _ => ZEDGE | ze.rank(j + 1, i + 1),
            }
        };
        for n in 0..case.n_triangles as usize {
            let t = case.triangles[n];
            triangles.push([vid(t[0]), vid(t[1]), vid(t[2])]);
            ribbon.push(
                surfels.piece_ribbon[cube.first_piece as usize + case.triangle_piece[n] as usize],
            );
        }
    }
    let areas = if want_areas {
        let sv = SliceValues {
            lower: lower.samples.as_ref(),
            upper: upper.samples.as_ref(),
            nx,
            ny,
            scaling: info.scaling,
        };
        crate::topology::genus::ribbon_areas(&surfels, &sv, opts.iso, &info.affine, conn)
    } else {
        vec![0.0; surfels.ribbons.len()]
    };
    SliceMesh {
        surfels,
        z_vertices,
        upper_vertices,
        triangles,
        ribbon,
        areas,
    }
}

/// Slices per parallel batch.
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
    let flip = info.affine.determinant() < 0.0;
    let mut out = MeshAssembly::new(flip, largest, opts.connectivity);
    crate::volume::reserve_slices(&info, BATCH + 1, "meshing reads them in batches")?;
    progress.start("mesh", nz as u64 + 1);
    // Planes -1 ..= nz; a batch covers slices z0 .. z1 (lower planes), upper planes z0+1 ..= z1.
    let mut lower = mesh_plane(None, nx, ny, &classifier);
    let mut z0: i32 = -1;
    while z0 < nz as i32 {
        let z1 = (z0 + BATCH as i32).min(nz as i32);
        let samples = read_planes(reader, info.dtype, z0 + 1..=z1, nz)?;
        let planes: Vec<MeshPlane> = samples
            .into_par_iter()
            .map(|s| mesh_plane(s, nx, ny, &classifier))
            .collect();
        for sm in mesh_batch(&lower, &planes, z0, opts, &info, largest) {
            out.add(sm)?;
            progress.advance(1);
        }
        crate::progress::between_steps(progress, "meshing")?;
        lower = planes.into_iter().last().expect("a batch has a plane");
        z0 = z1;
    }
    progress.finish();
    out.finish()
}

/// The samples of planes `planes`, read in order; plane `nz` (the padding above) has none.
fn read_planes(
    reader: &mut dyn SliceReader,
    dtype: DType,
    planes: std::ops::RangeInclusive<i32>,
    nz: usize,
) -> Result<Vec<Option<Samples>>> {
    let mut samples = Vec::new();
    for p in planes {
        samples.push(if p < nz as i32 {
            let mut s = Samples::new(dtype);
            reader.read_slice(&mut s)?;
            Some(s)
        } else {
            None
        });
    }
    Ok(samples)
}

/// A plane ready for meshing, from its samples (None: padding, all outside).
fn mesh_plane(
    samples: Option<Samples>,
    nx: usize,
    ny: usize,
    classifier: &Classifier,
) -> MeshPlane {
    let mut mask = PlaneMask::empty(nx, ny);
    if let Some(s) = &samples {
        mask.fill(s, classifier);
    }
    let edges = plane_edges(&mask);
    MeshPlane {
        mask,
        edges,
        samples,
    }
}

/// Meshes a batch of slices in parallel: slice `z0 + k` lies between `planes[k - 1]` (`lower`
/// for k = 0) and `planes[k]`.
fn mesh_batch(
    lower: &MeshPlane,
    planes: &[MeshPlane],
    z0: i32,
    opts: &SurfaceOptions,
    info: &VolumeInfo,
    want_areas: bool,
) -> Vec<SliceMesh> {
    (0..planes.len())
        .into_par_iter()
        .map(|k| {
            let lo = if k == 0 { lower } else { &planes[k - 1] };
            slice_mesh(lo, &planes[k], z0 + k as i32, opts, info, want_areas)
        })
        .collect()
}

/// The mesh being put together from slice meshes, bottom to top.
struct MeshAssembly {
    mesh: Mesh,
    /// The affine mirrors space: swap two corners of each triangle so it still faces out.
    flip: bool,
    /// Track the surfaces (ribbons joined across planes) to keep only the largest.
    largest: bool,
    conn: Connectivity,
    /// Ribbon (tracker number) of each triangle, when `largest`.
    tri_ribbon: Vec<u32>,
    tracker: SurfaceTracker,
    /// First vertex of the lower plane's x/y crossings.
    lower_base: u32,
    /// The previous slice's surfels and the tracker number of its first ribbon.
    prev: Option<(SliceSurfels, u32)>,
}

impl MeshAssembly {
    fn new(flip: bool, largest: bool, conn: Connectivity) -> MeshAssembly {
        MeshAssembly {
            mesh: Mesh::default(),
            flip,
            largest,
            conn,
            tri_ribbon: Vec::new(),
            tracker: SurfaceTracker::default(),
            lower_base: 0,
            prev: None,
        }
    }

    /// Appends the next slice: its vertices, its triangles with global vertex numbers, and with
    /// `largest` its ribbons.
    fn add(&mut self, sm: SliceMesh) -> Result<()> {
        // Global numbers: the lower plane's block exists; the z-edges come next, then the upper
        // plane's block.
        let mesh = &mut self.mesh;
        let z_base = mesh.vertices.len() as u32;
        mesh.vertices.extend_from_slice(&sm.z_vertices);
        let upper_base = mesh.vertices.len() as u32;
        mesh.vertices.extend_from_slice(&sm.upper_vertices);
        // Surfaces (to pick the largest) are only tracked when asked for.
        let base = if self.largest {
            self.tracker.add_slice(
                &sm.surfels,
                &sm.areas,
                self.prev.as_ref().map(|(p, b)| (p, *b)),
                self.conn,
            )?
        } else {
            0
        };
        let lower_base = self.lower_base;
        let map = |v: u32| -> u32 {
            let local = v & !KIND;
            match v & KIND {
                LOWER => lower_base + local,
                UPPER => upper_base + local,
                _ => z_base + local,
            }
        };
        mesh.triangles.reserve(sm.triangles.len());
        for t in &sm.triangles {
            let mut tri = [map(t[0]), map(t[1]), map(t[2])];
            if self.flip {
                tri.swap(1, 2);
            }
            mesh.triangles.push(tri);
        }
        if self.largest {
            self.tri_ribbon.extend(sm.ribbon.iter().map(|&r| base + r));
        }
        self.lower_base = upper_base;
        self.prev = Some((sm.surfels, base));
        Ok(())
    }

    /// The finished mesh; with `largest`, only the surface of largest area.
    fn finish(mut self) -> Result<Mesh> {
        if self.mesh.vertices.len() > u32::MAX as usize / 4 {
            return Err(Error::Internal(
                "mesh too large for 32-bit vertex numbers".into(),
            ));
        }
        if self.largest {
            keep_largest(&mut self.mesh, &self.tri_ribbon, &mut self.tracker);
        }
        Ok(self.mesh)
    }
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
    /// Euler characteristic of a closed mesh, where every edge joins two triangles: V - 3F/2 + F.
    pub fn closed_euler_characteristic(&self) -> i64 {
        self.vertices.len() as i64 - self.triangles.len() as i64 / 2
    }

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
