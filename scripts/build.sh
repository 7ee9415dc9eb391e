#!/usr/bin/env bash
# Installs what is missing, then configures and builds visloc (Release) into build/ with every
# core. Later runs only rebuild what changed.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release > build-configure.log 2>&1 || { cat build-configure.log; exit 1; }
rm -f build-configure.log
cmake --build build -j"$(nproc)" 2>&1 | grep -E 'error|warning|Error' || true
test -x build/client/visloc || { echo "build failed: build/client/visloc is missing"; exit 1; }
