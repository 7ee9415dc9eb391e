#!/usr/bin/env bash
# The test command: install, build, and run the whole suite through CTest in parallel.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh
cd build
ctest -j"$(nproc)" --output-on-failure --timeout 600
