# Sourced by the tests that run the example robots (examples/robot_client, examples/python).
# check_robot_summary NAME FILE FRAMES SANITIZERS: the robot's last line,
#   answered A of N frames, P with a pose; L late, D dropped, U undelivered
# must account for every one of FRAMES frames, and all but the first few answers carry a pose.
# A live robot's queue keeps the newest frames when the server is slower than its camera, so
# the frames answered in time are all but a few on a release build, and at least a quarter on a
# sanitizer build sharing two cores with the rest of the suite (ten times slower, and what the
# suite runs beside it varies: CI runs' Python robot answered 139, then 112, then 93 of 150
# EuRoC frames, and dropped the rest). The sanitizer build is there to find memory errors; the
# release build's run is the one that holds the robot to camera pace.
# robot_min_answered FRAMES SANITIZERS: the frames a robot must answer in time (above).
robot_min_answered() {
  if [[ -n $2 ]]; then echo $(($1 / 4)); else echo $(($1 - 3)); fi
}
# robot_min_poses FRAMES SANITIZERS: the poses a robot that passes check_robot_summary printed at
# least (all but 3 of its answers).
robot_min_poses() {
  echo $(($(robot_min_answered "$1" "$2") - 3))
}
check_robot_summary() {
  local name=$1 file=$2 frames=$3 sanitize=$4 answered total posed late dropped undelivered
  read -r answered total posed late dropped undelivered < <(sed -n \
    's/^answered \([0-9]*\) of \([0-9]*\) frames, \([0-9]*\) with a pose; \([0-9]*\) late, \([0-9]*\) dropped, \([0-9]*\) undelivered$/\1 \2 \3 \4 \5 \6/p' \
    "$file")
  local min_answered
  min_answered=$(robot_min_answered "$frames" "$sanitize")
  if [[ -z ${total:-} || $total != "$frames" ||
        $((answered + late + dropped + undelivered)) != "$frames" ||
        $answered -lt $min_answered || $posed -lt $((answered - 3)) ]]; then
    echo "$name: $(tail -1 "$file") (expected $frames frames all accounted for, at least" \
         "$min_answered answered, all but 3 of those with a pose)"
    return 1
  fi
  echo "$name: $(tail -1 "$file")"
}
