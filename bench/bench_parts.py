#!/usr/bin/env python3
"""`isotopo simplify --spherical` (one component, no handle, no cavity) on the real volumes, side
by side with TopoSimplifier (Zeng et al. 2020) when it is built (../shared/tools/toposimplifier:
/tmp/toposimp/build/TopoSimplifierBin), and against the naive way: deleting every component but
the largest and filling every cavity (sizes by scikit-image), plus `--tau inf`.

Samples changed with and without the well-composed step (TopoSimplifier's output is not
well-composed), time and peak memory (best of --repeat runs, `/usr/bin/time -v`), and the ratios.

    python3 bench/bench_parts.py [--repeat N] [--no-peer] [volume names...]
"""

import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "scripts"))
from common import REAL, ROOT, SHARED, isotopo_bin, load, run_isotopo, timed  # noqa: E402

DEFAULT = ["mni2009a-gm.nii.gz", "tooth_103x94x161_uint8.raw", "cranium-ct.nii.gz",
           "freesurfer-wm.mgz", "lidc2-chest-ct.nii.gz"]
# TopoSimplifier is run on these (the others take it much longer).
PEER_ON = {"mni2009a-gm.nii.gz", "tooth_103x94x161_uint8.raw"}
PEER = Path("/tmp/toposimp/build/TopoSimplifierBin")
COMPARE = ROOT.parent / "shared" / "tools" / "toposimplifier" / "compare.py"


def naive(name, tmp):
    """Samples changed by deleting every component but the largest, filling every cavity, and
    `--tau inf --no-well-composed` on the input."""
    from skimage.measure import label

    solid = np.pad(load(SHARED / name) > REAL[name], 1)
    comps = np.bincount(label(solid, connectivity=1).ravel())[1:]
    space = label(~solid, connectivity=3)
    spaces = np.bincount(space.ravel())
    spaces[space[0, 0, 0]] = 0
    out = Path(tmp) / "inf.nii.gz"
    run_isotopo("simplify", SHARED / name, "--iso", REAL[name], "--tau", "inf",
                "--no-well-composed", "-o", out, "--report", out.with_suffix(".json"), "-q")
    inf = json.loads(out.with_suffix(".json").read_text())["samples_changed"]
    return int(comps.sum() - comps.max()), int(spaces[1:].sum()), inf


def isotopo(name, tmp, repeat, *flags):
    out = Path(tmp) / "sph.nii.gz"
    report = out.with_suffix(".json")
    cmd = [isotopo_bin(), "simplify", SHARED / name, "--iso", REAL[name], "--spherical", *flags,
           "-o", out, "--report", report, "-q"]
    secs, mib, _ = timed(cmd, repeat=repeat)
    return secs, mib, json.loads(report.read_text())


def peer(name, tmp):
    """TopoSimplifier through compare.py (a NIfTI input; the tooth padded with outside)."""
    path = SHARED / name
    if not name.endswith(".nii.gz"):
        import nibabel as nib

        path = Path(tmp) / (name.split(".")[0] + ".nii.gz")
        nib.save(nib.Nifti1Image(load(SHARED / name).astype(np.float32), np.eye(4)), path)
    cmd = [sys.executable, COMPARE, path, str(REAL[name])]
    if name.startswith("tooth"):
        cmd.append("--pad")
    p = subprocess.run(list(map(str, cmd)), capture_output=True, text=True, check=True)
    return json.loads(p.stdout)


def main(argv):
    repeat, use_peer, names = 3, True, []
    it = iter(argv)
    for a in it:
        if a == "--repeat":
            repeat = int(next(it))
        elif a == "--no-peer":
            use_peer = False
        else:
            names.append(a)
    names = names or DEFAULT
    use_peer = use_peer and PEER.exists() and COMPARE.exists()
    print("| volume | (b0, b1, b2) | isotopo --spherical: samples (no well-composed step) | s | MiB "
          "| naive: other components + cavities + --tau inf | TopoSimplifier: samples | s | MiB "
          "| time ratio | memory ratio |")
    print("|---" * 11 + "|")
    with tempfile.TemporaryDirectory() as tmp:
        for name in names:
            if not (SHARED / name).exists():
                continue
            secs, mib, r = isotopo(name, tmp, repeat)
            _, _, bare = isotopo(name, tmp, 1, "--no-well-composed")
            others, cavities, inf = naive(name, tmp)
            before = (r["b0_before"], r["genus_before"], r["b2_before"])
            row = [name, str(before), f"{r['samples_changed']:,} ({bare['samples_changed']:,})",
                   f"{secs:.2f}", f"{mib:.0f}", f"{others:,} + {cavities:,} + {inf:,} = "
                   f"{others + cavities + inf:,}"]
            if use_peer and name in PEER_ON:
                t = peer(name, tmp)
                row += [f"{t['changed']:,}", f"{t['seconds']:.1f}", f"{t['peak_mib']}",
                        f"{t['seconds'] / secs:.1f}x", f"{t['peak_mib'] / mib:.1f}x"]
            else:
                row += ["-"] * 5
            print("| " + " | ".join(row) + " |", flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
