#!/usr/bin/env python3
"""A minimal Python robot on the visloc package: streams a folder of images (a camera's frames,
named by their timestamps in nanoseconds, as in EuRoC's cam0/data) to visloc-server at 15 Hz and
prints each pose. A real robot hands its camera driver's frames to submit() instead.

    robot_client.py SERVER MAP IMAGE_DIR --camera-yaml SENSOR_YAML

SENSOR_YAML is the camera's sensor.yaml as `visloc calibrate` writes it (or EuRoC's cam0).
The token, if the server wants one, comes from $VISLOC_TOKEN.
"""

import argparse
import os
import pathlib
import sys
import time

import cv2

from visloc import Session, SessionOptions, camera_from_yaml
from visloc.v1 import visloc_pb2 as pb


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("server")
    parser.add_argument("map")
    parser.add_argument("image_dir")
    parser.add_argument("--camera-yaml", required=True, help="the camera's sensor.yaml")
    args = parser.parse_args()
    try:
        camera = camera_from_yaml(args.camera_yaml)
    except ValueError as e:
        print(f"robot_client.py: {e}", file=sys.stderr)
        return 2
    # Every frame ends as exactly one of: answered, late, dropped (a live robot's queue keeps the
    # newest frames when the link or the server is slower than the camera) or undelivered.
    answered = posed = 0
    unanswered = {"late": 0, "dropped": 0, "undelivered": 0}

    def on_event(event):
        nonlocal answered, posed
        if event.kind in unanswered:
            unanswered[event.kind] += 1
        if event.kind == "link":
            print(f"link {event.link_state.value}: {event.detail}", flush=True)
        elif event.kind == "result":
            answered += 1
            r = event.response
            posed += r.has_pose
            p = r.map_from_cam
            print(f"{event.timestamp_ns * 1e-9:.3f} {pb.Status.Name(r.status)} "
                  f"position {p.tx:.3f} {p.ty:.3f} {p.tz:.3f} inliers {r.stats.inliers} "
                  f"latency {event.latency_ms:.1f} ms", flush=True)

    session = Session(SessionOptions(server=args.server, map_name=args.map, camera=camera,
                                     robot_id="example-python-robot",
                                     token=os.environ.get("VISLOC_TOKEN", ""),
                                     on_event=on_event))
    images = sorted(pathlib.Path(args.image_dir).iterdir())
    for path in images:
        sent = session.submit(int(path.stem), cv2.imread(str(path), cv2.IMREAD_GRAYSCALE))
        if not sent:
            print(f"not sent: {sent.reason}", file=sys.stderr)
        time.sleep(1 / 15)
    session.close()
    print(f"answered {answered} of {len(images)} frames, {posed} with a pose; "
          f"{unanswered['late']} late, {unanswered['dropped']} dropped, "
          f"{unanswered['undelivered']} undelivered")
    return 0 if answered > 0 else 1


if __name__ == "__main__":
    sys.exit(main())
