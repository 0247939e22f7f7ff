#!/usr/bin/env bash
# Mutation testing (not run by CI): cargo mutants on the given source files, in a scratch copy
# of the committed tree, with incremental release builds (a mutant rebuilds in 2-6 s instead of
# 35-70 s). The tests are those that reach simplify, closure, loops and sweep, less the one that
# takes a minute (fill_only_and_cut_only_on_every_shape): about 28 s a mutant. compose's tests
# are in because simplify composes its output (a field of its report went missing unseen).
#
#   scripts/mutants.sh OUT_DIR FILE... [-- extra cargo-mutants args, e.g. --shard 1/8 or --iterate]
#
# Needs `cargo install cargo-mutants`. Results: OUT_DIR/mutants.out/{caught,missed,...}.txt.
set -euo pipefail
cd "$(dirname "$0")/.."
out="$(realpath -m "$1")"
shift
files=()
while [ $# -gt 0 ] && [ "$1" != "--" ]; do files+=(--file "$1"); shift; done
[ $# -gt 0 ] && shift
scratch="$out/tree"
mkdir -p "$scratch"
git archive HEAD | tar -x -C "$scratch"
cd "$scratch"
export CARGO_PROFILE_RELEASE_INCREMENTAL=true CARGO_PROFILE_RELEASE_DEBUG=false
cargo mutants --in-place "${files[@]}" --test-package isotopo --profile release --timeout 150 \
  --cargo-test-arg=--test=jobs --cargo-test-arg=--test=simplify \
  --cargo-test-arg=--test=oracle_systole --cargo-test-arg=--test=sweep \
  --cargo-test-arg=--test=loops --cargo-test-arg=--test=parts --cargo-test-arg=--test=compose \
  --cargo-test-arg=--lib \
  --cargo-test-arg=-- --cargo-test-arg=--skip --cargo-test-arg=fill_only_and_cut_only_on_every_shape \
  -o "$out" "$@"
