//! Synthetic shapes with known topology. Each is a float32 volume; inside is `value > 0`.

use isotopo::volume::InMemoryVolume;

pub struct Shape {
    pub name: String,
    pub volume: InMemoryVolume,
    /// Expected (b0, b1, b2) under connectivity 6 and 26, where known by construction.
    pub expect6: Option<(i64, i64, i64)>,
    pub expect26: Option<(i64, i64, i64)>,
}

fn shape(
    name: &str,
    volume: InMemoryVolume,
    e6: Option<(i64, i64, i64)>,
    e26: Option<(i64, i64, i64)>,
) -> Shape {
    Shape {
        name: name.to_string(),
        volume,
        expect6: e6,
        expect26: e26,
    }
}

/// Rotation by `ax` about x, then `ay` about y, then `az` about z (radians).
pub fn rotate(p: [f64; 3], ax: f64, ay: f64, az: f64) -> [f64; 3] {
    let (s, c) = ax.sin_cos();
    let p = [p[0], c * p[1] - s * p[2], s * p[1] + c * p[2]];
    let (s, c) = ay.sin_cos();
    let p = [c * p[0] + s * p[2], p[1], -s * p[0] + c * p[2]];
    let (s, c) = az.sin_cos();
    [c * p[0] - s * p[1], s * p[0] + c * p[1], p[2]]
}

/// A field over a cube of side `n`, with coordinates centred (offset by a non-grid amount so
/// that no sample sits exactly on the surface).
pub fn field(n: usize, f: impl Fn([f64; 3]) -> f64) -> InMemoryVolume {
    let c = (n as f64 - 1.0) / 2.0 + 0.0137;
    InMemoryVolume::from_fn([n, n, n], |x, y, z| {
        f([x as f64 - c, y as f64 - c, z as f64 - c]) as f32
    })
}

fn len(p: [f64; 3]) -> f64 {
    (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt()
}

/// Solid torus about the z axis through `centre`: positive inside.
pub fn torus_field(p: [f64; 3], big_r: f64, small_r: f64) -> f64 {
    let q = ((p[0] * p[0] + p[1] * p[1]).sqrt() - big_r).hypot(p[2]);
    small_r - q
}

pub fn ball(n: usize, r: f64) -> InMemoryVolume {
    field(n, |p| r - len(p))
}

pub fn torus(n: usize, big_r: f64, small_r: f64, ax: f64, ay: f64, az: f64) -> InMemoryVolume {
    field(n, |p| torus_field(rotate(p, ax, ay, az), big_r, small_r))
}

/// A slab with `holes` round holes through it along z.
pub fn holed_slab(holes: usize) -> InMemoryVolume {
    let nx = 8 * holes + 6;
    let dims = [nx, 14, 8];
    InMemoryVolume::from_fn(dims, |x, y, z| {
        let (x, y, z) = (x as f64, y as f64, z as f64);
        let in_box = (2.0..=nx as f64 - 3.0).contains(&x)
            && (2.0..=11.0).contains(&y)
            && (2.0..=5.0).contains(&z);
        let in_hole = (0..holes).any(|h| {
            let cx = 6.5 + 8.0 * h as f64;
            (x - cx).hypot(y - 6.5) < 2.2
        });
        if in_box && !in_hole {
            1.0
        } else {
            -1.0
        }
    })
}

/// Two solid tori through each other like chain links.
pub fn linked_tori() -> InMemoryVolume {
    field(32, |p| {
        // Each ring passes through the other's centre; the tubes stay 2 voxels apart.
        let a = torus_field([p[0] + 3.0, p[1], p[2]], 6.0, 2.0);
        let b = torus_field(
            rotate(
                [p[0] - 3.0, p[1], p[2]],
                std::f64::consts::FRAC_PI_2,
                0.0,
                0.0,
            ),
            6.0,
            2.0,
        );
        a.max(b)
    })
}

/// A tube around a trefoil knot.
pub fn trefoil() -> InMemoryVolume {
    let pts: Vec<[f64; 3]> = (0..1500)
        .map(|k| {
            let t = k as f64 / 1500.0 * std::f64::consts::TAU;
            [
                5.0 * (t.sin() + 2.0 * (2.0 * t).sin()),
                5.0 * (t.cos() - 2.0 * (2.0 * t).cos()),
                5.0 * -(3.0 * t).sin(),
            ]
        })
        .collect();
    // The curve comes within 1.21 × 5 of itself; a tube of radius 1.5 leaves a gap of 3 voxels.
    field(36, |p| {
        let d = pts
            .iter()
            .map(|q| len([p[0] - q[0], p[1] - q[1], p[2] - q[2]]))
            .fold(f64::INFINITY, f64::min);
        1.5 - d
    })
}

/// Menger sponge of the given level; each cell is a 2×2×2 block of samples, with a margin.
pub fn menger(level: u32) -> InMemoryVolume {
    let cells = 3usize.pow(level);
    let n = 2 * cells + 2;
    InMemoryVolume::from_fn([n, n, n], |x, y, z| {
        if x == 0 || y == 0 || z == 0 || x > 2 * cells || y > 2 * cells || z > 2 * cells {
            return -1.0;
        }
        let (mut a, mut b, mut c) = ((x - 1) / 2, (y - 1) / 2, (z - 1) / 2);
        for _ in 0..level {
            let ones = (a % 3 == 1) as u32 + (b % 3 == 1) as u32 + (c % 3 == 1) as u32;
            if ones >= 2 {
                return -1.0;
            }
            a /= 3;
            b /= 3;
            c /= 3;
        }
        1.0
    })
}

/// A block of gyroid.
pub fn gyroid() -> InMemoryVolume {
    let n = 30;
    let k = std::f64::consts::TAU / 12.0;
    InMemoryVolume::from_fn([n, n, n], |x, y, z| {
        if x < 2 || y < 2 || z < 2 || x > n - 3 || y > n - 3 || z > n - 3 {
            return -1.0;
        }
        let (x, y, z) = (x as f64 * k + 0.1, y as f64 * k + 0.2, z as f64 * k + 0.3);
        (x.sin() * y.cos() + y.sin() * z.cos() + z.sin() * x.cos()) as f32
    })
}

/// A volume of -1 with the listed samples set to +1.
pub fn points(dims: [usize; 3], inside: &[[usize; 3]]) -> InMemoryVolume {
    InMemoryVolume::from_fn(dims, |x, y, z| {
        if inside.contains(&[x, y, z]) {
            1.0
        } else {
            -1.0
        }
    })
}

/// The small configurations that tell the two connectivities apart.
pub fn diagonal_cases() -> Vec<Shape> {
    let edge = points([4, 4, 3], &[[1, 1, 1], [2, 2, 1]]);
    let corner = points([4, 4, 4], &[[1, 1, 1], [2, 2, 2]]);
    let ring = points([5, 5, 3], &[[2, 1, 1], [3, 2, 1], [2, 3, 1], [1, 2, 1]]);
    // A one-sample-thick hollow box whose corner sample is missing: the cavity touches the outside
    // only through a corner.
    let leak = InMemoryVolume::from_fn([7, 7, 7], |x, y, z| {
        let shell = (1..=5).contains(&x) && (1..=5).contains(&y) && (1..=5).contains(&z);
        let cavity = (2..=4).contains(&x) && (2..=4).contains(&y) && (2..=4).contains(&z);
        if shell && !cavity && (x, y, z) != (5, 5, 5) {
            1.0
        } else {
            -1.0
        }
    });
    // The same box closed: a cavity under both conventions.
    let closed = InMemoryVolume::from_fn([7, 7, 7], |x, y, z| {
        let shell = (1..=5).contains(&x) && (1..=5).contains(&y) && (1..=5).contains(&z);
        let cavity = (2..=4).contains(&x) && (2..=4).contains(&y) && (2..=4).contains(&z);
        if shell && !cavity {
            1.0
        } else {
            -1.0
        }
    });
    vec![
        shape(
            "edge-touching samples",
            edge,
            Some((2, 0, 0)),
            Some((1, 0, 0)),
        ),
        shape(
            "corner-touching samples",
            corner,
            Some((2, 0, 0)),
            Some((1, 0, 0)),
        ),
        shape("diagonal ring", ring, Some((4, 0, 0)), Some((1, 1, 0))),
        shape(
            "cavity leaking through a corner",
            leak,
            Some((1, 0, 0)),
            Some((1, 0, 1)),
        ),
        shape(
            "closed hollow box",
            closed,
            Some((1, 0, 1)),
            Some((1, 0, 1)),
        ),
    ]
}

/// Every shape with known topology.
pub fn all() -> Vec<Shape> {
    use std::f64::consts::{FRAC_PI_2, FRAC_PI_3, FRAC_PI_4, FRAC_PI_6};
    let same = |e: (i64, i64, i64)| (Some(e), Some(e));
    let mut v = Vec::new();
    let (a, b) = same((1, 0, 0));
    v.push(shape("ball", ball(20, 7.3), a, b));
    let (a, b) = same((1, 0, 1));
    v.push(shape(
        "hollow ball",
        field(24, |p| (9.2 - len(p)).min(len(p) - 5.1)),
        a,
        b,
    ));
    let (a, b) = same((1, 1, 0));
    v.push(shape(
        "solid torus",
        torus(26, 8.0, 3.0, 0.0, 0.0, 0.0),
        a,
        b,
    ));
    v.push(shape(
        "torus on its side",
        torus(26, 8.0, 3.0, FRAC_PI_2, 0.0, 0.0),
        a,
        b,
    ));
    v.push(shape(
        "torus tilted 30° about x",
        torus(28, 8.0, 2.6, FRAC_PI_6, 0.0, 0.0),
        a,
        b,
    ));
    v.push(shape(
        "torus tilted 45° about y",
        torus(28, 8.0, 2.6, 0.0, FRAC_PI_4, 0.0),
        a,
        b,
    ));
    v.push(shape(
        "torus tilted 60° x, 20° z",
        torus(28, 8.0, 2.6, FRAC_PI_3, 0.0, 0.35),
        a,
        b,
    ));
    v.push(shape(
        "torus tilted in all three",
        torus(30, 9.0, 2.4, 0.4, 0.7, 1.1),
        a,
        b,
    ));
    for holes in 1..=4 {
        let (a, b) = same((1, holes as i64, 0));
        v.push(shape(
            &format!("slab with {holes} holes"),
            holed_slab(holes),
            a,
            b,
        ));
    }
    let (a, b) = same((2, 2, 0));
    v.push(shape("two linked tori", linked_tori(), a, b));
    let (a, b) = same((1, 1, 0));
    v.push(shape("trefoil tube", trefoil(), a, b));
    v.push(shape(
        "Menger sponge level 1",
        menger(1),
        Some((1, 5, 0)),
        None,
    ));
    v.push(shape(
        "Menger sponge level 2",
        menger(2),
        Some((1, 81, 0)),
        None,
    ));
    v.push(shape(
        "Menger sponge level 3",
        menger(3),
        Some((1, 1409, 0)),
        None,
    ));
    v.push(shape("gyroid block", gyroid(), None, None));
    v.extend(diagonal_cases());
    v
}
