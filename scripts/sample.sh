#!/usr/bin/env bash
# The main job on the small real sample carried in the repository (data/mni2009a-gm.nii.gz):
# describe the volume, then compute the topology of its isosurface and extract it as a mesh.
# Outputs go to out/sample/.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --quiet
bin=target/release/isotopo
vol=data/mni2009a-gm.nii.gz
mkdir -p out/sample
echo "== isotopo info $vol"
$bin info "$vol"
echo
echo "== isotopo genus $vol --iso 127.5"
$bin genus "$vol" --iso 127.5
echo
echo "== isotopo mesh $vol --iso 127.5 -o out/sample/mni-gm.ply"
$bin mesh "$vol" --iso 127.5 -o out/sample/mni-gm.ply
