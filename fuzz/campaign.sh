#!/usr/bin/env bash
# A fuzzing campaign: every target named (default: all) for SECONDS each, JOBS at a time, each
# growing its corpus in corpus/<target> from seeds/<target>; the last lines of each run (its
# CPU time, executions, corpus size, any crash) go to logs/<target>.log. The time is wall time:
# on a busy machine a target gets less CPU time than that. From the repository's root:
#   fuzz/campaign.sh 1200 2                    # 20 minutes a target, two at once
#   fuzz/campaign.sh 600 1 read_nifti read_npy
set -euo pipefail
cd "$(dirname "$0")"
seconds=${1:?seconds per target}
jobs=${2:-1}
shift 2 || shift $#
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
  mapfile -t targets < <(sed -n 's/^name = "\(.*\)"$/\1/p' Cargo.toml | grep -v isotopo-fuzz)
fi
mkdir -p logs
export RUSTC_BOOTSTRAP=1
# The read targets write a file per input: on a memory file system that costs the kernel
# little (on ext4, writeback took half the CPU).
if [ -z "${TMPDIR:-}" ] && [ -d /dev/shm ] && [ -w /dev/shm ]; then
  export TMPDIR=/dev/shm
fi
cargo fuzz build -O >/dev/null
run() {
  local t=$1
  mkdir -p "corpus/$t"
  local len=$([ "$t" = simplify_volume ] && echo 2048 || echo 65536)
  # -rss_limit_mb also bounds each allocation: one sized from a header the file cannot back
  # shows as a crash (artifacts/<target>/).
  local TIMEFORMAT="cpu: %U s user, %S s system, %R s wall"
  { time cargo fuzz run -O "$t" "corpus/$t" "seeds/$t" -- -max_total_time="$seconds" \
    -rss_limit_mb=2048 -max_len="$len" -print_final_stats=1 >"logs/$t.full" 2>&1; } 2>"logs/$t.time" || true
  { cat "logs/$t.time"
    grep -E "^(==|SUMMARY|stat::number_of_executed_units|stat::peak_rss|Done)|Test unit written|deadly signal|panicked" "logs/$t.full" | tail -n 12
    echo "corpus: $(ls "corpus/$t" | wc -l) inputs, $(du -sk "corpus/$t" | cut -f1) KB"; } >"logs/$t.log"
  echo "$t: $(grep -h number_of_executed_units "logs/$t.log" || echo 'no stats (crash?)')"
}
export -f run
export seconds
printf '%s\n' "${targets[@]}" | xargs -P "$jobs" -I{} bash -c 'run {}'
