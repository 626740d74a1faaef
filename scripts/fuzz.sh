#!/usr/bin/env bash
# Builds the libFuzzer targets of the hand-written parsers, the recording's decoders, our checks on third-party
# formats and the surface and label-image readers behind them (assimp, ITK, CGAL's ImageIO) with clang (ASan + UBSan) and runs each for
# the given number of seconds (default 30), starting from the seed files in tests/fuzz/seeds.
set -euo pipefail
cd "$(dirname "$0")/.."
SECONDS_EACH="${1:-30}"
if [ ! -f build-fuzz/CMakeCache.txt ]; then cmake --preset fuzz >/dev/null; fi
cmake --build build-fuzz -j"$(nproc)"
# One fuzzer per core at a time (each is single-threaded): the same time per parser, the whole run in half the time.
fuzz_one() {
  local target=$1
  # The surface and image readers run assimp and ITK, which leak on some files they refuse (a library's, not ours):
  # leaks are not findings there; crashes, hangs and memory past the limit are.
  local leaks=1
  if [ "$target" = surfaces ] || [ "$target" = images ] || [ "$target" = calibration ]; then leaks=0; fi
  local corpus="build-fuzz/corpus-$target" artifacts="build-fuzz/findings-$target/"
  mkdir -p "$corpus" "$artifacts"
  if ! ASAN_OPTIONS="detect_leaks=$leaks" build-fuzz/tests/fuzz/fuzz_$target -max_total_time="$SECONDS_EACH" -max_len=65536 -rss_limit_mb=2048 -timeout=20 \
      -artifact_prefix="$artifacts" -print_final_stats=1 "$corpus" "tests/fuzz/seeds/$target" > "build-fuzz/fuzz-$target.log" 2>&1; then
    echo "fuzz: the $target parser failed; input saved in $artifacts, log in build-fuzz/fuzz-$target.log:" >&2
    # The sanitizer's and libFuzzer's own lines, not the libraries' chatter on the inputs they refuse.
    grep -E "^==[0-9]+== ?ERROR|^SUMMARY|runtime error|deadly signal|ALARM|out-of-memory|Test unit written" \
      "build-fuzz/fuzz-$target.log" | head -8 >&2
    ls "$artifacts" >&2
    return 1
  fi
  echo "== fuzzed the $target parser for ${SECONDS_EACH}s: $(grep -E "^stat::(number_of_executed_units|peak_rss_mb)" \
    "build-fuzz/fuzz-$target.log" | tr -s ' \n' ' ')"
}
jobs_at_once=$(nproc)
status=0
pids=()
for target in gmsh vtk vtu medit recording input_checks surfaces images calibration; do
  fuzz_one "$target" &
  pids+=($!)
  if [ ${#pids[@]} -ge "$jobs_at_once" ]; then
    wait "${pids[0]}" || status=1
    pids=("${pids[@]:1}")
  fi
done
for pid in "${pids[@]}"; do wait "$pid" || status=1; done
exit $status
