//! `isotopo simplify` end to end on the real sample carried in the repository
//! (data/mni2009a-gm.nii.gz, a grey-matter probability map): the run succeeds, the volume and
//! report are written, and `isotopo genus` of the output agrees with the report (genus = handles
//! kept, components and cavities unchanged), inside above and inside below the isovalue.

mod common;

use common::isotopo;
use std::path::{Path, PathBuf};

fn sample() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../data/mni2009a-gm.nii.gz")
}

fn json(text: &str) -> serde_json::Value {
    serde_json::from_str(text).unwrap_or_else(|e| panic!("{e}: {text}"))
}

fn genus(path: &Path, inside: &str) -> serde_json::Value {
    let p = path.to_str().unwrap();
    let (code, out, err) = isotopo(&["genus", p, "--iso", "127.5", "--inside", inside, "--json"]);
    assert_eq!(code, 0, "{err}");
    json(&out)
}

#[test]
fn simplify_the_sample_inside_above_and_below() {
    let dir = std::env::temp_dir().join(format!("isotopo-cli-simplify-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let input = sample();
    let original = std::fs::read(&input).unwrap();
    for (inside, tau) in [("above", "20"), ("below", "inf")] {
        let out = dir.join(format!("out-{inside}.nii.gz"));
        let report = dir.join(format!("report-{inside}.json"));
        let args = [
            "simplify",
            input.to_str().unwrap(),
            "--iso",
            "127.5",
            "--inside",
            inside,
            "--tau",
            tau,
            "-o",
            out.to_str().unwrap(),
            "--report",
            report.to_str().unwrap(),
            "-q",
        ];
        let (code, _, err) = isotopo(&args);
        assert_eq!(code, 0, "inside {inside}: {err}");
        let r = json(&std::fs::read_to_string(&report).unwrap());
        let (before, after) = (genus(&input, inside), genus(&out, inside));
        let kept = r["kept"].as_array().unwrap();
        let what = format!("inside {inside}, tau {tau}");
        assert!(before["b1"].as_u64().unwrap() > 100, "{what}: {before}");
        assert_eq!(r["genus_before"], before["b1"], "{what}");
        assert_eq!(r["genus_after"], after["b1"], "{what}");
        assert_eq!(after["b1"].as_u64().unwrap() as usize, kept.len(), "{what}");
        assert_eq!(
            (&before["b0"], &before["b2"]),
            (&after["b0"], &after["b2"]),
            "{what}"
        );
        assert!(
            kept.iter().all(|k| k["reason"] == "size"),
            "{what}: {kept:?}"
        );
        if tau == "inf" {
            assert_eq!(after["b1"], 0, "{what}");
        } else {
            assert_eq!(r["certified"], true, "{what}");
        }
        let changed = r["samples_changed"].as_u64().unwrap();
        assert!(changed > 0, "{what}");
    }
    assert_eq!(
        std::fs::read(&input).unwrap(),
        original,
        "the input was changed"
    );
    std::fs::remove_dir_all(&dir).ok();
}
