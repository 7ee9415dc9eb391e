#!/usr/bin/env bash
# Regenerates docs/real-cameras.md from runs: visloc on the real recordings in ../shared/real
# (EuRoC V1_01 and KITTI 00 snippets: dataset check, maps with both detectors, localization
# in-process and through the server, relocalization of one frame, timing at full resolution),
# calibration (OpenCV's stereo chessboards against OpenCV's stereo_calib sample; rendered
# chessboards against the rigs that rendered them), and the generated sequences rendered through
# an ideal rig, a realistic rig and a realistic fisheye rig. Nothing in the report is typed by
# hand.
#
# Usage: scripts/real-cameras.sh [WORK_DIR=out/real-cameras]  (about 12 minutes on 2 cores from
# scratch; sequences and maps in WORK_DIR are reused). VISLOC_REAL_DATA names the recordings;
# VISLOC_REAL_REPORT_ONLY=1 rewrites the report from the runs in WORK_DIR.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh
source scripts/report-lib.sh
V=build/client/visloc
WORK=${1:-out/real-cameras}
REAL=${VISLOC_REAL_DATA:-../shared/real}
EUROC=$REAL/euroc_v1_01_micro
KITTI=$REAL/kitti00_first11
SAMPLES=/usr/share/doc/opencv-doc/examples
REPORT=docs/real-cameras.md
mkdir -p "$WORK/maps"
[[ -d $EUROC && -d $KITTI ]] || { echo "real-cameras.sh: no recordings in $REAL" >&2; exit 1; }

# The generated sequences rendered through each rig (the runs and the report both read it).
sequences=(query_square straight circle kidnap lowlight)

# VISLOC_REAL_REPORT_ONLY=1 rewrites the report from the runs already in WORK_DIR.
if [[ ${VISLOC_REAL_REPORT_ONLY:-0} != 1 ]]; then
git rev-parse --short HEAD > "$WORK/commit"  # The code the runs measure.
echo "== real recordings"
$V dataset check "$EUROC" --json > "$WORK/euroc.check.json"
$V dataset check "$EUROC" > "$WORK/euroc.check.txt"
$V dataset check "$KITTI" --json > "$WORK/kitti.check.json"
for features in harris_surf16 orb; do
  $V map build --dataset "$EUROC" --features "$features" --out "$WORK/maps/euroc_$features.db" \
    --json > "$WORK/euroc_$features.build.json"
  $V localize --map "$WORK/maps/euroc_$features.db" --dataset "$EUROC" \
    --trajectory "$WORK/euroc_$features.tum" --json > "$WORK/euroc_$features.localize.json"
  $V eval --est "$WORK/euroc_$features.tum" --spread --json > "$WORK/euroc_$features.spread.json"
  $V map build --dataset "$KITTI" --features "$features" --out "$WORK/maps/kitti_$features.db" \
    --trajectory "$WORK/kitti_$features.frames.tum" --json > "$WORK/kitti_$features.build.json"
  $V localize --map "$WORK/maps/kitti_$features.db" --dataset "$KITTI" \
    --json > "$WORK/kitti_$features.localize.json"
done
start_server "$WORK/maps" "$WORK"
$V stream --server "$SERVER_ADDRESS" --map euroc_harris_surf16 --dataset "$EUROC" --rate 0 \
  --trajectory "$WORK/euroc_stream.tum" --json > "$WORK/euroc_stream.json"
$V eval --est "$WORK/euroc_stream.tum" --spread --json > "$WORK/euroc_stream.spread.json"
frame=$(sed -n '52p' "$EUROC/mav0/cam0/data.csv" | cut -d, -f2 | tr -d '\r')
$V relocalize --server "$SERVER_ADDRESS" --map euroc_harris_surf16 --dataset "$EUROC" \
  "$EUROC/mav0/cam0/data/$frame" --json > "$WORK/euroc_relocalize.json"
stop_server
$V bench --dataset "$EUROC" --map "$WORK/maps/euroc_harris_surf16.db" --json > "$WORK/euroc.bench.json"
$V bench --dataset "$KITTI" --map "$WORK/maps/kitti_harris_surf16.db" --json > "$WORK/kitti.bench.json"

echo "== calibration"
calib_pairs=()
if [[ -f $SAMPLES/cpp/stereo_calib.cpp ]]; then
  (cd "$WORK" && g++ -O2 -w -o stereo_calib "$SAMPLES/cpp/stereo_calib.cpp" \
    $(pkg-config --cflags --libs opencv4))
  list="<?xml version=\"1.0\"?>\n<opencv_storage>\n<imagelist>\n"
  left=() right=()
  for i in 01 02 03 04 05 06 07 08 09 11 12 13 14; do
    left+=("$SAMPLES/data/left$i.jpg")
    right+=("$SAMPLES/data/right$i.jpg")
    list+="\"$SAMPLES/data/left$i.jpg\"\n\"$SAMPLES/data/right$i.jpg\"\n"
  done
  printf "$list</imagelist>\n</opencv_storage>\n" > "$WORK/stereo_calib.xml"
  (cd "$WORK" && ./stereo_calib -w=9 -h=6 -s=1.0 -nr stereo_calib.xml > stereo_calib.txt)
  $V calibrate --left "${left[@]}" --right "${right[@]}" --board 9x6 --square 1.0 \
    --out "$WORK/calib_opencv" --json > "$WORK/calib_opencv.json"
fi
for lens in pinhole fisheye; do
  model=pinhole
  [[ $lens == fisheye ]] && model=equidistant
  $V sim --out "$WORK/board_$lens" --board 9x6 --square 0.04 --views 30 --resolution 480x360 \
    --lens "$lens" --distortion --realistic > /dev/null
  $V calibrate --left "$WORK/board_$lens"/left/*.png --right "$WORK/board_$lens"/right/*.png \
    --board 9x6 --square 0.04 --model "$model" --out "$WORK/board_$lens/est" \
    --json > "$WORK/calib_$lens.json"
done

echo "== generated sequences: ideal, realistic and fisheye rigs"
declare -A rig_flags=([ideal]="" [realistic]="--realistic --distortion"
                      [fisheye]="--lens fisheye --realistic --distortion")
for rig in ideal realistic fisheye; do
  [[ -f $WORK/$rig/done ]] || {
    rm -rf "$WORK/$rig"
    # shellcheck disable=SC2086
    $V sim --out "$WORK/$rig" --sequence "map_square,$(IFS=,; echo "${sequences[*]}")" \
      ${rig_flags[$rig]} --no-contact-sheet > /dev/null &
    rig_pids+=($!)
  }
done
for pid in "${rig_pids[@]:-}"; do [[ -n $pid ]] && wait "$pid"; done
for rig in ideal realistic fisheye; do
  touch "$WORK/$rig/done"
  [[ -f $WORK/$rig.db ]] || $V map build --dataset "$WORK/$rig/map_square" --out "$WORK/$rig.db" \
    --json > "$WORK/$rig.build.json"
  for s in "${sequences[@]}"; do
    $V localize --map "$WORK/$rig.db" --dataset "$WORK/$rig/$s" --trajectory "$WORK/$rig.$s.tum" \
      --json > "$WORK/$rig.$s.localize.json"
    $V eval --gt "$WORK/$rig/$s/groundtruth_map.tum" --est "$WORK/$rig.$s.tum" \
      --json > "$WORK/$rig.$s.eval.json"
  done
done

fi  # VISLOC_REAL_REPORT_ONLY

echo "== report"
pct() { fmt "$1" 100 1; }
# The numbers of matrix KEY in an OpenCV YAML file, on one line.
matrix() {
  tr -d '\n' < "$1" | sed -n "s/.*$2: !!opencv-matrix[^[]*\[\([^]]*\)\].*/\1/p" | tr -d ',' | tr -s ' '
  echo
}
{
  echo "# visloc on real cameras"
  echo
  echo "Generated by \`scripts/real-cameras.sh\` on $(date -u +%Y-%m-%d) from the runs of commit"
  echo "$(cat "$WORK/commit"). Do not edit by hand: rerun the script."
  echo
  echo "## The real recordings (\`../shared/real\`)"
  echo
  echo "EuRoC V1_01_easy, first 95 stereo frames: 752x480, two cameras with their own intrinsics,"
  echo "radial-tangential lenses and T_BS; the MAV stands still (ground truth moves under 3 mm)."
  echo "KITTI 00, first 11 stereo frames: 1241x376, rectified, a car at about 8 m/s."
  echo
  echo "### \`visloc dataset check\`"
  echo
  echo '```'
  cat "$WORK/euroc.check.txt"
  echo '```'
  echo
  echo "| | EuRoC | KITTI |"
  echo "|---|---|---|"
  echo "| rectified focal length, baseline | $(fmt "$(field "$WORK/euroc.check.json" rectified_focal_px)" 1 1) px, $(fmt "$(field "$WORK/euroc.check.json" baseline_m)" 1 4) m | $(fmt "$(field "$WORK/kitti.check.json" rectified_focal_px)" 1 1) px, $(fmt "$(field "$WORK/kitti.check.json" baseline_m)" 1 4) m |"
  echo "| epipolar residual, median / 95th percentile | $(fmt "$(field "$WORK/euroc.check.json" row_difference_median_px)") / $(fmt "$(field "$WORK/euroc.check.json" row_difference_p95_px)") px | $(fmt "$(field "$WORK/kitti.check.json" row_difference_median_px)") / $(fmt "$(field "$WORK/kitti.check.json" row_difference_p95_px)") px |"
  echo "| keypoints, stereo matches per frame (median) | $(fmt "$(field "$WORK/euroc.check.json" keypoints_median)" 1 0), $(fmt "$(field "$WORK/euroc.check.json" stereo_matches_median)" 1 0) | $(fmt "$(field "$WORK/kitti.check.json" keypoints_median)" 1 0), $(fmt "$(field "$WORK/kitti.check.json" stereo_matches_median)" 1 0) |"
  echo "| depth, median (5th-95th percentile) | $(fmt "$(field "$WORK/euroc.check.json" depth_median_m)") m ($(fmt "$(field "$WORK/euroc.check.json" depth_p5_m)")-$(fmt "$(field "$WORK/euroc.check.json" depth_p95_m)")) | $(fmt "$(field "$WORK/kitti.check.json" depth_median_m)" 1 1) m ($(fmt "$(field "$WORK/kitti.check.json" depth_p5_m)" 1 1)-$(fmt "$(field "$WORK/kitti.check.json" depth_p95_m)" 1 1)) |"
  echo
  echo "### Maps and localization"
  echo
  echo "\`visloc map build --dataset D [--features orb]\`, then \`visloc localize\` of the same frames"
  echo "against the map, and \`visloc eval --spread\` of the poses (EuRoC: the camera stands still,"
  echo "so the spread is the jitter)."
  echo
  echo "| | keyframes | points | tracking failures | frames localized | position spread (max) | rotation spread (max) |"
  echo "|---|---|---|---|---|---|---|"
  for f in harris_surf16 orb; do
    b=$WORK/euroc_$f.build.json
    echo "| EuRoC, $f | $(field "$b" keyframes) | $(field "$b" points) | $(field "$b" tracking_failures) | $(pct "$(field "$WORK/euroc_$f.localize.json" localized_fraction)")% | $(fmt "$(field_in "$WORK/euroc_$f.spread.json" position_m max)" 1000 2) mm | $(fmt "$(field_in "$WORK/euroc_$f.spread.json" rotation_deg max)" 1 3) deg |"
  done
  echo "| EuRoC, harris_surf16, through visloc-server (\`stream\`) | | | | $(pct "$(field "$WORK/euroc_stream.json" localized_fraction)")% | $(fmt "$(field_in "$WORK/euroc_stream.spread.json" position_m max)" 1000 2) mm | $(fmt "$(field_in "$WORK/euroc_stream.spread.json" rotation_deg max)" 1 3) deg |"
  for f in harris_surf16 orb; do
    b=$WORK/kitti_$f.build.json
    echo "| KITTI, $f | $(field "$b" keyframes) | $(field "$b" points) | $(field "$b" tracking_failures) | $(pct "$(field "$WORK/kitti_$f.localize.json" localized_fraction)")% | | |"
  done
  echo
  first=$(sed -n '2p' "$WORK/kitti_harris_surf16.frames.tum" | awk '{print $4}')
  last=$(tail -1 "$WORK/kitti_harris_surf16.frames.tum" | awk '{print $4}')
  echo "KITTI's estimated motion: $(fmt "$(awk -v a="$first" -v b="$last" 'BEGIN{print b-a}')") m forward over 10 frames"
  echo "($(fmt "$(awk -v a="$first" -v b="$last" 'BEGIN{print (b-a)/10}')") m a frame). \`visloc relocalize\` of EuRoC frame 50 through the server:"
  echo "$(field "$WORK/euroc_relocalize.json" inliers) inliers, in $(fmt "$(field "$WORK/euroc_relocalize.json" ms)" 1 1) ms."
  echo
  echo "### Timing at full resolution (\`visloc bench\`)"
  echo
  echo "Medians per frame; ORB(500) is OpenCV's detector and descriptor measured in the same run."
  echo
  echo "| | tracking frame | ORB(500) | ratio (target <= 0.5) | global relocalization |"
  echo "|---|---|---|---|---|"
  for d in euroc kitti; do
    j=$WORK/$d.bench.json
    frame=$(field "$j" ms_per_frame_median) orb=$(field "$j" orb_reference_ms_per_frame_median)
    echo "| $d ($(field "$j" width)x$(field "$j" height)) | $(fmt "$frame") ms | $(fmt "$orb") ms | $(fmt "$(awk -v a="$frame" -v b="$orb" 'BEGIN{print a/b}')") | $(fmt "$(field "$j" relocalization_ms_median)") ms |"
  done
  echo
  echo "## Calibration (\`visloc calibrate\`)"
  echo
  if [[ -f $WORK/calib_opencv.json ]]; then
    c=$WORK/calib_opencv.json
    read -r m1fx _ _ _ m1fy _ < <(matrix "$WORK/intrinsics.yml" M1)
    read -r m2fx _ _ _ m2fy _ < <(matrix "$WORK/intrinsics.yml" M2)
    read -r tx ty tz < <(matrix "$WORK/extrinsics.yml" T)
    echo "OpenCV's 13 stereo chessboard pairs (opencv-doc, 640x480, 9x6 inner corners), against"
    echo "OpenCV's own \`stereo_calib\` sample on the same images. The sample fits one focal length"
    echo "to both cameras at a fixed aspect ratio with a rational lens model; visloc fits each"
    echo "camera (k1 k2 p1 p2). Baselines in squares (\`--square 1\`)."
    echo
    echo "| | fx | fy | RMS | corners' coverage | baseline |"
    echo "|---|---|---|---|---|---|"
    for cam in left right; do
      echo "| visloc, $cam | $(fmt "$(field_in "$c" "$cam" fx)") | $(fmt "$(field_in "$c" "$cam" fy)") | $(fmt "$(field_in "$c" "$cam" rms_px)" 1 3) px | $(pct "$(field_in "$c" "$cam" coverage)")% | |"
    done
    echo "| visloc, pair | | | $(fmt "$(field "$c" stereo_rms_px)" 1 3) px | | $(fmt "$(field "$c" baseline_m)" 1 4) |"
    echo "| OpenCV's sample, left / right | $(fmt "$m1fx") / $(fmt "$m2fx") | $(fmt "$m1fy") / $(fmt "$m2fy") | $(grep -o 'RMS error=[0-9.]*' "$WORK/stereo_calib.txt" | cut -d= -f2 | xargs -I{} awk 'BEGIN{printf "%.3f", {}}') px (pair) | | $(awk -v x="$tx" -v y="$ty" -v z="$tz" 'BEGIN{printf "%.4f", sqrt(x*x+y*y+z*z)}') |"
  fi
  echo
  echo "Chessboards rendered by \`visloc sim --board 9x6 --views 30\` through realistic rigs (their"
  echo "true calibration beside them), 480x360:"
  echo
  echo "| rig | | fx | fy | cx | cy | baseline | pair RMS |"
  echo "|---|---|---|---|---|---|---|---|"
  for lens in pinhole fisheye; do
    c=$WORK/calib_$lens.json
    t=$WORK/board_$lens/truth/cam0/sensor.yaml
    read -r tfx tfy tcx tcy < <(sed -n 's/^intrinsics: \[\(.*\)\].*/\1/p' "$t" | tr -d ',')
    # The right camera's T_BS (the left camera is the body): its translation is the baseline.
    baseline=$(sed -n 's/^  data: \[\(.*\)\]/\1/p' "$WORK/board_$lens/truth/cam1/sensor.yaml" |
      tr -d ',' | awk '{printf "%.2f", 1000 * sqrt($4 * $4 + $8 * $8 + $12 * $12)}')
    echo "| $lens | estimated | $(fmt "$(field_in "$c" left fx)") | $(fmt "$(field_in "$c" left fy)") | $(fmt "$(field_in "$c" left cx)") | $(fmt "$(field_in "$c" left cy)") | $(fmt "$(field "$c" baseline_m)" 1000 2) mm | $(fmt "$(field "$c" stereo_rms_px)" 1 3) px |"
    echo "| | true | $(fmt "$tfx") | $(fmt "$tfy") | $(fmt "$tcx") | $(fmt "$tcy") | $baseline mm | |"
  done
  echo
  echo "## Generated sequences through three rigs"
  echo
  echo "320x240, 15 fps, map of the 2 m square built from each rig's own rendering. *ideal*: the"
  echo "paper's pinhole head. *realistic* (\`visloc sim --realistic --distortion\`): two cameras with"
  echo "their own intrinsics and radial-tangential lenses, the right one turned about 0.5 deg,"
  echo "auto-exposure swinging 0.7x-1.3x with steps, the right sensor 10% darker, vignetting, 15 ms"
  echo "motion blur. *fisheye* (\`--lens fisheye --realistic --distortion\`): the same with equidistant"
  echo "fisheyes seeing 170 deg across the diagonal."
  echo
  echo "| sequence | rig | localized | median error | max error | median rotation |"
  echo "|---|---|---|---|---|---|"
  for s in "${sequences[@]}"; do
    for rig in ideal realistic fisheye; do
      e=$WORK/$rig.$s.eval.json
      echo "| $s | $rig | $(pct "$(field "$WORK/$rig.$s.localize.json" localized_fraction)")% | $(fmt "$(field_in "$e" translation_m median)" 100 2) cm | $(fmt "$(field_in "$e" translation_m max)" 100 2) cm | $(fmt "$(field_in "$e" rotation_deg median)" 1 3) deg |"
    done
  done
  echo
  echo "Maps: $(for rig in ideal realistic fisheye; do printf "%s %s keyframes / %s points; " "$rig" "$(field "$WORK/$rig.build.json" keyframes)" "$(field "$WORK/$rig.build.json" points)"; done)"
} > "$REPORT"
echo "wrote $REPORT"
