#!/usr/bin/env bash
# The main job on the embedded default: install, build, generate a mapping sequence and a
# query sequence with a kidnapping, build the map, start visloc-server on loopback, stream the
# query through it, print the per-frame story and a summary, draw the plot, and stop the server.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh
VISLOC=build/client/visloc
SERVER=build/server/visloc-server
OUT=${VISLOC_DEMO_OUT:-out/demo}
mkdir -p "$OUT/maps"

echo "== 1. Generating the mapping sequence and a query sequence with a kidnapping (320x240, 15 fps)"
"$VISLOC" sim --out "$OUT" --sequence map_square,kidnap

echo
echo "== 2. Building the map from the stereo mapping sequence"
# A generated rig's calibration is exact; a real rig's map leaves --rig-error out (or gives its own).
"$VISLOC" map build --dataset "$OUT/map_square" --out "$OUT/maps/square.db" --rig-error 0,0
"$VISLOC" map export "$OUT/maps/square.db" --keyframes "$OUT/keyframes.tum"
echo "-- keyframe poses against ground truth:"
"$VISLOC" eval --gt "$OUT/map_square/groundtruth_map.tum" --est "$OUT/keyframes.tum"

echo
echo "== 3. Starting visloc-server on a free loopback port"
"$SERVER" --maps "$OUT/maps" --listen 127.0.0.1:0 > "$OUT/server.out" 2> "$OUT/server.log" &
server_pid=$!
trap 'kill -TERM $server_pid 2>/dev/null || true' EXIT
for _ in $(seq 100); do
  grep -q "listening on" "$OUT/server.out" 2>/dev/null && break
  sleep 0.1
done
address=$(sed -n 's/^listening on //p' "$OUT/server.out")
[[ -n $address ]] || { cat "$OUT/server.log"; echo "the server did not start"; exit 1; }
echo "server at $address"

echo
echo "== 4. Streaming the kidnap sequence through the server at 15 fps (monocular, left images)"
"$VISLOC" stream --server "$address" --map square --dataset "$OUT/kidnap" \
  --trajectory "$OUT/kidnap_localized.tum" --stats "$OUT/kidnap_stats.csv" \
  --gt "$OUT/kidnap/groundtruth_map.tum"
echo "-- per frame, where the status changes (frame, status, inliers/putatives, relocalization):"
awk -F, 'NR > 1 { s = $2; if (s != prev || s == "relocalized") printf "  frame %4d  %-12s %4s/%-4s %s\n", NR - 2, s, $7, $6, $20; prev = s }' \
  "$OUT/kidnap_stats.csv"
# With the stats, eval also checks the sigmas the server reported against the errors.
"$VISLOC" eval --gt "$OUT/kidnap/groundtruth_map.tum" --est "$OUT/kidnap_localized.tum" \
  --stats "$OUT/kidnap_stats.csv"
"$VISLOC" plot --map "$OUT/maps/square.db" --trajectory "$OUT/kidnap_localized.tum" \
  --stats "$OUT/kidnap_stats.csv" --gt "$OUT/kidnap/groundtruth_map.tum" --out "$OUT/kidnap.png"

echo
echo "== 5. For comparison: the walking planner's dead reckoning on the same sequence"
"$VISLOC" eval --gt "$OUT/kidnap/groundtruth_map.tum" --est "$OUT/kidnap/odometry_map.tum"

kill -TERM "$server_pid"
wait "$server_pid" || true
trap - EXIT
echo
echo "Server log: $OUT/server.log"
tail -n 2 "$OUT/server.log" | sed 's/^/  /'
echo "Sequences, ground truth, contact sheets and outputs are in $OUT/."
