#!/usr/bin/env python3
"""Benchmark of `isotopo handles` (the sweep alone) and `isotopo analyze` (sweep + both loops of
every handle) on the real volumes: wall time, the share spent in loop searches, peak memory, and
the sweep's speed as a ratio to the genus pass in the same run.

    python3 bench/bench_analyze.py [volume names...]
"""

import json
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "scripts"))
from common import REAL, SHARED, isotopo_bin, timed  # noqa: E402


def run(*args):
    """(wall seconds, peak MiB, parsed JSON stdout), best of 2 for the time."""
    dt, rss, p = timed([isotopo_bin(), *args], repeat=2)
    return dt, rss, json.loads(p.stdout)


def main(names):
    names = names or ["bunny-ct.nii.gz", "mni2009a-gm.nii.gz"]
    print(f"{'volume':<22} {'voxels':>11} {'handles':>7} | {'genus s':>7} | {'sweep s':>7} {'MiB':>5} {'sweep/genus':>11} | {'analyze s':>9} {'MiB':>5} {'loops share':>11}")
    with tempfile.TemporaryDirectory() as d:
        for name in names:
            src = SHARED / name
            iso = REAL[name]
            nii = Path(d) / (name.split(".")[0] + ".nii")
            subprocess.run([isotopo_bin(), "convert", src, "-o", nii, "-q"], check=True)
            g_t, _, g = run("genus", nii, "--iso", iso, "--json", "-q")
            h_t, h_rss, h = run("handles", nii, "--iso", iso, "--json", "-q")
            a_t, a_rss, a = run("analyze", nii, "--iso", iso, "--json", "-q")
            loops = a["seconds"] - a["seconds_sweep"]
            vox = g["dims"][0] * g["dims"][1] * g["dims"][2]
            print(
                f"{name:<22} {vox:>11,} {len(a['handles']):>7} | {g_t:>7.2f} | {h_t:>7.2f} {h_rss:>5.0f} {h_t / g_t:>11.1f} | {a_t:>9.2f} {a_rss:>5.0f} {100 * loops / a['seconds']:>10.0f}%",
                flush=True,
            )
    print("\nwall times of whole runs on the uncompressed .nii, best of 2; peak RSS from /usr/bin/time -v")


if __name__ == "__main__":
    main(sys.argv[1:])
