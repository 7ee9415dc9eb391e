#!/usr/bin/env python3
"""The Python client against the real visloc-server (and, for a cut, through the link proxy).

Usage: session_test.py VISLOC_SERVER VISLOC_LINK_PROXY LOCALIZATION_DATA
The data folder is the localization test fixture (map.db and query_square/).
"""

import glob
import os
import shutil
import sys
import tempfile
import time
import unittest

import cv2

from harness import start
from visloc import (Session, SessionOptions, body_from_cam_from_yaml, pinhole_camera,
                    rig_camera_from_yaml)
from visloc.v1 import visloc_pb2 as pb

SERVER, PROXY, DATA = sys.argv[1], sys.argv[2], sys.argv[3]
del sys.argv[1:4]


def read_tum(path):
    """timestamp_ns -> Pose (TUM: t tx ty tz qx qy qz qw)."""
    poses = {}
    for line in open(path):
        if line.startswith("#") or not line.strip():
            continue
        stamp, *values = line.split()
        seconds, _, fraction = stamp.partition(".")  # Exact nanoseconds: no float rounding.
        timestamp_ns = int(seconds) * 1_000_000_000 + int((fraction + "000000000")[:9])
        tx, ty, tz, qx, qy, qz, qw = [float(v) for v in values]
        poses[timestamp_ns] = pb.Pose(tx=tx, ty=ty, tz=tz, qw=qw, qx=qx, qy=qy, qz=qz)
    return poses


class PythonClientTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.maps = tempfile.mkdtemp(prefix="visloc_py_maps")
        shutil.copy(os.path.join(DATA, "map.db"), os.path.join(cls.maps, "square.db"))
        # Admission by load off (--admit-busy 0): these tests share one server, and in CI the
        # unknown-map test, right after the rig replay kept it busy, was refused "at capacity"
        # instead of hearing its map is unknown. Admission has its own tests.
        cls.server, cls.address = start([SERVER, "--maps", cls.maps, "--listen", "127.0.0.1:0",
                                         "--admit-busy", "0"])
        images = sorted(glob.glob(os.path.join(DATA, "query_square/mav0/cam0/data/*.png")))
        cls.frames = [(int(os.path.basename(p)[:-4]), cv2.imread(p, cv2.IMREAD_GRAYSCALE))
                      for p in images]
        cls.truth = read_tum(os.path.join(DATA, "query_square/groundtruth_map.tum"))
        cls.odometry = read_tum(os.path.join(DATA, "query_square/odometry_map.tum"))

    @classmethod
    def tearDownClass(cls):
        cls.server.terminate()
        cls.server.wait()
        shutil.rmtree(cls.maps)

    def options(self, address, **kwargs):
        return SessionOptions(server=address, map_name="square",
                              camera=pinhole_camera(320, 240, 160, 160, 159.5, 119.5), **kwargs)

    def collect(self, session, until):
        events = []
        while time.monotonic() < until:
            event = session.next(0.02)
            if event:
                events.append(event)
        return events

    @staticmethod
    def describe(event):
        """One line per event, for failure messages."""
        if event.kind == "link":
            return f"link {event.link_state.value}: {event.detail}"
        if event.kind in ("result", "late"):
            r = event.response
            return (f"{event.kind} {event.timestamp_ns} {event.latency_ms:.0f} ms "
                    f"{pb.Status.Name(r.status)} {pb.PoseSource.Name(r.source)} "
                    f"{r.relocalization.kind} inliers={r.stats.inliers}")
        return f"{event.kind} {event.timestamp_ns}: {event.detail}"

    def position_error_m(self, event):
        truth = self.truth[event.timestamp_ns]
        p = event.response.map_from_cam
        return ((p.tx - truth.tx) ** 2 + (p.ty - truth.ty) ** 2 + (p.tz - truth.tz) ** 2) ** 0.5

    def test_streams_at_15_hz_and_poses_match_ground_truth(self):
        session = Session(self.options(self.address, encoding="jpeg", jpeg_quality=80))
        for timestamp_ns, image in self.frames[:45]:
            self.assertTrue(session.submit(timestamp_ns, image))
            time.sleep(1 / 15)
        session.close(drain_s=60)
        events = self.collect(session, time.monotonic() + 0.5)
        # Every frame is accounted for: answered, answered late, or dropped by the library for
        # a newer one when the server is slower than 15 Hz (a sanitized server in a loaded CI
        # run answered 33 of 45 in time); none is lost without a word.
        kinds = [e.kind for e in events if e.kind != "link"]
        self.assertEqual(len(kinds), 45, kinds)
        self.assertEqual(set(kinds) - {"result", "late", "dropped"}, set(), kinds)
        results = [e for e in events if e.kind in ("result", "late")]
        self.assertGreaterEqual(len(results), 15, kinds)
        posed = [e for e in results if e.response.has_pose]
        self.assertGreaterEqual(len(posed), len(results) - 1)
        errors = sorted(self.position_error_m(e) for e in posed)
        self.assertLess(errors[len(errors) // 2], 0.02)
        self.assertEqual(session.streams_opened, 1)

    def test_a_rig_keeps_the_pose_while_its_front_camera_is_covered(self):
        """The front-back kidnap walk (the fixture's rig): the rear camera's sensor.yaml places
        it, every frame carries its image, and no frame is without a pose."""
        walk = os.path.join(DATA, "front-back/kidnap/mav0")
        rear = rig_camera_from_yaml(os.path.join(walk, "cam2/sensor.yaml"), "rear")
        # A replay, not a live robot: every frame waits its turn (a loaded CI machine answered
        # 97 of 120 with the live queue of 2, dropping the rest on the robot's side), and a slow
        # answer is waited for. With the live robot's 2 s stall timeout, an ASan server beside
        # Chromium answered 88 of 120 in CI: the stream was taken for stalled and reopened again
        # and again, the frames on it undelivered (6 busy loops beside it: 60 of 120).
        options = self.options(self.address, rig_cameras=[rear], max_queued=120,
                               frame_deadline_s=30.0, stall_timeout_s=30.0)
        options.session.body_from_cam.CopyFrom(
            body_from_cam_from_yaml(os.path.join(walk, "cam0/sensor.yaml")))
        session = Session(options)
        refused = session.submit(*self.frames[0])
        self.assertFalse(refused)
        self.assertEqual(refused.reason, "the frame carries 0 rig images for 1 rig cameras")
        front = sorted(glob.glob(os.path.join(walk, "cam0/data/*.png")))[:120]
        for path in front:
            timestamp_ns = int(os.path.basename(path)[:-4])
            rear_image = cv2.imread(path.replace("/cam0/", "/cam2/"), cv2.IMREAD_GRAYSCALE)
            self.assertTrue(session.submit(timestamp_ns, cv2.imread(path, cv2.IMREAD_GRAYSCALE),
                                           rig_images=[rear_image]))
            time.sleep(1 / 30)
        # Close returns once every frame is answered; the bound is for a broken server only.
        session.close(drain_s=90)
        events = self.collect(session, time.monotonic() + 0.5)
        results = [e for e in events if e.kind == "result"]
        self.assertEqual(len(results), 120, [(e.kind, e.detail) for e in events if e.kind == "link"][:6])
        story = "\n".join(self.describe(e) for e in results)
        self.assertTrue(all(e.response.has_pose for e in results[1:]), story)
        self.assertTrue(all(len(e.response.cameras) == 2 for e in results), story)
        covered = [e for e in results if e.response.cameras[0].inliers == 0 and
                   e.response.cameras[1].inliers > 100]
        self.assertGreaterEqual(len(covered), 10, story)  # Frames 91-108: the rear camera's fix.

    def test_an_unknown_map_fails_once_with_the_reason(self):
        options = self.options(self.address)
        options.map_name = "nope"
        session = Session(options)
        for frame in self.frames[:3]:  # A camera goes on giving frames while the refusal comes.
            session.submit(*frame)
            time.sleep(0.03)
        events = self.collect(session, time.monotonic() + 3)
        # Frames that went out before the refusal came say why they were never answered (how
        # many went out depends on the timing; ClientSessionTest proves it in C++).
        for e in events:
            if e.kind == "undelivered":
                self.assertIn("no map named 'nope'", e.detail)
        failed = [e for e in events if e.kind == "link" and e.link_state.value == "failed"]
        self.assertEqual(len(failed), 1)
        self.assertIn("no map named 'nope'", failed[0].detail)
        refused = session.submit(*self.frames[1])
        self.assertFalse(refused)
        self.assertIn("no map named 'nope'", refused.reason)
        session.close()

    def test_a_cut_link_is_resumed_and_tracked(self):
        # The cut comes 3 s in, after the first pose (the map's first load and a global
        # relocalization take over a second in a loaded sanitizer build: a cut at 1.5 s once
        # came before any pose, leaving nothing to resume from); the link is back 2.5 s before
        # the end.
        proxy, address = start([PROXY, "--upstream", self.address, "--latency-ms", "5",
                                "--cut-every-s", "3", "--cut-ms", "1500", "--cuts", "1",
                                "--seconds", "30"])
        try:
            session = Session(self.options(address))
            for timestamp_ns, image in self.frames[:105]:  # 7 s at 15 Hz, with odometry.
                session.submit(timestamp_ns, image,
                               odom_from_cam=self.odometry.get(timestamp_ns))
                time.sleep(1 / 15)
            session.close()
            events = self.collect(session, time.monotonic() + 0.5)
        finally:
            proxy.terminate()
            proxy.wait()
        resumed = [i for i, e in enumerate(events) if e.kind == "link" and e.detail == "resumed"]
        self.assertTrue(resumed, [(e.kind, e.detail) for e in events if e.kind == "link"])
        posed_before = [e for e in events[:resumed[0]]
                        if e.kind == "result" and e.response.has_pose]
        self.assertTrue(posed_before, "no pose before the cut to resume from")
        first = next(e for e in events[resumed[0]:] if e.kind == "result")
        story = "\n".join(self.describe(e) for e in events)
        self.assertEqual(first.response.source, pb.SOURCE_TRACKING, story)
        self.assertNotEqual(first.response.relocalization.kind, "global", story)
        kinds = [e.kind for e in events]
        self.assertGreater(kinds.count("dropped") + kinds.count("undelivered"), 5)
        self.assertEqual(sum(kinds.count(k) for k in ("result", "late", "dropped", "undelivered")),
                         105)


if __name__ == "__main__":
    unittest.main(verbosity=2)
