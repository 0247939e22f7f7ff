"""Helpers shared by the cross-check and benchmark scripts: loading volumes independently of
isotopo, the scikit-image topology oracle, running the isotopo binary, and timing a command's
wall time and peak memory."""

import json
import os
import re
import subprocess
import sys
import time
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


def run_isotopo(*args, check=True, timeout=None):
    """Runs isotopo; returns its stdout (parsed as JSON when --json is among the args). With a
    timeout, raises subprocess.TimeoutExpired when the run takes longer."""
    cmd = [isotopo_bin(), *map(str, args)]
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    if check and p.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({p.returncode}):\n{p.stderr}")
    if "--json" in args:
        return json.loads(p.stdout)
    return p.stdout


def timed(cmd, repeat=1, check=True):
    """Runs cmd (a list of arguments, str() applied) under `/usr/bin/time -v`, `repeat` times.
    Returns (wall seconds, peak RSS in MiB, subprocess.CompletedProcess) of the fastest run; the
    process's stdout is the command's, its stderr the command's followed by time's report (see
    cpu_seconds). With check, a failing run prints its stderr and raises CalledProcessError;
    without, the failed run is returned at once (test its returncode)."""
    cmd = ["/usr/bin/time", "-v", *map(str, cmd)]
    best = None
    for _ in range(repeat):
        t = time.perf_counter()
        p = subprocess.run(cmd, capture_output=True, text=True)
        dt = time.perf_counter() - t
        rss = _time_v(p.stderr, "Maximum resident set size (kbytes)") / 1024
        if p.returncode != 0:
            if check:
                sys.stderr.write(p.stderr)
                raise subprocess.CalledProcessError(p.returncode, cmd, p.stdout, p.stderr)
            return dt, rss, p
        if best is None or dt < best[0]:
            best = (dt, rss, p)
    return best


def cpu_seconds(p):
    """User + system CPU seconds of a run returned by timed()."""
    return _time_v(p.stderr, "User time (seconds)") + _time_v(p.stderr, "System time (seconds)")


def _time_v(stderr, field):
    """A number from /usr/bin/time -v's report (the last occurrence: the command's own stderr comes
    first); NaN if absent."""
    found = re.findall(r"^\s*" + re.escape(field) + r": ([0-9.]+)\s*$", stderr, re.M)
    return float(found[-1]) if found else float("nan")


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


def vtk_image(values):
    """A vtkImageData of samples indexed [x, y, z] (VTK's x runs fastest: the array goes in
    Fortran order)."""
    import vtk
    from vtk.util import numpy_support

    image = vtk.vtkImageData()
    image.SetDimensions(*values.shape)
    flat = np.ascontiguousarray(values.transpose(2, 1, 0)).ravel()
    image.GetPointData().SetScalars(numpy_support.numpy_to_vtk(flat, deep=True))
    return image


def skimage_betti(solid, connectivity):
    """(b0, b1, b2, chi) of the solid (a boolean array) under connectivity 6 or 26, by
    scikit-image (docs/ARCHITECTURE.md, facts): euler_number gives chi, label gives b0 and, on the
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


def gudhi_betti(solid, connectivity):
    """(b0, b1, b2) of the solid by gudhi's cubical homology (mod 2): every Betti number from
    the homology itself, not through the Euler characteristic as skimage_betti. Connectivity 26:
    the union of the inside voxels as closed unit cubes; 6: the cubical complex on the voxel
    centres (a cube where all eight corners are inside)."""
    import gudhi

    padded = np.pad(solid.astype(bool), 1)
    values = np.where(padded, 0.0, 1.0)
    if connectivity == 26:
        cc = gudhi.CubicalComplex(top_dimensional_cells=values)
    else:
        cc = gudhi.CubicalComplex(vertices=values)
    cc.compute_persistence(homology_coeff_field=2, min_persistence=-1)
    b = list(cc.persistent_betti_numbers(0.0, 0.0)) + [0, 0, 0]
    return b[0], b[1], b[2]


def workers():
    """How many checks run at once: CROSSCHECK_JOBS, else the machine's cores (isotopo runs
    one core per process, and the oracles mostly one too)."""
    return max(1, int(os.environ.get("CROSSCHECK_JOBS", os.cpu_count() or 1)))


def in_parallel(fn, jobs):
    """fn(*job) for every job, in worker processes; the results in the order of the jobs. Jobs
    print their own lines (flushed, so lines of different jobs do not mix). Put the longest
    jobs first: they are started first."""
    jobs = list(jobs)
    if workers() == 1 or len(jobs) <= 1:
        return [fn(*job) for job in jobs]
    from concurrent.futures import ProcessPoolExecutor

    sys.stdout.flush()  # a forked worker would print the parent's unflushed lines again
    with ProcessPoolExecutor(max_workers=workers()) as pool:
        futures = [pool.submit(fn, *job) for job in jobs]
        return [f.result() for f in futures]
