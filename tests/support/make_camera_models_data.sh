#!/usr/bin/env bash
# Generates the data the camera-model end-to-end tests share (a CTest fixture): for a rig with
# what real cameras do (--realistic: two cameras with their own intrinsics and lenses, a
# slightly turned rig, auto-exposure changes, vignetting, motion blur) with radial-tangential
# lenses, and for the same with equidistant fisheye lenses (170 deg across the diagonal):
#   <rig>/map.db          built from the 2 m square rendered at 3 fps,
#   <rig>/query_square/   the offset square's first 90 frames at 15 fps, with ground truth.
# Usage: make_camera_models_data.sh VISLOC_BINARY OUT_DIR (skips the work when OUT_DIR is newer
# than the binary).
set -euo pipefail
visloc=$1
out=$2
stamp=$out/ready
if [[ -f $stamp && $stamp -nt $visloc ]]; then
  echo "camera model test data up to date in $out"
  exit 0
fi
rm -rf "$out"
make_rig() {
  local dir=$out/$1
  shift
  mkdir -p "$dir"
  "$visloc" sim --out "$dir" --no-contact-sheet --realistic --distortion "$@" \
    --sequence map_square --fps 3 > /dev/null
  "$visloc" sim --out "$dir" --no-contact-sheet --realistic --distortion "$@" \
    --sequence query_square --frames 90 > /dev/null
  "$visloc" map build --dataset "$dir/map_square" --out "$dir/map.db" > /dev/null
}
make_rig pinhole &
pinhole=$!
make_rig fisheye --lens fisheye
wait "$pinhole"
touch "$stamp"
echo "camera model test data written to $out"
