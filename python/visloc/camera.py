"""Cameras for a session: from a calibration's sensor.yaml, or a pinhole by hand.

sensor.yaml is the EuRoC/Kalibr layout that ``visloc calibrate`` and ``visloc sim`` write:
resolution [w, h], camera_model pinhole, intrinsics [fu, fv, cu, cv], distortion_model
(radial-tangential, equidistant or none) and distortion_coefficients (four). It is read with
OpenCV's FileStorage, as the C++ library's CameraFromYaml reads it, so both accept the same files.
"""

from typing import List

import cv2
import numpy as np

from visloc.v1 import visloc_pb2 as pb


def pinhole_camera(width, height, fx, fy, cx, cy, distortion=()) -> pb.CameraModel:
    """A pinhole camera (four radial-tangential distortion values, or none)."""
    return pb.CameraModel(width=width, height=height, fx=fx, fy=fy, cx=cx, cy=cy,
                          distortion=list(distortion))


def _numbers(path: str, node, key: str, expected: int) -> List[float]:
    if node.empty():
        raise ValueError(f"{path}: missing '{key}'")
    if not node.isSeq() or node.size() != expected:
        raise ValueError(f"{path}: '{key}' must be a list of {expected} numbers")
    values = []
    for i in range(node.size()):
        item = node.at(i)
        if not (item.isReal() or item.isInt()):
            raise ValueError(f"{path}: '{key}' has a non-number")
        values.append(item.real())
    return values


def _text(node) -> str:
    return node.string() if node.isString() else ""


def _read_yaml(path: str):
    try:
        with open(path, "r", encoding="utf-8", errors="replace") as f:
            text = f.read()
    except OSError as e:
        raise ValueError(f"{path}: no such file (or not readable): {e.strerror}") from None
    if not text.startswith("%YAML"):
        text = "%YAML:1.0\n" + text  # OpenCV needs EuRoC's directive; visloc's files lack it.
    try:
        storage = cv2.FileStorage(text, cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_MEMORY |
                                  cv2.FILE_STORAGE_FORMAT_YAML)
    except (cv2.error, SystemError) as e:  # cv2 wraps its parse errors in SystemError.
        cause = getattr(e, "err", None) or getattr(e.__cause__, "err", None) or "parse error"
        raise ValueError(f"{path}: not a YAML file OpenCV can read ({cause})") from None
    if not storage.isOpened():
        raise ValueError(f"{path}: not a YAML file OpenCV can read")
    return storage


def body_from_cam_from_yaml(path: str) -> pb.Pose:
    """The camera's pose on the body, a sensor.yaml's T_BS (identity when it has none)."""
    storage = _read_yaml(path)  # Kept: its nodes are views into it.
    node = storage.getNode("T_BS")
    if node.empty():
        return pb.Pose(qw=1.0)
    m = np.array(_numbers(path, node.getNode("data"), "T_BS.data", 16)).reshape(4, 4)
    r = m[:3, :3]
    # The rotation's quaternion from its largest diagonal term (stable for every angle).
    trace = np.trace(r)
    if trace > 0:
        s = 2.0 * np.sqrt(trace + 1.0)
        q = [0.25 * s, (r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s]
    else:
        i = int(np.argmax(np.diag(r)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * np.sqrt(1.0 + r[i, i] - r[j, j] - r[k, k])
        v = [0.0, 0.0, 0.0]
        v[i] = 0.25 * s
        v[j] = (r[j, i] + r[i, j]) / s
        v[k] = (r[k, i] + r[i, k]) / s
        q = [(r[k, j] - r[j, k]) / s] + v
    return pb.Pose(tx=m[0, 3], ty=m[1, 3], tz=m[2, 3], qw=q[0], qx=q[1], qy=q[2], qz=q[3])


def rig_camera_from_yaml(path: str, name: str = "") -> pb.RigCamera:
    """A rig's further camera from its sensor.yaml: the camera, placed on the body by T_BS."""
    return pb.RigCamera(camera=camera_from_yaml(path), body_from_cam=body_from_cam_from_yaml(path),
                        name=name)


def stereo_rig_from_yaml(left_path: str, right_path: str) -> pb.StereoRig:
    """A stereo rig (for mapping over the link) from its two cameras' sensor.yaml files."""
    return pb.StereoRig(left=camera_from_yaml(left_path), right=camera_from_yaml(right_path),
                        body_from_left=body_from_cam_from_yaml(left_path),
                        body_from_right=body_from_cam_from_yaml(right_path))


def camera_from_yaml(path: str) -> pb.CameraModel:
    """The camera a sensor.yaml describes; ValueError naming the file and what is wrong."""
    storage = _read_yaml(path)
    model = _text(storage.getNode("camera_model"))
    if not model:
        raise ValueError(f"{path}: missing 'camera_model'")
    if model != "pinhole":
        raise ValueError(f"{path}: unsupported camera_model '{model}' (expected pinhole)")
    width, height = _numbers(path, storage.getNode("resolution"), "resolution", 2)
    fx, fy, cx, cy = _numbers(path, storage.getNode("intrinsics"), "intrinsics", 4)
    if width < 1 or height < 1 or fx <= 0 or fy <= 0:
        raise ValueError(f"{path}: invalid resolution or focal length")
    camera = pinhole_camera(int(width), int(height), fx, fy, cx, cy)
    lens = _text(storage.getNode("distortion_model"))
    if lens and lens != "none":
        if lens in ("radial-tangential", "radtan"):
            camera.lens_model = pb.RADIAL_TANGENTIAL
        elif lens == "equidistant":
            camera.lens_model = pb.EQUIDISTANT
        else:
            raise ValueError(f"{path}: unsupported distortion_model '{lens}' "
                             "(expected radial-tangential, equidistant or none)")
        camera.distortion.extend(_numbers(path, storage.getNode("distortion_coefficients"),
                                          "distortion_coefficients", 4))
    return camera
