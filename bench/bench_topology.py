#!/usr/bin/env python3
"""Benchmark of the genus pass and mesh extraction against reference tools, in one run:
vtkFlyingEdges3D (extraction only, volume already in memory) and scikit-image's euler_number +
label (the topology oracle). isotopo is timed on the uncompressed .nii (page-cached), reading
included. Peak memory from /usr/bin/time -v.

    python3 bench/bench_topology.py [volume names...]
"""

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "scripts"))
from common import REAL, SHARED, isotopo_bin, load, skimage_betti, timed, vtk_image  # noqa: E402


def timed_isotopo(*args):
    """(wall seconds, peak RSS MiB, stdout) of one isotopo run, best of 3 for the time."""
    dt, rss, p = timed([isotopo_bin(), *args], repeat=3)
    return dt, rss, p.stdout


def vtk_flying_edges(values, iso, repeat=3):
    """(best seconds of `repeat` vtkFlyingEdges3D updates, triangles) on values indexed [x, y, z]."""
    import vtk

    img = vtk_image(values)
    best = None
    for _ in range(repeat):
        fe = vtk.vtkFlyingEdges3D()
        fe.SetInputData(img)
        fe.SetValue(0, iso)
        fe.ComputeNormalsOff()
        fe.ComputeGradientsOff()
        fe.ComputeScalarsOff()
        t = time.perf_counter()
        fe.Update()
        dt = time.perf_counter() - t
        best = dt if best is None else min(best, dt)
    return best, fe.GetOutput().GetNumberOfCells()


def main(names):
    names = names or ["bunny-ct.nii.gz", "mni2009a-gm.nii.gz"]
    rows = []
    with tempfile.TemporaryDirectory() as d:
        for name in names:
            src = SHARED / name
            iso = REAL[name]
            nii = Path(d) / (name.split(".")[0] + ".nii")
            subprocess.run([isotopo_bin(), "convert", src, "-o", nii, "-q"], check=True)
            values = load(src)
            voxels = values.size
            g_t, g_rss, _ = timed_isotopo("genus", nii, "--iso", iso, "--json", "-q")
            m_wall, m_rss, out = timed_isotopo("mesh", nii, "--iso", iso, "-o", Path(d) / "m.ply", "--json")
            m_t = json.loads(out)["seconds_extraction"]
            fe_t, fe_tris = vtk_flying_edges(values, iso)
            t = time.perf_counter()
            skimage_betti(values > iso, 6)
            sk_t = time.perf_counter() - t
            rows.append((name, voxels, g_t, g_rss, m_t, m_rss, fe_t, fe_tris, sk_t))
    print(f"\n{'volume':<20} {'voxels':>11} | {'genus s':>8} {'Mvox/s':>7} {'MiB':>5} | {'mesh s':>7} {'MiB':>5} | {'VTK FE s':>8} | {'skimage s':>9} | {'genus/FE':>8} {'skimage/genus':>13} {'mesh/FE':>7}")
    for (name, vox, g_t, g_rss, m_t, m_rss, fe_t, fe_tris, sk_t) in rows:
        print(
            f"{name:<20} {vox:>11,} | {g_t:>8.2f} {vox / g_t / 1e6:>7.0f} {g_rss:>5.0f} | {m_t:>7.2f} {m_rss:>5.0f} | {fe_t:>8.2f} | {sk_t:>9.1f} | {g_t / fe_t:>8.2f} {sk_t / g_t:>13.0f} {m_t / fe_t:>7.2f}"
        )
    print("\ngenus/FE < 1: the whole genus pass (reading the file included) beats VTK's extraction alone;")
    print("mesh s: extraction (reading the file included, writing the PLY excluded), best of 3.")


if __name__ == "__main__":
    main(sys.argv[1:])
