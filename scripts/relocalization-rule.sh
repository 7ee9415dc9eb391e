#!/usr/bin/env bash
# Chooses relocalization's acceptance rule from evidence and regenerates docs/relocalization.md
# (its curve). Every frame of every recording in ../shared/real goes
# alone against maps of other parts of it, both ways (positives, checked against the ground
# truth: within 5 cm and 2 degrees; EuRoC's halves, and its outer thirds, whose views lie further
# apart), and against maps of other places (negatives: any pose is a
# false positive): EuRoC against KITTI, the other EuRoC hall and a generated room; KITTI
# against EuRoC and the generated room; generated rooms against each other, and the generated
# out-of-map walk. The evidence is taken once, in process, with no acceptance rule
# (`visloc relocalize --map-file --evidence`: both feature passes, every candidate verified);
# scripts/relocalization_rule.py replays each candidate rule on it as the relocalizer decides
# (pass by pass, candidates in rank order, the early stop) and picks the rule with no false
# positive on any negative and the highest recall.
#
# Usage: scripts/relocalization-rule.sh [WORK_DIR=out/relocalization-rule]
# (about 10 minutes on 2 cores once built). VISLOC_REAL_DATA names the recordings folder.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh
source scripts/report-lib.sh
V=$PWD/build/client/visloc
WORK=$(realpath -m "${1:-out/relocalization-rule}")
REAL=$(realpath "${VISLOC_REAL_DATA:-../shared/real}")
mkdir -p "$WORK/maps" "$WORK/evidence" "$WORK/gt"
[[ -d $REAL ]] || { echo "relocalization-rule.sh: no recordings in $REAL" >&2; exit 1; }
JOBS=$WORK/jobs.tsv  # kind recording map query evidence ground_truth anchor_keyframes
: > "$JOBS"

frames_of() {
  if [[ -d $1/mav0 ]]; then grep -vc '^#' "$1/mav0/cam0/data.csv"; else grep -c . "$1/times.txt"; fi
}
build_map() {  # build_map DATASET NAME [MAP BUILD FLAGS...]
  local dataset=$1 name=$2
  shift 2
  [[ -f $WORK/maps/$name.db ]] ||
    $V map build --dataset "$dataset" --out "$WORK/maps/$name.db" "$@" --json > "$WORK/maps/$name.json"
}
# The map's keyframes (TUM), against which its relocalizations are judged (relocalization_rule.py).
keyframes_of() {
  [[ -f $WORK/maps/$1.keyframes.tum ]] ||
    $V map export "$WORK/maps/$1.db" --keyframes "$WORK/maps/$1.keyframes.tum" > /dev/null
  echo "$WORK/maps/$1.keyframes.tum"
}
# evidence KIND RECORDING MAP QUERY_DATASET GT ANCHOR: the candidates of every query frame.
evidence() {
  local kind=$1 rec=$2 map=$3 query=$4 gt=$5 anchor=$6
  local out=$WORK/evidence/$map.$(basename "$query").$rec.tsv
  [[ -f $out ]] || $V relocalize --map-file "$WORK/maps/$map.db" --dataset "$query" --frames all \
    --evidence "$out" 2> /dev/null
  printf '%s\t%s\t%s\t%s\t%s\t%s\t%s\n' "$kind" "$rec" "$map" "$(basename "$query")" "$out" "$gt" \
    "$anchor" >> "$JOBS"
}

echo "== generated rooms"
G=$WORK/generated
[[ -d $G/seed1/map_square ]] || $V sim --out "$G/seed1" --sequence map_square,query_square,circle,outofmap --no-contact-sheet > /dev/null
build_map "$G/seed1/map_square" room1 --rig-error 0,0
# The out-of-map walk's room (another layout, size and textures) as a map of its own. Not another
# seed of room1: its boxes and walls stand where room1's do, and its frames localize in room1's
# map at their true poses (within 1 cm), as a repainted room should.
build_map "$G/seed1/outofmap" outofmap_room --rig-error 0,0

echo "== real recordings: maps of their halves (and for KITTI, of their even and odd frames)"
declare -A whole_map=()
real=()
for d in "$REAL"/*/; do
  d=${d%/}
  rec=$(basename "$d")
  [[ -d $d/mav0 || -d $d/image_0 ]] || continue
  real+=("$rec")
  gt=$WORK/gt/$rec.tum
  if [[ -f $d/groundtruth_cam0_tum.txt ]]; then
    cp "$d/groundtruth_cam0_tum.txt" "$gt"
  else
    $V dataset groundtruth "$d" --out "$gt" > /dev/null 2>&1 || gt=-
  fi
  n=$(frames_of "$d")
  subs=$WORK/subsets/$rec
  subset "$d" "$subs/all" 0 "$n" 1
  build_map "$subs/all" "$rec"
  whole_map[$rec]=$rec
  if [[ -d $d/mav0 ]]; then  # One place throughout: each half localizes in the other's map.
    splits=("first_half 0 $((n / 2)) 1" "second_half $((n / 2)) $n 1")
  else  # A drive: the other half's views are not in the map; the interleaved frames are.
    splits=("even 0 $n 2" "odd 1 $n 2")
  fi
  for s in "${splits[@]}"; do
    read -r name first end step <<< "$s"
    subset "$d" "$subs/$name" "$first" "$end" "$step"
    build_map "$subs/$name" "${rec}_$name"
  done
  a=$(cut -d' ' -f1 <<< "${splits[0]}")
  b=$(cut -d' ' -f1 <<< "${splits[1]}")
  evidence positive "$rec" "${rec}_$a" "$subs/$b" "$gt" "$(keyframes_of "${rec}_$a")"
  evidence positive "$rec" "${rec}_$b" "$subs/$a" "$gt" "$(keyframes_of "${rec}_$b")"
  if [[ -d $d/mav0 ]]; then  # Harder: each outer third against a map of the other, views apart.
    subset "$d" "$subs/first_third" 0 "$((n / 3))" 1
    subset "$d" "$subs/last_third" "$((n - n / 3))" "$n" 1
    build_map "$subs/first_third" "${rec}_first_third"
    build_map "$subs/last_third" "${rec}_last_third"
    evidence positive "$rec" "${rec}_first_third" "$subs/last_third" "$gt" "$(keyframes_of "${rec}_first_third")"
    evidence positive "$rec" "${rec}_last_third" "$subs/first_third" "$gt" "$(keyframes_of "${rec}_last_third")"
  fi
done

echo "== generated positives (the map frame is groundtruth_map.tum's, the map exact)"
for q in query_square circle; do
  subset "$G/seed1/$q" "$WORK/subsets/room1/$q" 0 "$(frames_of "$G/seed1/$q")" 1
  evidence positive room1 room1 "$WORK/subsets/room1/$q" "$G/seed1/$q/groundtruth_map.tum" -
done

echo "== negatives: every recording against the maps of the other places"
for rec in "${real[@]}"; do
  for other in "${real[@]}"; do
    [[ $other == "$rec" ]] && continue
    # The two KITTI snippets are one city's streets; not another place for certain.
    [[ $rec == kitti* && $other == kitti* ]] && continue
    evidence negative "$rec" "$other" "$WORK/subsets/$rec/all" - -
  done
  evidence negative "$rec" room1 "$WORK/subsets/$rec/all" - -
done
subset "$G/seed1/outofmap" "$WORK/subsets/outofmap_room/outofmap" 0 "$(frames_of "$G/seed1/outofmap")" 1
evidence negative outofmap_room room1 "$WORK/subsets/outofmap_room/outofmap" - -
for rec in "${real[@]}" outofmap_room; do
  evidence negative room1 "$rec" "$WORK/subsets/room1/query_square" - -
done

echo "== replaying the rules"
/usr/bin/python3 scripts/relocalization_rule.py "$JOBS" --report docs/relocalization.md \
  --commit "$(git rev-parse --short HEAD)"
