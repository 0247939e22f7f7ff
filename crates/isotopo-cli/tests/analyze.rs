//! `isotopo analyze` end to end on a small volume with two known handles: the JSON has the
//! documented keys with consistent values, the CSV one row per handle, the loop file and plots
//! are written.

mod common;

use common::isotopo;
use std::path::Path;

/// A 3-voxel-thick square ring (one large handle) and a ring closed by a one-voxel bridge (a
/// handle of size 4), as a NumPy file.
fn write_two_rings(path: &Path) {
    let (nx, ny, nz) = (40usize, 20usize, 9usize);
    let mut v = vec![0u8; nx * ny * nz];
    let mut set = |x: usize, y: usize, z: usize| v[(z * ny + y) * nx + x] = 1; // written as Fortran below
    for z in 3..6 {
        for y in 2..17 {
            for x in 2..17 {
                let ring = !((5..14).contains(&x) && (5..14).contains(&y));
                if ring {
                    set(x, y, z);
                }
            }
        }
    }
    // Second ring: a U closed by a single voxel.
    for z in 3..6 {
        for y in 2..12 {
            for x in 22..37 {
                let u = y < 5 || (22..25).contains(&x) || (34..37).contains(&x);
                if u && y < 9 {
                    set(x, y, z);
                }
            }
        }
    }
    for x in 25..34 {
        set(x, 8, 4);
    }
    // Fortran-ordered uint8 [x, y, z].
    let mut dict =
        format!("{{'descr': '|u1', 'fortran_order': True, 'shape': ({nx}, {ny}, {nz}), }}");
    while (10 + dict.len() + 1) % 64 != 0 {
        dict.push(' ');
    }
    dict.push('\n');
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend_from_slice(&(dict.len() as u16).to_le_bytes());
    bytes.extend_from_slice(dict.as_bytes());
    bytes.extend_from_slice(&v);
    std::fs::write(path, bytes).unwrap();
}

#[test]
fn analyze_reports_loops_in_json_csv_files_and_plots() {
    let dir = tempfile::tempdir().unwrap();
    let vol = dir.path().join("rings.npy");
    write_two_rings(&vol);
    let v = vol.to_str().unwrap();
    let loops = dir.path().join("loops.obj");
    let plots = dir.path().join("plots");
    let (code, out, err) = isotopo(&[
        "analyze",
        v,
        "--iso",
        "0.5",
        "--json",
        "--loops",
        loops.to_str().unwrap(),
        "--plots",
        plots.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let r: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(r["genus"], 2);
    let hs = r["handles"].as_array().unwrap();
    assert_eq!(hs.len(), 2);
    let mut sizes: Vec<u64> = hs.iter().map(|h| h["size"].as_u64().unwrap()).collect();
    sizes.sort();
    assert_eq!(sizes[0], 4, "the bridge");
    assert!(sizes[1] >= 12, "the square ring: {}", sizes[1]);
    for h in hs {
        for key in [
            "id",
            "kind",
            "surface",
            "bbox",
            "reeb_loop",
            "cross_loop",
            "size",
        ] {
            assert!(!h[key].is_null(), "missing {key}");
        }
        for l in ["reeb_loop", "cross_loop"] {
            let lp = &h[l];
            let n = lp["length"].as_u64().unwrap();
            assert_eq!(lp["points"].as_array().unwrap().len() as u64, n);
            assert!(lp["length_mm"].as_f64().unwrap() > 0.0);
            assert!(["material", "void"].contains(&lp["encloses"].as_str().unwrap()));
        }
        assert_ne!(h["reeb_loop"]["encloses"], h["cross_loop"]["encloses"]);
        let m = h["reeb_loop"]["length"]
            .as_u64()
            .unwrap()
            .min(h["cross_loop"]["length"].as_u64().unwrap());
        assert_eq!(h["size"].as_u64().unwrap(), m);
    }
    // The loops file: one polyline per loop.
    let obj = std::fs::read_to_string(&loops).unwrap();
    assert_eq!(obj.lines().filter(|l| l.starts_with("l ")).count(), 4);
    // The plots.
    for f in [
        "histogram.svg",
        "histogram.png",
        "scatter.svg",
        "scatter.png",
    ] {
        let b = std::fs::read(plots.join(f)).unwrap();
        assert!(b.len() > 1000, "{f} is {} bytes", b.len());
        if f.ends_with(".png") {
            assert_eq!(&b[..8], b"\x89PNG\r\n\x1a\n");
        }
    }
    // CSV: a header and one row per handle.
    let (code, csv, err) = isotopo(&["analyze", v, "--iso", "0.5", "--csv"]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(csv.lines().count(), 3);
    assert!(csv.starts_with("id,surface,kind,"));
    // With --tau 6 the big ring's cross loop (around its 3×3 bar, 12 edges) is not searched.
    let (code, out, err) = isotopo(&["analyze", v, "--iso", "0.5", "--json", "--tau", "6"]);
    assert_eq!(code, 0, "{err}");
    let r: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert!(r["handles"]
        .as_array()
        .unwrap()
        .iter()
        .any(|h| h["cross_loop"].is_null()));
}
