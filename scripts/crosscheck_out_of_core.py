#!/usr/bin/env python3
"""Out of core changes nothing: on real volumes, `isotopo` run with a small window of planes in
memory (`--max-slices 12`, the rest in a scratch file) gives exactly what it gives with the whole
volume in memory (`--max-slices 0`):

- `simplify`: byte-identical output volumes and the same report (times aside);
- `handles` along x and y (input slices gathered into sweep planes): the same handles;
- `analyze`: the same handles with the same loop lengths.

    python3 scripts/crosscheck_out_of_core.py [volume names...]
"""

import filecmp
import json
import sys
import tempfile
from pathlib import Path

from common import REAL, SHARED, run_isotopo

DEFAULT = ["cranium-ct.nii.gz", "mni2009a-gm.nii.gz"]
WINDOW = "12"


def without_times(v):
    """The JSON value with every timing field dropped (they differ from run to run)."""
    if isinstance(v, dict):
        return {k: without_times(x) for k, x in v.items() if not k.startswith("seconds")}
    if isinstance(v, list):
        return [without_times(x) for x in v]
    return v


def main(names):
    failures = []
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        for name in names:
            path, iso = SHARED / name, REAL[name]
            ext = "".join(Path(name).suffixes)
            outs, reports = {}, {}
            for window in (WINDOW, "0"):
                # Same file names in two folders: the reports name their output.
                (d / window).mkdir(exist_ok=True)
                out = d / window / f"out{ext}"
                rep = d / window / "report.json"
                run_isotopo("simplify", path, "--iso", iso, "--tau", 20, "-o", out, "--report", rep, "--max-slices", window, "-q")
                report = without_times(json.loads(rep.read_text()))
                report.pop("output", None)
                outs[window], reports[window] = out, report
            same = filecmp.cmp(outs[WINDOW], outs["0"], shallow=False)
            print(f"{name}: simplify --max-slices {WINDOW} vs 0: outputs {'identical' if same else 'DIFFER'}")
            if not same:
                failures.append(f"{name}: simplify outputs differ")
            if reports[WINDOW] != reports["0"]:
                failures.append(f"{name}: simplify reports differ")
            for axis in ("x", "y"):
                got = [without_times(run_isotopo("handles", path, "--iso", iso, "--axis", axis, "--all", "--json", "--max-slices", w)) for w in (WINDOW, "0")]
                n = len(got[1]["handles"])
                print(f"{name}: handles --axis {axis}: {n} handles, {'same' if got[0] == got[1] else 'DIFFERENT'} out of core")
                if got[0] != got[1]:
                    failures.append(f"{name}: handles along {axis} differ out of core")
            got = [without_times(run_isotopo("analyze", path, "--iso", iso, "--tau", 20, "--json", "--max-slices", w)) for w in (WINDOW, "0")]
            print(f"{name}: analyze: {len(got[1]['handles'])} handles, {'same' if got[0] == got[1] else 'DIFFERENT'} out of core")
            if got[0] != got[1]:
                failures.append(f"{name}: analyze differs out of core")
    if failures:
        sys.exit("FAILED:\n" + "\n".join(failures))
    print("out of core == in memory on every volume")


if __name__ == "__main__":
    main(sys.argv[1:] or DEFAULT)
