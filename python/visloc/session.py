"""The Python client session (see the package docstring)."""

import collections
import dataclasses
import enum
import queue
import threading
import time
from typing import Callable, Deque, List, Optional, Sequence

import cv2
import grpc
import numpy as np

from visloc.v1 import visloc_pb2 as pb
from visloc.v1 import visloc_pb2_grpc as pb_grpc

# Statuses after which reconnecting cannot help: the request itself is refused.
# How long a session refused for capacity (RESOURCE_EXHAUSTED) waits before asking again,
# doubling while it is refused (server/admission.h).
_FIRST_CAPACITY_BACKOFF_S = 1.0
_MAX_CAPACITY_BACKOFF_S = 8.0

_PERMANENT = {grpc.StatusCode.INVALID_ARGUMENT, grpc.StatusCode.NOT_FOUND,
              grpc.StatusCode.PERMISSION_DENIED, grpc.StatusCode.UNAUTHENTICATED,
              grpc.StatusCode.UNIMPLEMENTED, grpc.StatusCode.FAILED_PRECONDITION}
_POSED = {pb.STATUS_TRACKING, pb.STATUS_RELOCALIZED, pb.STATUS_LIMITED}


class LinkState(enum.Enum):
    CONNECTING = "connecting"
    CONNECTED = "connected"
    DEGRADED = "degraded"
    RECONNECTING = "reconnecting"
    FAILED = "failed"
    CLOSED = "closed"


@dataclasses.dataclass
class Event:
    """kind: "result", "late", "dropped", "undelivered" or "link"."""
    kind: str
    timestamp_ns: int = 0
    latency_ms: float = 0.0
    response: Optional[pb.LocalizeResponse] = None
    link_state: Optional[LinkState] = None
    detail: str = ""


@dataclasses.dataclass
class SessionOptions:
    server: str
    map_name: str
    camera: pb.CameraModel
    session: pb.SessionOptions = dataclasses.field(default_factory=pb.SessionOptions)
    robot_id: str = "python"
    token: str = ""
    tls_ca_pem: bytes = b""
    tls_cert_pem: bytes = b""
    tls_key_pem: bytes = b""
    encoding: str = "jpeg"  # "jpeg", "png" or "raw"
    jpeg_quality: int = 90
    max_in_flight: int = 2
    max_queued: int = 2
    frame_deadline_s: float = 1.0
    stall_timeout_s: float = 2.0
    connect_timeout_s: float = 1.0
    backoff_initial_s: float = 0.05
    backoff_max_s: float = 0.5
    give_up_after_s: float = 0.0  # 0: never (a robot keeps trying).
    keepalive_time_ms: int = 10000  # Not below the server's --keepalive-min-ping-interval-s.
    on_event: Optional[Callable[[Event], None]] = None
    # A rig: the robot's other cameras (rig_camera_from_yaml), each placed on the body of
    # session.body_from_cam (the reference camera's own frame when unset); every frame then
    # carries one image of each (submit's rig_images).
    rig_cameras: List[pb.RigCamera] = dataclasses.field(default_factory=list)

    def problem(self) -> str:
        if not self.server:
            return "no server address"
        if not self.map_name:
            return "no map name"
        if self.camera.width == 0 or self.camera.height == 0:
            return "no camera (width and height)"
        if self.encoding not in ("jpeg", "png", "raw"):
            return "encoding is jpeg, png or raw"
        if not 1 <= self.jpeg_quality <= 100:
            return "jpeg_quality must be 1..100"
        if self.max_in_flight < 1 or self.max_queued < 1:
            return "max_in_flight and max_queued must be at least 1"
        if bool(self.tls_cert_pem) != bool(self.tls_key_pem):
            return "tls_cert_pem and tls_key_pem go together"
        return ""


class NotSent:
    """What submit() answers for a frame it cannot send: false, with the reason (the C++
    library's why_not), e.g. ``if not (sent := session.submit(t, image)): log(sent.reason)``."""

    __slots__ = ("reason",)

    def __init__(self, reason: str):
        self.reason = reason

    def __bool__(self) -> bool:
        return False

    def __str__(self) -> str:
        return self.reason

    def __repr__(self) -> str:
        return f"NotSent({self.reason!r})"


def next_replica_first(target: str) -> str:
    """A replica list ("ipv4:10.0.0.5:50051,10.0.0.6:50051") with its first address moved last,
    so that the next stream goes to the next replica; any other target as it is."""
    scheme, _, addresses = target.partition(":")
    if scheme not in ("ipv4", "ipv6") or "," not in addresses:
        return target
    first, _, others = addresses.partition(",")
    return f"{scheme}:{others},{first}"


def open_channel(server: str, tls_ca_pem: bytes, tls_cert_pem: bytes, tls_key_pem: bytes,
                 keepalive_time_ms: int, backoff_initial_s: float,
                 backoff_max_s: float) -> grpc.Channel:
    """A fresh connection for one stream (a stalled one may be dead without gRPC knowing)."""
    options = [("grpc.keepalive_time_ms", keepalive_time_ms),
               ("grpc.keepalive_timeout_ms", 5000),
               ("grpc.http2.max_pings_without_data", 0),
               ("grpc.use_local_subchannel_pool", 1),  # A fresh connection every time.
               ("grpc.initial_reconnect_backoff_ms", int(backoff_initial_s * 1000)),
               ("grpc.max_reconnect_backoff_ms", int(backoff_max_s * 1000)),
               # The wire's limit from the proto, as the C++ library's.
               ("grpc.max_receive_message_length", pb.MAX_MESSAGE_BYTES)]
    if tls_ca_pem:
        credentials = grpc.ssl_channel_credentials(tls_ca_pem, tls_key_pem or None,
                                                   tls_cert_pem or None)
        return grpc.secure_channel(server, credentials, options)
    return grpc.insecure_channel(server, options)


def encode_image(image: np.ndarray, encoding: str, jpeg_quality: int = 90) -> bytes:
    """The image as it goes on the wire: grey, then JPEG/PNG bytes or raw pixels."""
    if image is None or image.size == 0:
        raise ValueError("empty image")
    grey = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    if grey.dtype != np.uint8:
        raise ValueError("the image is not 8-bit")
    if encoding == "raw":
        return np.ascontiguousarray(grey).tobytes()
    ext, params = (".jpg", [cv2.IMWRITE_JPEG_QUALITY, jpeg_quality]) if encoding == "jpeg" \
        else (".png", [cv2.IMWRITE_PNG_COMPRESSION, 1])
    ok, data = cv2.imencode(ext, grey, params)
    if not ok:
        raise ValueError("the encoder refused the image")
    return data.tobytes()


def _quaternion_multiply(a, b):
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw)


def _rotate(q, v):
    w, x, y, z = _quaternion_multiply(_quaternion_multiply(q, (0.0, *v)), (q[0], -q[1], -q[2], -q[3]))
    return (x, y, z)


def _unit(p: pb.Pose):
    n = (p.qw ** 2 + p.qx ** 2 + p.qy ** 2 + p.qz ** 2) ** 0.5 or 1.0
    return (p.qw / n, p.qx / n, p.qy / n, p.qz / n)


def compose(a_from_b: pb.Pose, b_from_c: pb.Pose) -> pb.Pose:
    """a_from_c = a_from_b * b_from_c."""
    q = _unit(a_from_b)
    t = _rotate(q, (b_from_c.tx, b_from_c.ty, b_from_c.tz))
    r = _quaternion_multiply(q, _unit(b_from_c))
    return pb.Pose(tx=t[0] + a_from_b.tx, ty=t[1] + a_from_b.ty, tz=t[2] + a_from_b.tz,
                   qw=r[0], qx=r[1], qy=r[2], qz=r[3])


def invert(a_from_b: pb.Pose) -> pb.Pose:
    q = _unit(a_from_b)
    inverse = (q[0], -q[1], -q[2], -q[3])
    t = _rotate(inverse, (a_from_b.tx, a_from_b.ty, a_from_b.tz))
    return pb.Pose(tx=-t[0], ty=-t[1], tz=-t[2], qw=inverse[0], qx=inverse[1], qy=inverse[2],
                   qz=inverse[3])


def propagate_by_odometry(map_from_cam_then: pb.Pose, odom_from_cam_then: pb.Pose,
                          odom_from_cam_now: pb.Pose) -> pb.Pose:
    """The pose now: the earlier pose moved by the odometry's motion between the frames."""
    return compose(map_from_cam_then, compose(invert(odom_from_cam_then), odom_from_cam_now))


@dataclasses.dataclass
class _Queued:
    timestamp_ns: int
    image: Optional[np.ndarray]
    encoded: bytes
    odom_from_cam: Optional[pb.Pose]
    hint: Optional[pb.Pose]
    submitted: float
    rig_images: List[pb.RigImage] = dataclasses.field(default_factory=list)


class Session:
    """One localization session; starts connecting at once. Thread-safe."""

    def __init__(self, options: SessionOptions):
        problem = options.problem()
        if problem:
            raise ValueError("SessionOptions: " + problem)
        self._o = options
        self._target = options.server  # A replica list turns on each refusal for capacity.
        self._lock = threading.Condition()
        self._queue: Deque[_Queued] = collections.deque()
        self._in_flight: Deque[_Queued] = collections.deque()
        self._events: "queue.Queue[Event]" = queue.Queue()
        self._state = LinkState.CONNECTING
        self._closing = False
        self._refused = ""
        self._last_pose: Optional[pb.Pose] = None
        self._last_odom: Optional[pb.Pose] = None  # The odometry of the last posed frame.
        self.streams_opened = 0
        self.stats = collections.Counter()
        self._worker = threading.Thread(target=self._work, daemon=True)
        self._worker.start()

    # --- the application's side ---------------------------------------------------------
    def submit(self, timestamp_ns: int, image: Optional[np.ndarray] = None, *,
               encoded: bytes = b"", odom_from_cam: Optional[pb.Pose] = None,
               hint: Optional[pb.Pose] = None, rig_images: Sequence = (),
               rig_timestamps_ns: Sequence[int] = ()) -> bool:
        """Hands a frame over; never blocks. True when taken; a false NotSent with the reason
        when it cannot be sent (wrong size, no image, not 8-bit, closed, or refused by the
        server: link_state FAILED), as the C++ library's Submit answers. A rig's frame carries
        one of ``rig_images`` per rig camera: a grey image, encoded bytes, or None (that camera
        gave none this time), each taken at ``rig_timestamps_ns`` (default: timestamp_ns)."""
        if not encoded:
            if image is None or image.size == 0:
                return NotSent("the frame has no image")
            if image.shape[1] != self._o.camera.width or image.shape[0] != self._o.camera.height:
                return NotSent(f"the image is {image.shape[1]}x{image.shape[0]} but the session "
                               f"camera is {self._o.camera.width}x{self._o.camera.height}")
            if image.dtype != np.uint8:
                return NotSent("the image is not 8-bit")
        if len(rig_images) != len(self._o.rig_cameras):
            return NotSent(f"the frame carries {len(rig_images)} rig images for "
                           f"{len(self._o.rig_cameras)} rig cameras")
        try:
            rig = self._rig_messages(timestamp_ns, rig_images, rig_timestamps_ns)
        except ValueError as e:
            return NotSent(str(e))
        events = []
        with self._lock:
            if self._closing:
                return NotSent("the session is closed")
            if self._refused:
                return NotSent(self._refused)
            self._queue.append(_Queued(timestamp_ns, None if image is None else image.copy(),
                                       encoded, odom_from_cam, hint, time.monotonic(), rig))
            self.stats["submitted"] += 1
            while len(self._queue) > self._o.max_queued:
                old = self._queue.popleft()
                self.stats["dropped"] += 1
                events.append(Event("dropped", old.timestamp_ns,
                                    detail="the link is slower than the camera"))
            self._lock.notify_all()
        self._emit(events)
        return True

    def _rig_messages(self, timestamp_ns: int, rig_images: Sequence,
                      rig_timestamps_ns: Sequence[int]) -> List[pb.RigImage]:
        """The rig images on the wire, encoded now (the caller may reuse its buffers)."""
        messages = []
        for c, image in enumerate(rig_images):
            stamp = rig_timestamps_ns[c] if c < len(rig_timestamps_ns) else timestamp_ns
            message = pb.RigImage(timestamp_ns=stamp)
            if isinstance(image, (bytes, bytearray)):
                message.encoded = bytes(image)
            elif image is not None:
                camera = self._o.rig_cameras[c].camera
                if image.shape[1] != camera.width or image.shape[0] != camera.height or \
                        image.dtype != np.uint8:
                    raise ValueError(f"rig camera {c + 1}'s image is {image.shape[1]}x"
                                     f"{image.shape[0]} but that camera is {camera.width}x"
                                     f"{camera.height} (8-bit)")
                if self._o.encoding == "raw":
                    message.raw.width, message.raw.height = image.shape[1], image.shape[0]
                    message.raw.pixels = encode_image(image, "raw")
                else:
                    message.encoded = encode_image(image, self._o.encoding, self._o.jpeg_quality)
            messages.append(message)
        return messages

    def next(self, timeout_s: float = 0.0) -> Optional[Event]:
        try:
            return self._events.get(timeout=timeout_s) if timeout_s > 0 else \
                self._events.get_nowait()
        except queue.Empty:
            return None

    @property
    def link_state(self) -> LinkState:
        with self._lock:
            return self._state

    def close(self, drain_s: float = 2.0) -> None:
        """Waits up to drain_s for answers to frames already handed over, then ends."""
        deadline = time.monotonic() + drain_s
        with self._lock:
            while (self._queue or self._in_flight) and not self._refused and \
                    time.monotonic() < deadline:
                self._lock.wait(0.02)
            self._closing = True
            self._lock.notify_all()
        self._worker.join()

    # --- the library's side ---------------------------------------------------------------
    def _emit(self, events: List[Event]) -> None:
        for event in events:
            if self._o.on_event:
                self._o.on_event(event)
            else:
                self._events.put(event)

    def _set_state(self, state: LinkState, detail: str, events: List[Event]) -> None:
        if state != self._state:
            self._state = state
            events.append(Event("link", link_state=state, detail=detail))

    def _channel(self) -> grpc.Channel:
        o = self._o
        return open_channel(self._target, o.tls_ca_pem, o.tls_cert_pem, o.tls_key_pem,
                            o.keepalive_time_ms, o.backoff_initial_s, o.backoff_max_s)

    def _requests(self, stream_state):
        start = pb.LocalizeRequest()
        start.start.map_name = self._o.map_name
        start.start.camera.CopyFrom(self._o.camera)
        start.start.options.CopyFrom(self._o.session)
        start.start.robot_id = self._o.robot_id
        start.start.rig_cameras.extend(self._o.rig_cameras)
        yield start
        while True:
            with self._lock:
                while not (stream_state["ended"] or self._closing or
                           (self._queue and len(self._in_flight) < self._o.max_in_flight)):
                    self._lock.wait(0.05)
                if stream_state["ended"] or self._closing:
                    return
                item = self._queue.popleft()
                self._in_flight.append(item)
                resume = stream_state["resuming"] and not stream_state["posed"]
                hint = item.hint
                if hint is None and resume and self._last_pose is not None:
                    hint = self._last_pose
                    if self._last_odom is not None and item.odom_from_cam is not None:
                        hint = propagate_by_odometry(hint, self._last_odom, item.odom_from_cam)
            frame = pb.Frame(timestamp_ns=item.timestamp_ns)
            if item.encoded:
                frame.encoded = item.encoded
            elif self._o.encoding == "raw":
                frame.raw.width, frame.raw.height = item.image.shape[1], item.image.shape[0]
                frame.raw.pixels = encode_image(item.image, "raw")
            else:
                frame.encoded = encode_image(item.image, self._o.encoding, self._o.jpeg_quality)
            frame.rig_images.extend(item.rig_images)
            if item.odom_from_cam is not None:
                frame.odom_from_cam.CopyFrom(item.odom_from_cam)
            if hint is not None:
                frame.map_from_cam_hint.CopyFrom(hint)
            with self._lock:
                self.stats["sent"] += 1
                self.stats["bytes_sent"] += len(frame.encoded) + len(frame.raw.pixels) + sum(
                    len(r.encoded) + len(r.raw.pixels) for r in item.rig_images)
            yield pb.LocalizeRequest(frame=frame)

    def _read(self, call, stream_state) -> None:
        try:
            for response in call:
                events = []
                with self._lock:
                    if response.status == pb.STATUS_CLOSED:
                        stream_state["why"] = "the server closed the session: " + response.error
                        continue
                    if not self._in_flight:
                        continue
                    sent = self._in_flight.popleft()
                    latency_s = time.monotonic() - sent.submitted
                    late = latency_s > self._o.frame_deadline_s
                    self.stats["late" if late else "answered"] += 1
                    stream_state["answered"] = True
                    if response.has_pose and response.status in _POSED:
                        self._last_pose = response.map_from_cam
                        self._last_odom = sent.odom_from_cam
                        stream_state["posed"] = True
                    events.append(Event("late" if late else "result", sent.timestamp_ns,
                                        latency_s * 1000.0, response))
                    if not late and self._state == LinkState.DEGRADED:
                        self._set_state(LinkState.CONNECTED, "answering again", events)
                    self._lock.notify_all()
                self._emit(events)
        except grpc.RpcError as error:
            stream_state["status"] = error
        with self._lock:
            stream_state["ended"] = True
            self._lock.notify_all()

    def _open(self, events: List[Event]):
        channel = self._channel()
        try:
            grpc.channel_ready_future(channel).result(timeout=self._o.connect_timeout_s)
        except grpc.FutureTimeoutError:
            channel.close()
            return None
        # Whether this stream resumes is settled before the call exists: grpcio may read the
        # request iterator, and so send the first frame, before Localize returns, that is
        # before streams_opened counts this stream (a CI run sent it without the last pose).
        stream_state = {"ended": False, "posed": False, "answered": False, "why": "",
                        "status": None, "resuming": self.streams_opened > 0}
        metadata = [("authorization", "Bearer " + self._o.token)] if self._o.token else None
        call = pb_grpc.LocalizationStub(channel).Localize(self._requests(stream_state),
                                                           metadata=metadata)
        reader = threading.Thread(target=self._read, args=(call, stream_state), daemon=True)
        with self._lock:
            self.streams_opened += 1
            self._set_state(LinkState.CONNECTED,
                            "connected" if self.streams_opened == 1 else "resumed", events)
        reader.start()
        return channel, call, reader, stream_state

    def _end(self, stream, events: List[Event]) -> bool:
        """Ends the stream; True when the server refused it for capacity before any answer."""
        channel, call, reader, stream_state = stream
        call.cancel()
        reader.join()
        channel.close()
        error = stream_state["status"]
        code = error.code() if error is not None else None
        why = stream_state["why"] or (error.details() if error is not None else
                                      "the server ended the stream")
        if self._closing and code == grpc.StatusCode.CANCELLED:
            why = "the session was closed"  # Our own cancel, not the link's.
        with self._lock:
            # Each unanswered frame says why: a refusal is not a link that lost frames.
            for lost in self._in_flight:
                self.stats["undelivered"] += 1
                events.append(Event("undelivered", lost.timestamp_ns,
                                    detail="the stream broke before its answer: " + why))
            self._in_flight.clear()
            if code in _PERMANENT:
                self._refused = f"the server refused the session: {error.details()} ({code.name})"
                self._set_state(LinkState.FAILED, self._refused, events)
                for old in self._queue:
                    events.append(Event("dropped", old.timestamp_ns, detail=self._refused))
                self._queue.clear()
            elif not self._closing:
                self._set_state(LinkState.RECONNECTING, why, events)
            self._lock.notify_all()
        return code == grpc.StatusCode.RESOURCE_EXHAUSTED and not stream_state["answered"]

    def _check_link(self, stream_state, events: List[Event]) -> bool:
        """True when the stream has stalled (and should be reopened)."""
        now = time.monotonic()
        while self._queue and now - self._queue[0].submitted > self._o.frame_deadline_s:
            old = self._queue.popleft()
            self.stats["dropped"] += 1
            events.append(Event("dropped", old.timestamp_ns, detail="stale: waited for the link"))
        if not self._in_flight:
            return False
        waited = now - self._in_flight[0].submitted
        stall_after = self._o.stall_timeout_s if stream_state["answered"] else \
            max(self._o.stall_timeout_s, 10.0)
        if waited > stall_after:
            stream_state["why"] = f"stalled: no answer for {waited * 1000:.0f} ms"
            return True
        if waited > self._o.frame_deadline_s and self._state == LinkState.CONNECTED:
            self._set_state(LinkState.DEGRADED, "no answer within the deadline", events)
        return False

    def _work(self) -> None:
        backoff = self._o.backoff_initial_s
        capacity_backoff = _FIRST_CAPACITY_BACKOFF_S
        capacity_refusals = 0
        last_stream = time.monotonic()
        stream = None
        while True:
            events: List[Event] = []
            if stream is None:
                with self._lock:
                    while not (self._closing or self._queue or self.streams_opened == 0):
                        self._lock.wait(0.05)
                    if self._closing or self._refused:
                        if self._closing:  # Never silent: what still waits is reported.
                            for old in self._queue:
                                events.append(Event("dropped", old.timestamp_ns,
                                                    detail="the session was closed before it "
                                                    "was sent"))
                            self.stats["dropped"] += len(self._queue)
                            self._queue.clear()
                        self._set_state(LinkState.CLOSED if self._closing else self._state,
                                        "closed", events)
                        self._emit(events)
                        return
                stream = self._open(events)
                if stream is None:
                    with self._lock:
                        if self._o.give_up_after_s > 0 and \
                                time.monotonic() - last_stream > self._o.give_up_after_s:
                            self._refused = f"cannot reach {self._o.server}"
                            self._set_state(LinkState.FAILED, self._refused, events)
                        else:
                            self._set_state(LinkState.CONNECTING if self.streams_opened == 0
                                            else LinkState.RECONNECTING,
                                            f"cannot connect to {self._o.server}", events)
                            self._check_link({"answered": True}, events)
                            self._lock.wait(backoff)
                            backoff = min(backoff * 2, self._o.backoff_max_s)
                    self._emit(events)
                    continue
                backoff = self._o.backoff_initial_s
                last_stream = time.monotonic()
            stream_state = stream[3]
            with self._lock:
                self._lock.wait(0.02)
                stalled = self._check_link(stream_state, events)
                end = stalled or stream_state["ended"] or self._closing
            if end:
                at_capacity = self._end(stream, events)
                stream = None
                last_stream = time.monotonic()
                if at_capacity:
                    # A server at capacity: the next replica of a list at once, and once every
                    # replica has refused, again later, not at once (as the C++ library).
                    capacity_refusals += 1
                    self._target = next_replica_first(self._target)
                    if capacity_refusals % (1 + self._target.count(",")) == 0:
                        self._emit(events)
                        events = []
                        retry_at = time.monotonic() + capacity_backoff
                        with self._lock:  # Submits notify: wait out the whole backoff.
                            while not self._closing and time.monotonic() < retry_at:
                                self._lock.wait(retry_at - time.monotonic())
                        capacity_backoff = min(capacity_backoff * 2, _MAX_CAPACITY_BACKOFF_S)
                else:
                    capacity_backoff = _FIRST_CAPACITY_BACKOFF_S
                    capacity_refusals = 0
            self._emit(events)
