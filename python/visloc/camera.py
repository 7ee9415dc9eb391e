"""Cameras for a session: from a calibration's sensor.yaml, or a pinhole by hand.

sensor.yaml is the EuRoC/Kalibr layout that ``visloc calibrate`` and ``visloc sim`` write:
resolution [w, h], camera_model pinhole, intrinsics [fu, fv, cu, cv], distortion_model
(radial-tangential, equidistant or none) and distortion_coefficients (four). It is read with
OpenCV's FileStorage, as the C++ library's CameraFromYaml reads it, so both accept the same files.
"""

from typing import List

import cv2

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


def camera_from_yaml(path: str) -> pb.CameraModel:
    """The camera a sensor.yaml describes; ValueError naming the file and what is wrong."""
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
