#!/usr/bin/python3
"""Writes an EuRoC-layout sequence (as `visloc sim` makes it) into a ROS 1 bag with ROS's own
python3-rosbag: the independent side of visloc's bag import and ROS node tests.

  euroc_to_rosbag.py DIR OUT.bag [--mono] [--right-compressed] [--left-compressed]
                     [--odometry] [--drop-right N]

Topics: /cam0/image_raw (sensor_msgs/Image mono8, or .../compressed JPEG), /cam0/camera_info,
/cam1/image_raw (or /cam1/image_raw/compressed, PNG), /cam1/camera_info, /odom
(nav_msgs/Odometry, the sequence's odometry0 camera poses, child frame cam0). The camera_info
of a stereo pair is written the way ROS's stereo calibration writes it: the rectified frame is
the left camera's, R of the right camera turns it into that frame, P[3] = -fx * baseline.
Every --drop-right'th right image is left out, to exercise pairing reports.
"""
import argparse
import csv
import os
import sys

import numpy as np
import cv2
import yaml
import rosbag
import rospy
from nav_msgs.msg import Odometry
from sensor_msgs.msg import CameraInfo, CompressedImage, Image


def read_camera(path):
    with open(path) as f:
        s = yaml.safe_load(f)
    t_bs = np.array(s["T_BS"]["data"], dtype=float).reshape(4, 4)
    return s, t_bs


def camera_info(sensor, frame_id, stamp, r=np.eye(3), baseline_m=0.0):
    fu, fv, cu, cv_ = sensor["intrinsics"]
    info = CameraInfo()
    info.header.stamp = stamp
    info.header.frame_id = frame_id
    info.width, info.height = sensor["resolution"]
    model = sensor.get("distortion_model", "radial-tangential")
    d = list(sensor.get("distortion_coefficients", [0, 0, 0, 0]))
    if model == "equidistant":
        info.distortion_model = "equidistant"
        info.D = d
    else:
        info.distortion_model = "plumb_bob"
        info.D = d + [0.0]
    info.K = [fu, 0, cu, 0, fv, cv_, 0, 0, 1]
    info.R = list(np.asarray(r).reshape(-1))
    info.P = [fu, 0, cu, -fu * baseline_m, 0, fv, cv_, 0, 0, 0, 1, 0]
    return info


def to_time(ns):
    return rospy.Time(int(ns) // 1000000000, int(ns) % 1000000000)


def main():
    p = argparse.ArgumentParser()
    p.add_argument("dir")
    p.add_argument("out")
    p.add_argument("--mono", action="store_true")
    p.add_argument("--left-compressed", action="store_true")
    p.add_argument("--right-compressed", action="store_true")
    p.add_argument("--odometry", action="store_true")
    p.add_argument("--drop-right", type=int, default=0)
    a = p.parse_args()
    mav0 = os.path.join(a.dir, "mav0")
    left, body_from_left = read_camera(os.path.join(mav0, "cam0", "sensor.yaml"))
    stereo = not a.mono and os.path.exists(os.path.join(mav0, "cam1", "sensor.yaml"))
    r_right, baseline = np.eye(3), 0.0
    if stereo:
        right, body_from_right = read_camera(os.path.join(mav0, "cam1", "sensor.yaml"))
        left_from_right = np.linalg.inv(body_from_left) @ body_from_right
        t = left_from_right[:3, 3]
        baseline = float(np.linalg.norm(t))
        if abs(t[1]) > 1e-6 * baseline or abs(t[2]) > 1e-6 * baseline or t[0] <= 0:
            sys.exit("euroc_to_rosbag: the right camera is not along the left camera's x axis")
        r_right = left_from_right[:3, :3]  # rect (= left) from right
    with open(os.path.join(mav0, "cam0", "data.csv")) as f:
        stamps = [int(row[0]) for row in csv.reader(f) if row and not row[0].startswith("#")]
    bag = rosbag.Bag(a.out, "w")
    try:
        for i, ns in enumerate(stamps):
            t = to_time(ns)
            name = "%d.png" % ns
            grey = cv2.imread(os.path.join(mav0, "cam0", "data", name), cv2.IMREAD_GRAYSCALE)
            if a.left_compressed:
                msg = CompressedImage(format="jpeg")
                msg.data = cv2.imencode(".jpg", grey, [cv2.IMWRITE_JPEG_QUALITY, 95])[1].tobytes()
                topic = "/cam0/image_raw/compressed"
            else:
                msg = Image(height=grey.shape[0], width=grey.shape[1], encoding="mono8",
                            is_bigendian=0, step=grey.shape[1], data=grey.tobytes())
                topic = "/cam0/image_raw"
            msg.header.stamp, msg.header.frame_id = t, "cam0"
            bag.write(topic, msg, t)
            bag.write("/cam0/camera_info", camera_info(left, "cam0", t), t)
            if stereo:
                bag.write("/cam1/camera_info", camera_info(right, "cam1", t, r_right, baseline), t)
                if a.drop_right and i % a.drop_right == a.drop_right - 1:
                    continue
                grey = cv2.imread(os.path.join(mav0, "cam1", "data", name), cv2.IMREAD_GRAYSCALE)
                if a.right_compressed:
                    msg = CompressedImage(format="png")
                    msg.data = cv2.imencode(".png", grey)[1].tobytes()
                    topic = "/cam1/image_raw/compressed"
                else:
                    msg = Image(height=grey.shape[0], width=grey.shape[1], encoding="mono8",
                                is_bigendian=0, step=grey.shape[1], data=grey.tobytes())
                    topic = "/cam1/image_raw"
                msg.header.stamp, msg.header.frame_id = t, "cam1"
                bag.write(topic, msg, t)
        odometry = os.path.join(mav0, "odometry0", "data.csv")
        if a.odometry and os.path.exists(odometry):
            with open(odometry) as f:
                for row in csv.reader(f):
                    if not row or row[0].startswith("#"):
                        continue
                    t = to_time(int(row[0]))
                    msg = Odometry()
                    msg.header.stamp, msg.header.frame_id, msg.child_frame_id = t, "odom", "cam0"
                    x, y, z, qx, qy, qz, qw = map(float, row[1:8])
                    msg.pose.pose.position.x, msg.pose.pose.position.y, msg.pose.pose.position.z = x, y, z
                    o = msg.pose.pose.orientation
                    o.x, o.y, o.z, o.w = qx, qy, qz, qw
                    bag.write("/odom", msg, t)
    finally:
        bag.close()
    print("wrote %s: %d frames%s" % (a.out, len(stamps), " (stereo)" if stereo else ""))


if __name__ == "__main__":
    main()
