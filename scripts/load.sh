#!/usr/bin/env bash
# Concurrent sessions against a real visloc-server on loopback: N `visloc stream` clients at a
# fixed rate on one dataset, then the aggregate frames/s and each session's latency.
# Usage: scripts/load.sh MAP.db DATASET SESSIONS [RATE_HZ=15] [FRAMES=150] [POLICY=all|newest]
# Prints one line per session and a summary (median of the sessions' p50 and the worst p99).
# VISLOC_LOAD_THREADS=N gives the server N engine workers (--threads; default one per core), so
# a saturating run measures frames/s per core for capacity planning (docs/deployment.md).
# VISLOC_LOAD_ENCODING=file sends the image files' bytes as they are (a dataset of JPEG files, as
# scripts/capacity.sh prepares: the clients then cost little); the default is the stream's.
set -euo pipefail
cd "$(dirname "$0")/.."
map=$1 dataset=$2 sessions=$3 rate=${4:-15} frames=${5:-150} policy=${6:-all}
work=$(mktemp -d)
trap 'kill -TERM ${server_pid:-0} 2>/dev/null || true; rm -rf "$work"' EXIT
mkdir -p "$work/maps"
cp "$map" "$work/maps/load.db"
build/server/visloc-server --maps "$work/maps" --listen 127.0.0.1:0 --max-sessions 256 \
  --threads "${VISLOC_LOAD_THREADS:-0}" \
  > "$work/server.out" 2> "$work/server.log" &
server_pid=$!
for _ in $(seq 100); do grep -q "listening on" "$work/server.out" 2>/dev/null && break; sleep 0.1; done
address=$(sed -n 's/^listening on //p' "$work/server.out")
start=$(date +%s.%N)
for i in $(seq "$sessions"); do
  build/client/visloc stream --server "$address" --map load --dataset "$dataset" \
    --rate "$rate" --frames "$frames" --policy "$policy" ${VISLOC_LOAD_ENCODING:+--encoding "$VISLOC_LOAD_ENCODING"} --json > "$work/s$i.json" 2> "$work/s$i.err" &
done
wait $(jobs -p | grep -v "^$server_pid$") 2>/dev/null || true
end=$(date +%s.%N)
field() { sed -n "s/.*\"$2\":\([-0-9.e]*\).*/\1/p" "$1"; }
total=0
for i in $(seq "$sessions"); do
  n=$(field "$work/s$i.json" frames); total=$((total + n))
  echo "session $i: frames $n skipped $(field "$work/s$i.json" skipped) localized $(field "$work/s$i.json" localized_fraction) p50 $(field "$work/s$i.json" latency_ms_p50) ms p99 $(field "$work/s$i.json" latency_ms_p99) ms"
done
p50s=$(for i in $(seq "$sessions"); do field "$work/s$i.json" latency_ms_p50; done | sort -g)
p99s=$(for i in $(seq "$sessions"); do field "$work/s$i.json" latency_ms_p99; done | sort -g)
median_p50=$(echo "$p50s" | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}')
worst_p99=$(echo "$p99s" | tail -1)
awk -v n="$total" -v s="$start" -v e="$end" -v k="$sessions" -v r="$rate" -v p="$median_p50" -v q="$worst_p99" \
  'BEGIN { printf "summary: %d sessions at %s Hz: %d frames answered with a pose or status in %.1f s = %.1f frames/s; latency p50 %s ms (median session), p99 %s ms (worst session)\n", k, r, n, e - s, n / (e - s), p, q }'
