#!/usr/bin/env bash
# The HTML report in a real browser (headless Chromium, Debian's package: .ci/run installs it).
# For the repository's sample, and the Buddha of ../shared/data when that folder exists, the
# `analyze --html` and `simplify --html` reports are opened and checked by
# scripts/browser/report.test.mjs (no script error, nothing fetched, the handle count of
# `analyze --json` / the simplify report shown, the slider changes the counts, a clicked handle
# draws a non-blank WebGL view with its loops).
#
#   scripts/test_report.sh               # the checks
#   scripts/test_report.sh --screenshots # also rewrite docs/figures/report-*.png
set -euo pipefail
cd "$(dirname "$0")/.."
shots=${1:-}
if [ ! -x "${CHROMIUM:-/usr/bin/chromium}" ]; then
  echo "no Chromium at ${CHROMIUM:-/usr/bin/chromium}: apt-get install chromium (or set CHROMIUM)" >&2
  exit 1
fi
cargo build --release --quiet
bin=$PWD/target/release/isotopo
(cd scripts/browser && npm ci --no-audit --no-fund --silent)
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT

count() { python3 -c "import json, sys; d = json.load(open(sys.argv[1])); print($2)" "$1"; }

check() { # name volume iso
  local name=$1 vol=$2 iso=$3
  echo "== $name: analyze --html"
  "$bin" analyze "$vol" --iso "$iso" --json > "$out/$name.json"
  "$bin" analyze "$vol" --iso "$iso" --html "$out/$name.html" -q | grep '^html'
  local shot=()
  [ "$shots" = --screenshots ] && shot=(--screenshot "docs/figures/report-$name.png")
  node scripts/browser/report.test.mjs "$out/$name.html" \
    "$(count "$out/$name.json" 'len(d["handles"])')" "${shot[@]}"
  echo "== $name: simplify --tau 20 --html"
  "$bin" simplify "$vol" --iso "$iso" --tau 20 -o "$out/$name-simplified.nii.gz" \
    --report "$out/$name-simplify.json" --html "$out/$name-simplify.html" | grep '^html'
  [ "$shots" = --screenshots ] && shot=(--screenshot "docs/figures/report-$name-simplify.png")
  node scripts/browser/report.test.mjs "$out/$name-simplify.html" \
    "$(count "$out/$name-simplify.json" 'sum(r["handles"] for r in d["removed"]) + len(d["kept"])')" "${shot[@]}"
}

check mni data/mni2009a-gm.nii.gz 127.5

# A gyroid, 96³, period 48: a few tens of handles and an overview of more than 65,536 vertices
# (32-bit indices).
python3 - "$out/gyroid.npy" <<'EOF'
import math, struct, sys
n = 96
head = "{'descr': '<f4', 'fortran_order': True, 'shape': (%d, %d, %d), }" % (n, n, n)
head += " " * (63 - (10 + len(head)) % 64) + "\n"
k = 2 * math.pi / 48
values = [math.sin(k * x) * math.cos(k * y) + math.sin(k * y) * math.cos(k * z)
          + math.sin(k * z) * math.cos(k * x) + 0.05
          for z in range(n) for y in range(n) for x in range(n)]
with open(sys.argv[1], "wb") as f:
    f.write(b"\x93NUMPY\x01\x00" + struct.pack("<H", len(head)) + head.encode())
    f.write(struct.pack("<%df" % len(values), *values))
EOF
echo "== gyroid: analyze --html (32-bit indices)"
"$bin" analyze "$out/gyroid.npy" --iso 0 --json > "$out/gyroid.json"
"$bin" analyze "$out/gyroid.npy" --iso 0 --html "$out/gyroid.html" -q | grep '^html'
node scripts/browser/report.test.mjs "$out/gyroid.html" "$(count "$out/gyroid.json" 'len(d["handles"])')"
if [ -d ../shared/data ]; then
  check buddha ../shared/data/buddha-sdf.nii.gz 0
else
  echo "skipping the reports of ../shared/data: folder not found"
fi
echo "== the HTML reports pass in Chromium"
