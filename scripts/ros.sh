#!/usr/bin/env bash
# Regenerates docs/ros.md from a run of tests/ros/ros_e2e_test.py (the CTest ros_e2e_test) on
# the release build: a generated sequence written into a ROS 1 bag by python3-rosbag, imported
# and mapped; the real EuRoC snippet through a bag with rectified camera_info; roscore, the real
# visloc-server (once killed and restarted mid-run), visloc_ros_node by roslaunch and
# `rosbag play`, measured from a subscriber.
# Nothing in the report is typed by hand.
# Usage: scripts/ros.sh [WORK_DIR=out/ros]   (about 2 minutes once the build is there)
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh
WORK=${1:-out/ros}
REAL=${VISLOC_REAL_DATA:-../shared/real}
DATA=build/testdata/localization
mkdir -p "$WORK"
bash tests/support/make_localization_data.sh build/client/visloc "$DATA"
git rev-parse --short HEAD > "$WORK/commit"
/usr/bin/python3 tests/ros/ros_e2e_test.py --visloc build/client/visloc \
  --server build/server/visloc-server --ros-ws build/ros_ws --data "$DATA" --work "$WORK/run" \
  --report "$WORK/report.json" --real "$REAL/euroc_v1_01_micro" | tee "$WORK/run.log" | grep -E '^(ok|FAIL)'
/usr/bin/python3 - "$WORK/report.json" "$WORK/commit" docs/ros.md <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
commit = open(sys.argv[2]).read().strip()
template = open(sys.argv[3]).read()
begin, end = "<!-- figures: begin -->", "<!-- figures: end -->"
i, q, k = r["import"], r["query"], r["kidnap"]
lines = [begin, "", "Measured at commit %s by `scripts/ros.sh` on the machine's 2 cores (release build)." % commit, ""]
lines += ["| run | what | result |", "|---|---|---|"]
lines.append("| bag import (ROS 1) | generated square, stereo, right camera as PNG CompressedImage, every 50th right image missing, %.1f MB | %d of %d frames paired, %d unpaired reported, %.2f s |"
             % (i["bag_mb"], i["imported_frames"], i["bag_frames"], i["bag_frames"] - i["imported_frames"], i["import_s"]))
lines.append("| map from the bag, `visloc localize` | query_square, %d frames | %d localized, median error %.2f cm |"
             % (i["frames"], i["localized"], i["localize_median_cm"]))
if "real_import" in r:
    ri = r["real_import"]
    lines.append("| real EuRoC bag (camera_info with OpenCV's rectification) | 95 stereo frames, 752x480 | %d frames, baseline %.4f m, map of %d points |"
                 % (ri["frames"], ri["baseline_m"], ri["points"]))
lines.append("| node, raw images + odometry (every other message 20 ms after its image) + IMU | query_square, %d frames at %.0f Hz | %d poses (%.1f Hz; the first image comes before the IMU and is not sent), median error %.2f cm (max %.2f), TF map -> odom closes on every pose |"
             % (q["frames"], q["camera_rate_hz"], q["poses"], q["pose_rate_hz"], q["median_error_cm"], q["max_error_cm"]))
if "reconnect" in r:
    rc = r["reconnect"]
    lines.append("| node, the server killed 3 s into the run and restarted 1 s later | query_square | first pose %.2f s after the server was back, %d poses after it, median error %.2f cm |"
                 % (rc["first_pose_after_s"], rc["poses_after"], rc["median_error_cm"]))
lines.append("| node, JPEG CompressedImage, no odometry | kidnap, %d frames, camera covered for %d | %d poses, %d while covered, median error %.2f cm |"
             % (k["frames"], k["covered"], k["poses"], k["poses_while_covered"], k["median_error_cm"]))
if "real_node" in r:
    rn = r["real_node"]
    lines.append("| node, real EuRoC left camera | 95 frames at %.0f Hz, 752x480 | %d poses (%.1f Hz), positions within %.2f mm of their mean (the MAV stands still) |"
                 % (rn["camera_rate_hz"], rn["poses"], rn["pose_rate_hz"], rn["spread_mm"]))
lines += ["", "Latency through the node (image received by a subscriber -> its pose received; the node's decoding,",
          "the JPEG encoding, the gRPC round trip on loopback and the engine):", "",
          "| run | p50 | p95 |", "|---|---|---|",
          "| query_square, 320x240 | %.1f ms | %.1f ms |" % (q["latency_ms_p50"], q["latency_ms_p95"]),
          "| query_square, frames whose odometry comes 20 ms after the image (the node waits for it) | %.1f ms | |"
          % q["latency_odometry_late_ms_p50"]]
if "real_node" in r:
    lines.append("| real EuRoC, 752x480 | %.1f ms | %.1f ms |" % (rn["latency_ms_p50"], rn["latency_ms_p95"]))
lines += ["", end]
a, b = template.index(begin), template.index(end) + len(end)
open(sys.argv[3], "w").write(template[:a] + "\n".join(lines) + template[b:])
PY
echo "docs/ros.md updated"
