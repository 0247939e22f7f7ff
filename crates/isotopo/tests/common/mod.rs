//! Shared by the integration tests: a deterministic random generator, synthetic shapes with
//! known topology, smoothed-noise volumes, and an independent topology oracle.
#![allow(dead_code)]

pub mod oracle;
pub mod shapes;
pub mod systole;

use isotopo::grid::{Axis, MaskVolume};
use isotopo::progress::NoProgress;
use isotopo::topology::{genus, Connectivity, GenusReport, Inside, SurfaceOptions};
use isotopo::volume::InMemoryVolume;

/// splitmix64: small, deterministic, good enough for test data.
pub struct Rng(pub u64);

impl Rng {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E3779B97F4A7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58476D1CE4E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D049BB133111EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    pub fn f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn below(&mut self, n: u64) -> u64 {
        self.next_u64() % n
    }
}

/// Random values blurred `passes` times with a 3-tap box filter along each axis: blobs and
/// tunnels of a few voxels, like noisy scans.
pub fn smoothed_noise(dims: [usize; 3], passes: usize, rng: &mut Rng) -> Vec<f32> {
    let [nx, ny, nz] = dims;
    let idx = |x: usize, y: usize, z: usize| (z * ny + y) * nx + x;
    let mut v: Vec<f32> = (0..nx * ny * nz).map(|_| rng.f64() as f32).collect();
    let mut tmp = v.clone();
    for _ in 0..passes {
        for axis in 0..3 {
            for z in 0..nz {
                for y in 0..ny {
                    for x in 0..nx {
                        let p = [x, y, z];
                        let n = dims[axis];
                        let mut s = v[idx(x, y, z)];
                        let mut c = 1.0;
                        for d in [-1i64, 1] {
                            let q = p[axis] as i64 + d;
                            if q >= 0 && (q as usize) < n {
                                let mut pp = p;
                                pp[axis] = q as usize;
                                s += v[idx(pp[0], pp[1], pp[2])];
                                c += 1.0;
                            }
                        }
                        tmp[idx(x, y, z)] = s / c;
                    }
                }
            }
            std::mem::swap(&mut v, &mut tmp);
        }
    }
    v
}

/// A float32 in-memory volume from values laid out x fastest.
pub fn volume_from(dims: [usize; 3], v: &[f32]) -> InMemoryVolume {
    let [nx, ny, _] = dims;
    InMemoryVolume::from_fn(dims, |x, y, z| v[(z * ny + y) * nx + x])
}

/// The value of quantile `q` of `v` (an isovalue that puts about `1 - q` of samples inside).
pub fn quantile(v: &[f32], q: f64) -> f64 {
    let mut s: Vec<f32> = v.to_vec();
    s.sort_by(|a, b| a.partial_cmp(b).unwrap());
    let k = ((s.len() - 1) as f64 * q) as usize;
    // Halfway between neighbours so no sample ties the isovalue.
    (s[k] as f64 + s[(k + 1).min(s.len() - 1)] as f64) / 2.0
}

/// `rounds` volumes of smoothed noise (`passes` of smoothing), each with an isovalue at the
/// 35th, 50th or 65th percentile in turn: thick, balanced and thin material.
pub fn noise_rounds(
    rng: &mut Rng,
    dims: [usize; 3],
    passes: usize,
    rounds: usize,
) -> Vec<(InMemoryVolume, f64)> {
    (0..rounds)
        .map(|round| {
            let v = smoothed_noise(dims, passes, rng);
            let iso = quantile(&v, [0.35, 0.5, 0.65][round % 3]);
            (volume_from(dims, &v), iso)
        })
        .collect()
}

pub fn opts(iso: f64, conn: Connectivity) -> SurfaceOptions {
    SurfaceOptions {
        iso,
        inside: Inside::Above,
        connectivity: conn,
    }
}

pub fn run_genus(vol: &InMemoryVolume, iso: f64, conn: Connectivity) -> GenusReport {
    let mut v = vol.clone();
    genus(&mut v, &opts(iso, conn), &isotopo::progress::NoProgress)
        .expect("genus pass")
        .0
}

/// The masks of `vol` at `iso` (inside above), planes across `axis`.
pub fn masks(vol: &InMemoryVolume, iso: f64, conn: Connectivity, axis: Axis) -> MaskVolume {
    masks_with(vol, &opts(iso, conn), axis)
}

/// The masks of `vol` as `surface` defines its inside, planes across `axis`.
pub fn masks_with(vol: &InMemoryVolume, surface: &SurfaceOptions, axis: Axis) -> MaskVolume {
    let mut v = vol.clone();
    MaskVolume::from_reader(&mut v, surface, axis, None, &NoProgress).unwrap()
}

/// Inside mask of a volume (value > iso), x fastest.
pub fn mask_of(vol: &InMemoryVolume, iso: f64) -> Vec<bool> {
    mask_on(vol, iso, Inside::Above)
}

/// Inside mask of a volume, the inside on the given side of `iso` (ties outside), x fastest.
pub fn mask_on(vol: &InMemoryVolume, iso: f64, inside: Inside) -> Vec<bool> {
    let [nx, ny, nz] = vol.dims();
    let mut m = Vec::with_capacity(nx * ny * nz);
    for z in 0..nz {
        for y in 0..ny {
            for x in 0..nx {
                let v = vol.get(x, y, z);
                m.push(match inside {
                    Inside::Above => v > iso,
                    Inside::Below => v < iso,
                });
            }
        }
    }
    m
}

pub const BOTH: [Connectivity; 2] = [Connectivity::Six, Connectivity::TwentySix];

/// Union-find with path halving: the tests' own, independent of the library's.
pub struct UnionFind(Vec<u32>);

impl UnionFind {
    pub fn new(n: usize) -> UnionFind {
        UnionFind((0..n as u32).collect())
    }

    pub fn find(&mut self, mut x: u32) -> u32 {
        while self.0[x as usize] != x {
            let up = self.0[self.0[x as usize] as usize];
            self.0[x as usize] = up; // path halving
            x = up;
        }
        x
    }

    pub fn union(&mut self, a: u32, b: u32) {
        let (a, b) = (self.find(a), self.find(b));
        self.0[a as usize] = b;
    }
}

/// A mask from `tests/data` (dims, then the bits x fastest as hex) as a ±1 volume.
pub fn fixture(name: &str) -> InMemoryVolume {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name);
    let text = std::fs::read_to_string(&path).unwrap();
    let mut lines = text.lines().filter(|l| !l.starts_with('#'));
    let dims: Vec<usize> = lines
        .next()
        .unwrap()
        .split_whitespace()
        .map(|x| x.parse().unwrap())
        .collect();
    let hex: String = lines.collect();
    let bytes: Vec<u8> = (0..hex.len() / 2)
        .map(|i| u8::from_str_radix(&hex[2 * i..2 * i + 2], 16).unwrap())
        .collect();
    let [nx, ny, nz] = [dims[0], dims[1], dims[2]];
    let inside: Vec<bool> = (0..nx * ny * nz)
        .map(|i| (bytes[i / 8] >> (i % 8)) & 1 == 1)
        .collect();
    InMemoryVolume::from_fn([nx, ny, nz], |x, y, z| {
        match inside[(z * ny + y) * nx + x] {
            true => 1.0,
            false => -1.0,
        }
    })
}

/// Critical faces and cubes of a mask (x fastest), padded with outside: counted sample by
/// sample, sharing nothing with the library's word-wise count.
pub fn critical_cells(mask: &[bool], dims: [usize; 3]) -> (usize, usize) {
    let [nx, ny, nz] = dims.map(|n| n as i64);
    let at = |x: i64, y: i64, z: i64| -> bool {
        x >= 0
            && y >= 0
            && z >= 0
            && x < nx
            && y < ny
            && z < nz
            && mask[((z * ny + y) * nx + x) as usize]
    };
    let (mut faces, mut cubes) = (0, 0);
    for z in -1..nz {
        for y in -1..ny {
            for x in -1..nx {
                let c = |dx: i64, dy: i64, dz: i64| at(x + dx, y + dy, z + dz);
                // The three faces through (x, y, z) and the cube above it.
                let squares = [
                    [c(0, 0, 0), c(0, 1, 1), c(0, 1, 0), c(0, 0, 1)],
                    [c(0, 0, 0), c(1, 0, 1), c(1, 0, 0), c(0, 0, 1)],
                    [c(0, 0, 0), c(1, 1, 0), c(1, 0, 0), c(0, 1, 0)],
                ];
                for [a, d, b, e] in squares {
                    if a == d && b == e && a != b {
                        faces += 1;
                    }
                }
                let corners: Vec<bool> = (0..8).map(|k| c(k & 1, (k >> 1) & 1, k >> 2)).collect();
                let ones = corners.iter().filter(|&&v| v).count();
                for k in 0..4 {
                    let pair = [corners[k], corners[7 - k]];
                    if (ones == 2 && pair == [true, true]) || (ones == 6 && pair == [false, false])
                    {
                        cubes += 1;
                    }
                }
            }
        }
    }
    (faces, cubes)
}
