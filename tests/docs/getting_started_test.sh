#!/usr/bin/env bash
# Runs docs/getting-started.md as a reader would: every ```sh block, in order, in one shell, from
# the repository's top; then checks what the robots printed. Two ways:
#   generated: the page's defaults (rendered recordings);
#   real:      a real EuRoC recording (MAPPING = QUERY = euroc_mh01_moving) and opencv-doc's
#              real chessboard pairs.
# Every frame answered with a pose, and the poses within 3 cm of ground truth at the median.
# Usage: getting_started_test.sh generated|real SOURCE_DIR BUILD_DIR [REAL_DATA] [SANITIZERS]
# Exit 77 (skipped) when the real data are not there.
set -euo pipefail
mode=$1
source=$2
build=$3
real=${4:-}
sanitize=${5:-}
work=$(mktemp -d /tmp/visloc_getting_started.XXXXXX)
trap 'rm -rf "$work"' EXIT

# The page's commands, as written.
awk '/^```sh$/ { on = 1; next } /^```/ { on = 0 } on' "$source/docs/getting-started.md" \
  > "$work/page.sh"
[[ $(grep -c . "$work/page.sh") -gt 20 ]] || { echo "no sh blocks found in the page"; exit 1; }

export BUILD=$build WORK=$work/page
# A free loopback port for the page's server.
ADDR=127.0.0.1:$(/usr/bin/python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
export ADDR
if [[ -n $sanitize ]]; then  # The robot links a sanitizer-built library.
  export CXXFLAGS=-fsanitize=$sanitize LDFLAGS=-fsanitize=$sanitize
fi
if [[ $mode == real ]]; then
  samples=/usr/share/doc/opencv-doc/examples/data
  if [[ ! -d $real/euroc_mh01_moving || ! -f $samples/left01.jpg ]]; then
    echo "skipped: no real recording at $real/euroc_mh01_moving or no opencv-doc samples"
    exit 77
  fi
  export MAPPING=$real/euroc_mh01_moving QUERY=$real/euroc_mh01_moving
  # opencv-doc's 13 real stereo chessboard pairs (9x6 inner corners), in the page's layout.
  mkdir -p "$work/board/left" "$work/board/right"
  for f in "$samples"/left[0-9]*.jpg; do ln -s "$f" "$work/board/left/"; done
  for f in "$samples"/right[0-9]*.jpg; do ln -s "$f" "$work/board/right/"; done
  export BOARD=$work/board SQUARE=0.025
fi

cd "$source"
bash "$work/page.sh" > "$work/page.out" 2>&1 || {
  echo "the page failed:"; tail -40 "$work/page.out"; exit 1; }
tail -25 "$work/page.out"

# Every robot: every frame accounted for, all but a few answered with a pose.
source "$source/tests/support/robot_summary.sh"
frames=$(ls "${QUERY:-$WORK/recordings/query_square}/mav0/cam0/data" | wc -l)
for robot in robot_cpp robot_python; do
  check_robot_summary "$robot" "$work/page/$robot.txt" "$frames" "$sanitize"
done

# Every pose checked below: as many as check_robot_summary asks for (fewer on a sanitizer build,
# where a robot at camera pace drops what the loaded server cannot answer in time).
min_poses=$(robot_min_poses "$frames" "$sanitize")

# The poses the robots printed against ground truth in the map's frame (the mapping recording's
# first left camera): the rendered query's own, or the real recording's moved there.
if [[ $mode == generated ]]; then
  truth=$work/page/recordings/query_square/groundtruth_map.tum
else
  truth=$QUERY/groundtruth_cam0_tum.txt  # The left camera in EuRoC's world (shared/real README).
fi
for robot in robot_cpp robot_python; do
  /usr/bin/python3 - "$work/page/$robot.txt" "$truth" "$mode" "$min_poses" <<'PY'
import bisect, statistics, sys
import numpy as np

def rotation(qx, qy, qz, qw):
    x, y, z, w = qx, qy, qz, qw
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])

times, truth = [], []
for line in open(sys.argv[2]):
    if line.strip() and not line.startswith("#"):
        f = list(map(float, line.split()[:8]))
        times.append(f[0])
        truth.append((np.array(f[1:4]), rotation(*f[4:8])))
if sys.argv[3] == "real":  # World to map: the first frame's camera is the map's origin.
    t0, r0 = truth[0]
    truth = [(r0.T @ (t - t0), r0.T @ r) for t, r in truth]

def true_position(t):  # The ground truth nearest in time (the robot prints milliseconds).
    i = min(max(bisect.bisect_left(times, t), 1), len(times) - 1)
    i = i if abs(times[i] - t) < abs(times[i - 1] - t) else i - 1
    assert abs(times[i] - t) < 0.002, f"no ground truth at {t}"
    return truth[i][0]

errors = []
for line in open(sys.argv[1]):
    f = line.split()
    if len(f) >= 6 and f[2] == "position" and f[1] != "STATUS_LOST":
        errors.append(float(np.linalg.norm(np.array(list(map(float, f[3:6]))) -
                                           true_position(float(f[0])))))
median = statistics.median(errors)
print(f"{sys.argv[1]}: {len(errors)} poses, median error {median * 100:.2f} cm, "
      f"max {max(errors) * 100:.2f} cm")
if len(errors) < int(sys.argv[4]) or median >= 0.03:
    sys.exit(f"{sys.argv[1]}: expected at least {sys.argv[4]} poses, median error under 3 cm")
PY
done
echo "docs/getting-started.md ran as written ($mode)"
