#!/usr/bin/env bash
# Builds the libFuzzer targets (fuzz/) with clang, AddressSanitizer and UndefinedBehaviorSanitizer
# into build-fuzz/, then runs each for SECONDS from the committed seed corpus (fuzz/corpus/). Prints
# per target: executions, executions per second, coverage and corpus size. A crash stops that
# target and leaves the input in out/fuzz/crashes/TARGET/: fix the bug, then copy the input to
# fuzz/regressions/TARGET/ so CTest replays it in every build from then on.
# Usage: scripts/fuzz.sh [SECONDS=60] [TARGET...]   (targets: frame rpc dataset map ros2_message)
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh --fuzz
seconds=${1:-60}
shift || true
targets=("$@")
[ ${#targets[@]} -eq 0 ] && targets=(frame rpc dataset map ros2_message)
cmake -S . -B build-fuzz -DCMAKE_CXX_COMPILER=clang++ -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g" -DVISLOC_FUZZ=ON -DVISLOC_SANITIZE=address,undefined \
  -DVISLOC_BUILD_TESTS=OFF > /dev/null
cmake --build build-fuzz -j"$(nproc)" --target "${targets[@]/%/_fuzzer}" 2>&1 | grep -E 'error|warning' || true
status=0
for target in "${targets[@]}"; do
  corpus=out/fuzz/corpus/$target crashes=out/fuzz/crashes/$target
  mkdir -p "$corpus" "$crashes"
  cp -n fuzz/corpus/"$target"/* "$corpus"/ 2>/dev/null || true
  log=out/fuzz/$target.log
  if ! ASAN_OPTIONS=detect_leaks=1 build-fuzz/fuzz/"${target}"_fuzzer -max_total_time="$seconds" \
      -print_final_stats=1 -artifact_prefix="$crashes/" -timeout=30 -rss_limit_mb=4096 \
      "$corpus" > "$log" 2>&1; then
    status=1
    echo "$target: CRASH, input in $crashes/ (see $log)"
  fi
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log")
  rate=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log")
  cov=$(grep -oE 'cov: [0-9]+' "$log" | tail -1 | cut -d' ' -f2)
  echo "$target: ${execs:-?} executions in ${seconds} s (${rate:-?}/s), coverage ${cov:-?} edges, corpus $(ls "$corpus" | wc -l) inputs"
done
exit $status
