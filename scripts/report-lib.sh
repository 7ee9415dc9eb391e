# Helpers the report scripts (benchmarks.sh, real-cameras.sh, real-world.sh) share: numbers out of
# visloc's --json output and figure tables, formatting, and a loopback visloc-server. Sourced,
# not run.

# The figure of recording REC named KEY in a figures table (FILE REC KEY; tab-separated lines
# "REC KEY VALUE", as real-world.sh writes docs/real-world.tsv); empty when absent.
value() { awk -F'\t' -v r="$2" -v k="$3" '$1 == r && $2 == k { print $3 }' "$1"; }
# The number after "KEY": in a JSON file (the first occurrence).
field() { sed -n "s/.*\"$2\":\([-0-9.e]*\).*/\1/p" "$1" | head -1; }
# The number after "key": following the first occurrence of "section" in a JSON file (within
# that section's object). `${json#*...}` cuts at the first occurrence; a greedy sed would find
# the last (in `visloc eval --json`, "translation_m" is in both ate and rpe).
field_in() {
  local json
  json=$(tr -d '\n' < "$1")
  json=${json#*\"$2\"}
  sed -n "s/^[^}]*\"$3\":\([-0-9.e]*\).*/\1/p" <<< "$json" | head -1
}
# VALUE times SCALE (default 1) with DIGITS decimals (default 2).
fmt() { awk -v v="$1" -v s="${2:-1}" -v d="${3:-2}" 'BEGIN { printf "%.*f", d, v * s }'; }

# start_server MAPS_DIR WORK_DIR [SERVER FLAGS...]: a visloc-server (SERVER_BIN, by default the
# release build's) on a free loopback port; sets SERVER_PID and SERVER_ADDRESS. stop_server ends it.
start_server() {
  "${SERVER_BIN:-build/server/visloc-server}" --maps "$1" --listen 127.0.0.1:0 "${@:3}" > "$2/server.out" 2> "$2/server.log" &
  SERVER_PID=$!
  for _ in $(seq 100); do grep -q "listening on" "$2/server.out" 2>/dev/null && break; sleep 0.1; done
  SERVER_ADDRESS=$(sed -n 's/^listening on //p' "$2/server.out")
  [[ -n $SERVER_ADDRESS ]] || { cat "$2/server.log"; return 1; }
}
stop_server() {
  kill -TERM "$SERVER_PID"
  wait "$SERVER_PID" || true
}
