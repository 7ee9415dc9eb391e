#!/usr/bin/env bash
# Generates the data the localization end-to-end tests share (a CTest fixture):
#   map.db        built from the 2 m square rendered at 5 fps (the whole loop, kept quick),
#   map_build.json, map_trajectory.tum  that build's summary and estimated frame poses,
#   <sequence>/   short query sequences at 15 fps with ground truth in the map frame,
#   front-back/{kidnap,blankwall}, four/circle  walks filmed by rigs of two and four cameras.
# Usage: make_localization_data.sh VISLOC_BINARY OUT_DIR. Skips the work when OUT_DIR is newer
# than the binary (local re-runs); CI always starts from a fresh build folder.
set -euo pipefail
visloc=$1
out=$2
stamp=$out/ready
if [[ -f $stamp && $stamp -nt $visloc ]]; then
  echo "localization test data up to date in $out"
  exit 0
fi
rm -rf "$out"
mkdir -p "$out"
sim() { "$visloc" sim --out "$out" --no-contact-sheet "$@" >/dev/null; }
# name:frames (0: the whole sequence).
queries=(query_square:120 straight:0 circle:120 kidnap:150 lowlight:90 occluders:90 outofmap:45
         changed:120 outward:0 glances:450)
sim --sequence map_square --fps 5
# A generated rig's calibration is exact: the map says so (--rig-error 0,0), and its fixes' covariance
# holds the mapping's own error only.
"$visloc" map build --dataset "$out/map_square" --out "$out/map.db" --rig-error 0,0 --json \
  --trajectory "$out/map_trajectory.tum" > "$out/map_build.json" &
build=$!
pids=()
for q in "${queries[@]}"; do
  sim --sequence "${q%%:*}" --frames "${q##*:}" &
  pids+=($!)
done
# Rigs: the kidnap walk with a rear camera (cam2) that the cover leaves seeing, and the circle
# with four cameras (cam2 rear, cam3 left, cam4 right).
"$visloc" sim --out "$out/front-back" --no-contact-sheet --sequence kidnap,blankwall \
  --frames 150 --rig front-back >/dev/null &
pids+=($!)
"$visloc" sim --out "$out/four" --no-contact-sheet --sequence circle --frames 120 --rig four \
  >/dev/null &
pids+=($!)
for pid in "${pids[@]}"; do wait "$pid"; done
wait "$build"
touch "$stamp"
echo "localization test data written to $out"
