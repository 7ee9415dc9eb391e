"""visloc: the robot side of a visloc localization session, in Python.

The same session as the C++ client library (visloc::client): frames are encoded (JPEG, PNG or
raw grey), at most ``max_in_flight`` are on the wire, the oldest waiting frame is dropped when
the link is slower than the camera, answers later than ``frame_deadline_s`` are reported late,
and a broken or stalled stream is reopened with backoff and resumed from the last good pose (as
the frame's map_from_cam_hint) so tracking goes on.

    from visloc import Session, SessionOptions, camera_from_yaml
    session = Session(SessionOptions(server="127.0.0.1:50051", map_name="lab",
                                     camera=camera_from_yaml("calib/cam0/sensor.yaml")))
    sent = session.submit(timestamp_ns, grey_image)   # every camera frame; never blocks
    if not sent: print(sent.reason)                    # wrong size, closed, refused map ...
    event = session.next(timeout_s=0.05)               # answers, drops, link changes
    session.close()

Mapping over the link (``MappingSession``, ``stereo_rig_from_yaml``): a robot streams a stereo
run and the server builds the map (visloc.mapping).

The wire messages are visloc.v1 (``from visloc.v1 import visloc_pb2``), generated from the
repository's proto/ by Debian's protoc and grpc_python_plugin at build time.
"""

from visloc.camera import (body_from_cam_from_yaml, camera_from_yaml, pinhole_camera,
                           rig_camera_from_yaml, stereo_rig_from_yaml)
from visloc.mapping import MappingError, MappingOptions, MappingSession
from visloc.session import Event, LinkState, NotSent, Session, SessionOptions, encode_image

__all__ = ["Event", "LinkState", "MappingError", "MappingOptions", "MappingSession", "NotSent",
           "Session", "SessionOptions", "body_from_cam_from_yaml", "camera_from_yaml",
           "encode_image", "pinhole_camera", "rig_camera_from_yaml", "stereo_rig_from_yaml"]
