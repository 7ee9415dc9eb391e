#!/usr/bin/env bash
# The demo client of docker/compose.yaml: a robot's side of the main job against a server in
# another container. Generates a mapping sequence and a query sequence with a kidnapping,
# builds the map, uploads it to the server, streams the query through it and prints the results.
# Usage: visloc-demo-client [SERVER=$VISLOC_SERVER or server:50051]
set -euo pipefail
server=${1:-${VISLOC_SERVER:-server:50051}}
work=${VISLOC_DEMO_OUT:-$HOME/demo}
mkdir -p "$work"
cd "$work"

visloc health --server "$server" --timeout-s 10
echo "== Generating the sequences (320x240, 15 fps)"
visloc sim --out . --sequence map_square,kidnap
echo "== Building the map from the stereo sequence"
visloc map build --dataset map_square --out square.db
echo "== Uploading it to $server"
visloc map upload square.db --server "$server" --replace
echo "== Streaming the kidnap sequence through the server"
visloc stream --server "$server" --map square --dataset kidnap --stats kidnap_stats.csv \
  --trajectory kidnap_localized.tum --gt kidnap/groundtruth_map.tum
visloc eval --gt kidnap/groundtruth_map.tum --est kidnap_localized.tum
