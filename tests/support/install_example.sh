#!/usr/bin/env bash
# The client library as a robot program sees it: `cmake --install` into a fresh prefix, then
# examples/robot_client built against the installed tree twice (find_package(visloc CONFIG),
# and by hand with pkg-config), and run against the installed visloc-server on the fixture's
# map. Usage: install_example.sh BUILD_DIR SOURCE_DIR DATA_DIR [SANITIZERS]
set -euo pipefail
build=$1
source=$2
data=$3
sanitize=${4:-}
work=$(mktemp -d /tmp/visloc_install.XXXXXX)
server_pid=
cleanup() {
  [[ -n $server_pid ]] && kill "$server_pid" 2>/dev/null && wait "$server_pid" 2>/dev/null
  rm -rf "$work"
}
trap cleanup EXIT
source "$source/tests/support/robot_summary.sh"
flags=()
[[ -n $sanitize ]] && flags=(-fsanitize="$sanitize")

cmake --install "$build" --prefix "$work/prefix" > "$work/install.log"
for f in include/visloc/client/session.h include/visloc/v1/visloc.pb.h lib/libvisloc_client.a \
         lib/cmake/visloc/visloc-config.cmake lib/pkgconfig/visloc-client.pc bin/visloc-server; do
  [[ -e $work/prefix/$f ]] || { echo "not installed: $f"; exit 1; }
done

cmake -S "$source/examples/robot_client" -B "$work/robot" -DCMAKE_PREFIX_PATH="$work/prefix" \
  -DCMAKE_CXX_FLAGS="${flags[*]:-}" -DCMAKE_EXE_LINKER_FLAGS="${flags[*]:-}" > "$work/configure.log"
cmake --build "$work/robot" > "$work/build.log" 2>&1 || { cat "$work/build.log"; exit 1; }
export PKG_CONFIG_PATH=$work/prefix/lib/pkgconfig
# shellcheck disable=SC2046
g++ -std=c++17 -O1 "${flags[@]}" "$source/examples/robot_client/robot_client.cc" -o "$work/robot_pc" \
  $(pkg-config --cflags --libs visloc-client)

mkdir "$work/maps"
cp "$data/map.db" "$work/maps/square.db"
"$work/prefix/bin/visloc-server" --maps "$work/maps" --listen 127.0.0.1:0 \
  > "$work/server.out" 2> "$work/server.log" &
server_pid=$!
for _ in $(seq 100); do grep -q "listening on" "$work/server.out" && break; sleep 0.1; done
address=$(sed -n 's/^listening on //p' "$work/server.out")
[[ -n $address ]] || { cat "$work/server.log"; exit 1; }
images=$data/query_square/mav0/cam0/data
frames=$(ls "$images" | wc -l)
# The CMake-built robot reads its camera from the calibration's sensor.yaml; the other is given
# the same camera by hand. A broken sensor.yaml is refused by name before anything is sent.
printf 'camera_model: pinhole\nresolution: [320, 240]\n' > "$work/broken.yaml"
if "$work/robot/robot_client" "$address" square "$images" --camera-yaml "$work/broken.yaml" \
    2> "$work/broken.err"; then
  echo "robot_client accepted a sensor.yaml without intrinsics"; exit 1
fi
grep -q "broken.yaml: missing 'intrinsics'" "$work/broken.err" || { cat "$work/broken.err"; exit 1; }
for robot in "$work/robot/robot_client" "$work/robot_pc"; do
  camera=(320 240 160 160 159.5 119.5)
  [[ $robot == */robot/robot_client ]] && camera=(--camera-yaml "$data/query_square/mav0/cam0/sensor.yaml")
  "$robot" "$address" square "$images" "${camera[@]}" > "$work/robot.out"
  check_robot_summary "$robot" "$work/robot.out" "$frames" "$sanitize"
done
echo "installed client library: built with CMake and pkg-config, both localized $frames frames (one camera from sensor.yaml)"
