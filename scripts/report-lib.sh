# Helpers the report scripts (benchmarks.sh, real-cameras.sh, real-world.sh) share: numbers out of
# visloc's --json output and figure tables, formatting, and a loopback visloc-server. Sourced,
# not run.

# Which clones of the hot loops this CPU runs (core/util/cpu_dispatch.h): "AVX-512", "AVX2" or
# "baseline". Absolute times differ by it from machine to machine; a run's ratios do not.
vector_level() {
  if grep -qw avx512bw /proc/cpuinfo && grep -qw avx512vl /proc/cpuinfo &&
    grep -qw avx512dq /proc/cpuinfo; then
    echo AVX-512
  elif grep -qw avx2 /proc/cpuinfo; then
    echo AVX2
  else
    echo baseline
  fi
}

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

# mh01_setup WORK_DIR: for the scripts that load a server with EuRoC MH_01's frames
# (capacity.sh, admission.sh, soak-held.sh): V (the CLI), REC (the recording, which must be
# there) and WORK_DIR/maps/mh01.db (its map, built once).
mh01_setup() {
  V=$PWD/build/client/visloc
  REC=${VISLOC_REAL_DATA:-$PWD/../shared/real}/euroc_mh01_moving
  [[ -d $REC ]] || { echo "no $REC: this needs the real recordings" >&2; exit 1; }
  mkdir -p "$1/maps"
  [[ -f $1/maps/mh01.db ]] || "$V" map build --dataset "$REC" --out "$1/maps/mh01.db" > /dev/null
}

# build_baseline REV DIR: revision REV built (Release: visloc and visloc-server) in a worktree at
# DIR/src, binaries in DIR/build; kept while DIR/commit names REV. Sets BASELINE_COMMIT.
build_baseline() {
  BASELINE_COMMIT=$(git rev-parse --short "$1")
  [[ $(cat "$2/commit" 2>/dev/null) == "$BASELINE_COMMIT" ]] && return
  rm -rf "$2"
  git worktree prune
  git worktree add --detach "$2/src" "$BASELINE_COMMIT" > /dev/null
  cmake -S "$2/src" -B "$2/build" -DCMAKE_BUILD_TYPE=Release > /dev/null
  cmake --build "$2/build" -j"$(nproc)" --target visloc visloc-server > /dev/null
  echo "$BASELINE_COMMIT" > "$2/commit"
}

# start_server MAPS_DIR WORK_DIR [SERVER FLAGS...]: a visloc-server (SERVER_BIN, by default the
# release build's) on a free loopback port; sets SERVER_PID and SERVER_ADDRESS, and SERVER_HTTP
# when the flags ask for --http. stop_server ends it.
start_server() {
  "${SERVER_BIN:-build/server/visloc-server}" --maps "$1" --listen 127.0.0.1:0 "${@:3}" > "$2/server.out" 2> "$2/server.log" &
  SERVER_PID=$!
  local wanted="listening on"
  [[ " ${*:3} " == *" --http "* ]] && wanted="http on"  # Printed after the gRPC address.
  for _ in $(seq 100); do grep -q "$wanted" "$2/server.out" 2>/dev/null && break; sleep 0.1; done
  SERVER_ADDRESS=$(sed -n 's/^listening on //p' "$2/server.out")
  SERVER_HTTP=$(sed -n 's/^http on //p' "$2/server.out")
  [[ -n $SERVER_ADDRESS ]] || { cat "$2/server.log"; return 1; }
}
stop_server() {
  kill -TERM "$SERVER_PID"
  wait "$SERVER_PID" || true
}

# subset SRC OUT FIRST END STEP: frames FIRST, FIRST+STEP, ... before END of recording SRC as a
# recording of its own in OUT (links, not copies), and OUT/frames.txt: "timestamp_ns image" lines.
# frames.txt is written last, so a subset cut short (a run stopped) is made again, not reused.
subset() {
  local src=$1 out=$2 first=$3 end=$4 step=$5
  [[ -f $out/frames.txt ]] && return
  rm -rf "$out"
  mkdir -p "$out"
  if [[ -d $src/mav0 ]]; then
    for cam in cam0 cam1; do
      mkdir -p "$out/mav0/$cam/data"
      cp "$src/mav0/$cam/sensor.yaml" "$out/mav0/$cam/"
      awk -F, -v f="$first" -v e="$end" -v s="$step" '
        /^#/ { print; next }
        { i = n++; if (i >= f && i < e && (i - f) % s == 0) print }' \
        "$src/mav0/$cam/data.csv" | tr -d '\r' > "$out/mav0/$cam/data.csv"
      grep -v '^#' "$out/mav0/$cam/data.csv" | cut -d, -f2 |
        while read -r image; do ln -s "$src/mav0/$cam/data/$image" "$out/mav0/$cam/data/$image"; done
    done
    [[ -f $src/mav0/body.yaml ]] && cp "$src/mav0/body.yaml" "$out/mav0/"
    grep -v '^#' "$out/mav0/cam0/data.csv" |
      awk -F, -v dir="$out/mav0/cam0/data" '{ print $1, dir "/" $2 }' > "$out/frames.partial"
  else
    mkdir -p "$out/image_0" "$out/image_1"
    cp "$src/calib.txt" "$out/"
    local i=0 k=0 time
    : > "$out/times.txt"
    : > "$out/frames.partial"
    while read -r time; do
      if (( i >= first && i < end && (i - first) % step == 0 )); then
        echo "$time" >> "$out/times.txt"
        for cam in image_0 image_1; do
          ln -s "$src/$cam/$(printf %06d $i).png" "$out/$cam/$(printf %06d $k).png"
        done
        awk -v t="$time" -v p="$out/image_0/$(printf %06d $k).png" \
          'BEGIN { printf "%.0f %s\n", t * 1e9, p }' >> "$out/frames.partial"
        k=$((k + 1))
      fi
      i=$((i + 1))
    done < "$src/times.txt"
  fi
  mv "$out/frames.partial" "$out/frames.txt"
}
