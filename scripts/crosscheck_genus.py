#!/usr/bin/env python3
"""Cross-check `isotopo genus` on every real volume in ../shared/data, under both connectivities,
against the scikit-image oracle computed now (not copied from a table)."""

import sys
import time

from common import REAL, SHARED, load, run_isotopo, skimage_betti


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
        for conn in (6, 26):
            r = run_isotopo("genus", path, "--iso", iso, "--connectivity", conn, "--json", "-q")
            got = (r["b0"], r["b1"], r["b2"])
            t = time.time()
            b0, b1, b2, chi = skimage_betti(solid, conn)
            ts = time.time() - t
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
