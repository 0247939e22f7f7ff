#!/usr/bin/env python3
"""Property test against scikit-image and gudhi: random smoothed-noise volumes of several sizes
and isovalues, both connectivities; isotopo's b0, b1, b2 and chi must equal scikit-image's (b1
from the Euler characteristic) and its b0, b1, b2 gudhi's (cubical homology, b1 computed
directly), and the extracted mesh's Euler characteristic must be 2(b0 + b2) - 2 b1."""

import sys
import tempfile
from pathlib import Path

import numpy as np
from scipy.ndimage import uniform_filter

from common import gudhi_betti, run_isotopo, skimage_betti


def ply_euler(path):
    data = Path(path).read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode()
    nv = int(header.split("element vertex ")[1].split()[0])
    nf = int(header.split("element face ")[1].split()[0])
    faces = np.frombuffer(data[end + 12 * nv:], dtype=np.dtype([("n", "u1"), ("v", "<i4", 3)]), count=nf)
    tri = faces["v"]
    edges = np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1)
    ne = len(np.unique(edges, axis=0)) if len(edges) else 0
    return nv - ne + nf


def main(cases=240):
    rng = np.random.default_rng(20261122)
    failures = []
    done = 0
    with tempfile.TemporaryDirectory() as d:
        for k in range(cases // 2):
            shape = tuple(int(s) for s in rng.integers(5, 25, size=3))
            v = rng.random(shape)
            v = uniform_filter(v, size=int(rng.integers(2, 5)), mode="nearest").astype(np.float32)
            iso = float(np.quantile(v, rng.uniform(0.3, 0.7)))
            f = Path(d) / f"v{k}.npy"
            np.save(f, v)
            for conn in (6, 26):
                r = run_isotopo("genus", f, "--iso", iso, "--connectivity", conn, "--json", "-q")
                b0, b1, b2, chi = skimage_betti(v > iso, conn)
                done += 1
                if (r["b0"], r["b1"], r["b2"], r["chi"]) != (b0, b1, b2, chi):
                    failures.append(f"case {k} shape {shape} iso {iso} conn {conn}: isotopo {(r['b0'], r['b1'], r['b2'], r['chi'])}, oracle {(b0, b1, b2, chi)}")
                g = gudhi_betti(v > iso, conn)
                if (r["b0"], r["b1"], r["b2"]) != g:
                    failures.append(f"case {k} shape {shape} iso {iso} conn {conn}: isotopo {(r['b0'], r['b1'], r['b2'])}, gudhi {g}")
                if k % 4 == 0:
                    mesh = Path(d) / f"m{k}_{conn}.ply"
                    run_isotopo("mesh", f, "--iso", iso, "--connectivity", conn, "-o", mesh, "-q")
                    e = ply_euler(mesh)
                    if e != 2 * (b0 + b2) - 2 * b1:
                        failures.append(f"case {k} conn {conn}: mesh chi {e}, expected {2 * (b0 + b2) - 2 * b1}")
    print(f"{done} random volumes checked against scikit-image and gudhi")
    if failures:
        print("FAILED:\n" + "\n".join(failures))
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
