#!/usr/bin/env python3
"""The library's layout is the pipeline: no two top-level modules of crates/isotopo/src import
each other, directly or through others (a `crate::x` path anywhere in module y's files, comments
aside, is an import of x by y). Fails on a cycle; lists the order and the longest functions.

    python3 scripts/check_layout.py
"""

import re
import sys
from pathlib import Path

SRC = Path(__file__).resolve().parent.parent / "crates" / "isotopo" / "src"


def imports():
    deps = {}
    for f in SRC.rglob("*.rs"):
        top = f.relative_to(SRC).parts[0].removesuffix(".rs")
        if top == "lib":
            continue
        text = re.sub(r"//.*", "", f.read_text())
        deps.setdefault(top, set()).update(m for m in re.findall(r"crate::([a-z_]+)", text) if m != top)
    return {m: {d for d in ds if d in deps} for m, ds in deps.items()}


def cycle(deps):
    """A cycle of modules, or None (depth-first search, colouring)."""
    state, stack = {}, []

    def visit(m):
        state[m] = "open"
        stack.append(m)
        for d in sorted(deps[m]):
            if state.get(d) == "open":
                return stack[stack.index(d):] + [d]
            if d not in state and (c := visit(d)):
                return c
        state[m] = "done"
        stack.pop()
        return None

    for m in sorted(deps):
        if m not in state and (c := visit(m)):
            return c
    return None


def longest_functions(n=5):
    out = []
    for f in SRC.rglob("*.rs"):
        lines = f.read_text().splitlines()
        for i, line in enumerate(lines):
            m = re.match(r"(\s*)(pub(\([a-z]+\))? )?fn (\w+)", line)
            if not m or line.rstrip().endswith(";"):
                continue
            indent = m.group(1)
            for j in range(i + 1, len(lines)):
                if lines[j] == indent + "}":
                    out.append((j - i + 1, f"{f.relative_to(SRC)}:{i + 1} {m.group(4)}"))
                    break
    return sorted(out, reverse=True)[:n]


def main():
    deps = imports()
    c = cycle(deps)
    if c:
        print("import cycle: " + " -> ".join(c))
        return 1
    order = []
    while len(order) < len(deps):
        order += sorted(m for m in deps if m not in order and deps[m] <= set(order))
    print("no import cycle between modules; bottom up: " + ", ".join(order))
    print("longest functions: " + "; ".join(f"{name} ({n} lines)" for n, name in longest_functions()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
