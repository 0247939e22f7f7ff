//! The streaming genus pass: every closed surface's genus, area, bounding box and whether it
//! encloses material or a cavity, and the solid's Betti numbers — two planes in memory at a time.
//!
//! Each slice's pieces are grouped into ribbons; ribbons of consecutive slices that share
//! segments on the plane between them are joined in a union-find over ribbons. A surface's Euler
//! characteristic is the sum of its pieces' shares (`Piece::chi4`), so its genus follows from
//! `genus = (2 - chi) / 2`. Surfaces enclosing material count in `b0`, cavities in `b2`, and the
//! total genus is `b1` (docs/ARCHITECTURE.md, facts).

use super::cases::{cases, Connectivity};
use super::critical::CriticalCounts;
use super::mask::{Classifier, Inside, PlaneMask};
use super::slice::SliceSurfels;
use super::values::{edge_point, SliceValues};
use crate::error::{Error, Result};
use crate::progress::Progress;
use crate::unionfind::UnionFind;
use crate::volume::{Affine, BBox, Sample, Samples, SliceReader, VolumeInfo};
use rayon::prelude::*;

/// What defines the isosurface: the isovalue, which side is inside, and the digital connectivity.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct SurfaceOptions {
    /// Isovalue, in the volume's value units (after the header's scaling).
    pub iso: f64,
    /// Inside is above the isovalue (default) or below it (signed distance fields).
    pub inside: Inside,
    /// Digital connectivity of the solid; 6 by default.
    pub connectivity: Connectivity,
}

impl Default for SurfaceOptions {
    /// Isovalue 0, inside above it, connectivity 6.
    fn default() -> SurfaceOptions {
        SurfaceOptions {
            iso: 0.0,
            inside: Inside::Above,
            connectivity: Connectivity::Six,
        }
    }
}

impl SurfaceOptions {
    /// The inside/outside test for the raw samples of the volume `info` describes (the isovalue
    /// is compared with values after its scaling).
    pub fn classifier(&self, info: &VolumeInfo) -> Classifier {
        Classifier {
            iso: self.iso,
            inside: self.inside,
            scaling: info.scaling,
        }
    }
}

/// What a closed surface bounds (not to be confused with [`crate::loops::Encloses`], what a
/// loop goes round).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Bounds {
    /// The outer boundary of a component of the solid.
    Material,
    /// The boundary of a void inside the solid.
    Cavity,
}

/// One closed surface.
#[derive(Clone, Debug, serde::Serialize)]
pub struct SurfaceInfo {
    /// Stable id: surfaces are numbered by their lowest point (z, then y, then x).
    pub id: usize,
    /// Its genus: handles on it.
    pub genus: u32,
    /// Euler characteristic of the surface.
    pub chi: i64,
    /// A component's outer boundary, or a cavity's.
    #[serde(rename = "encloses")]
    pub bounds: Bounds,
    /// Area in mm² of the triangulated surface (vertices interpolated on cube edges).
    pub area: f64,
    /// Voxel index bounds of the cubes it passes through (clamped to the volume).
    pub bbox: BBox,
    /// The same box in millimetres.
    pub bbox_mm: [[f64; 3]; 2],
    /// Number of surfels (pieces in cubes).
    pub surfels: u64,
}

/// The genus pass's result.
#[derive(Clone, Debug, serde::Serialize)]
pub struct GenusReport {
    /// Components of the solid.
    pub b0: u64,
    /// Independent loops of the solid = total genus of its surfaces = number of handles.
    pub b1: u64,
    /// Cavities of the solid.
    pub b2: u64,
    /// Euler characteristic of the solid, b0 - b1 + b2.
    pub chi: i64,
    /// Surfaces, by decreasing genus then area.
    pub surfaces: Vec<SurfaceInfo>,
}

/// Per-ribbon facts accumulated into surfaces.
#[derive(Clone, Debug)]
pub(crate) struct RibbonStats {
    pub chi4: i64,
    pub area: f64,
    pub bbox: BBox,
    /// (z, j, i) of the ribbon's first cube: orders surfaces by their lowest point.
    pub key: (i32, u32, u32),
    pub upper_inside: Option<bool>,
    pub surfels: u64,
}

/// Joins ribbons slice after slice into surfaces.
#[derive(Default)]
pub(crate) struct SurfaceTracker {
    pub uf: UnionFind,
    pub ribbons: Vec<RibbonStats>,
}

impl SurfaceTracker {
    /// Adds the ribbons of `cur`, joined to those of `prev` (the slice below, whose ribbons
    /// start at `prev_base`). Returns the base index of `cur`'s ribbons.
    pub fn add_slice(
        &mut self,
        cur: &SliceSurfels,
        areas: &[f64],
        prev: Option<(&SliceSurfels, u32)>,
        conn: Connectivity,
    ) -> Result<u32> {
        let base = self.ribbons.len() as u32;
        let (nx, ny) = (cur.nx as i64, cur.ny as i64);
        for (r, rb) in cur.ribbons.iter().enumerate() {
            self.uf.push();
            let c = cur.cubes[rb.first_cube as usize];
            let mut bbox = BBox::EMPTY;
            // Cubes span samples i-1 ..= i along x (padded index i); clamp to the volume.
            let z = cur.z as i64;
            bbox.include([
                (rb.min[0] as i64 - 1).max(0),
                (rb.min[1] as i64 - 1).max(0),
                z.max(0),
            ]);
            bbox.include([
                (rb.max[0] as i64).min(nx - 1),
                (rb.max[1] as i64).min(ny - 1),
                z + 1,
            ]);
            self.ribbons.push(RibbonStats {
                chi4: rb.surface_chi4 as i64,
                area: areas.get(r).copied().unwrap_or(0.0),
                bbox,
                key: (cur.z, c.j, c.i),
                upper_inside: rb.upper_inside,
                surfels: rb.pieces as u64,
            });
        }
        if let Some((p, pbase)) = prev {
            if p.top.len() != cur.bottom.len() {
                return Err(Error::Internal(format!(
                    "plane {}: {} squares from below, {} from above",
                    cur.z,
                    p.top.len(),
                    cur.bottom.len()
                )));
            }
            let table = cases(conn);
            for (&qa, &qb) in p.top.iter().zip(&cur.bottom) {
                let n = table[p.cubes[qa as usize].case as usize].face_owner[5]
                    .iter()
                    .filter(|&&o| o != super::cases::NONE)
                    .count();
                for slot in 0..n {
                    let ra = pbase + p.face_ribbon(table, qa as usize, 5, slot);
                    let rb = base + cur.face_ribbon(table, qb as usize, 4, slot);
                    self.uf.union(ra, rb);
                }
            }
        }
        Ok(base)
    }

    /// Folds ribbons into surfaces and computes the report.
    pub fn report(&mut self, dims: [usize; 3], affine: &Affine) -> Result<GenusReport> {
        let acc = self.sum_surfaces();
        let mut surfaces = Vec::with_capacity(acc.len());
        for a in &acc {
            surfaces.push((a.key, surface_info(a, dims, affine)?));
        }
        // Ids by lowest point, then the listing order: genus, then area, both decreasing.
        surfaces.sort_by_key(|s| s.0);
        let mut surfaces: Vec<SurfaceInfo> = surfaces
            .into_iter()
            .enumerate()
            .map(|(id, (_, mut s))| {
                s.id = id;
                s
            })
            .collect();
        let b0 = surfaces
            .iter()
            .filter(|s| s.bounds == Bounds::Material)
            .count() as u64;
        let b2 = surfaces.len() as u64 - b0;
        let b1: u64 = surfaces.iter().map(|s| s.genus as u64).sum();
        surfaces.sort_by(|a, b| {
            b.genus
                .cmp(&a.genus)
                .then(
                    b.area
                        .partial_cmp(&a.area)
                        .unwrap_or(std::cmp::Ordering::Equal),
                )
                .then(a.id.cmp(&b.id))
        });
        Ok(GenusReport {
            b0,
            b1,
            b2,
            chi: b0 as i64 - b1 as i64 + b2 as i64,
            surfaces,
        })
    }

    /// The ribbons' stats summed per surface (union-find class), in order of each surface's
    /// first ribbon; a surface's key and `upper_inside` come from its lowest ribbon.
    fn sum_surfaces(&mut self) -> Vec<RibbonStats> {
        let n = self.ribbons.len();
        let mut root_index = vec![u32::MAX; n];
        let mut acc: Vec<RibbonStats> = Vec::new();
        for r in 0..n {
            let root = self.uf.find(r as u32) as usize;
            if root_index[root] == u32::MAX {
                root_index[root] = acc.len() as u32;
                acc.push(RibbonStats {
                    chi4: 0,
                    area: 0.0,
                    bbox: BBox::EMPTY,
                    key: (i32::MAX, u32::MAX, u32::MAX),
                    upper_inside: None,
                    surfels: 0,
                });
            }
            let a = &mut acc[root_index[root] as usize];
            let rb = &self.ribbons[r];
            a.chi4 += rb.chi4;
            a.area += rb.area;
            a.bbox.union(&rb.bbox);
            a.surfels += rb.surfels;
            if rb.key < a.key {
                a.key = rb.key;
                a.upper_inside = rb.upper_inside;
            }
        }
        acc
    }
}

/// A surface's report entry (id 0 until numbered) from its summed ribbon stats `a`, after
/// checking that its Euler characteristic is even and at most 2, as a connected closed
/// orientable surface's is.
fn surface_info(a: &RibbonStats, dims: [usize; 3], affine: &Affine) -> Result<SurfaceInfo> {
    if a.chi4 % 8 != 0 {
        return Err(Error::Internal(format!(
            "a surface has Euler characteristic {}/4, not an even integer",
            a.chi4
        )));
    }
    let chi = a.chi4 / 4;
    if chi > 2 {
        return Err(Error::Internal(format!(
            "a connected surface has Euler characteristic {chi} > 2"
        )));
    }
    let mut bbox = a.bbox;
    for k in 0..3 {
        bbox.min[k] = bbox.min[k].clamp(0, dims[k] as i64 - 1);
        bbox.max[k] = bbox.max[k].clamp(0, dims[k] as i64 - 1);
    }
    Ok(SurfaceInfo {
        id: 0,
        genus: ((2 - chi) / 2) as u32,
        chi,
        bounds: if a.upper_inside.unwrap_or(true) {
            Bounds::Material
        } else {
            Bounds::Cavity
        },
        area: a.area,
        bbox,
        bbox_mm: bbox.to_mm(affine),
        surfels: a.surfels,
    })
}

/// Area (mm²) of each ribbon of a slice, from its triangles with interpolated vertices.
pub(crate) fn ribbon_areas(
    s: &SliceSurfels,
    values: &SliceValues,
    iso: f64,
    affine: &Affine,
    conn: Connectivity,
) -> Vec<f64> {
    let Some(dtype) = values.lower.or(values.upper).map(|v| v.dtype()) else {
        return vec![0.0; s.ribbons.len()];
    };
    crate::volume::with_dtype!(dtype, T => areas_typed::<T>(
        s,
        values.lower.and_then(T::view),
        values.upper.and_then(T::view),
        values,
        iso,
        affine,
        conn,
    ))
}

/// Cofactor matrix of the affine's linear part: maps a voxel-space cross product (twice a
/// triangle's vector area) to the world-space one.
fn cofactor(a: &Affine) -> [[f64; 3]; 3] {
    let m = &a.m;
    let c =
        |r0: usize, r1: usize, c0: usize, c1: usize| m[r0][c0] * m[r1][c1] - m[r0][c1] * m[r1][c0];
    [
        [c(1, 2, 1, 2), -c(1, 2, 0, 2), c(1, 2, 0, 1)],
        [-c(0, 2, 1, 2), c(0, 2, 0, 2), -c(0, 2, 0, 1)],
        [c(0, 1, 1, 2), -c(0, 1, 0, 2), c(0, 1, 0, 1)],
    ]
}

fn areas_typed<T: Sample>(
    s: &SliceSurfels,
    lower: Option<&[T]>,
    upper: Option<&[T]>,
    values: &SliceValues,
    iso: f64,
    affine: &Affine,
    conn: Connectivity,
) -> Vec<f64> {
    let table = cases(conn);
    let cof = cofactor(affine);
    let (nx, ny) = (values.nx, values.ny);
    let scaling = values.scaling;
    let identity = scaling.is_identity();
    let value = |raw: T| match identity {
        true => raw.to_f64(),
        false => scaling.apply(raw.to_f64()),
    };
    let diagonal = (0..3).all(|r| (0..3).all(|c| r == c || cof[r][c] == 0.0));
    let mut sums = AreaSums::new(s.ribbons.len());
    let mut pts = [[0.0f64; 3]; 12];
    for cube in &s.cubes {
        let case = &table[cube.case as usize];
        let (i, j) = (cube.i as usize, cube.j as usize);
        // Corner values; NaN for padding. Most cubes have all eight corners in the volume.
        let v = match (lower, upper) {
            (Some(lo), Some(up)) if (1..nx).contains(&i) && (1..ny).contains(&j) => {
                let b = (j - 1) * nx + i - 1;
                let (b2, b3) = (b + nx, b + nx + 1);
                [
                    lo[b],
                    lo[b + 1],
                    lo[b2],
                    lo[b3],
                    up[b],
                    up[b + 1],
                    up[b2],
                    up[b3],
                ]
                .map(value)
            }
            _ => values.corners(cube.i, cube.j),
        };
        // The crossing points first, each once (testing each triangle's corners for one
        // already made mispredicted branches). Triangles use crossed edges only: the other
        // entries of `pts` are left from earlier cubes (zeroing them was 3% of the pass).
        // The first four without a branch (most cubes have three or four), then the rest.
        for e in case.first_crossed {
            pts[e as usize] = edge_point(&v, e, iso);
        }
        let mut crossed = case.crossed_after_first;
        while crossed != 0 {
            let e = crossed.trailing_zeros() as u8;
            crossed &= crossed - 1;
            pts[e as usize] = edge_point(&v, e, iso);
        }
        for n in 0..case.n_triangles as usize {
            let t = case.triangles[n];
            let (p0, p1, p2) = (pts[t[0] as usize], pts[t[1] as usize], pts[t[2] as usize]);
            let u = [p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]];
            let w = [p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2]];
            let c = [
                u[1] * w[2] - u[2] * w[1],
                u[2] * w[0] - u[0] * w[2],
                u[0] * w[1] - u[1] * w[0],
            ];
            // World-space cross product; an axis-aligned affine (most scans) needs 3 products.
            let d = match diagonal {
                true => [cof[0][0] * c[0], cof[1][1] * c[1], cof[2][2] * c[2]],
                false => cof.map(|row| row[0] * c[0] + row[1] * c[1] + row[2] * c[2]),
            };
            let piece = cube.first_piece + case.triangle_piece[n] as u32;
            let r = s.piece_ribbon[piece as usize];
            sums.push(d[0] * d[0] + d[1] * d[1] + d[2] * d[2], r);
        }
    }
    sums.finish()
}

/// Triangles whose square roots are taken together: one at a time, each waited for its
/// square root's latency (a quarter of the areas' time on the bunny); a chunk's roots are
/// independent, and the compiler takes two per instruction.
const AREA_CHUNK: usize = 256;

/// Sums of triangle areas by ribbon, from their squared doubled areas (`|d|^2`, d twice the
/// triangle's vector area): `0.5 * sqrt` of each, added in the order pushed, so the sums are
/// those of adding each area as it comes.
struct AreaSums {
    squared: [f64; AREA_CHUNK],
    ribbon_of: [u32; AREA_CHUNK],
    len: usize,
    /// One entry per ribbon, and a last one for the sum before the first triangle.
    areas: Vec<f64>,
    /// The ribbon being added to, and its running sum: it stays in a register until a
    /// triangle is another ribbon's (adding each to memory made a chain of loads waiting on
    /// stores).
    ribbon: usize,
    sum: f64,
}

impl AreaSums {
    fn new(ribbons: usize) -> AreaSums {
        AreaSums {
            squared: [0.0; AREA_CHUNK],
            ribbon_of: [0; AREA_CHUNK],
            len: 0,
            areas: vec![0.0; ribbons + 1],
            ribbon: ribbons,
            sum: 0.0,
        }
    }

    #[inline]
    fn push(&mut self, squared: f64, ribbon: u32) {
        self.squared[self.len] = squared;
        self.ribbon_of[self.len] = ribbon;
        self.len += 1;
        if self.len == AREA_CHUNK {
            self.flush();
        }
    }

    fn flush(&mut self) {
        let n = self.len;
        for x in &mut self.squared[..n] {
            *x = 0.5 * x.sqrt();
        }
        for k in 0..n {
            let r = self.ribbon_of[k] as usize;
            if r != self.ribbon {
                self.areas[self.ribbon] = self.sum;
                (self.ribbon, self.sum) = (r, self.areas[r]);
            }
            self.sum += self.squared[k];
        }
        self.len = 0;
    }

    fn finish(mut self) -> Vec<f64> {
        self.flush();
        self.areas[self.ribbon] = self.sum;
        self.areas.pop();
        self.areas
    }
}

/// Slices per parallel batch: one per thread at least, and otherwise few, so that their samples
/// are still in the cache when the areas read them (4 planes of a 512² int16 scan are 2 MiB;
/// with 16 on 2 threads the bunny's pass took 6-11% longer and 38 MB instead of 17).
fn batch_len() -> i32 {
    rayon::current_num_threads().clamp(4, 64) as i32
}

/// Where meshers may disagree on a volume: the critical configurations of its inside/outside
/// pattern, the samples exactly at the isovalue, and the solid under the other connectivity.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct Agreement {
    /// Unit faces with one diagonal inside, unit cubes with two opposite corners alone (see
    /// [`super::critical`]): none, and every mesher sees one topology.
    pub critical: CriticalCounts,
    /// Samples exactly at the isovalue: isotopo (and scikit-image) count them outside, VTK inside.
    pub samples_at_iso: u64,
    /// The other connectivity (26 when the surface's is 6).
    pub other_connectivity: u32,
    /// Components, handles and cavities under the other connectivity.
    pub b0: u64,
    /// Total genus under the other connectivity.
    pub b1: u64,
    /// Cavities under the other connectivity.
    pub b2: u64,
}

/// The per-slice work of the genus pass beyond the surface: the other connectivity's surfels,
/// critical cells, samples at the isovalue.
struct SliceSurvey {
    /// `None` where they are the chosen connectivity's (see [`SliceSurfels::build_both`]).
    other: Option<SliceSurfels>,
    critical: CriticalCounts,
    at_iso: u64,
}

/// Planes `z0 + 1 ..= z1` of a batch, read ahead: their masks and samples (`None` for the
/// padding plane `nz`). The buffers are kept from batch to batch.
#[derive(Default)]
struct Batch {
    planes: Vec<PlaneMask>,
    values: Vec<Option<Samples>>,
    /// Samples of each plane exactly at the isovalue (counted while they are in the cache).
    at_iso: Vec<u64>,
}

impl Batch {
    /// Reads planes `z0 + 1 ..= z1` into this batch's buffers and classifies them.
    ///
    /// Each plane is classified (by either thread) while the next is read: the thread that
    /// joins the last batch to the surfaces beside the reading classifies too once it is done
    /// (the join takes half as long as the reading).
    fn read(
        &mut self,
        reader: &mut dyn SliceReader,
        classifier: &Classifier,
        z0: i32,
        z1: i32,
    ) -> Result<()> {
        let info = reader.info();
        let ([nx, ny, nz], dtype) = (info.dims, info.dtype);
        let n = (z1 - z0) as usize;
        self.planes.truncate(n);
        self.values.truncate(n);
        self.planes.resize_with(n, || PlaneMask::empty(nx, ny));
        self.values.resize_with(n, || None);
        self.at_iso.resize(n, 0);
        let planes = self.planes.iter_mut().zip(&mut self.values);
        let planes = planes.zip((z0 + 1..=z1).zip(&mut self.at_iso));
        rayon::scope(|scope| {
            for ((plane, values), (p, at_iso)) in planes {
                *at_iso = 0;
                if p >= nz as i32 {
                    *values = None;
                    plane.bits.fill(0);
                    continue;
                }
                let v = values.get_or_insert_with(|| Samples::new(dtype));
                reader.read_slice(v)?;
                let v = &*v;
                scope.spawn(move |_| {
                    plane.fill(v, classifier);
                    *at_iso = classifier.count_on_iso(v);
                });
            }
            Ok(())
        })
    }
}

/// A slice's surfels, their ribbons' areas and its survey.
type BuiltSlice = (SliceSurfels, Vec<f64>, SliceSurvey);

/// Both connectivities' surfaces, joined slice after slice, and the survey's totals.
struct GenusTracking {
    chosen: SurfaceTracker,
    other: SurfaceTracker,
    /// The last slice added, and its ribbons' base index, for each tracker (`None` for the
    /// other connectivity's surfels where they are the chosen ones).
    prev: Option<(SliceSurfels, u32)>,
    prev_other: Option<(Option<SliceSurfels>, u32)>,
    agreement: Agreement,
    /// Slices no longer needed, whose buffers the next batch builds in.
    spare: Vec<SliceSurfels>,
}

impl GenusTracking {
    fn add(
        &mut self,
        built: Vec<BuiltSlice>,
        conn: Connectivity,
        progress: &dyn Progress,
    ) -> Result<()> {
        for (s, areas, survey) in built {
            let prev = self.prev.as_ref().map(|(p, b)| (p, *b));
            let base = self.chosen.add_slice(&s, &areas, prev, conn)?;
            let prev_other = match (&self.prev_other, prev) {
                (Some((o, b)), Some((p, _))) => Some((o.as_ref().unwrap_or(p), *b)),
                _ => None,
            };
            let o = survey.other.as_ref().unwrap_or(&s);
            let base_other = self.other.add_slice(o, &[], prev_other, conn.other())?;
            if let Some((old, _)) = self.prev.replace((s, base)) {
                self.spare.push(old);
            }
            self.prev_other = Some((survey.other, base_other));
            self.agreement.critical.add(survey.critical);
            self.agreement.samples_at_iso += survey.at_iso;
            progress.advance(1);
            crate::progress::between_steps(progress, "genus pass")?;
        }
        Ok(())
    }
}

/// Builds the slices of a batch in parallel: slice `z0 + k` lies between plane `z0 + k` (the
/// batch's plane `k - 1`, or `lower` for k = 0) and the batch's plane `k`; their surfels are
/// built in the buffers of `spare`, one slice each.
fn build_batch(
    batch: &Batch,
    lower: (&PlaneMask, Option<&Samples>),
    z0: i32,
    spare: Vec<SliceSurfels>,
    info: &VolumeInfo,
    opts: &SurfaceOptions,
) -> Vec<BuiltSlice> {
    let [nx, ny, _] = info.dims;
    let conn = opts.connectivity;
    spare
        .into_par_iter()
        .enumerate()
        .map(|(k, spare)| {
            let (lo, lo_v) = match k {
                0 => lower,
                _ => (&batch.planes[k - 1], batch.values[k - 1].as_ref()),
            };
            let (up, up_v) = (&batch.planes[k], batch.values[k].as_ref());
            let (s, other) = SliceSurfels::build_both(spare, lo, up, z0 + k as i32, conn);
            let sv = SliceValues {
                lower: lo_v,
                upper: up_v,
                nx,
                ny,
                scaling: info.scaling,
            };
            let areas = ribbon_areas(&s, &sv, opts.iso, &info.affine, conn);
            let survey = SliceSurvey {
                other,
                critical: super::critical::count_critical(lo, up),
                at_iso: batch.at_iso[k],
            };
            (s, areas, survey)
        })
        .collect()
}

/// Runs the genus pass over a volume, streaming its slices; also surveys where meshers may
/// disagree ([`Agreement`]).
///
/// Batches of slices are built in parallel; while one batch's slices are joined to the
/// surfaces (in order, on one thread), the next batch is read and classified.
pub fn genus(
    reader: &mut dyn SliceReader,
    opts: &SurfaceOptions,
    progress: &dyn Progress,
) -> Result<(GenusReport, Agreement)> {
    let info = reader.info().clone();
    let [nx, ny, nz] = info.dims;
    let classifier = opts.classifier(&info);
    let conn = opts.connectivity;
    let mut tracking = GenusTracking {
        chosen: SurfaceTracker::default(),
        other: SurfaceTracker::default(),
        prev: None,
        prev_other: None,
        agreement: Agreement {
            other_connectivity: conn.other().number(),
            ..Agreement::default()
        },
        spare: Vec::new(),
    };
    let batch = batch_len();
    crate::volume::reserve_slices(
        &info,
        2 * batch as usize + 1,
        "the genus pass reads them in batches, one ahead",
    )?;
    progress.start("genus", nz as u64 + 1);
    // Planes -1 ..= nz with their samples; a batch covers slices z0 .. z1 (lower planes), and
    // holds their upper planes z0 + 1 ..= z1.
    let mut lower_plane = PlaneMask::empty(nx, ny);
    let mut lower_values: Option<Samples> = None;
    let (mut cur, mut next) = (Batch::default(), Batch::default());
    let mut z0: i32 = -1;
    let mut z1 = (z0 + batch).min(nz as i32);
    cur.read(reader, &classifier, z0, z1)?;
    while z0 < nz as i32 {
        let n = (z1 - z0) as usize;
        let spare: Vec<SliceSurfels> = (0..n)
            .map(|_| tracking.spare.pop().unwrap_or_default())
            .collect();
        let lower = (&lower_plane, lower_values.as_ref());
        let built = build_batch(&cur, lower, z0, spare, &info, opts);
        let z2 = (z1 + batch).min(nz as i32);
        let (tracked, read) = rayon::join(
            || tracking.add(built, conn, progress),
            || match z1 < nz as i32 {
                true => next.read(reader, &classifier, z1, z2),
                false => Ok(()),
            },
        );
        tracked?;
        read?;
        // The batch's last plane is the next batch's lower plane; the old lower plane's
        // buffers go back into the batch for reuse.
        if let (Some(p), Some(v)) = (cur.planes.last_mut(), cur.values.last_mut()) {
            std::mem::swap(&mut lower_plane, p);
            std::mem::swap(&mut lower_values, v);
        }
        std::mem::swap(&mut cur, &mut next);
        (z0, z1) = (z1, z2);
    }
    progress.finish();
    let o = tracking.other.report(info.dims, &info.affine)?;
    let mut agreement = tracking.agreement;
    (agreement.b0, agreement.b1, agreement.b2) = (o.b0, o.b1, o.b2);
    Ok((tracking.chosen.report(info.dims, &info.affine)?, agreement))
}
