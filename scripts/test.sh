#!/usr/bin/env bash
# The test command (README, .ci/run): installs what is missing, builds everything once into
# build-test/ and runs the whole suite through CTest on every core: unit, end-to-end against the
# real server and client, fault tests, ROS, the operator's page in Chromium, the deployment
# checks, and the replay of the fuzzing corpus and past crashes.
#
# The build is the release build's optimization (-O3, what robots and benchmarks run) with
# libstdc++'s assertions on: an index past a vector's end or a front() of an empty container
# aborts with the place instead of reading on. 22 min on 2 cores from a fresh clone with the
# packages present, where the same suite under AddressSanitizer and ThreadSanitizer takes an
# hour: that run is scripts/test-sanitizers.sh (docs/reliability.md).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
source scripts/test-lib.sh
configure build-test -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_FLAGS=-D_GLIBCXX_ASSERTIONS
build build-test
(cd build-test && ctest -j"$jobs" --output-on-failure --timeout 900)
echo "all tests passed"
