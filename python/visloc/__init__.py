"""visloc: the robot side of a visloc localization session, in Python.

The same session as the C++ client library (visloc::client): frames are encoded (JPEG, PNG or
raw grey), at most ``max_in_flight`` are on the wire, the oldest waiting frame is dropped when
the link is slower than the camera, answers later than ``frame_deadline_s`` are reported late,
and a broken or stalled stream is reopened with backoff and resumed from the last good pose (as
the frame's map_from_cam_hint) so tracking goes on.

    from visloc import Session, SessionOptions, pinhole_camera
    session = Session(SessionOptions(server="127.0.0.1:50051", map_name="lab",
                                     camera=pinhole_camera(640, 480, 525, 525, 319.5, 239.5)))
    session.submit(timestamp_ns, grey_image)          # every camera frame; never blocks
    event = session.next(timeout_s=0.05)               # answers, drops, link changes
    session.close()

The wire messages are visloc.v1 (``from visloc.v1 import visloc_pb2``), generated from the
repository's proto/ by Debian's protoc and grpc_python_plugin at build time.
"""

from visloc.session import (Event, LinkState, Session, SessionOptions, encode_image,
                            pinhole_camera)

__all__ = ["Event", "LinkState", "Session", "SessionOptions", "encode_image", "pinhole_camera"]
