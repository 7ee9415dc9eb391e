#!/usr/bin/env bash
# The whole suite under the sanitizers (about an hour on 2 cores; scripts/test.sh, the README's
# test command and CI, is the same suite on one optimized build in under half an hour). Run it
# before a release and after any change to memory, threads or parsing. It installs what is
# missing, then
#   1. builds everything with AddressSanitizer + UndefinedBehaviorSanitizer (build-asan/) and runs
#      the whole suite through CTest in parallel: unit, end-to-end, fault tests, and the replay
#      of the fuzzing corpus and past crashes;
#   2. builds the server's tests with ThreadSanitizer (build-tsan/) and runs its concurrency tests.
# Any sanitizer report fails the run (reports are kept in out/sanitizers/).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
source scripts/test-lib.sh
reports=$PWD/out/sanitizers
rm -rf "$reports" && mkdir -p "$reports"
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1:log_path=$reports/asan
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1:log_path=$reports/ubsan
export TSAN_OPTIONS=halt_on_error=1:second_deadlock_stack=1:log_path=$reports/tsan
# -O1 and no debug information (the reports name functions and lines all the same); the hottest
# loops are compiled at -O2 (visloc_hot_loops_under_sanitizers, cmake/VislocHelpers.cmake).
sanitized=(-DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1)
check_reports() {
  if compgen -G "$reports/*" > /dev/null; then
    echo "sanitizer reports:"
    cat "$reports"/*
    exit 1
  fi
}

echo "== AddressSanitizer + UndefinedBehaviorSanitizer: the whole suite"
configure build-asan "${sanitized[@]}" -DVISLOC_SANITIZE=address,undefined
build build-asan
(cd build-asan && ctest -j"$jobs" --output-on-failure --timeout 900)
check_reports

echo "== ThreadSanitizer: the server's concurrency tests"
# The map cache under racing sessions, the worker permits and the rate limiter, in-process.
# (Debian's gRPC is not built with TSan, so the whole server under TSan reports false races
# inside gRPC's code: docs/reliability.md. VISLOC_TEST_SERVER=build-tsan/server/visloc-server
# runs the end-to-end tests against it by hand, after `cmake --build build-tsan --target
# visloc-server`.)
configure build-tsan "${sanitized[@]}" -DVISLOC_SANITIZE=thread
build build-tsan --target server_test
TSAN_OPTIONS=$TSAN_OPTIONS:suppressions=$PWD/tests/tsan.supp build-tsan/server/server_test
check_reports
echo "all tests passed under ASan+UBSan, and the server's concurrency tests under TSan"
