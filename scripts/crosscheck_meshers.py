"""One topology for every mesher: the outputs of `isotopo simplify` on the real volumes, meshed
by tools that share no code with isotopo, have the genus the report gives.

For every volume in ../shared/data at tau 20 and inf (connectivity 6, the default well-composed
output), and for the input and the `--no-well-composed` output for comparison, the genus of the
isosurface as seen by:

- scikit-image marching cubes (Lewiner; the genus from each closed component's Euler
  characteristic V - E + F);
- VTK flying edges (the same, on VTK's mesh);
- the solid under connectivity 6 and 26 (scikit-image's euler_number and label, as
  scripts/crosscheck_simplify.py).

The meshers run at the report's `mesh_iso`: the isovalue itself, or for integer samples with the
isovalue on a stored value, halfway to the next one (the same samples inside and none on it,
where VTK and isotopo count ties differently). Checks, on the well-composed outputs: critical
faces and cubes (counted here) as the report says; where it says well-composed, all four genera
equal `genus_after`; where not, connectivity 6 and 26 give the report's two genera. Prints the
table of the README.

    python3 scripts/crosscheck_meshers.py [VOLUME ...]

CI runs the same checks on the outputs of scripts/crosscheck_simplify.py (`mesher_failures`);
this script makes the comparison table (with the input and `--no-well-composed`) for the README.
"""

import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from common import REAL, SHARED, load, run_isotopo, skimage_betti, vtk_image


def mesh_genus(verts, faces):
    """Total genus of a triangle mesh: for each connected component, (2 - V + E - F) / 2;
    None if some edge does not have exactly two triangles (not closed)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    faces = np.asarray(faces, dtype=np.int64)
    nv = len(verts)
    if len(faces) == 0:
        return 0
    e = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    keys, counts = np.unique(e[:, 0] * nv + e[:, 1], return_counts=True)
    if (counts != 2).any():
        return None
    edges = np.stack([keys // nv, keys % nv], axis=1)
    graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(nv, nv))
    _, label = connected_components(graph, directed=False)
    used = np.zeros(nv, bool)
    used[faces.ravel()] = True
    v = np.bincount(label[used], minlength=label.max() + 1)
    en = np.bincount(label[edges[:, 0]], minlength=label.max() + 1)
    f = np.bincount(label[faces[:, 0]], minlength=label.max() + 1)
    chi = v - en + f
    chi = chi[v > 0]
    return int(((2 - chi) // 2).sum())


def padded(values, iso, inside):
    """The samples padded by one sample outside (every surface closed): as float32 when that
    holds them exactly (integers of up to 16 bits, float32; half the memory and time), else
    float64."""
    exact32 = values.dtype == np.float32 or (values.dtype.kind in "iu" and values.dtype.itemsize <= 2)
    outside = iso - 1 if inside == "above" else iso + 1
    return np.pad(values.astype(np.float32 if exact32 else np.float64), 1, constant_values=outside)


def skimage_genus(values, iso, inside):
    from skimage.measure import marching_cubes

    v = padded(values, iso, inside)
    verts, faces, _, _ = marching_cubes(v, level=iso)
    return mesh_genus(verts, faces)


def vtk_genus(values, iso, inside):
    import vtk
    from vtk.util import numpy_support

    fe = vtk.vtkFlyingEdges3D()
    fe.SetInputData(vtk_image(padded(values, iso, inside)))
    fe.SetValue(0, iso)
    fe.ComputeNormalsOff()
    fe.ComputeGradientsOff()
    fe.Update()
    poly = fe.GetOutput()
    verts = numpy_support.vtk_to_numpy(poly.GetPoints().GetData()) if poly.GetNumberOfPoints() else np.zeros((0, 3))
    cells = numpy_support.vtk_to_numpy(poly.GetPolys().GetConnectivityArray()) if poly.GetNumberOfPolys() else np.zeros(0, np.int64)
    return mesh_genus(verts, cells.reshape(-1, 3))


def critical_counts(solid):
    """(critical faces, critical cubes) of a boolean array padded with outside, counted here."""
    a = np.pad(solid, 1).astype(np.int8)

    def diagonal(p00, p11, p10, p01):
        return (p00 == p11) & (p10 == p01) & (p00 != p10)

    faces = 0
    for ax in range(3):
        b, c = [d for d in range(3) if d != ax]

        def sl(db, dc):
            idx = [slice(None)] * 3
            idx[b] = slice(db, a.shape[b] - 1 + db)
            idx[c] = slice(dc, a.shape[c] - 1 + dc)
            return a[tuple(idx)]

        faces += int(diagonal(sl(0, 0), sl(1, 1), sl(1, 0), sl(0, 1)).sum())
    corners = [a[dx:a.shape[0] - 1 + dx, dy:a.shape[1] - 1 + dy, dz:a.shape[2] - 1 + dz]
               for dz in (0, 1) for dy in (0, 1) for dx in (0, 1)]
    total = sum(c.astype(np.int16) for c in corners)
    cubes = np.zeros(total.shape, bool)
    for k in range(4):
        pair = corners[k].astype(np.int16) + corners[7 - k]
        cubes |= ((total == 2) & (pair == 2)) | ((total == 6) & (pair == 0))
    return faces, int(cubes.sum())


def seen_by_meshers(values, iso, mesh_iso, inside):
    """The genus scikit-image and VTK mesh at `mesh_iso`, the solid's genus under connectivity
    26, and the critical faces and cubes counted here."""
    solid = values > iso if inside == "above" else values < iso
    return {
        "skimage": skimage_genus(values, mesh_iso, inside),
        "vtk": vtk_genus(values, mesh_iso, inside),
        "c26": skimage_betti(solid, 26)[1],
        "critical": critical_counts(solid),
    }


def report_failures(g, r, what):
    """What `g` (seen_by_meshers) contradicts in the report `r` of a well-composed run."""
    failures = []
    w = r.get("well_composed")
    if w is None:
        return failures
    crit = (w["critical_left"]["faces"], w["critical_left"]["cubes"])
    if g["critical"] != crit:
        failures.append(f"{what}: {g['critical']} critical faces/cubes here, report {crit}")
    if g["c26"] != r["genus_after_other"]:
        failures.append(f"{what}: genus under the other connectivity {g['c26']}, report {r['genus_after_other']}")
    if w["well_composed"]:
        seen = {k: v for k, v in g.items() if k != "critical"}
        if any(v != r["genus_after"] for v in seen.values()):
            failures.append(f"{what}: well-composed but genus {seen}, report {r['genus_after']}")
    return failures


def mesher_failures(values, r, iso, what, inside="above"):
    """The checks of this file on one simplified output (its samples and report), for
    scripts/crosscheck_simplify.py: returns (failures, the genera seen)."""
    g = seen_by_meshers(values, iso, float(r["mesh_iso"]), inside)
    return report_failures(g, r, what), g


def genera(path, iso, mesh_iso, inside):
    """seen_by_meshers of a file, and the genus under connectivity 6."""
    values = load(path)
    solid = values > iso if inside == "above" else values < iso
    return {**seen_by_meshers(values, iso, mesh_iso, inside), "c6": skimage_betti(solid, 6)[1]}


def main():
    names = sys.argv[1:] or list(REAL)
    failures = []
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for name in names:
            iso = REAL[name]
            path = SHARED / name
            suffix = ".nii.gz" if name.endswith(".raw") else "".join(Path(name).suffixes)
            rows_of = []
            for tau in ("20", "inf"):
                for wc in (True, False):
                    out, rep = tmp / f"out{suffix}", tmp / "report.json"
                    args = ["simplify", path, "--iso", iso, "--tau", tau, "-o", out, "--report", rep, "-q"]
                    if not wc:
                        args.append("--no-well-composed")
                    t = time.perf_counter()
                    run_isotopo(*args)
                    secs = time.perf_counter() - t
                    r = json.loads(rep.read_text())
                    mesh_iso = float(r["mesh_iso"])
                    if tau == "20" and wc:
                        g_in = genera(path, float(iso), mesh_iso, "above")
                        rows_of.append((name, "input", g_in, None, None))
                    g = genera(out, float(iso), mesh_iso, "above")
                    rows_of.append((name, f"tau {tau}" + ("" if wc else ", --no-well-composed"), g, r, secs))
                    if not wc:
                        continue
                    what = f"{name} tau {tau}"
                    failures += report_failures(g, r, what)
                    if g["c6"] != r["genus_after"]:
                        failures.append(f"{what}: genus c6 {g['c6']}, report {r['genus_after']}")
            for row in rows_of:
                rows.append(row)
                name, what, g, r, secs = row
                extra = ""
                if r is not None and r.get("well_composed"):
                    w = r["well_composed"]
                    extra = (f"flipped {w['samples_flipped']:>5}, left {w['critical_left']['faces'] + w['critical_left']['cubes']:>3}, "
                             f"at iso {r['samples_at_iso']}, largest move {r['largest_move']:.6g}")
                print(f"{name:<28} {what:<30} | skimage {g['skimage']!s:>5} | vtk {g['vtk']!s:>5} | c6 {g['c6']:>5} "
                      f"| c26 {g['c26']:>5} | critical {g['critical'][0]:>5} {g['critical'][1]:>4} | {extra}", flush=True)
    if failures:
        print("\nFAILED:")
        for f in failures:
            print("  " + f)
        sys.exit(1)
    print("\nevery well-composed output: one genus for scikit-image, VTK, connectivity 6 and 26")


if __name__ == "__main__":
    main()
