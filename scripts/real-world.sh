#!/usr/bin/env bash
# Regenerates docs/real-world.md (and the figures behind it, docs/real-world.tsv): visloc on
# every recording in ../shared/real, each figure beside the same figure of a baseline, so that a
# change that helps rendered data and hurts real data shows. Per recording:
#   - the map of all its frames (`map build`): keyframes, points, frames a second; with ground
#     truth, its keyframes against it from the first frame, no alignment (median and max error,
#     error per distance travelled), and the last frame's error as a share of the path (drift);
#   - held-apart frames: a map of the even frames, the odd frames localized in it as a sequence
#     (`localize`): share localized, error, ms a frame, and whether the reported covariance
#     tells the truth (`eval --stats`: error in sigmas); for a camera at rest, how far its
#     ground truth scatters by itself (`eval --spread`), the floor of those errors;
#   - a kidnapped robot's first image: each odd frame alone through the real server
#     (`relocalize`, no session, no prior): recall, error, server time; for an EuRoC recording
#     (one place throughout) also every frame of each half alone against a map of the other
#     half, both ways (the negatives, frames of other places: scripts/relocalization-rule.sh).
# The baseline is, with --baseline REV, revision REV built in a worktree and measured the same
# way; without it, the figures docs/real-world.tsv holds at HEAD (the last regeneration).
# Frame subsets are folders of links made here, and relocalization asks one image at a time, so
# any revision's binaries can be measured; evaluation uses the current build's `visloc eval`.
#
# Usage: scripts/real-world.sh [--baseline REV] [WORK_DIR=out/real-world]
# (about 5 minutes on 2 cores once built; a baseline adds its build, about 10 minutes).
# VISLOC_REAL_DATA names the recordings folder.
set -euo pipefail
cd "$(dirname "$0")/.."
baseline_rev=""
if [[ ${1:-} == --baseline ]]; then
  baseline_rev=$2
  shift 2
fi
bash scripts/build.sh
source scripts/report-lib.sh
T=$PWD/build/client/visloc  # The evaluation tools.
WORK=$(realpath -m "${1:-out/real-world}")
REAL=$(realpath "${VISLOC_REAL_DATA:-../shared/real}")
REPORT=docs/real-world.md
FIGURES=docs/real-world.tsv
mkdir -p "$WORK"
[[ -d $REAL ]] || { echo "real-world.sh: no recordings in $REAL" >&2; exit 1; }
recordings=()
for d in "$REAL"/*/; do
  d=${d%/}
  [[ -d $d/mav0 || -d $d/image_0 ]] && recordings+=("$(basename "$d")")
done

# relocalize_each BIN_DIR MAP SUBSET OUT: each image of SUBSET alone through the server
# (SERVER_ADDRESS); OUT.tum gets the poses found, OUT.txt "found ms passes" per image (passes:
# the answer's feature_passes, 0 from a visloc before them).
passes_of() { grep -q '"feature_passes"' "$1" && field "$1" feature_passes || echo 0; }
relocalize_each() {
  local bin=$1 map=$2 sub=$3 out=$4 t path json
  : > "$out.txt"
  echo "# timestamp tx ty tz qx qy qz qw" > "$out.tum"
  while read -r t path; do
    json=$("$bin/client/visloc" relocalize --server "$SERVER_ADDRESS" --map "$map" \
      --dataset "$sub" "$path" --json) || true
    echo "$json" > "$out.last.json"
    if grep -q '"localized":true' <<< "$json"; then
      echo "1 $(field "$out.last.json" ms) $(passes_of "$out.last.json")" >> "$out.txt"
      awk -v t="$t" -v x="$(field "$out.last.json" tx)" -v y="$(field "$out.last.json" ty)" \
        -v z="$(field "$out.last.json" tz)" -v qx="$(field "$out.last.json" qx)" \
        -v qy="$(field "$out.last.json" qy)" -v qz="$(field "$out.last.json" qz)" \
        -v qw="$(field "$out.last.json" qw)" \
        'BEGIN { printf "%.9f %s %s %s %s %s %s %s\n", t / 1e9, x, y, z, qx, qy, qz, qw }' >> "$out.tum"
    else
      echo "0 $(field "$out.last.json" ms) $(passes_of "$out.last.json")" >> "$out.txt"
    fi
  done < "$sub/frames.txt"
}

# The share of relocalize_each's images that took the second feature pass, %; "-" when the
# answers do not say (a visloc before the two passes).
second_pass_pct() {
  awk '$3 == 0 { old = 1 } $3 == 2 { s++ } END { if (old) print "-"; else printf "%.1f", 100 * s / NR }' "$1"
}

# The median of a column of numbers on stdin.
median() { sort -g | awk '{ v[NR] = $1 } END { if (NR == 0) print "nan"; else if (NR % 2) print v[(NR + 1) / 2]; else print (v[NR / 2] + v[NR / 2 + 1]) / 2 }'; }

# measure BIN_DIR OUT: every figure of the binaries in BIN_DIR into OUT/figures.tsv
# ("recording key value" lines).
measure() {
  local bin=$1 out=$2
  local V=$bin/client/visloc
  mkdir -p "$out/maps"
  : > "$out/figures.tsv"
  put() { printf '%s\t%s\t%s\n' "$rec" "$1" "$2" >> "$out/figures.tsv"; }
  # eval_into PREFIX EST [ARGS...]: error figures of EST against the recording's ground truth.
  eval_into() {
    local prefix=$1 est=$2
    shift 2
    [[ -f $gt ]] || return 0
    $T eval --gt "$gt" ${gt_origin-"--gt-origin-first"} --est "$est" --json "$@" \
      > "$out/$rec.$prefix.eval.json"
    local e=$out/$rec.$prefix.eval.json
    [[ $(field "$e" matched_poses) != 0 ]] || return 0  # Nothing localized: no error to give.
    put "${prefix}_error_median_cm" "$(fmt "$(field_in "$e" ate median)" 100 2)"
    put "${prefix}_error_max_cm" "$(fmt "$(field_in "$e" ate max)" 100 2)"
    put "${prefix}_rotation_max_deg" "$(fmt "$(field_in "$e" rotation_deg max)" 1 2)"
  }
  # reroot_tum IN ROOT_NS OUT: the TUM trajectory IN relative to its pose nearest ROOT_NS.
  reroot_tum() {
    /usr/bin/python3 - "$@" << 'PY'
import sys
def mul(a, b):  # Quaternions (x, y, z, w).
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz)
def rotate(q, v):
    x, y, z, _ = mul(mul(q, (v[0], v[1], v[2], 0.0)), (-q[0], -q[1], -q[2], q[3]))
    return (x, y, z)
src, root_ns, dst = sys.argv[1], int(sys.argv[2]), sys.argv[3]
rows = [[float(x) for x in l.split()] for l in open(src) if l.strip() and not l.startswith('#')]
root = min(rows, key=lambda r: abs(r[0] - root_ns / 1e9))
inverse = (-root[4], -root[5], -root[6], root[7])
with open(dst, 'w') as out:
    out.write('# timestamp tx ty tz qx qy qz qw (relative to the pose at %.9f)\n' % root[0])
    for r in rows:
        position = rotate(inverse, [r[k] - root[k] for k in (1, 2, 3)])
        quaternion = mul(inverse, r[4:8])
        out.write('%.9f %s\n' % (r[0], ' '.join('%.9f' % v for v in (*position, *quaternion))))
PY
  }
  # relocalize_against_half MAP_HALF QUERY_HALF: a map of one half of the recording, then each
  # image of the other half alone through the server (figures QUERY_HALF_*), against the ground
  # truth re-rooted at the map half's first frame (its map frame).
  relocalize_against_half() {
    local map_half=$1 query_half=$2 full_gt=$gt
    $V map build --dataset "$subs/$map_half" --out "$out/maps/${rec}_$map_half.db" --json \
      > "$out/$rec.$map_half.build.json"
    stop_server
    SERVER_BIN=$bin/server/visloc-server start_server "$out/maps" "$out"
    relocalize_each "$bin" "${rec}_$map_half" "$subs/$query_half" "$out/$rec.$query_half"
    put "${query_half}_relocalized_pct" "$(awk '{ s += $1 } END { printf "%.1f", 100 * s / NR }' "$out/$rec.$query_half.txt")"
    put "${query_half}_second_pass_pct" "$(second_pass_pct "$out/$rec.$query_half.txt")"
    [[ -f $full_gt ]] || return 0
    gt=$out/$rec.gt_from_$map_half.tum
    reroot_tum "$full_gt" "$(head -1 "$subs/$map_half/frames.txt" | cut -d' ' -f1)" "$gt"
    gt_origin="" eval_into "$query_half" "$out/$rec.$query_half.tum"
    gt=$full_gt
  }
  for rec in "${recordings[@]}"; do
    echo "== $rec ($bin)"
    local d=$REAL/$rec subs=$WORK/subsets/$rec gt=$out/$rec.gt.tum
    rm -f "$gt"
    if [[ -f $d/groundtruth_cam0_tum.txt ]]; then
      cp "$d/groundtruth_cam0_tum.txt" "$gt"
    else
      $T dataset groundtruth "$d" --out "$gt" > /dev/null 2>&1 || rm -f "$gt"
    fi
    local n
    n=$(if [[ -d $d/mav0 ]]; then grep -vc '^#' "$d/mav0/cam0/data.csv"; else grep -c . "$d/times.txt"; fi)
    subset "$d" "$subs/even" 0 "$n" 2
    subset "$d" "$subs/odd" 1 "$n" 2
    # The map of all frames.
    $V map build --dataset "$d" --out "$out/maps/$rec.db" --trajectory "$out/$rec.frames.tum" \
      --json > "$out/$rec.build.json"
    put keyframes "$(field "$out/$rec.build.json" keyframes)"
    put points "$(field "$out/$rec.build.json" points)"
    put map_fps "$(fmt "$(field "$out/$rec.build.json" fps)" 1 1)"
    $V map export "$out/maps/$rec.db" --keyframes "$out/$rec.keyframes.tum" > /dev/null
    eval_into keyframe "$out/$rec.keyframes.tum"
    # Shares of the distance travelled, where the ground truth travels far enough to share over.
    if [[ -f $gt && $(field_in "$out/$rec.keyframe.eval.json" ate_per_distance count) != 0 ]]; then
      put keyframe_error_per_distance_pct "$(fmt "$(field_in "$out/$rec.keyframe.eval.json" ate_per_distance median)" 100 2)"
      { head -1 "$out/$rec.frames.tum"; tail -1 "$out/$rec.frames.tum"; } > "$out/$rec.last.tum"
      $T eval --gt "$gt" --gt-origin-first --est "$out/$rec.last.tum" --json > "$out/$rec.last.eval.json"
      put end_error_per_distance_pct "$(fmt "$(field_in "$out/$rec.last.eval.json" ate_per_distance max)" 100 2)"
    fi
    # Held-apart frames: the odd ones in a map of the even ones, as a sequence.
    $V map build --dataset "$subs/even" --out "$out/maps/${rec}_even.db" --json > "$out/$rec.even.build.json"
    $V localize --map "$out/maps/${rec}_even.db" --dataset "$subs/odd" --trajectory "$out/$rec.odd.tum" \
      --stats "$out/$rec.odd.csv" --json > "$out/$rec.odd.json"
    put odd_localized_pct "$(fmt "$(field "$out/$rec.odd.json" localized_fraction)" 100 1)"
    put odd_ms_per_frame "$(fmt "$(field_in "$out/$rec.odd.json" total_ms median)" 1 2)"
    eval_into odd "$out/$rec.odd.tum" --stats "$out/$rec.odd.csv"
    if [[ -f $gt && $(field "$out/$rec.odd.eval.json" matched_poses) != 0 ]]; then
      local e=$out/$rec.odd.eval.json
      put covariance_median_sigmas "$(fmt "$(field_in "$e" normalized_error median)" 1 2)"
      put covariance_beyond_3_sigma_pct "$(fmt "$(field_in "$e" consistency beyond_3_sigma)" 100 1)"
      put covariance_beyond_6_sigma_pct "$(fmt "$(field_in "$e" consistency beyond_6_sigma)" 100 1)"
    fi
    # A camera at rest (its ground truth within 1 cm of its mean): how far the ground truth itself
    # scatters, the floor of any error measured against it.
    if [[ -f $gt ]]; then
      $T eval --spread --est "$gt" --json > "$out/$rec.gt_spread.json"
      local scatter_max
      scatter_max=$(field_in "$out/$rec.gt_spread.json" position_m max)
      if awk -v m="$scatter_max" 'BEGIN { exit !(m < 0.01) }'; then
        put ground_truth_scatter_mm "$(fmt "$(field_in "$out/$rec.gt_spread.json" position_m median)" 1000 2) / $(fmt "$scatter_max" 1000 2)"
      fi
    fi
    # A kidnapped robot's first image: each odd frame alone, through the server.
    SERVER_BIN=$bin/server/visloc-server start_server "$out/maps" "$out"
    relocalize_each "$bin" "${rec}_even" "$subs/odd" "$out/$rec.reloc"
    put relocalized_pct "$(awk '{ s += $1 } END { printf "%.1f", 100 * s / NR }' "$out/$rec.reloc.txt")"
    put relocalized_second_pass_pct "$(second_pass_pct "$out/$rec.reloc.txt")"
    put relocalization_ms "$(cut -d' ' -f2 "$out/$rec.reloc.txt" | median | xargs -I{} awk 'BEGIN { printf "%.1f", {} }')"
    eval_into relocalized "$out/$rec.reloc.tum"
    if [[ -d $d/mav0 ]]; then
      # One place throughout: each half's images alone against a map of the other half.
      local half=$((n / 2))
      subset "$d" "$subs/first_half" 0 "$half" 1
      subset "$d" "$subs/second_half" "$half" "$n" 1
      relocalize_against_half first_half second_half
      relocalize_against_half second_half first_half
    fi
    stop_server
  done
}

git rev-parse --short HEAD > "$WORK/commit"
measure "$PWD/build" "$WORK/now"
if [[ -n $baseline_rev ]]; then
  build_baseline "$baseline_rev" "$WORK/baseline"
  base_commit=$BASELINE_COMMIT
  measure "$WORK/baseline/build" "$WORK/baseline/figures"
  cp "$WORK/baseline/figures/figures.tsv" "$WORK/before.tsv"
  before_label="commit $base_commit"
else
  git show "HEAD:$FIGURES" > "$WORK/before.tsv" 2>/dev/null || : > "$WORK/before.tsv"
  before_label="the figures at $(git log -1 --format=%h -- "$FIGURES" 2>/dev/null || echo none)"
fi
now_commit=$(cat "$WORK/commit")
{
  echo "# commit $now_commit"
  cat "$WORK/now/figures.tsv"
} > "$FIGURES"

echo "== report"
# cell REC KEY: "now (before)", or "now" when the baseline lacks the figure.
cell() {
  local now before
  now=$(value "$WORK/now/figures.tsv" "$1" "$2")
  before=$(value "$WORK/before.tsv" "$1" "$2")
  [[ -z $now ]] && { echo "-"; return; }
  [[ -n $before && $before != "$now" ]] && { echo "$now ($before)"; return; }
  echo "$now"
}
rows=(
  "keyframes|map of all frames: keyframes"
  "points|map of all frames: points"
  "map_fps|map building, frames a second"
  "keyframe_error_median_cm|keyframes against ground truth, median error, cm (no alignment, from frame 0)"
  "keyframe_error_max_cm|keyframes against ground truth, max error, cm"
  "keyframe_rotation_max_deg|keyframes against ground truth, max rotation error, deg"
  "keyframe_error_per_distance_pct|keyframe error per distance travelled, median, %"
  "end_error_per_distance_pct|last frame's error per distance travelled (drift), %"
  "odd_localized_pct|odd frames localized in a map of the even frames, %"
  "odd_error_median_cm|odd frames, median error, cm"
  "odd_error_max_cm|odd frames, max error, cm"
  "odd_ms_per_frame|odd frames, ms a frame (median, in-process)"
  "covariance_median_sigmas|covariance: median error in sigmas (honest 1.54)"
  "covariance_beyond_3_sigma_pct|covariance: poses beyond 3 sigma, % (honest 2.9)"
  "covariance_beyond_6_sigma_pct|covariance: poses beyond 6 sigma, % (honest 0)"
  "ground_truth_scatter_mm|at rest: the ground truth's own scatter about its mean, median / max, mm"
  "relocalized_pct|each odd frame alone through the server (relocalize): found, %"
  "relocalized_error_max_cm|... max error, cm"
  "relocalized_rotation_max_deg|... max rotation error, deg"
  "relocalization_ms|... server time, ms (median)"
  "relocalized_second_pass_pct|... that took the second pass (features at every scale), %"
  "second_half_relocalized_pct|each frame of the second half alone, map of the first half: found, %"
  "second_half_error_max_cm|... max error, cm"
  "second_half_rotation_max_deg|... max rotation error, deg"
  "second_half_second_pass_pct|... that took the second pass (features at every scale), %"
  "first_half_relocalized_pct|each frame of the first half alone, map of the second half: found, %"
  "first_half_error_max_cm|... max error, cm"
  "first_half_rotation_max_deg|... max rotation error, deg"
  "first_half_second_pass_pct|... that took the second pass (features at every scale), %"
)
{
  echo "# visloc on real places"
  echo
  echo "Generated by \`scripts/real-world.sh\` on $(date -u +%Y-%m-%d) from the runs of commit"
  echo "$now_commit; in brackets, where it differs, the same figure for $before_label. Do not edit"
  echo "by hand: rerun the script (\`--baseline REV\` measures a revision of your choice beside it)."
  echo
  echo "The recordings are \`../shared/real\` (its README). Errors are against each recording's"
  echo "ground truth taken from its first frame, which is the map frame (\`visloc eval"
  echo "--gt-origin-first\`), with no alignment. The covariance figures compare each odd frame's"
  echo "position error with the covariance the engine reported for it (\`visloc eval --stats\`: the"
  echo "Mahalanobis distance in the stats CSV's position covariance; a CSV from before those columns,"
  echo "a baseline's, is read as its per-axis sigma, position_sigma_m, on every axis)."
  echo "kitti00_first11 has no ground truth."
  echo
  printf "| |"
  for rec in "${recordings[@]}"; do printf " %s |" "$rec"; done
  echo
  printf "|---|"
  for _ in "${recordings[@]}"; do printf -- "---|"; done
  echo
  for row in "${rows[@]}"; do
    key=${row%%|*}
    printf "| %s |" "${row#*|}"
    for rec in "${recordings[@]}"; do printf " %s |" "$(cell "$rec" "$key")"; done
    echo
  done
} > "$REPORT"
echo "wrote $REPORT and $FIGURES"
