#!/usr/bin/env python3
"""Benchmark in the form of Table 1 of Wood, Hoppe, Desbrun and Schröder, "Isosurface Topology
Simplification" (2002), on the real volumes of ../shared/data, with reference tools timed in the
same run and an out-of-core row.

    python3 bench/bench_table1.py [volume names...] [--tau T] [--repeat N] [--big | --no-big]
                                  [--noise SIDES] [--giga] [--json FILE] [--keep DIR]

    volume names   files of ../shared/data (isovalues from scripts/common.py REAL); default
                   buddha-sdf.nii.gz cranium-ct.nii.gz mni2009a-gm.nii.gz freesurfer-wm.mgz
                   bunny-ct.nii.gz (the whole default run takes several minutes and ~3 GB of disk)
    --tau T        handle size threshold of `isotopo simplify` (voxel edges; `inf` allowed), 20
    --repeat N     genus and VTK extraction, the two fast passes compared, are timed best of N (3);
                   every other stage runs once
    --big          out-of-core row (default: on when bunny-ct.nii.gz is among the volumes)
    --noise SIDES  sides of the generated noise cubes of table 2c, comma-separated (default 128:
                   53,546 handles; 0: none)
    --giga         gigavoxel row (table 6; off by default: about 4 minutes and 7 GB of disk)
    --json FILE    write every number below (and the paper's rows) as JSON
    --keep DIR     work in DIR and keep the files (uncompressed inputs, outputs, reports)

What it does, per volume: `isotopo convert` to an uncompressed .nii (.mgh for .mgz) in a work
directory, so that gzip does not dominate the timings; then, each under `/usr/bin/time -v` with -q,
`isotopo genus`, `isotopo handles`, `isotopo analyze` (all --json) and `isotopo simplify --tau T
--report`. Then the reference tools, in this process, on the volume as nibabel reads it from the
original file (on-disk sample type, already in memory): VTK's vtkFlyingEdges3D (extraction only)
and scikit-image's euler_number + label (scripts/common.py skimage_betti, connectivity 6).
A tool whose Python module is missing is skipped with a note.

Tables printed (times are wall seconds of the whole run, file reading included; MiB = peak
resident memory from /usr/bin/time -v; CPU = user + system seconds, isotopo is multithreaded):

  1. Table 1 form      grid, tau, genus before -> after (as reported; "(output)": the genus of
                       the written volume, measured again by `isotopo genus`), #intra-ribbon
                       (handles the first simplify pass met as intra-ribbon), #collapse (handles
                       removed by adding material), #pinch (by removing material), samples
                       changed, simplify wall and CPU seconds, peak MiB.
  2. Stages            wall s / peak MiB of genus, handles (the sweep), analyze (sweep + both loops
                       of every handle) and simplify; handles found by `handles` and how many of
                       them are intra-ribbon; where simplify's time went (report seconds_stages).
  2b. Every handle     simplify --tau inf (wall s, MiB, samples changed, ms per removed handle
      removed          beyond the genus pass) and --spherical (the same, and b0/b1/b2 after).
  2c. Noise           simplify --tau inf on generated noise (bench_analyze.py's: Gaussian-smoothed
                       white noise thresholded at 0, about 26 handles per 1,000 voxels), with one
                       thread (RAYON_NUM_THREADS=1) and with all: wall s, peak MiB, ms per removed
                       handle beyond the genus pass, and the speed-up of all threads over one.
  3. Reference tools   VTK FE s and triangles; skimage s and its b1; genus/FE = isotopo genus wall
                       time / VTK FE time (< 1: the whole isotopo run, reading included, beats VTK's
                       extraction alone); skimage/genus = skimage time / isotopo genus time.
  4. Paper             the paper's Table 1 row for the same model where there is one (CPU minutes
                       on 2002 hardware, their grid and tau), against our simplify CPU and wall
                       minutes. Our Buddha is a signed distance field on a different grid, and the
                       paper's brain is a different scan: the ratios only give orders of magnitude.
  5. Out of core       (--big) bunny-ct and the same CT repeated 4 times along z (512x512x1444
                       int16, written uncompressed with the bunny's header): simplify peak MiB of
                       each and their ratio (target: 4x within 1.25x of 1x, and under 256 MiB),
                       then the 4x simplify again with `--max-slices 0` (whole volume in memory):
                       the two output volumes must be byte-identical (PASS/FAIL). Skipped with a
                       note if the binary does not know --max-slices.
  6. Gigavoxel         (--giga) the bunny CT tiled 2x2x3 (1024x1024x1083 int16, 2.3 GB):
                       simplify --tau T windowed (the default) and with --max-slices 0: wall and
                       CPU s, peak MiB, against the targets (under 120 s, at most 256 MiB), and
                       whether the two outputs are the same bytes (PASS/FAIL).

Consistency checks (genus = handles = analyze = simplify genus_before = skimage b1, removed =
collapse + pinch, b0 and b2 unchanged by simplify, the output volume's Betti numbers = the
report's) are printed as notes when they fail.
"""

import argparse
import hashlib
import importlib.util
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "scripts"))
from common import REAL, SHARED, cpu_seconds, isotopo_bin, load, skimage_betti, timed  # noqa: E402

DEFAULT = ["buddha-sdf.nii.gz", "cranium-ct.nii.gz", "mni2009a-gm.nii.gz", "freesurfer-wm.mgz", "bunny-ct.nii.gz"]
BUNNY = "bunny-ct.nii.gz"
MIB_TARGET = 256  # out-of-core row: the 4x simplify must stay under this (and the gigavoxel run)
GIGA_TILES = (2, 2, 3)  # the gigavoxel row: the bunny CT tiled along x, y and z
GIGA_SECONDS = 120  # ... whose simplify must take less than this
RATIO_TARGET = 1.25  # ... and within this factor of the 1x run

# Table 1 of Wood et al. 2002, transcribed from
# ../shared/paper/wood-hoppe-desbrun-schroeder-2002-isosurface-topology-simplification.txt
# (section 3). Columns: grid, #faces, threshold tau (cube edges), genus original -> simplified,
# #intra-ribbon, handles removed by collapse and by pinching, time in CPU minutes.
PAPER = {
    "Buddha": dict(grid=(400, 400, 950), faces=4736292, tau=9.5, genus=106, genus_after=6, intra=26, collapse=42, pinch=58, minutes=6.5),
    "Dragon": dict(grid=(500, 714, 324), faces=3222612, tau=46.5, genus=60, genus_after=1, intra=18, collapse=31, pinch=28, minutes=3.8),
    "David": dict(grid=(885, 736, 709), faces=15244302, tau=166.5, genus=1063, genus_after=0, intra=76, collapse=332, pinch=731, minutes=87.5),
    "Brain": dict(grid=(125, 255, 255), faces=688248, tau=32.5, genus=366, genus_after=0, intra=6, collapse=320, pinch=46, minutes=2.8),
    "Feline": dict(grid=(332, 148, 316), faces=653922, tau=4.5, genus=6, genus_after=2, intra=1, collapse=2, pinch=2, minutes=0.2),
}
# Our volume -> (paper row, how they differ). Volumes not listed have no counterpart in the paper.
PAPER_MATCH = {
    "buddha-sdf.nii.gz": ("Buddha", "same model (Stanford Happy Buddha) but not the same volume: ours is a signed distance to the VRIP res3 mesh on a {grid} grid, the paper's a 400x400x950 grid"),
    "mni2009a-gm.nii.gz": ("Brain", "not the same data: the paper's brain is a 125x255x255 MRI (Harvard Medical School), ours the {grid} MNI ICBM152 2009a grey-matter map"),
    "freesurfer-wm.mgz": ("Brain", "not the same data: the paper's brain is a 125x255x255 MRI (Harvard Medical School), ours a {grid} FreeSurfer white-matter mask"),
}


def have(module):
    return importlib.util.find_spec(module) is not None


def grid(dims):
    return "x".join(map(str, dims))


def table(headers, rows, right=None):
    """Aligned text table: headers and rows of strings; columns right-aligned except the first."""
    right = right if right is not None else [False] + [True] * (len(headers) - 1)
    widths = [max(len(str(r[i])) for r in [headers, *rows]) for i in range(len(headers))]

    def line(r):
        return "  ".join(str(c).rjust(w) if ra else str(c).ljust(w) for c, w, ra in zip(r, widths, right)).rstrip()

    return "\n".join([line(headers), line(["-" * w for w in widths]), *map(line, rows)])


def f(x, fmt):
    return "-" if x is None or (isinstance(x, float) and np.isnan(x)) else format(x, fmt)


def uncompressed_name(name):
    stem = name.split(".")[0]
    return stem + (".mgh" if name.endswith((".mgz", ".mgh")) else ".nii")


def load_native(path):
    """The volume indexed [x, y, z] in its on-disk sample type when nibabel reads it (float when
    scaled), else as common.load gives it (float64)."""
    if str(path).endswith((".nii", ".nii.gz", ".mgz", ".mgh")):
        import nibabel as nib

        return np.asanyarray(nib.load(str(path)).dataobj)
    return load(path)


def isotopo_stage(*args, repeat=1):
    """Runs an isotopo subcommand under /usr/bin/time -v: dict of wall s, CPU s, peak MiB, and the
    parsed JSON stdout under "json" when --json is among the args."""
    dt, rss, p = timed([isotopo_bin(), *args], repeat=repeat)
    out = {"seconds": dt, "cpu_seconds": cpu_seconds(p), "peak_mib": rss}
    if "--json" in args:
        out["json"] = json.loads(p.stdout)
    return out


def simplify(src, iso, tau, out, report, *extra, check=True):
    """`isotopo simplify` once: dict of wall s, CPU s, peak MiB and the report (None if it failed
    with check=False, then "stderr" holds why)."""
    tau_args = ["--tau", tau] if tau is not None else []  # None: --spherical, which implies tau inf
    dt, rss, p = timed([isotopo_bin(), "simplify", src, "--iso", iso, *tau_args, "-o", out, "--report", report, "-q", *extra], check=check)
    res = {"seconds": dt, "cpu_seconds": cpu_seconds(p), "peak_mib": rss, "returncode": p.returncode, "output": str(out)}
    if p.returncode != 0:
        res["stderr"] = p.stderr.split("\tCommand being timed:")[0].strip()
        res["report"] = None
        return res
    res["report"] = json.loads(Path(report).read_text())
    return res


REPORT_FIELDS = [
    "dims", "tau", "genus_before", "genus_after", "intra_ribbon", "collapse", "pinch", "samples_changed", "samples_filled",
    "samples_cut", "b0_before", "b0_after", "b2_before", "b2_after", "passes", "rewinds", "closures_refused", "seconds",
    "seconds_read", "seconds_simplify", "seconds_write", "seconds_stages",
]


def bench_volume(name, tau, repeat, work, notes):
    src = SHARED / name
    iso = REAL[name]
    row = {"name": name, "iso": iso}
    conv = work / uncompressed_name(name)
    t = time.perf_counter()
    timed([isotopo_bin(), "convert", src, "-o", conv, "-q"])
    row["convert_seconds"] = time.perf_counter() - t
    row["file"] = str(conv)

    print(f"{name}: genus", end="", flush=True)
    g = isotopo_stage("genus", conv, "--iso", iso, "--json", "-q", repeat=repeat)
    gj = g.pop("json")
    row["dims"] = gj["dims"]
    row["voxels"] = int(np.prod(gj["dims"]))
    row["genus"] = {**g, "b0": gj["b0"], "b1": gj["b1"], "b2": gj["b2"], "chi": gj["chi"]}

    print(", handles", end="", flush=True)
    h = isotopo_stage("handles", conv, "--iso", iso, "--json", "-q")
    hj = h.pop("json")
    kinds = [x.get("kind") for x in hj["handles"]]
    row["handles"] = {**h, "genus": hj["genus"], "count": len(kinds), "intra_ribbon": kinds.count("intra_ribbon")}

    print(", analyze", end="", flush=True)
    a = isotopo_stage("analyze", conv, "--iso", iso, "--json", "-q")
    aj = a.pop("json")
    row["analyze"] = {**a, "genus": aj["genus"], "count": len(aj["handles"]), "seconds_sweep": aj.get("seconds_sweep"), "seconds_report": aj.get("seconds")}

    print(", simplify", end="", flush=True)
    out = work / ("simplified-" + conv.name)
    s = simplify(conv, iso, tau, out, work / (conv.stem + "-report.json"))
    r = s.pop("report")
    row["simplify"] = {**s, "report": {k: r.get(k) for k in REPORT_FIELDS}}
    # The written volume, measured again (untimed): its genus must be the report's genus_after.
    oj = isotopo_stage("genus", out, "--iso", iso, "--json", "-q")["json"]
    row["simplify"]["output_betti"] = [oj["b0"], oj["b1"], oj["b2"]]

    # Every handle removed: where a search change shows most (walls decide which handles the
    # sweep meets next), and issue 17's comparison with TopoSimplifier (--spherical).
    for key, tau_x, extra in (("tau_inf", "inf", ()), ("spherical", None, ("--spherical",))):
        print(f", {key}", end="", flush=True)
        s2 = simplify(conv, iso, tau_x, work / f"{key}-{conv.name}", work / f"{conv.stem}-{key}.json", *extra)
        r2 = s2.pop("report")
        row[key] = {**s2, "removed": r2["genus_before"] - r2["genus_after"], "samples_changed": r2["samples_changed"],
                    "after": [r2.get("b0_after"), r2["genus_after"], r2.get("b2_after")]}

    values = None
    if have("vtk") or have("skimage"):
        try:
            values = load_native(src)
            row["loaded_dtype"] = str(values.dtype)
        except ImportError as e:
            notes.append(f"{name}: reference tools skipped, cannot load the volume without {e.name}")
    if values is not None and have("vtk"):
        print(", VTK", end="", flush=True)
        from bench_topology import vtk_flying_edges

        fe_t, fe_tris = vtk_flying_edges(values, float(iso), repeat=repeat)
        row["vtk_fe"] = {"seconds": fe_t, "triangles": fe_tris}
    if values is not None and have("skimage"):
        print(", skimage", end="", flush=True)
        t = time.perf_counter()
        b0, b1, b2, chi = skimage_betti(values > iso, 6)
        row["skimage"] = {"seconds": time.perf_counter() - t, "b0": b0, "b1": b1, "b2": b2, "chi": chi}
    del values
    print(flush=True)

    # Ratios and consistency checks.
    ratios = {}
    if "vtk_fe" in row:
        ratios["genus_over_vtk_fe"] = row["genus"]["seconds"] / row["vtk_fe"]["seconds"]
    if "skimage" in row:
        ratios["skimage_over_genus"] = row["skimage"]["seconds"] / row["genus"]["seconds"]
    row["ratios"] = ratios
    b1 = row["genus"]["b1"]
    for what, v in [("handles genus", hj["genus"]), ("handles count", len(kinds)), ("analyze genus", aj["genus"]),
                    ("analyze count", len(aj["handles"])), ("simplify genus_before", r["genus_before"])] + (
                        [("skimage b1", row["skimage"]["b1"])] if "skimage" in row else []):
        if v != b1:
            notes.append(f"{name}: {what} = {v} but genus b1 = {b1}")
    if "skimage" in row and (row["skimage"]["b0"], row["skimage"]["b2"]) != (gj["b0"], gj["b2"]):
        notes.append(f"{name}: skimage b0/b2 = {row['skimage']['b0']}/{row['skimage']['b2']} but genus b0/b2 = {gj['b0']}/{gj['b2']}")
    down = r["genus_before"] - r["genus_after"] + r.get("handles_opened", 0)
    if r["collapse"] + r["pinch"] != down:
        notes.append(f"{name}: collapse + pinch = {r['collapse'] + r['pinch']} but genus went down by {down} "
                     f"(handles opened by the well-composed step included)")
    if [r.get("b0_after"), r["genus_after"], r.get("b2_after")] != row["simplify"]["output_betti"]:
        notes.append(f"{name}: the simplified volume has b0/b1/b2 = {row['simplify']['output_betti']} by `isotopo genus`, the report says "
                     f"{r.get('b0_after')}/{r['genus_after']}/{r.get('b2_after')}")
    if (r.get("b0_before"), r.get("b2_before")) != (r.get("b0_after"), r.get("b2_after")):
        notes.append(f"{name}: simplify changed b0/b2: {r.get('b0_before')}/{r.get('b2_before')} -> {r.get('b0_after')}/{r.get('b2_after')}")
    if r["intra_ribbon"] != row["handles"]["intra_ribbon"]:
        notes.append(
            f"{name}: simplify counts {r['intra_ribbon']} intra-ribbon handles (first pass, first visit of each slice, after earlier "
            f"closures), `isotopo handles` finds {row['handles']['intra_ribbon']} on the unmodified volume"
        )
    if name in PAPER_MATCH:
        prow, how = PAPER_MATCH[name]
        p = PAPER[prow]
        row["paper"] = {
            "row": prow,
            "difference": how.format(grid=grid(row["dims"])),
            "cpu_minutes": p["minutes"],
            "ours_cpu_minutes": s["cpu_seconds"] / 60,
            "ours_wall_minutes": s["seconds"] / 60,
            "ours_cpu_over_paper": s["cpu_seconds"] / 60 / p["minutes"],
        }
    return row


def bench_noise(sides, work):
    """Table 2c: every handle of generated noise removed, with one thread and with all."""
    from bench_analyze import noise_volume

    rows = []
    for side in sides:
        nii = work / f"noise{side}.nii"
        noise_volume(side, nii)
        print(f"noise {side}^3: genus", end="", flush=True)
        g = isotopo_stage("genus", nii, "--iso", 0, "--json", "-q", repeat=2)
        row = {"side": side, "voxels": side**3, "genus": g["json"]["b1"], "genus_seconds": g["seconds"]}
        for key, threads in (("one_thread", "1"), ("all_threads", None)):
            print(f", simplify --tau inf ({key.replace('_', ' ')})", end="", flush=True)
            env_before = os.environ.pop("RAYON_NUM_THREADS", None)
            if threads is not None:
                os.environ["RAYON_NUM_THREADS"] = threads
            try:
                s = simplify(nii, 0, "inf", work / f"noise{side}-{key}.nii", work / f"noise{side}-{key}.json")
            finally:
                os.environ.pop("RAYON_NUM_THREADS", None)
                if env_before is not None:
                    os.environ["RAYON_NUM_THREADS"] = env_before
            r = s.pop("report")
            removed = r["genus_before"] - r["genus_after"]
            per = (s["seconds"] - row["genus_seconds"]) * 1000 / removed if removed else None
            row[key] = {**s, "removed": removed, "genus_after": r["genus_after"], "ms_per_handle": per,
                        "seconds_stages": r.get("seconds_stages")}
        print(flush=True)
        rows.append(row)
    return rows


def write_repeated_z(src_nii, header_from, dst, copies):
    """Writes dst: the volume of src_nii (uncompressed NIfTI) repeated `copies` times along z, with
    the header (affine, type, scaling) of header_from, streamed slab by slab."""
    return write_tiled(src_nii, header_from, dst, (1, 1, copies))


def write_tiled(src_nii, header_from, dst, tiles):
    """Writes dst: the volume of src_nii (uncompressed NIfTI) tiled (tx, ty, tz) times along x, y
    and z, with the header (affine, type, scaling) of header_from, streamed slab by slab."""
    import nibabel as nib

    hdr = nib.load(str(header_from)).header.copy()
    img = nib.load(str(src_nii), mmap=True)
    sh = img.header
    if (sh.get_data_dtype().newbyteorder("=") != hdr.get_data_dtype().newbyteorder("=") or sh.get_slope_inter() != hdr.get_slope_inter()
            or tuple(img.shape) != tuple(nib.load(str(header_from)).shape)):
        raise SystemExit(f"{src_nii} does not hold the samples of {header_from} as stored: cannot stream them")
    data = img.dataobj.get_unscaled()  # a memmap, [x, y, z] in Fortran order
    nx, ny, nz = data.shape
    tx, ty, tz = tiles
    hdr.set_data_shape((nx * tx, ny * ty, nz * tz))
    hdr["vox_offset"] = 0  # let nibabel place the data right after the header
    dtype = hdr.get_data_dtype()
    with open(dst, "wb") as out:
        hdr.write_to(out)
        out.seek(hdr.get_data_offset())
        for _ in range(tz):
            for z in range(0, nz, 16):
                # A z slab of a Fortran-ordered array, transposed, is C-contiguous in file order:
                # [z, y, x], tiled along y and x.
                slab = np.ascontiguousarray(data[:, :, z:z + 16].T, dtype=dtype)
                np.tile(slab, (1, ty, tx)).tofile(out)
    del data, img
    return (nx * tx, ny * ty, nz * tz)


def sha256(path):
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 24), b""):
            h.update(chunk)
    return h.hexdigest()


def bench_big(rows, tau, work, notes):
    """Out-of-core row: bunny 1x vs 4x along z, and the 4x run windowed vs whole (--max-slices 0)."""
    iso = REAL[BUNNY]
    src = SHARED / BUNNY
    big = {"tau": tau}
    one = next((r for r in rows if r["name"] == BUNNY), None)
    if one is not None:
        conv = Path(one["file"])
        s1 = {k: one["simplify"][k] for k in ("seconds", "cpu_seconds", "peak_mib")}
        s1["genus_before"] = one["simplify"]["report"]["genus_before"]
        s1["genus_after"] = one["simplify"]["report"]["genus_after"]
    else:
        conv = work / uncompressed_name(BUNNY)
        print(f"big: converting {BUNNY}", flush=True)
        timed([isotopo_bin(), "convert", src, "-o", conv, "-q"])
        print(f"big: simplify {BUNNY}", flush=True)
        s = simplify(conv, iso, tau, work / ("simplified-" + conv.name), work / "bunny-report.json")
        s1 = {k: s[k] for k in ("seconds", "cpu_seconds", "peak_mib")}
        s1["genus_before"] = s["report"]["genus_before"]
        s1["genus_after"] = s["report"]["genus_after"]
    big["1x"] = s1

    four = work / "bunny-ct-4z.nii"
    print(f"big: writing {four.name}", flush=True)
    t = time.perf_counter()
    dims = write_repeated_z(conv, src, four, 4)
    big["4x_dims"] = list(dims)
    big["4x_write_seconds"] = time.perf_counter() - t
    print("big: simplify 4x", flush=True)
    s = simplify(four, iso, tau, work / "simplified-bunny-ct-4z.nii", work / "bunny-4z-report.json")
    s4 = {k: s[k] for k in ("seconds", "cpu_seconds", "peak_mib")}
    s4["genus_before"] = s["report"]["genus_before"]
    s4["genus_after"] = s["report"]["genus_after"]
    big["4x"] = s4
    ratio = s4["peak_mib"] / s1["peak_mib"]
    big["peak_ratio"] = ratio
    big["peak_ratio_pass"] = ratio <= RATIO_TARGET
    big["peak_under_target_pass"] = s4["peak_mib"] < MIB_TARGET

    help_text = timed([isotopo_bin(), "simplify", "--help"])[2].stdout
    if "--max-slices" not in help_text:
        big["whole"] = None
        big["identical"] = None
        big["whole_note"] = "this isotopo binary has no --max-slices option (not built in yet?): windowed vs whole-volume comparison skipped"
        notes.append("big: " + big["whole_note"])
        return big
    print("big: simplify 4x with --max-slices 0", flush=True)
    w = simplify(four, iso, tau, work / "simplified-bunny-ct-4z-whole.nii", work / "bunny-4z-whole-report.json", "--max-slices", "0", check=False)
    if w["returncode"] != 0:
        big["whole"] = None
        big["identical"] = None
        big["whole_note"] = f"`isotopo simplify --max-slices 0` failed ({w['returncode']}), comparison skipped: {w['stderr'][:300]}"
        notes.append("big: " + big["whole_note"])
        return big
    big["whole"] = {k: w[k] for k in ("seconds", "cpu_seconds", "peak_mib")}
    a, b = Path(s["output"]), Path(w["output"])
    ha, hb = sha256(a), sha256(b)
    big["sha256_windowed"], big["sha256_whole"] = ha, hb
    big["identical"] = a.stat().st_size == b.stat().st_size and ha == hb
    return big


def bench_giga(tau, work, notes):
    """Gigavoxel row: the bunny CT tiled 2x2x3 (1024x1024x1083 int16, 2.3 GB), simplify --tau T
    windowed (the default) and with the whole volume in memory (--max-slices 0): time, peak
    memory, and whether the two outputs are the same bytes."""
    iso = REAL[BUNNY]
    src = SHARED / BUNNY
    conv = work / uncompressed_name(BUNNY)
    if not conv.exists():
        print(f"giga: converting {BUNNY}", flush=True)
        timed([isotopo_bin(), "convert", src, "-o", conv, "-q"])
    tiled = work / "bunny-ct-2x2x3.nii"
    print(f"giga: writing {tiled.name}", flush=True)
    giga = {"tau": tau, "dims": list(write_tiled(conv, src, tiled, GIGA_TILES))}
    runs = [("windowed", ()), ("whole", ("--max-slices", "0"))]
    for key, extra in runs:
        print(f"giga: simplify ({key})", flush=True)
        out = work / f"simplified-{key}-{tiled.name}"
        s = simplify(tiled, iso, tau, out, work / f"giga-{key}-report.json", *extra, check=False)
        if s["returncode"] != 0:
            notes.append(f"giga: simplify ({key}) failed ({s['returncode']}): {s['stderr'][:300]}")
            giga[key] = None
            continue
        giga[key] = {k: s[k] for k in ("seconds", "cpu_seconds", "peak_mib")}
        giga[key]["genus_before"] = s["report"]["genus_before"]
        giga[key]["genus_after"] = s["report"]["genus_after"]
        giga[key]["sha256"] = sha256(out)
        out.unlink()
    tiled.unlink()
    w, h = giga["windowed"], giga["whole"]
    giga["identical"] = None if not (w and h) else w["sha256"] == h["sha256"]
    giga["time_pass"] = None if not w else w["seconds"] < GIGA_SECONDS
    giga["peak_pass"] = None if not w else w["peak_mib"] <= MIB_TARGET
    return giga


def print_giga(giga):
    print(f"\n6. Gigavoxel: isotopo simplify --tau {giga['tau']} on {BUNNY} tiled "
          f"{'x'.join(map(str, GIGA_TILES))} ({grid(giga['dims'])})\n")
    hdr = ["run", "genus", "after", "wall s", "CPU s", "peak MiB"]
    out = [[n, r["genus_before"], r["genus_after"], f(r["seconds"], ".1f"), f(r["cpu_seconds"], ".1f"),
            f(r["peak_mib"], ".0f")]
           for n, r in [("windowed (default)", giga["windowed"]), ("--max-slices 0", giga["whole"])] if r]
    print(table(hdr, out))
    ok = {True: "PASS", False: "FAIL", None: "SKIP"}
    if giga["windowed"]:
        print(f"\n  windowed wall {giga['windowed']['seconds']:.1f} s (target < {GIGA_SECONDS}): {ok[giga['time_pass']]}")
        print(f"  windowed peak {giga['windowed']['peak_mib']:.0f} MiB (target <= {MIB_TARGET}): {ok[giga['peak_pass']]}")
    print(f"  windowed vs --max-slices 0 outputs byte-identical: {ok[giga['identical']]}")


def print_noise(noise):
    print("\n2c. Every handle of generated noise removed (one run each): simplify --tau inf with one thread and with")
    print("    all; ms/handle = (simplify s - genus s) / handles removed\n")
    hdr = ["volume", "voxels", "genus", "genus s", "1 thread s", "MiB", "ms/handle", "all threads s", "MiB", "ms/handle", "speed-up", "after"]
    out = []
    for r in noise:
        one, every = r["one_thread"], r["all_threads"]
        out.append([f"noise {r['side']}^3", f"{r['voxels']:,}", f"{r['genus']:,}", f(r["genus_seconds"], ".2f"), f(one["seconds"], ".1f"),
                    f(one["peak_mib"], ".0f"), f(one["ms_per_handle"], ".2f"), f(every["seconds"], ".1f"), f(every["peak_mib"], ".0f"),
                    f(every["ms_per_handle"], ".2f"), f(one["seconds"] / every["seconds"], ".2f"), every["genus_after"]])
    print(table(hdr, out))


def print_tables(rows, big, tau, notes, noise=(), giga=None):
    print("\n1. Table 1 form (isotopo simplify, tau = %s voxel edges)\n" % tau)
    hdr = ["volume", "grid", "tau", "genus", "after", "(output)", "#intra", "#collapse", "#pinch", "samples", "wall s", "CPU s", "MiB"]
    out = []
    for r in rows:
        rep = r["simplify"]["report"]
        s = r["simplify"]
        out.append([r["name"], grid(r["dims"]), tau, rep["genus_before"], rep["genus_after"], s["output_betti"][1], rep["intra_ribbon"], rep["collapse"],
                    rep["pinch"], rep["samples_changed"], f(s["seconds"], ".1f"), f(s["cpu_seconds"], ".1f"), f(s["peak_mib"], ".0f")])
    print(table(hdr, out))

    print("\n2. Stages (wall s / peak MiB; genus best of --repeat, others one run)\n")
    hdr = ["volume", "voxels", "convert s", "genus s", "MiB", "handles s", "MiB", "#handles", "(intra)", "analyze s", "MiB",
           "simplify s", "MiB", "sweep", "loops", "closures"]
    out = []
    for r in rows:
        st = r["simplify"]["report"]["seconds_stages"] or {}
        out.append([r["name"], f"{r['voxels']:,}", f(r["convert_seconds"], ".2f"), f(r["genus"]["seconds"], ".2f"), f(r["genus"]["peak_mib"], ".0f"),
                    f(r["handles"]["seconds"], ".2f"), f(r["handles"]["peak_mib"], ".0f"), r["handles"]["count"], r["handles"]["intra_ribbon"],
                    f(r["analyze"]["seconds"], ".2f"), f(r["analyze"]["peak_mib"], ".0f"), f(r["simplify"]["seconds"], ".1f"),
                    f(r["simplify"]["peak_mib"], ".0f"), f(st.get("sweep"), ".1f"), f(st.get("loops"), ".1f"), f(st.get("closures"), ".1f")])
    print(table(hdr, out))

    print("\n2b. Every handle removed (one run each): simplify --tau inf, and --spherical (one component, no handle,")
    print("    no cavity); ms/handle = (simplify s - genus s) / handles removed\n")
    hdr = ["volume", "genus", "inf s", "MiB", "samples", "ms/handle", "spherical s", "MiB", "samples", "after (b0, b1, b2)"]
    out = []
    for r in rows:
        ti, sp = r["tau_inf"], r["spherical"]
        per = (ti["seconds"] - r["genus"]["seconds"]) * 1000 / ti["removed"] if ti["removed"] else None
        out.append([r["name"], r["genus"]["b1"], f(ti["seconds"], ".1f"), f(ti["peak_mib"], ".0f"), f"{ti['samples_changed']:,}", f(per, ".1f"),
                    f(sp["seconds"], ".1f"), f(sp["peak_mib"], ".0f"), f"{sp['samples_changed']:,}", tuple(sp["after"])])
    print(table(hdr, out))

    if noise:
        print_noise(noise)

    print("\n3. Reference tools (in process, volume already in memory)\n")
    hdr = ["volume", "type", "genus s", "b1", "VTK FE s", "triangles", "skimage s", "skimage b1", "genus/FE", "skimage/genus"]
    out = []
    for r in rows:
        fe, sk = r.get("vtk_fe"), r.get("skimage")
        out.append([r["name"], r.get("loaded_dtype", "-"), f(r["genus"]["seconds"], ".3f"), r["genus"]["b1"],
                    f(fe and fe["seconds"], ".3f"), f(fe and fe["triangles"], ","), f(sk and sk["seconds"], ".2f"), sk["b1"] if sk else "-",
                    f(r["ratios"].get("genus_over_vtk_fe"), ".2f"), f(r["ratios"].get("skimage_over_genus"), ".0f")])
    print(table(hdr, out))
    if not have("vtk"):
        print("(VTK skipped: no module named vtk)")
    if not have("skimage"):
        print("(scikit-image skipped: no module named skimage)")

    print("\n4. Against the paper's Table 1 (Wood et al. 2002; their times are CPU minutes on 2002 hardware)\n")
    hdr = ["model", "grid", "#faces", "tau", "genus", "after", "#intra", "#collapse", "#pinch", "minutes"]
    print(table(hdr, [[k, grid(p["grid"]), f"{p['faces']:,}", p["tau"], p["genus"], p["genus_after"], p["intra"], p["collapse"], p["pinch"], p["minutes"]]
                      for k, p in PAPER.items()]))
    matched = [r for r in rows if "paper" in r]
    if matched:
        print()
        hdr = ["our volume", "our grid", "paper row", "paper grid", "paper min", "our CPU min", "our wall min", "our CPU / paper"]
        print(table(hdr, [[r["name"], grid(r["dims"]), r["paper"]["row"], grid(PAPER[r["paper"]["row"]]["grid"]), PAPER[r["paper"]["row"]]["minutes"],
                           f(r["paper"]["ours_cpu_minutes"], ".2f"), f(r["paper"]["ours_wall_minutes"], ".2f"), f(r["paper"]["ours_cpu_over_paper"], ".3f")]
                          for r in matched]))
        for r in matched:
            print(f"  {r['name']}: {r['paper']['difference']}; paper tau {PAPER[r['paper']['row']]['tau']}, ours {tau}.")
    else:
        print("\n(no volume of this run has a counterpart in the paper: buddha-sdf, mni2009a-gm and freesurfer-wm do)")

    if big is not None:
        print(f"\n5. Out of core: isotopo simplify --tau {tau} on {BUNNY} and on it repeated 4 times along z ({grid(big['4x_dims'])})\n")
        hdr = ["run", "genus", "after", "wall s", "CPU s", "peak MiB"]
        out = [[n, big[k]["genus_before"], big[k]["genus_after"], f(big[k]["seconds"], ".1f"), f(big[k]["cpu_seconds"], ".1f"), f(big[k]["peak_mib"], ".0f")]
               for n, k in [("bunny 1x", "1x"), ("bunny 4x", "4x")]]
        if big.get("whole"):
            w = big["whole"]
            out.append(["bunny 4x --max-slices 0", "", "", f(w["seconds"], ".1f"), f(w["cpu_seconds"], ".1f"), f(w["peak_mib"], ".0f")])
        print(table(hdr, out))
        ok = {True: "PASS", False: "FAIL", None: "SKIP"}
        print(f"\n  peak 4x / 1x = {big['peak_ratio']:.2f} (target <= {RATIO_TARGET}): {ok[big['peak_ratio_pass']]}")
        print(f"  peak 4x = {big['4x']['peak_mib']:.0f} MiB (target < {MIB_TARGET}): {ok[big['peak_under_target_pass']]}")
        if big["identical"] is None:
            print(f"  windowed vs --max-slices 0 outputs byte-identical: SKIP ({big['whole_note']})")
        else:
            print(f"  windowed vs --max-slices 0 outputs byte-identical: {ok[big['identical']]} "
                  f"(sha256 {big['sha256_windowed'][:16]}… vs {big['sha256_whole'][:16]}…)")

    if giga is not None:
        print_giga(giga)

    if notes:
        print("\nNotes:")
        for n in notes:
            print("  - " + n)


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog="See the module docstring (top of this file) for what each column means.")
    ap.add_argument("volumes", nargs="*", help=f"files of {SHARED} (default: {' '.join(DEFAULT)})")
    ap.add_argument("--tau", default="20", help="handle size threshold for simplify (default 20)")
    ap.add_argument("--repeat", type=int, default=3, help="best of N for the genus pass and VTK extraction (default 3)")
    ap.add_argument("--big", action=argparse.BooleanOptionalAction, default=None,
                    help=f"out-of-core row: bunny 1x vs 4x along z (default: on when {BUNNY} is among the volumes)")
    ap.add_argument("--giga", action="store_true",
                    help=f"gigavoxel row: {BUNNY} tiled 2x2x3, windowed and whole (about 4 minutes, 7 GB of disk)")
    ap.add_argument("--noise", default="128", metavar="SIDES",
                    help="sides of the noise cubes of table 2c, comma-separated (default 128; 0: none)")
    ap.add_argument("--json", metavar="FILE", help="write all the numbers as JSON")
    ap.add_argument("--keep", metavar="DIR", help="work in DIR and keep the generated files")
    args = ap.parse_args(argv)
    names = args.volumes or DEFAULT
    for n in names:
        if n not in REAL:
            ap.error(f"unknown volume {n!r}: one of {', '.join(REAL)}")
        if not (SHARED / n).exists():
            ap.error(f"{SHARED / n} not found (see ../shared/data/README.md)")
    try:
        sides = [int(x) for x in args.noise.split(",") if int(x) > 0]
    except ValueError:
        ap.error(f"--noise takes sides separated by commas, not {args.noise!r}")
    big_on = args.big if args.big is not None else BUNNY in names
    if big_on and not (SHARED / BUNNY).exists():
        ap.error(f"--big needs {SHARED / BUNNY}")
    if big_on and not have("nibabel"):
        ap.error("--big needs nibabel to write the 4x volume")
    if args.giga and not ((SHARED / BUNNY).exists() and have("nibabel")):
        ap.error(f"--giga needs {SHARED / BUNNY} and nibabel")
    isotopo_bin()

    notes = []
    if not have("vtk"):
        notes.append("VTK reference skipped: Python module vtk is not installed (pip install -r bench/requirements.txt)")
    if not have("skimage"):
        notes.append("scikit-image reference skipped: Python module skimage is not installed (pip install -r bench/requirements.txt)")

    if args.keep:
        work = Path(args.keep)
        work.mkdir(parents=True, exist_ok=True)
        cleanup = None
    else:
        cleanup = tempfile.TemporaryDirectory(prefix="bench_table1-")
        work = Path(cleanup.name)
    try:
        rows = [bench_volume(n, args.tau, args.repeat, work, notes) for n in names]
        big = bench_big(rows, args.tau, work, notes) if big_on else None
        noise = bench_noise(sides, work)
        giga = bench_giga(args.tau, work, notes) if args.giga else None
    finally:
        if cleanup is not None:
            cleanup.cleanup()

    print_tables(rows, big, args.tau, notes, noise, giga)
    if args.keep:
        print(f"\nfiles kept in {work}")
    if args.json:
        doc = {
            "isotopo": isotopo_bin(),
            "tau": args.tau,
            "repeat": args.repeat,
            "cpus": os.cpu_count(),
            "volumes": rows,
            "big": big,
            "noise": noise,
            "giga": giga,
            "paper_table1": {"source": "Wood, Hoppe, Desbrun, Schröder 2002, Table 1; times in CPU minutes", "rows": PAPER},
            "notes": notes,
        }
        Path(args.json).write_text(json.dumps(doc, indent=1) + "\n")
        print(f"numbers written to {args.json}")


if __name__ == "__main__":
    main(sys.argv[1:])
