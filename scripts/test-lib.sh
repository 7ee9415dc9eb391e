# Sourced by scripts/test.sh and scripts/test-sanitizers.sh: configure and build a test tree.
#
# Ninja, not Make: it keeps both cores busy across targets where Make waits at each target's
# boundary (the same ASan tree on this machine: 16.1 min, against 22.5 by Make in the
# fresh clone of the day before). Unity builds (up to 8 of a target's
# sources compiled as one): the headers every file includes (Eigen, OpenCV, Ceres, gRPC) are
# parsed once per batch instead of once per file. The release build (scripts/build.sh) compiles
# file by file, so both ways must build.
jobs=$(nproc)

# configure DIR [cmake args...]
configure() {
  local dir=$1
  shift
  # A tree configured by the Make generator of earlier versions cannot switch: start it again.
  if grep -qs 'CMAKE_GENERATOR:INTERNAL=Unix Makefiles' "$dir/CMakeCache.txt"; then rm -rf "$dir"; fi
  mkdir -p "$dir"
  cmake -S . -B "$dir" -G Ninja -DCMAKE_UNITY_BUILD=ON -DCMAKE_UNITY_BUILD_BATCH_SIZE=8 "$@" \
    > "$dir/configure.log" 2>&1 || { cat "$dir/configure.log"; exit 1; }
}

# build DIR [cmake --build args...]: errors shown, warnings listed.
build() {
  local dir=$1
  shift
  cmake --build "$dir" -j"$jobs" "$@" > "$dir/build.log" 2>&1 || { grep -E -B2 -A8 'error' "$dir/build.log" | head -80; exit 1; }
  grep -E 'warning' "$dir/build.log" || true
}
