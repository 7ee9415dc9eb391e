#!/usr/bin/python3
"""Writes an EuRoC-layout sequence (as `visloc sim` makes it) into a ROS 1 bag with ROS's own
python3-rosbag: the independent side of visloc's bag import and ROS node tests.

  euroc_to_rosbag.py DIR OUT.bag [--mono] [--right-compressed] [--left-compressed]
                     [--odometry] [--odometry-lag-ms MS] [--imu] [--drop-right N]
                     [--rig-camera CAM ...] [--rig-compressed]

Topics: /cam0/image_raw (sensor_msgs/Image mono8, or .../compressed JPEG), /cam0/camera_info,
/cam1/image_raw (or /cam1/image_raw/compressed, PNG), /cam1/camera_info, /odom
(nav_msgs/Odometry, the sequence's odometry0 camera poses, child frame cam0), /imu
(sensor_msgs/Imu in frame "imu", the EuRoC body) with /tf_static imu -> cam0. The camera_info
of a stereo pair is written the way ROS's stereo calibration writes it: the rectified frame is
the left camera's, R of the right camera turns it into that frame, P[3] = -fx * baseline.
Every --drop-right'th right image is left out, to exercise pairing reports. With
--odometry-lag-ms, every other odometry message is recorded (so played) that long after its own
stamp, as odometry from another node arrives after the image of the same instant. Each
--rig-camera CAM (a rig's further camera, as `visloc sim --rig` writes cam2, ...) adds
/CAM/image_raw (with --rig-compressed, /CAM/image_raw/compressed JPEG), /CAM/camera_info and
/tf_static cam0 -> CAM (from both cameras' T_BS).
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
from geometry_msgs.msg import TransformStamped
from sensor_msgs.msg import CameraInfo, CompressedImage, Image, Imu
from tf2_msgs.msg import TFMessage


def read_camera(path):
    with open(path) as f:  # EuRoC's files start with OpenCV's "%YAML:1.0", not YAML's own.
        s = yaml.safe_load("".join(l for l in f if not l.startswith("%")))
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


def rectify(left, right, right_from_left):
    """rect_from_left, rect_from_right and the baseline of a stereo pair (OpenCV's convention:
    a point p in the left camera is right_from_left p in the right one)."""
    def k_d(s):
        fu, fv, cu, cv_ = s["intrinsics"]
        return (np.array([[fu, 0, cu], [0, fv, cv_], [0, 0, 1]]),
                np.array(s.get("distortion_coefficients", [0, 0, 0, 0]), dtype=float))
    k1, d1 = k_d(left)
    k2, d2 = k_d(right)
    size = tuple(left["resolution"])
    r, t = right_from_left[:3, :3], right_from_left[:3, 3].reshape(3, 1)
    if left.get("distortion_model") == "equidistant":
        r1, r2, p1, p2, _ = cv2.fisheye.stereoRectify(k1, d1, k2, d2, size, r, t, 0)
    else:
        r1, r2, p1, p2, _, _, _ = cv2.stereoRectify(k1, d1, k2, d2, size, r, t, alpha=0)
    return r1, r2, float(-p2[0, 3] / p2[0, 0])


def write_imu(bag, path, body_from_left, t0):
    """/imu (frame "imu", the EuRoC body frame) and /tf_static imu -> cam0 (cam0's T_BS)."""
    tf = TransformStamped()
    tf.header.stamp, tf.header.frame_id, tf.child_frame_id = t0, "imu", "cam0"
    tf.transform.translation.x, tf.transform.translation.y, tf.transform.translation.z = body_from_left[:3, 3]
    r = body_from_left[:3, :3]
    w = np.sqrt(max(1e-12, 1 + r[0, 0] + r[1, 1] + r[2, 2])) / 2
    q = tf.transform.rotation
    q.w, q.x, q.y, q.z = w, (r[2, 1] - r[1, 2]) / (4 * w), (r[0, 2] - r[2, 0]) / (4 * w), (r[1, 0] - r[0, 1]) / (4 * w)
    bag.write("/tf_static", TFMessage(transforms=[tf]), t0)
    with open(path) as f:
        for row in csv.reader(f):
            if not row or row[0].startswith("#"):
                continue
            t = to_time(int(row[0]))
            msg = Imu()
            msg.header.stamp, msg.header.frame_id = t, "imu"
            v = [float(x) for x in row[1:7]]
            msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z = v[0:3]
            msg.linear_acceleration.x, msg.linear_acceleration.y, msg.linear_acceleration.z = v[3:6]
            bag.write("/imu", msg, t)


def write_image(bag, mav0, cam, name, t, compressed):
    """/CAM/image_raw (mono8), or /CAM/image_raw/compressed as `compressed` ("jpeg", "png")."""
    grey = cv2.imread(os.path.join(mav0, cam, "data", name), cv2.IMREAD_GRAYSCALE)
    if compressed:
        msg = CompressedImage(format=compressed)
        params = [cv2.IMWRITE_JPEG_QUALITY, 95] if compressed == "jpeg" else []
        msg.data = cv2.imencode("." + ("jpg" if compressed == "jpeg" else "png"), grey, params)[1].tobytes()
        topic = "/%s/image_raw/compressed" % cam
    else:
        msg = Image(height=grey.shape[0], width=grey.shape[1], encoding="mono8",
                    is_bigendian=0, step=grey.shape[1], data=grey.tobytes())
        topic = "/%s/image_raw" % cam
    msg.header.stamp, msg.header.frame_id = t, cam
    bag.write(topic, msg, t)


def static_transform(parent, child, parent_from_child, t0):
    tf = TransformStamped()
    tf.header.stamp, tf.header.frame_id, tf.child_frame_id = t0, parent, child
    tf.transform.translation.x, tf.transform.translation.y, tf.transform.translation.z = parent_from_child[:3, 3]
    w, x, y, z = quaternion_wxyz(parent_from_child[:3, :3])
    q = tf.transform.rotation
    q.w, q.x, q.y, q.z = w, x, y, z
    return tf


def quaternion_wxyz(r):
    """The unit quaternion of a rotation matrix, from its largest diagonal term."""
    trace = np.trace(r)
    if trace > 0:
        s = 2.0 * np.sqrt(trace + 1.0)
        return 0.25 * s, (r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s
    i = int(np.argmax(np.diag(r)))
    j, k = (i + 1) % 3, (i + 2) % 3
    s = 2.0 * np.sqrt(1.0 + r[i, i] - r[j, j] - r[k, k])
    v = [0.0, 0.0, 0.0]
    v[i], v[j], v[k] = 0.25 * s, (r[j, i] + r[i, j]) / s, (r[k, i] + r[i, k]) / s
    return ((r[k, j] - r[j, k]) / s, v[0], v[1], v[2])


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
    p.add_argument("--odometry-lag-ms", type=float, default=0.0)
    p.add_argument("--drop-right", type=int, default=0)
    p.add_argument("--imu", action="store_true")
    p.add_argument("--rig-camera", action="append", default=[])
    p.add_argument("--rig-compressed", action="store_true",
                   help="the rig's further cameras as /CAM/image_raw/compressed (JPEG)")
    a = p.parse_args()
    mav0 = os.path.join(a.dir, "mav0")
    left, body_from_left = read_camera(os.path.join(mav0, "cam0", "sensor.yaml"))
    stereo = not a.mono and os.path.exists(os.path.join(mav0, "cam1", "sensor.yaml"))
    r_left, r_right, baseline = np.eye(3), np.eye(3), 0.0
    if stereo:
        right, body_from_right = read_camera(os.path.join(mav0, "cam1", "sensor.yaml"))
        left_from_right = np.linalg.inv(body_from_left) @ body_from_right
        t = left_from_right[:3, 3]
        baseline = float(np.linalg.norm(t))
        if abs(t[1]) < 1e-6 * baseline and abs(t[2]) < 1e-6 * baseline and t[0] > 0:
            r_right = left_from_right[:3, :3]  # The rectified frame is the left camera's.
        else:
            # A real rig: rectified as ROS's stereo calibration does it (OpenCV's stereoRectify).
            r_left, r_right, baseline = rectify(left, right, np.linalg.inv(left_from_right))
    with open(os.path.join(mav0, "cam0", "data.csv")) as f:
        stamps = [int(row[0]) for row in csv.reader(f) if row and not row[0].startswith("#")]
    rig = [(cam,) + read_camera(os.path.join(mav0, cam, "sensor.yaml")) for cam in a.rig_camera]
    bag = rosbag.Bag(a.out, "w")
    try:
        if rig:
            t0 = to_time(stamps[0])
            bag.write("/tf_static", TFMessage(transforms=[
                static_transform("cam0", cam, np.linalg.inv(body_from_left) @ t_bs, t0)
                for cam, _, t_bs in rig]), t0)
        for i, ns in enumerate(stamps):
            t = to_time(ns)
            name = "%d.png" % ns
            write_image(bag, mav0, "cam0", name, t, "jpeg" if a.left_compressed else None)
            bag.write("/cam0/camera_info", camera_info(left, "cam0", t, r_left), t)
            for cam, sensor, _ in rig:
                write_image(bag, mav0, cam, name, t, "jpeg" if a.rig_compressed else None)
                bag.write("/%s/camera_info" % cam, camera_info(sensor, cam, t), t)
            if stereo:
                bag.write("/cam1/camera_info", camera_info(right, "cam1", t, r_right, baseline), t)
                if a.drop_right and i % a.drop_right == a.drop_right - 1:
                    continue
                write_image(bag, mav0, "cam1", name, t, "png" if a.right_compressed else None)
        imu = os.path.join(mav0, "imu0", "data.csv")
        if a.imu and os.path.exists(imu):
            write_imu(bag, imu, body_from_left, to_time(stamps[0]))
        odometry = os.path.join(mav0, "odometry0", "data.csv")
        if a.odometry and os.path.exists(odometry):
            with open(odometry) as f:
                rows = [row for row in csv.reader(f) if row and not row[0].startswith("#")]
                for i, row in enumerate(rows):
                    t = to_time(int(row[0]))
                    msg = Odometry()
                    msg.header.stamp, msg.header.frame_id, msg.child_frame_id = t, "odom", "cam0"
                    x, y, z, qx, qy, qz, qw = map(float, row[1:8])
                    msg.pose.pose.position.x, msg.pose.pose.position.y, msg.pose.pose.position.z = x, y, z
                    o = msg.pose.pose.orientation
                    o.x, o.y, o.z, o.w = qx, qy, qz, qw
                    lag_ns = int(a.odometry_lag_ms * 1e6) if i % 2 else 0
                    bag.write("/odom", msg, to_time(int(row[0]) + lag_ns))
    finally:
        bag.close()
    print("wrote %s: %d frames%s" % (a.out, len(stamps), " (stereo)" if stereo else ""))


if __name__ == "__main__":
    main()
