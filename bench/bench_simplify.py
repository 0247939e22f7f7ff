#!/usr/bin/env python3
"""`isotopo simplify` on the real volumes, as a table in the form of the paper's Table 1: grid,
tau, genus before and after, intra-ribbon handles, handles removed by collapse and by pinch,
samples changed, time (and where it went) and peak memory. Release build; one run each.

    python3 bench/bench_simplify.py [--tau T] [--mesh-dir DIR] [volume names...]

With --mesh-dir, also writes the isosurface before and after (binary PLY) for each volume.
"""

import json
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "scripts"))
from common import REAL, SHARED, isotopo_bin, timed  # noqa: E402

DEFAULT = ["buddha-sdf.nii.gz", "cranium-ct.nii.gz", "mni2009a-gm.nii.gz", "freesurfer-wm.mgz", "bunny-ct.nii.gz"]


def main(argv):
    tau, mesh_dir, names = "20", None, []
    it = iter(argv)
    for a in it:
        if a == "--tau":
            tau = next(it)
        elif a == "--mesh-dir":
            mesh_dir = Path(next(it))
        else:
            names.append(a)
    names = names or DEFAULT
    rows = []
    with tempfile.TemporaryDirectory() as d:
        for name in names:
            path = SHARED / name
            stem = name.split(".")[0]
            out = Path(d) / ("out" + "".join(Path(name).suffixes))
            report = Path(d) / "report.json"
            cmd = [isotopo_bin(), "simplify", str(path), "--iso", str(REAL[name]), "--tau", tau, "-o", str(out), "--report", str(report), "-q"]
            if mesh_dir:
                mesh_dir.mkdir(parents=True, exist_ok=True)
                cmd += ["--mesh", str(mesh_dir / f"{stem}-after.ply")]
            _, rss, p = timed(cmd, check=False)
            if p.returncode != 0:
                sys.exit(f"{name}: simplify failed:\n{p.stderr}")
            r = json.loads(report.read_text())
            if mesh_dir:
                subprocess.run([isotopo_bin(), "mesh", str(path), "--iso", str(REAL[name]), "-o", str(mesh_dir / f"{stem}-before.ply"), "-q"], check=True)
            rows.append((name, r, rss))
            s = r["seconds_stages"]
            print(
                f"{name:<22} {'×'.join(map(str, r['dims'])):>12} tau {tau:>4} | genus {r['genus_before']:>4} -> {r['genus_after']:<3} "
                f"intra {r['intra_ribbon']:>4} collapse {r['collapse']:>4} pinch {r['pinch']:>4} | samples {r['samples_changed']:>5} "
                f"| {r['seconds']:6.1f} s (sweep {s['sweep']:.1f}, loops {s['loops']:.1f}, closures {s['closures']:.1f}) {rss:6.0f} MiB",
                flush=True,
            )
    print("\n| model | grid | tau | genus before | genus after | #intra-ribbon | #collapse | #pinch | samples changed | time (s) | peak MiB |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for name, r, rss in rows:
        print(
            f"| `{name}` | {'×'.join(map(str, r['dims']))} | {tau} | {r['genus_before']} | {r['genus_after']} | {r['intra_ribbon']} "
            f"| {r['collapse']} | {r['pinch']} | {r['samples_changed']} | {r['seconds']:.1f} | {rss:.0f} |"
        )


if __name__ == "__main__":
    main(sys.argv[1:])
