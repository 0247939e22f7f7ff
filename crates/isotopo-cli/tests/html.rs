//! `analyze --html` and `simplify --html` end to end, read back as report.js reads them: the
//! payloads decode, every handle is listed with its loops, each close-up's bricks exist, every
//! mesh lies in the binary payload with indices within its vertices, and for simplify the
//! bricks the edits changed have a mesh after. (The page itself is opened in Chromium by
//! scripts/test_report.sh.)

mod common;

use base64::Engine;
use common::isotopo;
use std::io::Read;

/// A 24³ float volume: a solid torus (the handle of size > 4) and a cube with a one-voxel
/// tunnel (a small handle), as a NumPy file.
fn write_volume(path: &std::path::Path) {
    let n = 24usize;
    let mut v = vec![0f32; n * n * n];
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                let (fx, fy, fz) = (x as f32 - 8.0, y as f32 - 8.0, z as f32 - 8.0);
                let ring = ((fx * fx + fy * fy).sqrt() - 5.0).hypot(fz);
                let torus = 2.0 - ring;
                // A block at x 16..22 with a tunnel along z through (19, 19).
                let block = (16..22).contains(&x)
                    && (15..22).contains(&y)
                    && (3..12).contains(&z)
                    && !(x == 19 && y == 18);
                v[(x * n + y) * n + z] = if block { 1.0 } else { torus };
            }
        }
    }
    let mut dict =
        format!("{{'descr': '<f4', 'fortran_order': False, 'shape': ({n}, {n}, {n}), }}");
    while (10 + dict.len() + 1) % 64 != 0 {
        dict.push(' ');
    }
    dict.push('\n');
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend_from_slice(&(dict.len() as u16).to_le_bytes());
    bytes.extend_from_slice(dict.as_bytes());
    for s in v {
        bytes.extend_from_slice(&s.to_le_bytes());
    }
    std::fs::write(path, bytes).unwrap();
}

/// A payload of the page (gzip + base64 in a script element).
fn payload(html: &str, id: &str) -> Vec<u8> {
    let start = html.find(&format!("id=\"{id}\">")).unwrap() + id.len() + 6;
    let end = start + html[start..].find("</script>").unwrap();
    let packed = base64::engine::general_purpose::STANDARD
        .decode(html[start..end].trim())
        .unwrap();
    let mut out = Vec::new();
    flate2::read::GzDecoder::new(&packed[..])
        .read_to_end(&mut out)
        .unwrap();
    out
}

/// Checks one mesh of the binary payload; returns its triangle count.
fn check_mesh(bin: &[u8], m: &serde_json::Value) -> usize {
    let at = |k: &str, i: usize| m[k][i].as_u64().unwrap() as usize;
    let (nv, nt, width) = (at("v", 1), at("t", 1), m["w"].as_u64().unwrap() as usize);
    assert!(at("v", 0) + 6 * nv <= bin.len() && at("t", 0) + 3 * width * nt <= bin.len());
    assert_eq!(at("t", 0) % width, 0, "indices aligned");
    // Indices are delta-coded: their running sum stays below the vertex count.
    let mut index: u64 = 0;
    for k in 0..3 * nt {
        let o = at("t", 0) + k * width;
        let d = if width == 2 {
            u16::from_le_bytes([bin[o], bin[o + 1]]) as u64
        } else {
            u32::from_le_bytes([bin[o], bin[o + 1], bin[o + 2], bin[o + 3]]) as u64
        };
        index = (index + d) % (1u64 << (8 * width));
        assert!((index as usize) < nv, "index {index} of {nv} vertices");
    }
    nt
}

#[test]
fn the_html_reports_hold_every_handle_and_sound_meshes() {
    let dir = tempfile::tempdir().unwrap();
    let vol = dir.path().join("shapes.npy");
    write_volume(&vol);
    let v = vol.to_str().unwrap();
    let (code, out, err) = isotopo(&["analyze", v, "--iso", "0.5", "--json"]);
    assert_eq!(code, 0, "{err}");
    let analysis: serde_json::Value = serde_json::from_str(&out).unwrap();
    let handles = analysis["handles"].as_array().unwrap().len();
    assert_eq!(handles, 2, "a torus and a tunnel");

    let page = dir.path().join("report.html");
    let (code, out, err) = isotopo(&[
        "analyze",
        v,
        "--iso",
        "0.5",
        "--html",
        page.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("html        "), "{out}");
    let html = std::fs::read_to_string(&page).unwrap();
    assert!(html.starts_with("<!DOCTYPE html>") && html.contains("default-src 'none'"));
    let data: serde_json::Value = serde_json::from_slice(&payload(&html, "report-data")).unwrap();
    let bin = payload(&html, "report-bin");
    assert!(
        payload(&html, "three-bundle").len() > 400_000,
        "three.js embedded"
    );
    assert_eq!(data["kind"], "analyze");
    let solid = data["summary"]
        .as_array()
        .unwrap()
        .iter()
        .find(|l| l[0] == "solid")
        .expect("the solid's Betti numbers in the summary");
    assert_eq!(
        solid[1],
        "b0 2 components, b1 2 handles (total genus), b2 0 cavities"
    );
    assert_eq!(data["handle_count"], handles);
    let rows = data["handles"].as_array().unwrap();
    assert_eq!(rows.len(), handles);
    let bricks = data["bricks"].as_array().unwrap();
    for (row, h) in rows.iter().zip(analysis["handles"].as_array().unwrap()) {
        assert_eq!(row["id"], h["id"]);
        assert_eq!(row["size"], h["size"]);
        // Both loops, doubled coordinates: the Reeb loop's points as analyze gives them.
        let reeb: Vec<f64> = row["loops"][0]
            .as_array()
            .unwrap()
            .iter()
            .map(|c| c.as_f64().unwrap() / 2.0)
            .collect();
        let want: Vec<f64> = h["reeb_loop"]["points"]
            .as_array()
            .unwrap()
            .iter()
            .flat_map(|p| p.as_array().unwrap().iter().map(|c| c.as_f64().unwrap()))
            .collect();
        assert_eq!(reeb, want);
        let mine = row["bricks"]
            .as_array()
            .expect("every handle has a close-up here");
        assert!(!mine.is_empty());
        let triangles: usize = mine
            .iter()
            .map(|k| check_mesh(&bin, &bricks[k.as_u64().unwrap() as usize]["before"]))
            .sum();
        assert!(triangles > 20, "the surface round handle {}", row["id"]);
    }
    assert!(check_mesh(&bin, &data["overview"][0]) > 50);

    // simplify: every handle removed (tau inf), the bricks of the walls meshed after.
    let page = dir.path().join("simplify.html");
    let report = dir.path().join("simplify.json");
    let out_vol = dir.path().join("out.npy");
    let (code, _, err) = isotopo(&[
        "simplify",
        v,
        "--iso",
        "0.5",
        "--tau",
        "inf",
        "-o",
        out_vol.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
        "--html",
        page.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let html = std::fs::read_to_string(&page).unwrap();
    let data: serde_json::Value = serde_json::from_slice(&payload(&html, "report-data")).unwrap();
    let bin = payload(&html, "report-bin");
    let removed = r["removed"].as_array().unwrap().len();
    assert!(removed >= 1);
    // Handles, not walls: a wall may close tiny handles beside its own.
    let handles_removed: u64 = r["removed"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w["handles"].as_u64().unwrap())
        .sum();
    assert_eq!(
        data["handle_count"],
        handles_removed + r["kept"].as_array().unwrap().len() as u64
    );
    assert_eq!(
        data["handles"].as_array().unwrap().len(),
        removed + r["kept"].as_array().unwrap().len()
    );
    let bricks = data["bricks"].as_array().unwrap();
    for row in data["handles"].as_array().unwrap().iter().take(removed) {
        assert!(["collapse", "pinch"].contains(&row["status"].as_str().unwrap()));
        assert!(
            !row["wall"].as_array().unwrap().is_empty(),
            "the wall's samples"
        );
        let changed = row["bricks"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|k| !bricks[k.as_u64().unwrap() as usize]["after"].is_null())
            .count();
        assert!(changed >= 1, "a brick of handle {} changed", row["id"]);
    }
    for b in bricks {
        check_mesh(&bin, &b["before"]);
        if !b["after"].is_null() {
            check_mesh(&bin, &b["after"]);
        }
    }
    assert_eq!(data["overview"].as_array().unwrap().len(), 2);
}

#[test]
fn an_html_report_over_its_input_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let vol = dir.path().join("shapes.npy");
    write_volume(&vol);
    let before = std::fs::read(&vol).unwrap();
    let v = vol.to_str().unwrap();
    let (code, _, err) = isotopo(&["analyze", v, "--iso", "0.5", "--html", v]);
    assert_ne!(code, 0);
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(std::fs::read(&vol).unwrap(), before, "input untouched");
    let missing = dir.path().join("no/such/dir/r.html");
    let (code, _, err) = isotopo(&[
        "analyze",
        v,
        "--iso",
        "0.5",
        "--html",
        missing.to_str().unwrap(),
    ]);
    assert_ne!(code, 0);
    assert!(err.contains("no/such/dir"), "{err}");
}
