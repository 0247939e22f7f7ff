#!/usr/bin/env python3
"""Benchmark of `isotopo handles` (the sweep alone) and `isotopo analyze` (sweep + both loops of
every handle) on the real volumes: wall time, the share spent in loop searches, peak memory, and
the sweep's speed as a ratio to the genus pass in the same run. Then `analyze` on generated
noise with tens to hundreds of thousands of handles, at two sizes, against the genus pass: its
memory must stay flat in the number of handles.

    python3 bench/bench_analyze.py [volume names...] [--noise 128,256 | --no-noise]

    --noise SIDES   sides of the noise cubes (default 128,256: 53,546 and 431,857 handles; the
                    256 one takes several minutes)
"""

import json
import re
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


def noise_volume(side, path):
    """Gaussian-smoothed white noise (sigma 0.7 voxel), unit variance, float32 NIfTI: thresholded
    at 0 its surface is a sponge with about 26 handles per 1,000 voxels."""
    import nibabel
    import numpy as np
    from scipy import ndimage

    rng = np.random.default_rng(7)
    a = ndimage.gaussian_filter(rng.standard_normal((side,) * 3).astype(np.float32), 0.7)
    a = (a / a.std()).astype(np.float32)
    nibabel.save(nibabel.Nifti1Image(a, np.eye(4)), str(path))


# The planes' window analyze may hold by default (--max-slices): the bound on its peak is
# 1.25 x the genus pass's plus this.
WINDOW_MIB = 16


def noise_rows(sides):
    """`genus` and `analyze` (text report, every handle measured) on noise cubes: peak memory
    of both and their ratio, time per handle."""
    print(f"\n{'noise':<10} {'voxels':>11} {'handles':>8} | {'genus s':>7} {'MiB':>5} | {'analyze s':>9} {'MiB':>5} {'MiB / genus':>11} {'bound MiB':>9} | {'ms/handle':>9} {'loops ms/handle':>15}")
    with tempfile.TemporaryDirectory() as d:
        for side in sides:
            nii = Path(d) / f"noise{side}.nii"
            noise_volume(side, nii)
            g_t, g_rss, _ = timed([isotopo_bin(), "genus", nii, "--iso", 0, "--json", "-q"], repeat=2)
            a_t, a_rss, p = timed([isotopo_bin(), "analyze", nii, "--iso", 0, "-q"])
            handles = int(re.search(r"^handles +(\d+)", p.stdout, re.M).group(1))
            loops = float(re.search(r"s sweep, ([\d.]+) s loops", p.stdout).group(1))
            print(
                f"{side}^3{'':<5} {side ** 3:>11,} {handles:>8,} | {g_t:>7.2f} {g_rss:>5.0f} | {a_t:>9.1f} {a_rss:>5.0f} {a_rss / g_rss:>11.2f} {1.25 * g_rss + WINDOW_MIB:>9.0f}{'' if a_rss <= 1.25 * g_rss + WINDOW_MIB else ' OVER'} | {1000 * a_t / handles:>9.3f} {1000 * loops / handles:>15.3f}",
                flush=True,
            )
    print("analyze holds each handle only while it is measured (its report waits in a scratch file), so its")
    print("memory is the sweep's window and the searches' caches, not the handles'; ms/handle is wall time")


def main(args):
    sides = [128, 256]
    names = []
    it = iter(args)
    for a in it:
        if a == "--noise":
            sides = [int(x) for x in next(it).split(",")]
        elif a == "--no-noise":
            sides = []
        else:
            names.append(a)
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
    if sides:
        noise_rows(sides)


if __name__ == "__main__":
    main(sys.argv[1:])
