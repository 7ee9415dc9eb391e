#!/usr/bin/env python3
"""The Python client's resume logic against a scripted in-process Localization service.

A unit test of visloc.Session alone: the service is a few lines of grpcio that answer the first
stream's first frame with a pose and then break the stream, as a lost access point does. What the
session sends on the reopened stream is checked frame by frame.

Usage: session_unit_test.py  (PYTHONPATH holds the assembled package, build/python)
"""

import concurrent.futures
import itertools
import threading
import time
import unittest
from unittest import mock

import grpc
import numpy as np

from visloc import LinkState, Session, SessionOptions, pinhole_camera
from visloc.session import next_replica_first
from visloc.v1 import visloc_pb2 as pb
from visloc.v1 import visloc_pb2_grpc as pb_grpc

# The pose the service answers (map_from_cam: 1 m along x, turned 90 degrees about z).
ANSWERED = pb.Pose(tx=1.0, ty=0.5, tz=0.2, qw=0.7071067811865476, qx=0.0, qy=0.0,
                   qz=0.7071067811865476)


class ScriptedService(pb_grpc.LocalizationServicer):
    """Answers every frame with ANSWERED; the first stream breaks after its first answer (unless
    breaks_first is False)."""

    def __init__(self, breaks_first=True):
        self.lock = threading.Lock()
        self.streams = []  # The frames received, per stream.
        self.breaks_first = breaks_first

    def Localize(self, request_iterator, context):
        with self.lock:
            frames = []
            self.streams.append(frames)
            breaks = self.breaks_first and len(self.streams) == 1
        for request in request_iterator:
            if not request.HasField("frame"):
                continue
            with self.lock:
                frames.append(request.frame)
            yield pb.LocalizeResponse(timestamp_ns=request.frame.timestamp_ns,
                                      status=pb.STATUS_TRACKING, source=pb.SOURCE_TRACKING,
                                      has_pose=True, map_from_cam=ANSWERED)
            if breaks:
                context.abort(grpc.StatusCode.UNAVAILABLE, "the access point went away")

    def first_frame_of(self, stream):
        with self.lock:
            frames = self.streams[stream] if len(self.streams) > stream else []
            return frames[0] if frames else None


class EagerStub:
    """A Localization stub that reads the session start and the first frame from the request
    iterator before Localize returns. grpcio reads request iterators in a thread of its own, at
    any time from the call's creation on; this stub always reads at the earliest moment."""

    real = pb_grpc.LocalizationStub

    def __init__(self, channel):
        self._stub = EagerStub.real(channel)

    def Localize(self, requests, metadata=None):
        early = [next(requests), next(requests)]
        return self._stub.Localize(itertools.chain(early, requests), metadata=metadata)


class ResumeTest(unittest.TestCase):
    def setUp(self):
        self.service = ScriptedService()
        self.server = grpc.server(concurrent.futures.ThreadPoolExecutor(max_workers=4))
        pb_grpc.add_LocalizationServicer_to_server(self.service, self.server)
        self.port = self.server.add_insecure_port("127.0.0.1:0")
        self.server.start()

    def tearDown(self):
        self.server.stop(grace=None)

    def test_the_first_frame_of_a_reopened_stream_carries_the_last_pose(self):
        image = np.zeros((240, 320), np.uint8)
        options = SessionOptions(server=f"127.0.0.1:{self.port}", map_name="lab",
                                 camera=pinhole_camera(320, 240, 160, 160, 159.5, 119.5),
                                 encoding="raw")
        with mock.patch.object(pb_grpc, "LocalizationStub", EagerStub):
            session = Session(options)
            # A camera at 20 Hz until the reopened stream has its first frame (at most 5 s).
            timestamp_ns = 1_000_000_000
            deadline = time.monotonic() + 5.0
            while self.service.first_frame_of(1) is None and time.monotonic() < deadline:
                session.submit(timestamp_ns, image)
                timestamp_ns += 50_000_000
                time.sleep(0.05)
            session.close(drain_s=0.5)
        self.assertGreaterEqual(session.streams_opened, 2)
        first = self.service.first_frame_of(1)
        self.assertIsNotNone(first, "the session never reopened its stream")
        # Without odometry, the hint is the last answered pose itself.
        self.assertTrue(first.HasField("map_from_cam_hint"),
                        "the reopened stream's first frame went without the last pose: the "
                        "service must relocalize globally")
        self.assertEqual(first.map_from_cam_hint, ANSWERED)
        # And the first stream's first frame had no hint: there was nothing to resume.
        self.assertFalse(self.service.first_frame_of(0).HasField("map_from_cam_hint"))


class FullService(pb_grpc.LocalizationServicer):
    """A server at capacity: every stream is refused at its start."""

    def __init__(self):
        self.lock = threading.Lock()
        self.refusals = []  # When each stream was refused (monotonic s).

    def Localize(self, request_iterator, context):
        next(request_iterator)
        with self.lock:
            self.refusals.append(time.monotonic())
        context.abort(grpc.StatusCode.RESOURCE_EXHAUSTED,
                      "server at capacity: ... Retry in a few seconds, or on another replica")


class CapacityTest(unittest.TestCase):
    """A session refused for capacity backs off (1 s, doubling) instead of asking at once."""

    def test_a_refused_session_asks_again_later_and_says_why(self):
        service = FullService()
        server = grpc.server(concurrent.futures.ThreadPoolExecutor(max_workers=4))
        pb_grpc.add_LocalizationServicer_to_server(service, server)
        port = server.add_insecure_port("127.0.0.1:0")
        server.start()
        try:
            links = []
            options = SessionOptions(server=f"127.0.0.1:{port}", map_name="lab",
                                     camera=pinhole_camera(320, 240, 160, 160, 159.5, 119.5),
                                     encoding="raw",
                                     on_event=lambda e: e.kind == "link" and links.append(e))
            session = Session(options)
            image = np.zeros((240, 320), np.uint8)
            started = time.monotonic()
            while time.monotonic() - started < 3.5:
                session.submit(int(time.monotonic() * 1e9), image)
                time.sleep(0.05)
            state = session.link_state
            session.close(drain_s=0.0)
        finally:
            server.stop(grace=None)
        with service.lock:
            refusals = list(service.refusals)
        # At 0, ~1 and ~3 s: three in 3.5 s (at the link's pace it would be dozens).
        self.assertGreaterEqual(len(refusals), 2)
        self.assertLessEqual(len(refusals), 4, refusals)
        self.assertGreaterEqual(refusals[1] - refusals[0], 0.9)
        self.assertTrue(any("server at capacity" in e.detail for e in links),
                        [e.detail for e in links])
        self.assertNotEqual(state, LinkState.FAILED)


class ReplicaTest(unittest.TestCase):
    """A session refused by a replica at capacity goes on to the next one of its list at once."""

    def test_the_next_replica_first(self):
        self.assertEqual(next_replica_first("ipv4:10.0.0.5:50051,10.0.0.6:50051,10.0.0.7:50051"),
                         "ipv4:10.0.0.6:50051,10.0.0.7:50051,10.0.0.5:50051")
        self.assertEqual(next_replica_first("ipv6:[::1]:5001,[::1]:5002"),
                         "ipv6:[::1]:5002,[::1]:5001")
        for one in ["127.0.0.1:5001", "ipv4:127.0.0.1:5001", "dns:///visloc:50051"]:
            self.assertEqual(next_replica_first(one), one)

    def test_a_robot_refused_by_a_full_replica_is_served_by_the_other(self):
        full, serving = FullService(), ScriptedService(breaks_first=False)
        servers, ports = [], []
        for service in (full, serving):
            server = grpc.server(concurrent.futures.ThreadPoolExecutor(max_workers=4))
            pb_grpc.add_LocalizationServicer_to_server(service, server)
            ports.append(server.add_insecure_port("127.0.0.1:0"))
            server.start()
            servers.append(server)
        try:
            answers = []
            options = SessionOptions(
                server=f"ipv4:127.0.0.1:{ports[0]},127.0.0.1:{ports[1]}", map_name="lab",
                camera=pinhole_camera(320, 240, 160, 160, 159.5, 119.5), encoding="raw",
                on_event=lambda e: e.kind == "result" and answers.append(time.monotonic()))
            session = Session(options)
            image = np.zeros((240, 320), np.uint8)
            started = time.monotonic()
            while not answers and time.monotonic() - started < 5.0:
                session.submit(int(time.monotonic() * 1e9), image)
                time.sleep(0.05)
            session.close(drain_s=0.0)
        finally:
            for server in servers:
                server.stop(grace=None)
        with full.lock:
            refusals = list(full.refusals)
        self.assertEqual(len(refusals), 1, "refused once, then served by the other replica")
        self.assertTrue(answers, "the other replica never answered")
        # At once: not after the second of backoff a lone server at capacity gets.
        self.assertLess(answers[0] - refusals[0], 0.9)


class SilentService(pb_grpc.LocalizationServicer):
    """Reads every frame and answers none (a server stuck behind its engine)."""

    def Localize(self, request_iterator, context):
        for _ in request_iterator:
            pass
        return iter(())


class CloseTest(unittest.TestCase):
    """Closing reports every frame handed over: those on the wire undelivered, those still
    waiting dropped (as the C++ library does); none vanish."""

    def test_every_frame_submitted_before_close_is_accounted_for(self):
        server = grpc.server(concurrent.futures.ThreadPoolExecutor(max_workers=4))
        pb_grpc.add_LocalizationServicer_to_server(SilentService(), server)
        port = server.add_insecure_port("127.0.0.1:0")
        server.start()
        events = []
        options = SessionOptions(server=f"127.0.0.1:{port}", map_name="lab",
                                 camera=pinhole_camera(320, 240, 160, 160, 159.5, 119.5),
                                 encoding="raw", frame_deadline_s=30.0, stall_timeout_s=30.0,
                                 on_event=events.append)
        session = Session(options)
        image = np.zeros((240, 320), np.uint8)
        for i in range(4):  # Two on the wire, two waiting.
            self.assertIs(session.submit(1_000 + i, image), True)
            time.sleep(0.1)
        session.close(drain_s=0.2)
        server.stop(grace=None)
        fates = {e.timestamp_ns: e.kind for e in events if e.kind != "link"}
        self.assertEqual(sorted(fates), [1_000, 1_001, 1_002, 1_003], events)
        self.assertEqual(sorted(fates.values()),
                         ["dropped", "dropped", "undelivered", "undelivered"], events)


class RefusedFramesTest(unittest.TestCase):
    """Frames the session cannot send are refused at once with the reason, as in C++."""

    def test_bad_frames_and_a_closed_session_say_why(self):
        options = SessionOptions(server="127.0.0.1:1", map_name="lab",
                                 camera=pinhole_camera(320, 240, 160, 160, 159.5, 119.5),
                                 give_up_after_s=0.2)
        session = Session(options)
        wrong = session.submit(1, np.zeros((100, 100), np.uint8))
        self.assertFalse(wrong)
        self.assertEqual(wrong.reason, "the image is 100x100 but the session camera is 320x240")
        self.assertEqual(session.submit(2, None).reason, "the frame has no image")
        self.assertEqual(session.submit(3, np.zeros((240, 320), np.float32)).reason,
                         "the image is not 8-bit")
        self.assertIs(session.submit(4, np.zeros((240, 320), np.uint8)), True)
        session.close(drain_s=0.0)
        self.assertEqual(str(session.submit(5, np.zeros((240, 320), np.uint8))),
                         "the session is closed")


if __name__ == "__main__":
    unittest.main(verbosity=2)
