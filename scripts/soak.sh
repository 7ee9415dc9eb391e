#!/usr/bin/env bash
# Sustained load against a real visloc-server on loopback: SESSIONS robots streaming at RATE Hz
# for DURATION seconds. Each robot streams FRAMES-frame sessions back to back (sessions open and
# close all the time, as robots come and go), and the server's resident memory is sampled every
# 5 s. Prints frames/s, latency (median of the sessions' p50, worst p99), sessions completed,
# and memory at the start, the end and its peak; writes OUT/memory.csv (and memory.png).
# Bounded in time and count, loopback only.
# Usage: scripts/soak.sh MAP.db DATASET SESSIONS DURATION_S [RATE_HZ=15] [FRAMES=150] [OUT=out/soak]
set -euo pipefail
cd "$(dirname "$0")/.."
map=$1 dataset=$2 sessions=$3 duration=$4 rate=${5:-15} frames=${6:-150} out=${7:-out/soak}
rm -rf "$out" && mkdir -p "$out/maps" "$out/runs"
cp "$map" "$out/maps/soak.db"
build/server/visloc-server --maps "$out/maps" --listen 127.0.0.1:0 --max-sessions 256 \
  > "$out/server.out" 2> "$out/server.log" &
server_pid=$!
trap 'kill -TERM $server_pid 2>/dev/null || true' EXIT
for _ in $(seq 100); do grep -q "listening on" "$out/server.out" 2>/dev/null && break; sleep 0.1; done
address=$(sed -n 's/^listening on //p' "$out/server.out")
start=$(date +%s.%N)
deadline=$(( $(date +%s) + duration ))

robot() {  # Streams sessions back to back until the deadline.
  local id=$1 n=0
  while [ "$(date +%s)" -lt "$deadline" ]; do
    n=$((n + 1))
    build/client/visloc stream --server "$address" --map soak --dataset "$dataset" --rate "$rate" \
      --frames "$frames" --json > "$out/runs/r${id}_$n.json" 2> "$out/runs/r${id}_$n.err" || true
  done
}
for i in $(seq "$sessions"); do robot "$i" & done

echo "seconds,server RSS (MiB)" > "$out/memory.csv"
while [ "$(date +%s)" -lt "$deadline" ]; do
  rss_kb=$(awk '/^VmRSS/ {print $2}' "/proc/$server_pid/status")
  awk -v t="$(date +%s.%N)" -v s="$start" -v r="$rss_kb" 'BEGIN { printf "%.0f,%.1f\n", t - s, r / 1024 }' >> "$out/memory.csv"
  sleep 5
done
wait $(jobs -p | grep -v "^$server_pid$") 2>/dev/null || true
end=$(date +%s.%N)
rss_kb=$(awk '/^VmRSS/ {print $2}' "/proc/$server_pid/status")
awk -v t="$end" -v s="$start" -v r="$rss_kb" 'BEGIN { printf "%.0f,%.1f\n", t - s, r / 1024 }' >> "$out/memory.csv"

field() { sed -n "s/.*\"$2\":\([-0-9.e]*\).*/\1/p" "$1"; }
total=0 completed=0 failed=0
for f in "$out"/runs/*.json; do
  n=$(field "$f" frames)
  if [ -n "$n" ]; then total=$((total + n)); completed=$((completed + 1)); else failed=$((failed + 1)); fi
done
p50=$(for f in "$out"/runs/*.json; do field "$f" latency_ms_p50; done | sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}')
p99=$(for f in "$out"/runs/*.json; do field "$f" latency_ms_p99; done | sort -g | tail -1)
mem=$(awk -F, 'NR == 2 {first = $2} NR > 1 {last = $2; if ($2 > peak) peak = $2} END {printf "start %.1f MiB, end %.1f MiB, peak %.1f MiB", first, last, peak}' "$out/memory.csv")
build/client/visloc plot --curves "$out/memory.csv" --out "$out/memory.png" > /dev/null || true
kill -TERM "$server_pid"; wait "$server_pid" || true
trap - EXIT
awk -v n="$total" -v s="$start" -v e="$end" -v k="$sessions" -v r="$rate" -v c="$completed" -v x="$failed" -v p="$p50" -v q="$p99" -v m="$mem" \
  'BEGIN { printf "soak: %d robots at %s Hz for %.0f s: %d sessions completed (%d failed), %d frames answered = %.1f frames/s; latency p50 %s ms (median session), p99 %s ms (worst session); server memory %s\n", k, r, e - s, c, x, n, n / (e - s), p, q, m }'
