#!/usr/bin/env bash
# Regenerates docs/localizability.md: how well `visloc map localizability` (issue 57) predicts
# where localization works, from the map alone, against what the localizer really did.
#   - generated: the 2 m square mapped at 15 fps (the benchmarks' map; the rule's constants were
#     chosen on it) and at 5 fps (another map of the same place: held out), each walk localized
#     in it and predicted at its ground-truth poses; the five-room suite's map and its query walk;
#   - real (../shared/real): maps of the even frames, the odd frames localized in them and
#     predicted at the poses they were localized at (all localized, within a centimetre or two);
#   - the time for a 10,000-keyframe map (Google Benchmark, BM_LocalizabilityGrid).
# Usage: scripts/localizability.sh [WORK_DIR=out/localizability] (about 10 minutes on 2 cores
# once built). VISLOC_REAL_DATA names the recordings folder; BIN_DIR a build folder to run from
# instead of building build/.
set -euo pipefail
cd "$(dirname "$0")/.."
if [[ -z ${BIN_DIR:-} ]]; then
  bash scripts/build.sh
  BIN_DIR=$PWD/build
fi
V=$BIN_DIR/client/visloc
WORK=$(realpath -m "${1:-out/localizability}")
REAL=$(realpath "${VISLOC_REAL_DATA:-../shared/real}")
REPORT=docs/localizability.md
walks=(query_square straight circle outward glances kidnap)
mkdir -p "$WORK" docs/img
: > "$WORK/manifest.tsv"

echo "== data"
[[ -f $WORK/seq/done ]] || {
  rm -rf "$WORK/seq"
  "$V" sim --out "$WORK/seq" --sequence "map_square,$(IFS=,; echo "${walks[*]}")" \
    --no-contact-sheet > /dev/null
  touch "$WORK/seq/done"
}
[[ -f $WORK/seq5/done ]] || {
  rm -rf "$WORK/seq5"
  "$V" sim --out "$WORK/seq5" --sequence map_square --fps 5 --no-contact-sheet > /dev/null
  touch "$WORK/seq5/done"
}
[[ -f $WORK/suite/done ]] || {
  rm -rf "$WORK/suite"
  "$V" sim --out "$WORK/suite" --sequence map_suite,query_suite --no-contact-sheet > /dev/null
  touch "$WORK/suite/done"
}
build_map() {  # build_map NAME DATASET [flags]
  local name=$1 dataset=$2
  shift 2
  [[ -f $WORK/$name.db ]] || "$V" map build --dataset "$dataset" --out "$WORK/$name.db" \
    --rig-error 0,0 "$@" --json > "$WORK/$name.build.json"
}
build_map square15 "$WORK/seq/map_square"
build_map square5 "$WORK/seq5/map_square"
build_map suite "$WORK/suite/map_suite"

# predict GROUP MAP WALK_NAME DATASET POSES.tum CELL [SEQUENCE_JSON [LABEL]]: the walk localized
# in the map (once), the map's grid with the walk's poses predicted, a manifest line.
predict() {
  local group=$1 map=$2 walk=$3 dataset=$4 poses=$5 cell=$6 seq=${7:-} label=${8:-$3}
  local base=$WORK/$(basename "$map" .db).$walk
  [[ -f $base.csv ]] || "$V" localize --map "$map" --dataset "$dataset" --trajectory "$base.tum" \
    --stats "$base.csv" --json > "$base.localize.json"
  [[ -n $poses ]] || poses=$base.tum
  "$V" map localizability "$map" --out "$base.cell$cell" --cell "$cell" --at "$poses" \
    --threads 2 --json > "$base.cell$cell.summary.json"
  printf '%s\t%s\t%s\t%s\t%s\n' "$group" "$label" "$base.cell$cell.path.csv" "$base.csv" "$seq" \
    >> "$WORK/manifest.tsv"
}

echo "== generated walks"
for cell in 0.5 0.25; do
  for map in square15 square5; do
    for walk in "${walks[@]}"; do
      predict "$map map, cell $cell m" "$WORK/$map.db" "$walk" "$WORK/seq/$walk" \
        "$WORK/seq/$walk/groundtruth_map.tum" "$cell" "$WORK/seq/$walk/sequence.json"
    done
  done
done
predict "suite map, cell 0.5 m" "$WORK/suite.db" query_suite "$WORK/suite/query_suite" \
  "$WORK/suite/query_suite/groundtruth_map.tum" 0.5 "$WORK/suite/query_suite/sequence.json"

echo "== real recordings"
real=()
for rec in euroc_mh01_moving euroc_v1_01_micro kitti01_first51; do
  [[ -d $REAL/$rec ]] || continue
  real+=("$rec")
  [[ -f $WORK/${rec}_even.db ]] || "$V" map build --dataset "$REAL/$rec" --frames 0::2 \
    --out "$WORK/${rec}_even.db" --json > "$WORK/${rec}_even.build.json"
  [[ -f $WORK/${rec}_even.odd.csv ]] || "$V" localize --map "$WORK/${rec}_even.db" \
    --dataset "$REAL/$rec" --frames 1::2 --trajectory "$WORK/${rec}_even.odd.tum" \
    --stats "$WORK/${rec}_even.odd.csv" --json > "$WORK/${rec}_even.odd.localize.json"
  predict "real, odd frames in a map of the even ones, cell 0.5 m" "$WORK/${rec}_even.db" odd \
    "$REAL/$rec" "$WORK/${rec}_even.odd.tum" 0.5 "" "$rec"
done

echo "== 10,000 keyframes"
runs=()
for _ in 1 2 3; do
  runs+=("$("$BIN_DIR/core/localization/localization_benchmark" \
    --benchmark_filter='BM_LocalizabilityGrid/10000' --benchmark_format=json 2>/dev/null |
    /usr/bin/python3 -c 'import json,sys; b=json.load(sys.stdin)["benchmarks"][0]; print(b["real_time"], int(b["poses"]))')")
done
big=$(printf '%s\n' "${runs[@]}" | sort -n | sed -n 2p)

# figure SOURCE.png NAME: docs/img/NAME.jpg, at most 760 px wide (the repository keeps figures
# small).
figure() {
  /usr/bin/python3 - "$1" "docs/img/$2.jpg" <<'PY'
import sys
import cv2
image = cv2.imread(sys.argv[1])
scale = min(1.0, 760 / image.shape[1])
image = cv2.resize(image, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
cv2.imwrite(sys.argv[2], image, [cv2.IMWRITE_JPEG_QUALITY, 70])
PY
}
figure "$WORK/square15.query_square.cell0.25.png" localizability_square
figure "$WORK/suite.query_suite.cell0.5.png" localizability_suite
[[ -f $WORK/euroc_mh01_moving_even.odd.cell0.5.png ]] &&
  figure "$WORK/euroc_mh01_moving_even.odd.cell0.5.png" localizability_mh01

table=$(/usr/bin/python3 scripts/localizability_report.py "$WORK/manifest.tsv" 2> "$WORK/report.json")
field() { /usr/bin/python3 -c "import json,sys; print(json.load(open('$1'))['$2'])"; }
square_s=$(field "$WORK/square15.query_square.cell0.5.summary.json" seconds)
suite_s=$(field "$WORK/suite.query_suite.cell0.5.summary.json" seconds)
suite_kf=$(field "$WORK/suite.query_suite.cell0.5.summary.json" keyframes)
suite_poses=$(field "$WORK/suite.query_suite.cell0.5.summary.json" poses)

{
  cat <<EOF
# Localizability: where a robot will localize, from the map alone

Generated by \`scripts/localizability.sh\` on $(git log -1 --format='%h %cs'). Part of the site
(docs/site.md, issue 57).

\`visloc map localizability MAP.db --out PREFIX [--cell M] [--headings N] [--height M] [--pitch
DEG] [--at POSES.tum] [--json]\` answers an operator's question before a robot gets lost: for
each cell of a grid over the mapped area (the map's site frame, z up) and each of 16 headings
around it, a camera at the mapping robot's height and pitch, how many inliers will it have and
how well will they pin its position? From the map alone (core/localization/localizability.h):

- **in view**: each map point weighted by the learned visibility kernel of the most similar
  keyframe that saw it (the kernel was fitted to how much keyframes' visible sets overlap, so it
  reads as the share of that keyframe's view seen from here), in front of the camera and inside
  its image. Not normalized over the nearest keyframes as the tracker's prediction is: a pose far
  from every keyframe sees nothing;
- **matched**: 75% of those, saturating at 600 at 320x240 (the localizer's keypoints):
  600 (1 - exp(-0.75 v / 600)) for v points in view. The keypoints are shared out over the
  image, so each further point finds a free one less often; clipped at 600 instead, every pose
  beyond it tied, and a walk inside the mapped area (most of its poses beyond) ranked as noise;
- **how well**: the Fisher information of the pose from those projections with 0.4 px keypoint
  noise; the points' own uncertainty from their stereo observations as the pose follows it, and
  the map's and rig's error, as the tracker counts them. A pose is **good** with at least 30
  expected inliers (the localizer's tracking minimum), a position sigma of at most 5 cm and a
  point share of the position variance of at most 2.5 (the localizer reports a fix limited when
  its inliers' share exceeds 1; the prediction, over every point in view rather than the nearer,
  better-known ones the matcher keeps, runs higher: frames the localizer called limited were
  predicted at 3.7-7.6, tracked ones mostly below 2.5, on the square's 15 fps map).

Written: \`PREFIX.png\` (below), \`PREFIX.csv\` (x_m, y_m, heading_deg, expected_inliers,
position_sigma_m, point_variance_ratio, visible_points, good: one row per cell and heading, site
frame), \`PREFIX.json\` (the grid, its frame and \`site_from_map\`), and with \`--at\` each pose of a
trajectory (a planned path) predicted one by one and read from the grid (\`PREFIX.path.csv\`).

## Against what the localizer did

Each walk localized in the map (\`visloc localize\`, the engine a server session runs); each frame's
prediction at its ground-truth pose (*pose*) and read from its grid cell and nearest heading
(*cell*: what the operator sees). Frames a sequence covers on purpose (the kidnap walk's hand over
the lens) are left out: a covered lens is not a property of the place. Poor: not good.

$table

Targets (issue 57): Spearman >= 0.6, >= 90% of lost or limited frames predicted poor, >= 90% of
frames predicted good localized. The square's constants (75% matched, 2.5) were chosen on its
15 fps map; its 5 fps map, the suite and the real recordings are held out. A Spearman ranking
depends only on the points in view: the matched share and the saturation are monotone, so they
move what is called good, not the ranking. The prediction runs low by a median 12-15% (actual
over predicted, above); a larger share (0.9) centres it but calls more of the outward walk's
lost frames good (93% instead of 99% predicted poor). The real recordings' odd frames all
tracked: they test the ranking and that good means localized, not the poor side.

Not met, or met only pooled: single walks rank below 0.6 where the walk's inliers barely vary
or vary for reasons the map does not hold. The straight walk (0.46-0.53) keeps 370-420 inliers
through the mapped area while the points the kernel puts in view fall by a third as it leaves
the keyframes' path: the frame's keypoints, not the points in view, bound its inliers there.
The suite's query walk ranks at 0.57-0.58 and the circle read from its 0.5 m cells at
0.15-0.28 (from 0.25 m cells, 0.66-0.72). Of the real recordings KITTI 01's 25 odd frames rank
at 0.17 (a car at 10 m/s between maps of every other frame: inliers vary with the road's
texture, which no map predicts); EuRoC V1_01's cell ranking is flat (-0.12: 47 frames of a MAV
hovering in one cell). Tried and dropped: weighting each point by how close the pose's ray to it
is to a ray it was seen along (angle and distance), with or instead of the kernel. It ranked the
straight walk at 0.79 but called most of the outward walk's lost frames good (5-70% predicted
poor). Also tried and dropped: the cap per cell of the extractor's 8 x 6 keypoint grid (each
cell's matchable points saturating at its quota of the frame's keypoints, so points crowded into
part of the image expect less than points spread over it). It moved single walks by a few
hundredths each way (straight 0.48 / 0.55, the suite 0.59, the circle 0.64 / 0.66 on the square's
two maps) and put the prediction 28-31% below the actual inliers instead of 12-15%. The
10,000-keyframe figure is a synthetic map (lanes of keyframes with 500 points each),
not a building mapped from images.

## Time

| map | keyframes | poses (cells x headings) | seconds (2 threads) |
|---|---|---|---|
| the square, 15 fps | $(field "$WORK/square15.query_square.cell0.5.summary.json" keyframes) | $(field "$WORK/square15.query_square.cell0.5.summary.json" poses) | $(printf '%.2f' "$square_s") |
| the five-room suite | $suite_kf | $suite_poses | $(printf '%.2f' "$suite_s") |
| synthetic building floor: 100 m lanes 3 m apart (\`BM_LocalizabilityGrid/10000\`, median of 3) | 10000 | ${big#* } | $(printf '%.1f' "${big% *}") |

Target: a 10,000-keyframe map in under a minute.

## Pictures

Each cell is a wheel of its 16 headings, each wedge coloured by the inliers a camera looking that
way can expect (red none, yellow the tracking minimum, green three times it; white: nothing in
view), under the map's points (grey) and the keyframes' path (blue), in metres of the site frame.

The square (cell 0.25 m): inside it, looking out at the walls the mapping walk saw, good; looking
along the walk's direction from outside it, poor.

![the square](img/localizability_square.jpg)

The five-room suite (cell 0.5 m):

![the suite](img/localizability_suite.jpg)
EOF
  if [[ -f docs/img/localizability_mh01.jpg ]]; then
    cat <<EOF

EuRoC MH_01 (a map of its even frames; its level frame from the floor):

![MH_01](img/localizability_mh01.jpg)
EOF
  fi
} > "$REPORT"
echo "wrote $REPORT"
