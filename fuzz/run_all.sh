#!/usr/bin/env bash
# Runs every fuzz target for SECS seconds (default 15) on a scratch copy of its seed corpus and
# fails on the first crash, leak, timeout or out-of-memory. Usage: fuzz/run_all.sh [SECS]
# SECS=0 only replays the seed corpus through every target (a smoke run).
# MIMIC_FUZZ_BUILD=--dev for an unoptimised (quicker to build) run.
# The tracked seeds in fuzz/corpus/<target>/ are only read: libFuzzer writes new inputs to fuzz/work/.
set -euo pipefail
cd "$(dirname "$0")"
secs="${1:-15}"
# MIMIC_FUZZ_BUILD=--dev builds without optimisation: ~4x quicker to build cold (CI's smoke run),
# fewer executions per second. The default -O is for long runs.
build="${MIMIC_FUZZ_BUILD:--O}"
export RUSTC_BOOTSTRAP=1 # cargo-fuzz passes -Z flags; the stable toolchain accepts them with this
cargo fuzz build "$build"
for t in $(cargo fuzz list); do
  mkdir -p "work/$t"
  if [ "$secs" -eq 0 ]; then
    limits=(-runs=0)
  else
    limits=(-max_total_time="$secs")
  fi
  echo "== fuzz $t (${secs}s)"
  # -rss_limit_mb: a parser that needs 2 GiB on a <= 4 KiB input is a bug worth failing on.
  if ! cargo fuzz run "$build" "$t" "work/$t" "corpus/$t" -- "${limits[@]}" \
    -max_len=4096 -rss_limit_mb=2048 -timeout=10 -print_final_stats=1 >"work/$t.log" 2>&1; then
    tail -n 60 "work/$t.log"
    echo "fuzz target $t failed: the crashing input is under fuzz/artifacts/$t/"
    exit 1
  fi
  grep -E '^(Done|stat::number_of_executed_units|stat::peak_rss_mb)' "work/$t.log" | tr '\n' ' '
  echo
done
