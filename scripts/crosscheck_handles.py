#!/usr/bin/env python3
"""Every handle is found on the real volumes: `isotopo handles` along each axis, under both
connectivities, must locate exactly as many handles on every surface as its genus from the Euler
characteristic, and the total must equal b1 of the scikit-image oracle computed now."""

import sys

from common import REAL, SHARED, load, run_isotopo, skimage_betti


def main():
    if not SHARED.exists():
        print(f"skipping: {SHARED} not found")
        return 0
    failures = []
    print(f"{'volume':<28} {'conn':>4} {'axis':>4}  {'handles':>7} {'reeb':>6} {'intra':>6} {'oracle b1':>9}  {'s':>6}")
    for name, iso in REAL.items():
        path = SHARED / name
        solid = load(path) > iso
        for conn in (6, 26):
            b1 = skimage_betti(solid, conn)[1]
            for axis in ("x", "y", "z"):
                r = run_isotopo("handles", path, "--iso", iso, "--connectivity", conn, "--axis", axis, "--json", "-q")
                h = r["handles"]
                reeb = sum(x["kind"] == "reeb_cycle" for x in h)
                bad = [s for s in r["surfaces"] if s["genus"] != s["handles"]]
                ok = not bad and len(h) == b1 == r["genus"]
                print(f"{name:<28} {conn:>4} {axis:>4}  {len(h):>7} {reeb:>6} {len(h) - reeb:>6} {b1:>9}  {r['seconds']:>6.2f}{'' if ok else '   <-- MISMATCH'}", flush=True)
                for s in bad:
                    failures.append(f"{name} conn {conn} axis {axis}: surface {s['id']} genus {s['genus']}, {s['handles']} handles located")
                if len(h) != b1:
                    failures.append(f"{name} conn {conn} axis {axis}: {len(h)} handles, oracle b1 {b1}")
    if failures:
        print("\nFAILED:\n" + "\n".join(failures))
        return 1
    print("\nevery handle found on every surface, along every axis")
    return 0


if __name__ == "__main__":
    sys.exit(main())
