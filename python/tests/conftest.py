"""Shared pieces of the Python package's tests: the scikit-image topology oracle and the real
volumes (from scripts/common.py, which the cross-check scripts use too)."""

import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "scripts"))

from common import REAL, SHARED, skimage_betti  # noqa: E402

SAMPLE = ROOT / "data" / "mni2009a-gm.nii.gz"
RAW_TOOTH = {"dims": (103, 94, 161), "dtype": "uint8"}


def real_volumes():
    """(name, iso) of every volume in ../shared/data; a skip when the folder is absent."""
    if not SHARED.is_dir():
        return [pytest.param(None, None, marks=pytest.mark.skip(reason=f"{SHARED} not found"))]
    return [pytest.param(name, iso, id=name) for name, iso in REAL.items()]


def reference(name):
    """{6: (b0, b1, b2), 26: (b0, b1, b2)} of a real volume, from scikit-image, as the data
    folder's README tabulates it (computing it again takes 20 s on the largest volume)."""
    for line in (SHARED / "README.md").read_text().splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 6 and cells[0] == f"`{name}`":
            six, twenty_six = (tuple(int(n) for n in c.split("/")) for c in cells[4:6])
            return {6: six, 26: twenty_six}
    raise KeyError(f"{name} is not in {SHARED / 'README.md'}")


def load_real(name):
    import isotopo

    extra = RAW_TOOTH if name.endswith(".raw") else {}
    return isotopo.load(SHARED / name, **extra)


def torus(shape=(40, 40, 20), R=12.0, r=4.0, center=None):
    """Signed field positive inside a torus round z (float64)."""
    c = center or [s / 2 - 0.5 for s in shape]
    x, y, z = np.meshgrid(*[np.arange(n) - ci for n, ci in zip(shape, c)], indexing="ij")
    return r - np.hypot(np.hypot(x, y) - R, z)


def noise(rng, shape, smooth=3):
    """Random smoothed noise in [0, 1]: many handles, cavities and components at mid isovalues."""
    from scipy.ndimage import uniform_filter

    return uniform_filter(rng.random(shape), size=smooth, mode="nearest")


def betti(solid, connectivity=6):
    """(b0, b1, b2) of a boolean solid by scikit-image."""
    return skimage_betti(solid, connectivity)[:3]
