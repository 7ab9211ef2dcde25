#!/usr/bin/env bash
# Runs every libFuzzer target of fuzz/ for SECONDS each; fails on any crash, leak or timeout.
# Usage: scripts/run-fuzz.sh BUILD_DIR SECONDS [TARGET...] (default: every target). The committed seed corpus (fuzz/corpus/NAME) is
# copied to a scratch corpus, so runs never modify the repository; crash inputs are written to
# out/fuzz/NAME-crash-* (add them to tests/fuzz_regression_test.cpp once fixed).
set -euo pipefail
build=${1:?build dir}
seconds=${2:-60}
root=$(cd "$(dirname "$0")/.." && pwd)
mkdir -p "$root/out/fuzz"
status=0
targets=("${@:3}")
[ ${#targets[@]} -gt 0 ] || targets=(json_scene model pk3 cli texture)
for target in "${targets[@]}"; do
  bin="$build/fuzz_$target"
  [ -x "$bin" ] || { echo "run-fuzz: $bin missing" >&2; exit 1; }
  scratch=$(mktemp -d)
  opts=(-max_total_time="$seconds" -timeout=20 -rss_limit_mb=4096 -print_final_stats=1 -close_fd_mask=3
        -artifact_prefix="$root/out/fuzz/$target-")
  [ "$target" = json_scene ] && opts+=(-dict="$root/fuzz/json.dict")
  # An importer that crashes is jumped out of (fuzz/README.md); what it held is lost, not leaked
  # by our code, so the two assimp targets run without leak detection.
  leaks=1
  case $target in model|pk3) opts+=(-detect_leaks=0); leaks=0 ;; esac
  echo "run-fuzz: $target for ${seconds}s"
  if ! ASAN_OPTIONS=abort_on_error=1:detect_leaks=$leaks UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1 \
      "$bin" "${opts[@]}" "$scratch" "$root/fuzz/corpus/$target" > "$root/out/fuzz/$target.log" 2>&1; then
    echo "run-fuzz: $target FAILED (see out/fuzz/$target.log)" >&2
    tail -40 "$root/out/fuzz/$target.log" >&2
    status=1
  else
    grep -E "stat::number_of_executed_units|cov: " "$root/out/fuzz/$target.log" | tail -2
  fi
  rm -rf "$scratch"
done
exit $status
