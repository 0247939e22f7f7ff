#!/usr/bin/env bash
# The main job on the small real sample carried in the repository (data/mni2009a-gm.nii.gz):
# describe the volume, measure the topology of its isosurface and every handle, then remove the
# handles smaller than 20 voxel edges and write the volume and meshes before and after.
# Outputs go to out/sample/.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --quiet
bin=target/release/isotopo
vol=data/mni2009a-gm.nii.gz
out=out/sample
mkdir -p $out
run() { echo; echo "== isotopo $*"; $bin "$@"; }
run info "$vol"
run genus "$vol" --iso 127.5
run analyze "$vol" --iso 127.5 --plots $out/plots --loops $out/loops.ply --html $out/report.html
run mesh "$vol" --iso 127.5 -o $out/mni-gm-before.ply
run simplify "$vol" --iso 127.5 --tau 20 -o $out/mni-gm-simplified.nii.gz \
  --mesh $out/mni-gm-after.ply --report $out/simplify.json
run genus $out/mni-gm-simplified.nii.gz --iso 127.5
echo
echo "outputs in $out/: report.html (open it in a browser), plots/ (handle sizes), loops.ply, meshes before and after, the simplified"
echo "volume and simplify.json (every handle removed or kept)"
