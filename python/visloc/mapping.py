"""Mapping over the link from Python: a robot streams a stereo run, the server builds the map.

The same session as the C++ library's visloc::client::MappingSession: at most ``max_in_flight``
frames are unanswered (``submit`` waits for room: a map needs every frame); when the stream
breaks the session reconnects with backoff and resumes the same job, which the server keeps for
its --mapping-resume-s window (a restarted server takes the job up from its spool), re-sending
the unanswered frames after the last one it mapped.

    from visloc import MappingOptions, MappingSession
    mapping = MappingSession(MappingOptions(server="10.0.0.5:50051", map_name="hall", rig=rig,
                                            token=admin_token))
    for t, left, right in frames:
        mapping.submit(t, left, right)        # raises MappingError when the job cannot go on
    for answer, latency_ms in mapping.answers(): ...
    published = mapping.finish()              # the map's MappingProgress (state PUBLISHED)
"""

import collections
import dataclasses
import threading
import time
import queue
from typing import Deque, List, Optional, Tuple

import grpc
import numpy as np

from visloc.session import encode_image, open_channel
from visloc.v1 import visloc_pb2 as pb
from visloc.v1 import visloc_pb2_grpc as pb_grpc

# Statuses after which resuming cannot help: the server refused the job or has no such job.
_REFUSED = {grpc.StatusCode.INVALID_ARGUMENT, grpc.StatusCode.ALREADY_EXISTS,
            grpc.StatusCode.NOT_FOUND, grpc.StatusCode.PERMISSION_DENIED,
            grpc.StatusCode.UNAUTHENTICATED, grpc.StatusCode.RESOURCE_EXHAUSTED,
            grpc.StatusCode.FAILED_PRECONDITION, grpc.StatusCode.UNIMPLEMENTED}
_FRAME_ANSWERS = {pb.MAPPING_TRACKING, pb.MAPPING_LOST, pb.MAPPING_FRAME_ERROR}


class MappingError(RuntimeError):
    """The job cannot go on or was not published; the message says why."""


@dataclasses.dataclass
class MappingOptions:
    server: str
    map_name: str
    rig: pb.StereoRig
    mapping: pb.MappingOptions = dataclasses.field(default_factory=pb.MappingOptions)
    robot_id: str = "python"
    token: str = ""
    tls_ca_pem: bytes = b""
    tls_cert_pem: bytes = b""
    tls_key_pem: bytes = b""
    encoding: str = "png"  # Lossless: a map from JPEG frames differs slightly.
    jpeg_quality: int = 95
    max_in_flight: int = 8
    resume_timeout_s: float = 30.0
    backoff_initial_s: float = 0.25
    backoff_max_s: float = 2.0

    def check(self):
        if not self.server or not self.map_name:
            raise ValueError("MappingOptions: server and map_name are needed")
        if not self.rig.HasField("left") or not self.rig.HasField("right"):
            raise ValueError("MappingOptions.rig needs both cameras")
        if not 1 <= self.max_in_flight <= 64:
            raise ValueError("MappingOptions.max_in_flight: 1..64")


class _Stream:
    """One BuildMap call: requests through a queue, answers read on a thread."""

    def __init__(self, channel: grpc.Channel, metadata, start: pb.MappingRequest):
        self.requests: "queue.Queue[Optional[pb.MappingRequest]]" = queue.Queue()
        self.requests.put(start)
        stub = pb_grpc.MappingStub(channel)
        self.answers = stub.BuildMap(iter(self.requests.get, None), metadata=metadata)
        self.first = next(self.answers)  # STARTED or RESUMED; raises grpc.RpcError.
        self.done = False
        self.code: Optional[grpc.StatusCode] = None
        self.details = ""

    def send(self, request: pb.MappingRequest):
        self.requests.put(request)

    def end(self):
        self.requests.put(None)


class MappingSession:
    def __init__(self, options: MappingOptions):
        options.check()
        self._o = options
        self._lock = threading.Condition()
        self._unanswered: Deque[Tuple[pb.MappingRequest, float]] = collections.deque()
        self._answers: List[Tuple[pb.MappingProgress, float]] = []
        self._published: Optional[pb.MappingProgress] = None
        self._job_failure = ""
        self.job_id = 0
        self.resumes = 0
        self.submitted = 0
        self._stream: Optional[_Stream] = None
        self._reader: Optional[threading.Thread] = None
        try:
            self._open(resume=False)
        except grpc.RpcError as e:
            raise MappingError(f"server {options.server}: {e.details()} ({e.code().name})")

    def submit(self, timestamp_ns: int, left: Optional[np.ndarray] = None,
               right: Optional[np.ndarray] = None, *, left_encoded: bytes = b"",
               right_encoded: bytes = b""):
        """Sends a stereo frame, waiting while max_in_flight are unanswered."""
        request = pb.MappingRequest()
        frame = request.frame
        frame.timestamp_ns = timestamp_ns
        o = self._o
        frame.left_encoded = left_encoded or encode_image(left, o.encoding, o.jpeg_quality)
        frame.right_encoded = right_encoded or encode_image(right, o.encoding, o.jpeg_quality)
        with self._lock:
            self._lock.wait_for(lambda: self._stream.done or
                                len(self._unanswered) < self._o.max_in_flight)
            self._unanswered.append((request, time.monotonic()))
            self.submitted += 1
            broken = self._stream.done
            if not broken:
                self._stream.send(request)
        if broken:
            self._resume()

    def answers(self) -> List[Tuple[pb.MappingProgress, float]]:
        """The answers since the last call, oldest first, with their latencies (ms)."""
        with self._lock:
            taken, self._answers = self._answers, []
        return taken

    def finish(self) -> pb.MappingProgress:
        """MappingEnd, then the outcome: the PUBLISHED answer, or MappingError saying why."""
        while True:
            end = pb.MappingRequest()
            end.end.SetInParent()
            self._stream.send(end)
            self._stream.end()
            self._reader.join()
            if self._published is not None:
                return self._published
            if self._job_failure:
                raise MappingError(self._job_failure)
            if self._stream.code in _REFUSED:
                raise MappingError(f"server {self._o.server}: {self._stream.details}")
            # The link broke around MappingEnd: the job either waits (resume it and end it
            # again) or is already published (by this server, or by a restarted one that took
            # the job up from its spool).
            try:
                self._resume()
            except MappingError:
                done = self._published_meanwhile()
                if done is None:
                    raise
                return done

    def _published_meanwhile(self) -> Optional[pb.MappingProgress]:
        """After a break around MappingEnd: the job's PUBLISHED record, if the server has one."""
        metadata = [("authorization", "Bearer " + self._o.token)] if self._o.token else None
        try:
            jobs = pb_grpc.MappingStub(self._channel).ListJobs(pb.ListJobsRequest(),
                                                               metadata=metadata, timeout=5)
        except grpc.RpcError:
            return None
        for job in jobs.jobs:
            if job.job_id == self.job_id and job.state == pb.MAPPING_PUBLISHED:
                done = pb.MappingProgress(state=pb.MAPPING_PUBLISHED, job_id=job.job_id,
                                          frame_index=job.frames, keyframes=job.keyframes,
                                          points=job.points)
                done.map.name = job.map_name
                return done
        return None

    def _open(self, resume: bool):
        o = self._o
        channel = open_channel(o.server, o.tls_ca_pem, o.tls_cert_pem, o.tls_key_pem, 10000,
                               o.backoff_initial_s, o.backoff_max_s)
        self._channel = channel
        start = pb.MappingRequest()
        start.start.map_name = o.map_name
        start.start.robot_id = o.robot_id
        start.start.rig.CopyFrom(o.rig)
        start.start.options.CopyFrom(o.mapping)
        if resume:
            start.start.resume_job_id = self.job_id
        metadata = [("authorization", "Bearer " + o.token)] if o.token else None
        stream = _Stream(channel, metadata, start)
        with self._lock:
            self.job_id = stream.first.job_id
            if resume:  # Mapped already (their answers were lost): not sent again.
                while (self._unanswered and self._unanswered[0][0].frame.timestamp_ns <=
                       stream.first.timestamp_ns):
                    self._unanswered.popleft()
                for request, _ in self._unanswered:
                    stream.send(request)
            self._stream = stream
        self._reader = threading.Thread(target=self._read, args=(stream,), daemon=True)
        self._reader.start()

    def _read(self, stream: _Stream):
        try:
            for answer in stream.answers:
                with self._lock:
                    if answer.state in _FRAME_ANSWERS:
                        latency_ms = 0.0
                        while (self._unanswered and self._unanswered[0][0].frame.timestamp_ns <=
                               answer.timestamp_ns):
                            latency_ms = (time.monotonic() - self._unanswered.popleft()[1]) * 1000
                        self._answers.append((answer, latency_ms))
                    elif answer.state == pb.MAPPING_PUBLISHED:
                        self._published = answer
                    elif answer.state == pb.MAPPING_FAILED:
                        self._job_failure = "the server failed the job: " + answer.error
                    self._lock.notify_all()
        except grpc.RpcError as e:
            stream.code, stream.details = e.code(), e.details()
        with self._lock:
            stream.done = True
            self._lock.notify_all()

    def _resume(self):
        """Takes the job up again on a new stream, retrying for resume_timeout_s."""
        self._stream.end()
        self._reader.join()
        if self._job_failure:
            raise MappingError(self._job_failure)
        deadline = time.monotonic() + self._o.resume_timeout_s
        backoff = self._o.backoff_initial_s
        why = self._stream.details
        while time.monotonic() < deadline:
            time.sleep(backoff)
            backoff = min(backoff * 2, self._o.backoff_max_s)
            try:
                self._open(resume=True)
                self.resumes += 1
                return
            except grpc.RpcError as e:
                why = f"{e.details()} ({e.code().name})"
                if e.code() in _REFUSED:
                    break
        raise MappingError(f"the mapping stream of '{self._o.map_name}' broke and could not be "
                           f"resumed ({why}): nothing was published")
