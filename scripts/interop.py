#!/usr/bin/env python3
"""Format interoperability, value by value:
  A. files written by nibabel, pynrrd, numpy and tifffile read correctly in isotopo;
  B. files written by isotopo read correctly in those libraries, with the same geometry;
  C. every volume in ../shared/data reads in isotopo exactly as the Python libraries read it."""

import sys
import tempfile
from pathlib import Path

import numpy as np

from common import SHARED, load, run_isotopo

failures = []


def check(cond, what):
    print(("ok   " if cond else "FAIL ") + what, flush=True)
    if not cond:
        failures.append(what)


def isotopo_values(path, *extra):
    """The samples isotopo reads from `path`, via `isotopo convert` to .npy (raw stored values)."""
    out = Path(path).parent / (Path(path).name.replace(".", "_") + ".out.npy")
    run_isotopo("convert", path, "-o", out, "-q", *extra)
    return np.load(out)


def isotopo_affine(path, *extra):
    return np.array(run_isotopo("info", path, "--json", *extra)["affine"])


def same(a, b):
    """Same shape, same type (whatever the byte order) and the same values."""
    a, b = np.asarray(a), np.asarray(b)
    return a.shape == b.shape and a.dtype.newbyteorder("=") == b.dtype.newbyteorder("=") and np.array_equal(a, b, equal_nan=True)


def written_by_others(d, rng):
    import nibabel as nib
    import nrrd
    import tifffile

    shape = (13, 11, 7)
    arrays = {
        "uint8": rng.integers(0, 256, shape).astype(np.uint8),
        "int16": rng.integers(-32768, 32767, shape).astype(np.int16),
        "uint16": rng.integers(0, 65535, shape).astype(np.uint16),
        "int32": rng.integers(-(2**31), 2**31 - 1, shape).astype(np.int32),
        "float32": rng.standard_normal(shape).astype(np.float32),
        "float64": rng.standard_normal(shape),
    }
    th = np.radians(25)
    affine = np.array([[np.cos(th) * 0.8, -np.sin(th), 0, -12.5], [np.sin(th) * 0.8, np.cos(th), 0, 40.25], [0, 0, 2.5, 7.0], [0, 0, 0, 1]])
    for t, a in arrays.items():
        for ext in (".nii", ".nii.gz"):
            p = d / f"nib_{t}{ext}"
            nib.save(nib.Nifti1Image(a, affine), str(p))
            check(same(isotopo_values(p), a), f"nibabel NIfTI-1 {t} {ext}")
            check(np.allclose(isotopo_affine(p), affine[:3], atol=1e-5), f"nibabel NIfTI-1 {t} {ext} affine")
        p = d / f"nib2_{t}.nii.gz"
        nib.save(nib.Nifti2Image(a, affine), str(p))
        check(same(isotopo_values(p), a), f"nibabel NIfTI-2 {t}")
        if t in ("uint8", "int16", "int32", "float32"):
            p = d / f"nib_{t}.mgz"
            nib.save(nib.MGHImage(a, affine.astype(np.float32)), str(p))
            check(same(isotopo_values(p), a), f"nibabel MGZ {t}")
            check(np.allclose(isotopo_affine(p), nib.load(str(p)).affine[:3], atol=1e-4), f"nibabel MGZ {t} affine")
        for enc in ("raw", "gzip"):
            for endian in ("little", "big"):
                p = d / f"pynrrd_{t}_{enc}_{endian}.nrrd"
                hdr = {"encoding": enc, "endian": endian, "space": "left-posterior-superior", "space directions": np.diag([0.5, 0.75, 2.0]), "space origin": np.array([1.0, 2.0, 3.0])}
                nrrd.write(str(p), a, hdr)
                check(same(isotopo_values(p), a), f"pynrrd {t} {enc} {endian}")
                ras = np.array([[-0.5, 0, 0, -1.0], [0, -0.75, 0, -2.0], [0, 0, 2.0, 3.0]])
                check(np.allclose(isotopo_affine(p), ras), f"pynrrd {t} {enc} {endian} affine (LPS to RAS)")
        p = d / f"pynrrd_{t}_detached.nhdr"
        nrrd.write(str(p), a, {"encoding": "gzip"}, detached_header=True)
        check(same(isotopo_values(p), a), f"pynrrd {t} detached header")
        for order in ("C", "F"):
            p = d / f"numpy_{t}_{order}.npy"
            np.save(str(p), np.asarray(a, order=order))
            check(same(isotopo_values(p), a), f"numpy {t} {order} order")
        # tifffile: pages are z-slices, each page (rows y, columns x).
        p = d / f"tifffile_{t}.tif"
        tifffile.imwrite(str(p), np.ascontiguousarray(a.transpose(2, 1, 0)))
        check(same(isotopo_values(p), a), f"tifffile {t} multi-page")
        p = d / f"raw_{t}.raw"
        a.ravel(order="F").tofile(str(p))
        got = isotopo_values(p, "--raw-dims", ",".join(map(str, shape)), "--raw-type", t)
        check(same(got, a), f"raw {t}")
    # Scaling: scl_slope / scl_inter are applied on read.
    a = arrays["int16"]
    img = nib.Nifti1Image(a, affine)
    img.header.set_slope_inter(0.5, -100.0)
    p = d / "nib_scaled.nii.gz"
    nib.save(img, str(p))
    info = run_isotopo("info", p, "--json")
    f = nib.load(str(p)).get_fdata()
    check(np.isclose(info["stats"]["min"], f.min()) and np.isclose(info["stats"]["max"], f.max()), "scl_slope/scl_inter applied")
    # Big-endian NIfTI.
    p = d / "nib_big.nii"
    img = nib.Nifti1Image(arrays["float32"].astype(">f4"), affine)
    nib.save(img, str(p))
    check(same(isotopo_values(p), arrays["float32"]), "nibabel big-endian NIfTI")


def read_metaimage(path):
    """A MetaImage file read here, independently of isotopo (no MetaImage reader is among the
    requirements): the text header's keys, then the samples, attached (.mha, ElementDataFile =
    LOCAL) or in the named data file (.mhd), zlib-compressed when CompressedData = True. Returns
    the array indexed [x, y, z] and the spacing."""
    import zlib

    data = Path(path).read_bytes()
    fields, pos = {}, 0
    while "ElementDataFile" not in fields:
        end = data.index(b"\n", pos)
        key, _, value = data[pos:end].decode().partition("=")
        fields[key.strip()] = value.strip()
        pos = end + 1
    types = {"MET_UCHAR": "u1", "MET_CHAR": "i1", "MET_USHORT": "u2", "MET_SHORT": "i2",
             "MET_UINT": "u4", "MET_INT": "i4", "MET_FLOAT": "f4", "MET_DOUBLE": "f8"}
    order = ">" if fields.get("BinaryDataByteOrderMSB", fields.get("ElementByteOrderMSB")) == "True" else "<"
    dims = [int(x) for x in fields["DimSize"].split()]
    name = fields["ElementDataFile"]
    raw = data[pos:] if name == "LOCAL" else (Path(path).parent / name).read_bytes()
    if fields.get("CompressedData") == "True":
        raw = zlib.decompress(raw)
    samples = np.frombuffer(raw, dtype=order + types[fields["ElementType"]])
    spacing = [float(x) for x in fields["ElementSpacing"].split()]
    return samples.reshape(dims[::-1]).transpose(2, 1, 0), spacing


def written_by_isotopo(d, rng):
    import nibabel as nib
    import nrrd
    import tifffile

    shape = (9, 8, 6)
    for t in ("uint8", "int16", "float32", "uint16", "float64"):
        a = (rng.standard_normal(shape) * 1000).astype(t) if "float" in t else rng.integers(0, 200, shape).astype(t)
        src = d / f"ref_{t}.npy"
        np.save(str(src), np.asfortranarray(a))
        for ext in (".nii", ".nii.gz", ".nrrd", ".nhdr", ".mgz", ".tif", ".npy", ".mha", ".mhd"):
            if ext == ".mgz" and t in ("uint16", "float64"):
                continue
            out = d / f"iso_{t}{ext}"
            run_isotopo("convert", src, "-o", out, "-q", "--raw-spacing", "0.5,0.75,2")
            if ext in (".nii", ".nii.gz", ".mgz"):
                img = nib.load(str(out))
                got = np.asarray(img.dataobj)
                check(np.allclose(img.affine[:3, :3], np.diag([0.5, 0.75, 2.0]), atol=1e-6), f"isotopo {t} {ext} affine in nibabel")
            elif ext in (".nrrd", ".nhdr"):
                got, hdr = nrrd.read(str(out))
                check(np.allclose(hdr["space directions"], np.diag([0.5, 0.75, 2.0])), f"isotopo {t} {ext} space directions in pynrrd")
            elif ext == ".tif":
                got = tifffile.imread(str(out)).transpose(2, 1, 0)
            elif ext == ".npy":
                got = np.load(str(out))
            else:
                got, spacing = read_metaimage(out)
                check(np.allclose(spacing, [0.5, 0.75, 2.0]), f"isotopo {t} {ext} ElementSpacing")
            check(same(np.asarray(got), a), f"isotopo {t} {ext} read back by Python")


def shared_volumes():
    if not SHARED.exists():
        print(f"skipping shared volumes: {SHARED} not found")
        return
    with tempfile.TemporaryDirectory() as d:
        for p in sorted(SHARED.iterdir()):
            if p.suffix == ".md":
                continue
            expected = load(p)
            out = Path(d) / (p.name + ".npy")
            run_isotopo("convert", p, "-o", out, "-q")
            got = np.load(out).astype(np.float64)
            check(got.shape == expected.shape and np.array_equal(got, expected), f"shared {p.name}: {got.shape} values equal")
            out.unlink()


def main():
    rng = np.random.default_rng(7)
    with tempfile.TemporaryDirectory() as d:
        written_by_others(Path(d), rng)
        written_by_isotopo(Path(d), rng)
    shared_volumes()
    if failures:
        print(f"\n{len(failures)} FAILED:\n" + "\n".join(failures))
        return 1
    print("\nall interoperability checks passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
