#!/usr/bin/env python3
"""Benchmark of the Python package, in one run: `isotopo.genus` on an array in memory against
scikit-image's euler_number + label (the topology oracle, the usual way in Python) as a
ratio, and the cost of the Python call against the command line on the same volume (genus and
simplify --tau 20), with peak memory from /usr/bin/time -v. Best of 3 (scikit-image: 1 run).

Needs the package installed (`pip install .`) in the Python that runs it, and a release
build of the command line:

    python bench/bench_python.py [volume names from ../shared/data...]   # default: the bunny CT
"""

import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "scripts"))
from common import REAL, ROOT, SHARED, isotopo_bin, skimage_betti, timed  # noqa: E402

import isotopo  # noqa: E402


def best(f, repeat=3):
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        result = f()
        times.append(time.perf_counter() - t)
    return min(times), result


def peak_mib(code):
    """Peak RSS of a fresh Python running `code` (isotopo imported)."""
    _, rss, _ = timed([sys.executable, "-c", "import isotopo, numpy as np\n" + code])
    return rss


def bench(name):
    path = SHARED / name if (SHARED / name).exists() else ROOT / "data" / name
    iso = REAL[name]
    vol = isotopo.load(path)
    a = vol.array
    print(f"\n{name}: {a.shape} {a.dtype}, iso {iso}")
    t_py, topo = best(lambda: isotopo.genus(a, iso, progress=False))
    t_sk, sk = best(lambda: skimage_betti(a > iso, 6), repeat=1)
    assert (topo.b0, topo.b1, topo.b2) == sk[:3], (topo, sk)
    print(f"  genus, array in memory: isotopo {t_py:.2f} s, scikit-image euler_number + label "
          f"{t_sk:.2f} s: {t_sk / t_py:.0f}x faster")

    with tempfile.TemporaryDirectory() as d:
        nii = Path(d) / "v.nii"  # uncompressed, page-cached: reading costs the same for both
        isotopo.save(nii, a, like=vol)
        t_load, _ = best(lambda: isotopo.load(nii))
        t_cli, rss_cli, _ = timed([isotopo_bin(), "genus", nii, "--iso", iso, "-q"], repeat=3)
        code = f"v = isotopo.load({str(nii)!r}); isotopo.genus(v, {iso}, progress=False)"
        rss_py = peak_mib(code)
        print(f"  genus of a file: command line {t_cli:.2f} s ({rss_cli:.0f} MiB); Python "
              f"load + genus {t_load + t_py:.2f} s ({rss_py:.0f} MiB, the whole array held)")

        out = Path(d) / "out.nii"
        t_cli_s, rss_cli_s, _ = timed(
            [isotopo_bin(), "simplify", nii, "--iso", iso, "--tau", 20, "-o", out, "-q"], repeat=3
        )
        t_py_s, _ = best(lambda: isotopo.simplify(vol, iso, 20, progress=False))
        code = (f"v = isotopo.load({str(nii)!r}); o, r = isotopo.simplify(v, {iso}, 20, "
                f"progress=False); isotopo.save({str(Path(d) / 'py.nii')!r}, o, like=v)")
        rss_py_s = peak_mib(code)
        print(f"  simplify --tau 20: command line {t_cli_s:.2f} s ({rss_cli_s:.0f} MiB, file to "
              f"file); Python simplify(array) {t_py_s:.2f} s, +load {t_load:.2f} s "
              f"({rss_py_s:.0f} MiB with load and save): overhead "
              f"{(t_py_s + t_load) / t_cli_s - 1:+.0%}")


def main(names):
    for name in names or ["bunny-ct.nii.gz"]:
        bench(name)


if __name__ == "__main__":
    main(sys.argv[1:])
