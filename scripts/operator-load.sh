#!/usr/bin/env bash
# What watching costs the robots: SESSIONS `visloc stream` clients replay a dataset as fast as
# the server answers, against one visloc-server --http, alternately with nobody watching and
# with WATCHERS operator pages open (each reads /api/events, 5 pushes a second) plus a
# Prometheus scrape of /metrics every second. Prints each run's frames/s and the median ratio
# watched / unwatched (measured in the same run; the machine's noise cancels in the ratio).
# Usage: scripts/operator-load.sh MAP.db DATASET [SESSIONS=8] [FRAMES=150] [ROUNDS=3] [WATCHERS=2]
set -euo pipefail
cd "$(dirname "$0")/.."
map=$1 dataset=$2 sessions=${3:-8} frames=${4:-150} rounds=${5:-3} watchers=${6:-2}
work=$(mktemp -d)
trap 'kill $(jobs -p) 2>/dev/null || true; rm -rf "$work"' EXIT
mkdir -p "$work/maps"
cp "$map" "$work/maps/load.db"
build/server/visloc-server --maps "$work/maps" --listen 127.0.0.1:0 --http 127.0.0.1:0 \
  --max-sessions 64 > "$work/server.out" 2> "$work/server.log" &
for _ in $(seq 100); do grep -q "http on" "$work/server.out" 2>/dev/null && break; sleep 0.1; done
address=$(sed -n 's/^listening on //p' "$work/server.out")
http=$(sed -n 's/^http on //p' "$work/server.out")

# One round of SESSIONS robots; prints its frames/s.
robots() {
  local start end
  start=$(date +%s.%N)
  local pids=()
  for i in $(seq "$sessions"); do
    build/client/visloc stream --server "$address" --map load --dataset "$dataset" --rate 0 \
      --frames "$frames" --json > /dev/null 2>&1 &
    pids+=($!)
  done
  wait "${pids[@]}"
  end=$(date +%s.%N)
  echo "$sessions * $frames / ($end - $start)" | bc -l
}

ratios=()
for round in $(seq "$rounds"); do
  quiet=$(robots)
  watcher_pids=()
  for _ in $(seq "$watchers"); do
    curl -sN "http://$http/api/events" > /dev/null &
    watcher_pids+=($!)
  done
  (while true; do curl -s "http://$http/metrics" > /dev/null; sleep 1; done) &
  watcher_pids+=($!)
  watched=$(robots)
  kill "${watcher_pids[@]}" 2>/dev/null || true
  wait "${watcher_pids[@]}" 2>/dev/null || true
  ratio=$(echo "$watched / $quiet" | bc -l)
  ratios+=("$ratio")
  printf 'round %d: %.1f frames/s unwatched, %.1f watched by %d pages + /metrics at 1 Hz: %.3f\n' \
    "$round" "$quiet" "$watched" "$watchers" "$ratio"
done
median=$(printf '%s\n' "${ratios[@]}" | sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}')
printf 'median ratio watched / unwatched: %.3f (%d robots, %d frames each)\n' "$median" \
  "$sessions" "$frames"
