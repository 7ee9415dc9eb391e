#!/usr/bin/env bash
# Checks that docker/Dockerfile, docker/compose.yaml and deploy/k8s/ agree with the code: paths,
# binaries, flags, ports, mounts, probes, one writer of the maps (tests/deployment_config_test.cc,
# also part of every CI run). Builds first if needed. Needs no container engine or cluster.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh
cmake --build build --target deployment_config_test -j"$(nproc)" > /dev/null
build/tests/deployment_config_test
