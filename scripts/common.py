"""Helpers shared by the cross-check and benchmark scripts: loading volumes independently of
isotopo, the scikit-image topology oracle, and running the isotopo binary."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
SHARED = ROOT.parent / "shared" / "data"

# The real volumes and their isovalues (from ../shared/data/README.md).
REAL = {
    "cranium-ct.nii.gz": 226,
    "bunny-ct.nii.gz": 500,
    "lidc2-chest-ct.nii.gz": 59,
    "freesurfer-wm.mgz": 0.5,
    "mni2009a-gm.nii.gz": 127.5,
    "embryo.nrrd": 35,
    "tooth_103x94x161_uint8.raw": 128,
    "buddha-sdf.nii.gz": 0,
}


def isotopo_bin():
    exe = os.environ.get("ISOTOPO", str(ROOT / "target" / "release" / "isotopo"))
    if not Path(exe).exists():
        sys.exit(f"{exe} not found: run `cargo build --release` first (or set ISOTOPO)")
    return exe


def run_isotopo(*args, check=True):
    """Runs isotopo; returns its stdout (parsed as JSON when --json is among the args)."""
    cmd = [isotopo_bin(), *map(str, args)]
    p = subprocess.run(cmd, capture_output=True, text=True)
    if check and p.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({p.returncode}):\n{p.stderr}")
    if "--json" in args:
        return json.loads(p.stdout)
    return p.stdout


def load(path):
    """A volume as a float64 numpy array indexed [x, y, z], read without isotopo."""
    path = Path(path)
    name = path.name.lower()
    if name.endswith((".nii", ".nii.gz", ".mgz", ".mgh")):
        import nibabel as nib

        return np.asarray(nib.load(str(path)).get_fdata(), dtype=np.float64)
    if name.endswith((".nrrd", ".nhdr")):
        import nrrd

        data, _ = nrrd.read(str(path))
        return data.astype(np.float64)
    if name.endswith(".npy"):
        return np.load(str(path)).astype(np.float64)
    if name.startswith("tooth_103x94x161_uint8"):
        return np.fromfile(str(path), dtype=np.uint8).reshape((161, 94, 103)).transpose(2, 1, 0).astype(np.float64)
    raise ValueError(f"no loader for {path}")


def skimage_betti(solid, connectivity):
    """(b0, b1, b2, chi) of the solid (a boolean array) under connectivity 6 or 26, by
    scikit-image (DESIGN.md section 2): euler_number gives chi, label gives b0 and, on the
    complement of the padded volume, b2 + 1."""
    from skimage.measure import euler_number, label

    padded = np.pad(solid.astype(bool), 1)
    if connectivity == 6:
        fg, bg = 1, 3
    else:
        fg, bg = 3, 1
    chi = int(euler_number(padded, connectivity=fg))
    b0 = int(label(padded, connectivity=fg).max())
    b2 = int(label(~padded, connectivity=bg).max()) - 1
    return b0, b0 + b2 - chi, b2, chi
