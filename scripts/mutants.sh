#!/usr/bin/env bash
# Mutation testing (not run by CI): cargo mutants on the given source files, in a scratch copy
# of the committed tree, with incremental release builds. The tests are those that reach
# simplify, closure, loops and sweep, less the one that takes a minute
# (fill_only_and_cut_only_on_every_shape); compose's tests are in because simplify composes its
# output (a field of its report went missing unseen), but not compose's own unit tests: compose
# calls none of the four modules, and its slowest test is the library's slowest (19 s alone on
# a loaded machine; the library's tests took 17 s of a mutant's 41 s, shard 25's baseline). Only those test targets are built: they
# are given with --cargo-arg, which reaches the build step too (--cargo-test-arg did not, and
# every test target of the package was built for each mutant).
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
  --cargo-arg=--test=jobs --cargo-arg=--test=simplify \
  --cargo-arg=--test=oracle_systole --cargo-arg=--test=sweep \
  --cargo-arg=--test=loops --cargo-arg=--test=parts --cargo-arg=--test=compose \
  --cargo-arg=--lib \
  --cargo-test-arg=-- --cargo-test-arg=--skip --cargo-test-arg=fill_only_and_cut_only_on_every_shape \
  --cargo-test-arg=--skip --cargo-test-arg=compose::tests:: \
  -o "$out" "$@"
