#!/usr/bin/env python3
"""One row of docs/site.md's table of up directions: a map's up (`visloc map info --json`)
against its recording's ground truth.

Usage: site_up.py LABEL INFO.json DATASET_DIR
The truth is up (world z) in the map frame, the first left camera's: from EuRoC's
state_groundtruth_estimate0 (the body's pose) and cam0's T_BS, or from groundtruth_cam0_tum.txt
(the left camera's pose) where the recording has that instead.
"""
import json
import re
import sys

import numpy as np


def rotation(w, x, y, z):
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def body_from_cam0(dataset):
    text = open(f"{dataset}/mav0/cam0/sensor.yaml").read()
    data = re.search(r"T_BS:.*?data:\s*\[([^\]]*)\]", text, re.S).group(1)
    return np.array([float(v) for v in data.replace("\n", " ").split(",")]).reshape(4, 4)[:3, :3]


def first_frame_ns(dataset):
    for line in open(f"{dataset}/mav0/cam0/data.csv"):
        if not line.startswith("#"):
            return int(line.split(",")[0])
    raise SystemExit(f"{dataset}: no frames")


def true_up(dataset):
    try:
        rows = [[float(v) for v in line.split()] for line in
                open(f"{dataset}/groundtruth_cam0_tum.txt") if not line.startswith("#")]
        world_from_cam = rotation(rows[0][7], *rows[0][4:7])  # TUM: qx qy qz qw.
    except FileNotFoundError:
        t0 = first_frame_ns(dataset)
        rows = [[float(v) for v in line.split(",")] for line in
                open(f"{dataset}/mav0/state_groundtruth_estimate0/data.csv")
                if not line.startswith("#")]
        # The pose nearest the first frame (EuRoC V1_01's starts later, the MAV still).
        row = min(rows, key=lambda r: abs(r[0] - t0))
        world_from_cam = rotation(*row[4:8]) @ body_from_cam0(dataset)
    return world_from_cam.T @ np.array([0.0, 0.0, 1.0])


def main():
    label, info_path, dataset = sys.argv[1:4]
    gravity = json.load(open(info_path))["gravity"]
    truth = true_up(dataset)
    tilt = np.degrees(np.arccos(np.clip(-truth[1], -1, 1)))
    if gravity is None:
        print(f"| {label} | not found | | | {tilt:.1f} |")
        return
    up = np.array(gravity["up_in_map"])
    error = np.degrees(np.arctan2(np.linalg.norm(np.cross(up, truth)), up @ truth))
    print(f"| {label} | {gravity['source']} | {error:.2f} | {gravity['sigma_deg']:.2f} | "
          f"{tilt:.1f} |")


if __name__ == "__main__":
    main()
