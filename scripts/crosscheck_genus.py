#!/usr/bin/env python3
"""Cross-check `isotopo genus` on every real volume in ../shared/data, under both connectivities,
against the scikit-image oracle computed now (not copied from a table). Also its survey of where
meshers disagree (`meshers` in the JSON): the other connectivity's Betti numbers against the
oracle's, the critical faces and cubes against a count made here with numpy, and the samples
exactly at the isovalue."""

import sys
import time

from common import REAL, SHARED, load, run_isotopo, skimage_betti


def critical_cells(solid):
    """Critical faces (one diagonal) and cubes (two opposite corners alone) of a mask padded
    with outside, counted with numpy slices."""
    import numpy as np

    m = np.pad(solid, 1)
    faces = 0
    for ax in range(3):
        a = np.moveaxis(m, ax, 0)
        p00, p10, p01, p11 = a[:, :-1, :-1], a[:, 1:, :-1], a[:, :-1, 1:], a[:, 1:, 1:]
        faces += int(((p00 & p11 & ~p10 & ~p01) | (~p00 & ~p11 & p10 & p01)).sum())
    nx, ny, nz = m.shape
    c = [m[dx:nx - 1 + dx, dy:ny - 1 + dy, dz:nz - 1 + dz] for dz in (0, 1) for dy in (0, 1) for dx in (0, 1)]
    ones = sum(x.astype(np.uint8) for x in c)
    cubes = 0
    for k in range(4):
        pair_in = c[k] & c[7 - k]
        pair_out = ~c[k] & ~c[7 - k]
        cubes += int(((ones == 2) & pair_in).sum() + ((ones == 6) & pair_out).sum())
    return faces, cubes


def main():
    if not SHARED.exists():
        print(f"skipping: {SHARED} not found")
        return 0
    failures = []
    print(f"{'volume':<28} {'conn':>4}  {'isotopo b0/b1/b2':>20}  {'oracle b0/b1/b2':>20}  {'isotopo s':>9}  {'oracle s':>8}")
    for name, iso in REAL.items():
        path = SHARED / name
        if not path.exists():
            failures.append(f"{name}: missing")
            continue
        values = load(path)
        solid = values > iso
        oracle, seconds = {}, {}
        for conn in (6, 26):
            t = time.time()
            oracle[conn] = skimage_betti(solid, conn)
            seconds[conn] = time.time() - t
        survey = {
            "critical": critical_cells(solid),
            "samples_at_iso": int((values == iso).sum()),
        }
        for conn in (6, 26):
            r = run_isotopo("genus", path, "--iso", iso, "--connectivity", conn, "--json", "-q")
            got = (r["b0"], r["b1"], r["b2"])
            b0, b1, b2, chi = oracle[conn]
            ts = seconds[conn]
            m = r["meshers"]
            other = 32 - conn
            expected = {
                "betti": oracle[other][:3],
                "critical": survey["critical"],
                "samples_at_iso": survey["samples_at_iso"],
            }
            found = {
                "betti": (m["b0"], m["b1"], m["b2"]),
                "critical": (m["critical"]["faces"], m["critical"]["cubes"]),
                "samples_at_iso": m["samples_at_iso"],
            }
            if m["other_connectivity"] != other or found != expected:
                failures.append(f"{name} conn {conn}: meshers survey {found}, expected {expected}")
            ok = got == (b0, b1, b2) and r["chi"] == chi
            mark = "" if ok else "   <-- MISMATCH"
            print(f"{name:<28} {conn:>4}  {'%d/%d/%d' % got:>20}  {'%d/%d/%d' % (b0, b1, b2):>20}  {r['seconds']:>9.2f}  {ts:>8.1f}{mark}", flush=True)
            if not ok:
                failures.append(f"{name} conn {conn}: isotopo {got} chi {r['chi']}, oracle {(b0, b1, b2)} chi {chi}")
            # Per-surface consistency: genera sum to b1, kinds count b0 and b2.
            s = r["surfaces"]
            if sum(x["genus"] for x in s) != r["b1"] or sum(x["encloses"] == "material" for x in s) != r["b0"]:
                failures.append(f"{name} conn {conn}: surfaces do not add up to the totals")
    if failures:
        print("\nFAILED:\n" + "\n".join(failures))
        return 1
    print("\nall real volumes agree with the scikit-image oracle")
    return 0


if __name__ == "__main__":
    sys.exit(main())
