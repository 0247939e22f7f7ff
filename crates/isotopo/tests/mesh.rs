//! Extracted meshes are closed, manifold, consistently oriented outward, and their topology
//! equals the oracle's: chi = 2(b0 + b2) - 2 b1, one component per surface, each of the right genus.

mod common;

use common::{oracle, shapes, Rng, BOTH};
use isotopo::mesh::{extract, Mesh};
use isotopo::progress::NoProgress;
use isotopo::topology::Connectivity;
use isotopo::volume::InMemoryVolume;
use std::collections::HashMap;

struct Check {
    components: Vec<(i64, f64)>, // (genus, signed volume) per connected component
    chi: i64,
}

/// Verifies closedness, manifoldness and orientation; returns per-component genus and volume.
fn check_mesh(m: &Mesh) -> Result<Check, String> {
    let mut directed: HashMap<(u32, u32), u32> = HashMap::new();
    for t in &m.triangles {
        if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
            return Err(format!("degenerate triangle {t:?}"));
        }
        for k in 0..3 {
            *directed.entry((t[k], t[(k + 1) % 3])).or_default() += 1;
        }
    }
    for (&(a, b), &n) in &directed {
        if n != 1 {
            return Err(format!(
                "directed edge ({a},{b}) used {n} times: inconsistent orientation"
            ));
        }
        if !directed.contains_key(&(b, a)) {
            return Err(format!(
                "edge ({a},{b}) is a boundary edge: mesh not closed"
            ));
        }
    }
    // Manifold vertices: the triangles around a vertex form a single cycle.
    let mut around: HashMap<u32, Vec<(u32, u32)>> = HashMap::new();
    for t in &m.triangles {
        for k in 0..3 {
            around
                .entry(t[k])
                .or_default()
                .push((t[(k + 1) % 3], t[(k + 2) % 3]));
        }
    }
    for (v, fan) in &around {
        let next: HashMap<u32, u32> = fan.iter().copied().collect();
        let mut cur = fan[0].0;
        let mut steps = 0;
        loop {
            cur = match next.get(&cur) {
                Some(&n) => n,
                None => return Err(format!("vertex {v}: open fan")),
            };
            steps += 1;
            if cur == fan[0].0 {
                break;
            }
            if steps > fan.len() {
                return Err(format!("vertex {v}: fan does not close"));
            }
        }
        if steps != fan.len() {
            return Err(format!(
                "vertex {v}: {} triangles in {} fans (non-manifold vertex)",
                fan.len(),
                fan.len() / steps.max(1)
            ));
        }
    }
    if around.len() != m.vertices.len() {
        return Err(format!(
            "{} unused vertices",
            m.vertices.len() - around.len()
        ));
    }
    // Components by union-find over triangles' vertices.
    let mut uf = common::UnionFind::new(m.vertices.len());
    for t in &m.triangles {
        uf.union(t[0], t[1]);
        uf.union(t[1], t[2]);
    }
    let mut comp: HashMap<u32, (i64, i64, i64, f64)> = HashMap::new(); // V, 2E, F, volume
    for v in 0..m.vertices.len() as u32 {
        comp.entry(uf.find(v)).or_default().0 += 1;
    }
    for t in &m.triangles {
        let c = comp.entry(uf.find(t[0])).or_default();
        c.1 += 3;
        c.2 += 1;
        let p = t.map(|i| m.vertices[i as usize].map(|x| x as f64));
        c.3 += (p[0][0] * (p[1][1] * p[2][2] - p[1][2] * p[2][1])
            - p[0][1] * (p[1][0] * p[2][2] - p[1][2] * p[2][0])
            + p[0][2] * (p[1][0] * p[2][1] - p[1][1] * p[2][0]))
            / 6.0;
    }
    let components: Vec<(i64, f64)> = comp
        .values()
        .map(|&(v, e2, f, vol)| ((2 - (v - e2 / 2 + f)) / 2, vol))
        .collect();
    Ok(Check {
        components,
        chi: m.euler_characteristic(),
    })
}

fn verify(vol: &InMemoryVolume, iso: f64, conn: Connectivity, name: &str) -> Result<(), String> {
    let mut v = vol.clone();
    let m =
        extract(&mut v, &common::opts(iso, conn), false, &NoProgress).map_err(|e| e.to_string())?;
    let c = check_mesh(&m).map_err(|e| format!("{name} ({}): {e}", conn.number()))?;
    let (b0, b1, b2, _) = oracle::betti(&common::mask_of(vol, iso), vol.dims(), conn);
    if c.chi != 2 * (b0 + b2) - 2 * b1 {
        return Err(format!(
            "{name} ({}): mesh chi {} but oracle b = ({b0}, {b1}, {b2})",
            conn.number(),
            c.chi
        ));
    }
    if c.components.len() as i64 != b0 + b2 {
        return Err(format!(
            "{name} ({}): {} mesh components, oracle b0 + b2 = {}",
            conn.number(),
            c.components.len(),
            b0 + b2
        ));
    }
    // Each component's genus and orientation match the genus pass's surfaces.
    let r = common::run_genus(vol, iso, conn);
    let mut ours: Vec<(i64, bool)> = c
        .components
        .iter()
        .map(|&(g, vol)| (g, vol > 0.0))
        .collect();
    let mut theirs: Vec<(i64, bool)> = r
        .surfaces
        .iter()
        .map(|s| {
            (
                s.genus as i64,
                s.bounds == isotopo::topology::Bounds::Material,
            )
        })
        .collect();
    ours.sort();
    theirs.sort();
    if ours != theirs {
        return Err(format!("{name} ({}): mesh components (genus, encloses material) {ours:?} vs genus pass {theirs:?}", conn.number()));
    }
    let positive = c.components.iter().filter(|c| c.1 > 0.0).count() as i64;
    if positive != b0 {
        return Err(format!(
            "{name} ({}): {positive} outward components with positive volume, oracle b0 = {b0}",
            conn.number()
        ));
    }
    Ok(())
}

#[test]
fn meshes_of_shapes_are_closed_manifolds_of_the_right_topology() {
    let mut failures = Vec::new();
    for s in shapes::all() {
        for conn in BOTH {
            if let Err(e) = verify(&s.volume, 0.0, conn, &s.name) {
                failures.push(e);
            }
        }
    }
    assert!(failures.is_empty(), "\n{}", failures.join("\n"));
}

#[test]
fn meshes_of_random_volumes_are_closed_manifolds_of_the_right_topology() {
    let mut rng = Rng(77);
    let mut failures = Vec::new();
    let mut n = 0;
    for round in 0..40 {
        let dims = [[7, 8, 9], [12, 12, 12], [15, 10, 12], [18, 18, 18]][round % 4];
        let v = common::smoothed_noise(dims, 1 + round % 3, &mut rng);
        let vol = common::volume_from(dims, &v);
        for q in [0.4, 0.6] {
            let iso = common::quantile(&v, q);
            for conn in BOTH {
                n += 1;
                if let Err(e) = verify(&vol, iso, conn, &format!("noise round {round} q {q}")) {
                    failures.push(e);
                }
            }
        }
    }
    assert!(n >= 160);
    assert!(
        failures.is_empty(),
        "{} of {n}:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

#[test]
fn largest_keeps_one_surface() {
    // Two balls of different sizes: --largest keeps the bigger one only.
    let vol = InMemoryVolume::from_fn([30, 16, 16], |x, y, z| {
        let d1 =
            ((x as f64 - 8.0).powi(2) + (y as f64 - 7.7).powi(2) + (z as f64 - 7.9).powi(2)).sqrt();
        let d2 = ((x as f64 - 23.0).powi(2) + (y as f64 - 7.7).powi(2) + (z as f64 - 7.9).powi(2))
            .sqrt();
        (6.2 - d1).max(3.1 - d2) as f32
    });
    let mut v = vol.clone();
    let all = extract(
        &mut v,
        &common::opts(0.0, Connectivity::Six),
        false,
        &NoProgress,
    )
    .unwrap();
    let mut v = vol.clone();
    let big = extract(
        &mut v,
        &common::opts(0.0, Connectivity::Six),
        true,
        &NoProgress,
    )
    .unwrap();
    let c = check_mesh(&big).unwrap();
    assert_eq!(c.components.len(), 1);
    assert!(
        big.vertices.iter().all(|p| p[0] < 16.0),
        "kept the small ball"
    );
    assert!(big.triangles.len() < all.triangles.len());
    assert_eq!(check_mesh(&all).unwrap().components.len(), 2);
}

/// The genus pass's surface areas are the areas of the extracted mesh, and a ball's area is close
/// to 4πr², in millimetres (anisotropic voxels).
#[test]
fn areas_match_the_mesh_and_the_sphere() {
    let r = 9.0;
    let spacing = [0.5, 0.8, 1.25];
    let dims = [46, 29, 19];
    let mut vol = InMemoryVolume::from_fn(dims, |x, y, z| {
        let p = [
            x as f64 * spacing[0] - 11.3,
            y as f64 * spacing[1] - 11.1,
            z as f64 * spacing[2] - 11.2,
        ];
        (r - (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt()) as f32
    });
    vol.info.affine = isotopo::volume::Affine::from_spacing(spacing, [0.0; 3]);
    let g = common::run_genus(&vol, 0.0, Connectivity::Six);
    assert_eq!(g.surfaces.len(), 1);
    let mut v = vol.clone();
    let m = extract(
        &mut v,
        &common::opts(0.0, Connectivity::Six),
        false,
        &NoProgress,
    )
    .unwrap();
    let mesh_area: f64 = m
        .triangles
        .iter()
        .map(|t| {
            let p = t.map(|i| m.vertices[i as usize].map(|c| c as f64));
            let u = [p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]];
            let w = [p[2][0] - p[0][0], p[2][1] - p[0][1], p[2][2] - p[0][2]];
            let c = [
                u[1] * w[2] - u[2] * w[1],
                u[2] * w[0] - u[0] * w[2],
                u[0] * w[1] - u[1] * w[0],
            ];
            0.5 * (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt()
        })
        .sum();
    let area = g.surfaces[0].area;
    assert!(
        (area - mesh_area).abs() < 1e-4 * area,
        "genus pass area {area}, mesh area {mesh_area}"
    );
    let sphere = 4.0 * std::f64::consts::PI * r * r;
    assert!(
        (area - sphere).abs() < 0.03 * sphere,
        "area {area} vs 4πr² = {sphere}"
    );
}

/// A rotated scan has the same surface areas as the unrotated one: the genus pass maps each
/// triangle's vector area through the affine's cofactor matrix, not only through its diagonal.
#[test]
fn areas_do_not_change_when_the_scan_is_rotated() {
    let dims = [23, 21, 9];
    let vol = InMemoryVolume::from_fn(dims, |x, y, z| {
        let (x, y, z) = (x as f64 - 11.2, y as f64 - 10.1, z as f64 - 4.3);
        // A torus: its area depends on the spacing's anisotropy, so a wrong matrix shows.
        let ring = (x * x + y * y).sqrt() - 6.0;
        (3.0 - (ring * ring + z * z).sqrt()) as f32
    });
    let spacing = [0.7, 1.1, 1.6];
    let (c, s) = (0.6f64, 0.8f64);
    // Columns: the unit directions of i, j, k (a rotation about z, then one about x).
    let rotated = [[c, s * c, s * s], [s, -c * c, -c * s], [0.0, s, -c]];
    let mut areas = Vec::new();
    for direction in [[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], rotated] {
        let mut v = vol.clone();
        v.info.affine = isotopo::volume::Affine::from_parts(direction, spacing, [5.0, -3.0, 2.0]);
        let g = common::run_genus(&v, 0.0, Connectivity::Six);
        assert_eq!((g.b0, g.b1, g.b2), (1, 1, 0));
        areas.push(g.surfaces[0].area);
    }
    assert!(
        (areas[0] - areas[1]).abs() < 1e-9 * areas[0],
        "axis-aligned area {}, rotated {}",
        areas[0],
        areas[1]
    );
    // The anisotropy matters: with unit spacing the area is another.
    let g = common::run_genus(&vol, 0.0, Connectivity::Six);
    assert!((g.surfaces[0].area - areas[0]).abs() > 0.1 * areas[0]);
}
