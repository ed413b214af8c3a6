"""The recorder service: every key of every session into ``<out>/<session>.mcap``.

    findme/<session>/**  ->  <out>/<session>.mcap   (one file per session)

What a recording holds (recordings/README.md has the full table):

* **Bus channels**, one per key *kind*: topic ``findme/<session>/<kind>`` (``frame``,
  ``hypotheses``, ``selection``, ``scene``, ``motion``, ``pose``, ``trajectory``, ``error``,
  ``measured``), protobuf encoding, the message's own schema (a FileDescriptorSet, so any
  MCAP reader decodes it without our code), the payload bytes exactly as they were on the bus.
  The rest of the key follows from the payload (``frame/<n>`` is ``Frame.index``,
  ``motion/<a>/<b>`` is ``Motion.index_a/index_b``, ...: ``key_of``); the recorder checks
  that rule on every message, and a message whose key does not follow from it (malformed,
  foreign, an unknown kind) goes on a channel named by its exact key instead. Either way
  ``findme replay`` puts every message back on the key it came from. One channel per kind
  rather than per key keeps a video session within MCAP's 65535 channels and gives Foxglove
  one topic per stream.
* **View channels** (metadata ``findme.channel = view``; replay skips them), derived for
  Foxglove Studio and Rerun's MCAP loader: ``findme/<s>/foxglove/image``
  (foxglove.CompressedImage: the Frame's ``image`` field), ``.../calibration``
  (foxglove.CameraCalibration), ``.../hypotheses`` (foxglove.ImageAnnotations: numbered line
  strips), ``.../boundary`` (the chosen boundary), ``.../measured`` (tapped pixels),
  ``.../pose`` (foxglove.PoseInFrame), ``.../trajectory`` (foxglove.PosesInFrame) and
  ``.../tf`` (foxglove.FrameTransform: level frame of photo 0 -> level frame of photo n from
  the poses, level frame n -> camera n from gravity).

Durability: chunked MCAP; a flusher thread closes the open chunk and flushes the file every
``flush_s`` (0.5 s), so a recorder killed with SIGKILL loses at most the last
``FLUSH_BOUND_S`` = 1 s (flush period + queueing); ``findme recover`` salvages such a file.
A file that exists is never overwritten: the next one is ``<session>~2.mcap``.

Log time of a message = when the recorder received it (ns since the epoch); publish time
the same. Write failures (disk full) are logged and counted, never published as bus errors
(the recorder would record its own errors in a loop).
"""

from __future__ import annotations

import functools
import logging
import math
import struct
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from foxglove_schemas_protobuf.CameraCalibration_pb2 import CameraCalibration
from foxglove_schemas_protobuf.Color_pb2 import Color
from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform
from foxglove_schemas_protobuf.ImageAnnotations_pb2 import ImageAnnotations
from foxglove_schemas_protobuf.PointsAnnotation_pb2 import PointsAnnotation
from foxglove_schemas_protobuf.PoseInFrame_pb2 import PoseInFrame
from foxglove_schemas_protobuf.PosesInFrame_pb2 import PosesInFrame
from foxglove_schemas_protobuf.Quaternion_pb2 import Quaternion
from google.protobuf.message import DecodeError
from mcap.writer import CompressionType, Writer
from mcap_protobuf.schema import build_file_descriptor_set

import schemas
from findme_core.errors import FindmeError

from . import bus
from .runtime import Handler, Input

log = logging.getLogger("findme.services.recorder")

VERSION = "findme-recorder/1"
#: A recorder killed with SIGKILL loses at most the messages it received in this many
#: seconds before it died (flush period + queueing); tested in tests/recording.
FLUSH_BOUND_S = 1.0
FLUSH_S = 0.5

# channel metadata
CHANNEL = "findme.channel"     # "bus" (key from payload), "bus-exact" (topic = key), "view"
KIND = "findme.kind"

#: message type -> (key kind, index fields after the kind)
KEY_RULES: dict[str, tuple[str, tuple[str, ...]]] = {
    "findme.v1.Frame": ("frame", ("index",)),
    "findme.v1.HypothesisSet": ("hypotheses", ("index",)),
    "findme.v1.Selection": ("selection", ("index",)),
    "findme.v1.Scene": ("scene", ("index",)),
    "findme.v1.Motion": ("motion", ("index_a", "index_b")),
    "findme.v1.Pose": ("pose", ("index",)),
    "findme.v1.Trajectory": ("trajectory", ()),
    "findme.v1.Error": ("error", ()),
    # a MeasureReply published for the record by whoever asked (findme run does)
    "findme.v1.MeasureReply": ("measured", ("index",)),
}
KIND_TYPES = {kind: name for name, (kind, _) in KEY_RULES.items()}

MCAP_MAGIC = b"\x89MCAP0\r\n"

_COMPRESSION = {"none": CompressionType.NONE, "lz4": CompressionType.LZ4,
                "zstd": CompressionType.ZSTD}


def key_of(session: str, msg) -> str | None:
    """The bus key a message of a known kind belongs on (``findme/<session>/<kind>/...``)."""
    rule = KEY_RULES.get(msg.DESCRIPTOR.full_name)
    if rule is None:
        return None
    kind, fields = rule
    return "/".join([bus.ROOT, session, kind, *(str(getattr(msg, f)) for f in fields)])


def kind_topic(session: str, kind: str) -> str:
    return f"{bus.ROOT}/{session}/{kind}"


def view_topic(session: str, name: str) -> str:
    return f"{bus.ROOT}/{session}/foxglove/{name}"


def parse(payload: bytes):
    """(message or None, type name or ""): a Find Me message parsed without validation."""
    try:
        name = schemas.schema_of(payload)
    except FindmeError:
        return None, ""
    cls = schemas.MESSAGE_TYPES.get(name)
    if cls is None:
        return None, ""
    try:
        return cls.FromString(payload), name
    except DecodeError:
        return None, ""


def recording_path(out_dir: Path, session: str) -> Path:
    """``<out>/<session>.mcap``, or ``<session>~<k>.mcap`` when that exists: never overwrite."""
    p = out_dir / f"{session}.mcap"
    k = 2
    while p.exists():
        p = out_dir / f"{session}~{k}.mcap"
        k += 1
    return p


# ------------------------------------------------------------------------------ helpers
def _rgba(bgr, a: float = 1.0) -> Color:
    b, g, r = bgr
    return Color(r=r / 255.0, g=g / 255.0, b=b / 255.0, a=a)


def _quat_from_matrix(R) -> Quaternion:
    """Unit quaternion (x, y, z, w) of a 3x3 rotation matrix."""
    R = np.asarray(R, float)
    t = np.trace(R)
    if t > 0:
        s = math.sqrt(t + 1.0) * 2
        w, x = 0.25 * s, (R[2, 1] - R[1, 2]) / s
        y, z = (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s
    elif R[0, 0] > R[1, 1] and R[0, 0] > R[2, 2]:
        s = math.sqrt(1.0 + R[0, 0] - R[1, 1] - R[2, 2]) * 2
        w, x = (R[2, 1] - R[1, 2]) / s, 0.25 * s
        y, z = (R[0, 1] + R[1, 0]) / s, (R[0, 2] + R[2, 0]) / s
    elif R[1, 1] > R[2, 2]:
        s = math.sqrt(1.0 + R[1, 1] - R[0, 0] - R[2, 2]) * 2
        w, x = (R[0, 2] - R[2, 0]) / s, (R[0, 1] + R[1, 0]) / s
        y, z = 0.25 * s, (R[1, 2] + R[2, 1]) / s
    else:
        s = math.sqrt(1.0 + R[2, 2] - R[0, 0] - R[1, 1]) * 2
        w, x = (R[1, 0] - R[0, 1]) / s, (R[0, 2] + R[2, 0]) / s
        y, z = (R[1, 2] + R[2, 1]) / s, 0.25 * s
    return Quaternion(x=float(x), y=float(y), z=float(z), w=float(w))


def _label_anchor(pts, width: int, height: int, slot: float) -> tuple[float, float]:
    """Where a hypothesis' number goes: above its polyline at ``slot`` of the width."""
    u = min(max(slot * (width - 1), 12.0), max(12.0, width - 13.0))
    v = pts[-1].v
    for a, b in zip(pts, pts[1:]):
        if a.u <= u <= b.u:
            v = a.v if b.u == a.u else a.v + (b.v - a.v) * (u - a.u) / (b.u - a.u)
            break
    else:
        if u < pts[0].u:
            v = pts[0].v
    return u, min(max(v - 10.0, 12.0), max(12.0, height - 6.0))


@functools.lru_cache(maxsize=64)
def _palette(n: int) -> tuple[Color, ...]:
    from findme_core.overlay import palette
    return tuple(_rgba(c) for c in palette(n))


_BLACK = Color(r=0, g=0, b=0, a=0.7)
_POSES_TAG = bytes([3 << 3 | 2])   # PosesInFrame.poses: field 3, length-delimited


def _varint(n: int) -> bytes:
    out = bytearray()
    while True:
        b, n = n & 0x7F, n >> 7
        out.append(b | (0x80 if n else 0))
        if not n:
            return bytes(out)


# Pixel convention: bus pixels have (0, 0) at the CENTRE of the top-left pixel; Foxglove
# image annotations (like Rerun's 2D space) put (0, 0) at its top-left CORNER: add 0.5.
PIXEL_TO_VIEWER = 0.5


class FoxgloveView:
    """Derives the view channels of one session from its bus messages (pure: messages in,
    (topic, message class, serialised message) out)."""

    def __init__(self, session: str):
        self.session = session
        self.stamp: dict[int, int] = {}      # photo n -> capture time ns
        self.frame_id: dict[int, str] = {}   # photo n -> the camera's frame name
        self._cams: dict = {}
        self._quats: dict = {}
        self._last_cal = None
        self._pose_entries: dict[tuple, bytes] = {}

    def _ts(self, n: int, fallback: int):
        return schemas.ns_to_timestamp(self.stamp.get(n, fallback))

    def _fid(self, n: int) -> str:
        return self.frame_id.get(n) or f"{self.session}/camera/{n}"

    def derive(self, name: str, msg, log_time: int) -> list[tuple[str, type, bytes]]:
        fn = getattr(self, "_" + name.rsplit(".", 1)[1].lower(), None)
        return fn(msg, log_time) if fn else []

    def _camera(self, f):
        """The findme_core Camera of a frame (cached by size, lens and gravity), None if
        the image or the lens is invalid."""
        from findme.imageio import image_size

        from .convert import frame_camera
        try:
            w, h = image_size(f.image.data, f"frame {f.index}")
        except FindmeError:
            return None
        lens = (w, h, f.WhichOneof("lens"), f.intrinsics.SerializeToString(), f.hfov_deg,
                f.gravity.SerializeToString() if f.HasField("gravity") else b"")
        if lens not in self._cams:
            try:
                self._cams[lens] = frame_camera(f, w, h)
            except FindmeError:
                self._cams[lens] = None
            if len(self._cams) > 256:
                self._cams.pop(next(iter(self._cams)))
        return self._cams[lens]

    def _frame(self, f, t):
        n = f.index
        self.stamp[n] = f.capture_time_ns or t
        self.frame_id[n] = f.image.frame_id or f"{self.session}/camera/{n}"
        ts = self._ts(n, t)
        if f.image.frame_id and f.image.HasField("timestamp"):
            data = f.image.SerializeToString()
        else:
            img = CompressedImage()
            img.CopyFrom(f.image)
            img.frame_id = self._fid(n)
            img.timestamp.CopyFrom(ts)
            data = img.SerializeToString()
        out = [(view_topic(self.session, "image"), CompressedImage, data)]
        cam = self._camera(f)
        if cam is None:   # calibration and the level -> camera transform need a valid lens
            return out
        cal_key = (cam.fx, cam.fy, cam.cx, cam.cy, cam.width, cam.height, self._fid(n))
        if cal_key != self._last_cal:   # Foxglove and Rerun keep the latest calibration
            self._last_cal = cal_key
            cal = CameraCalibration(frame_id=self._fid(n), width=cam.width, height=cam.height,
                                    distortion_model="plumb_bob", D=[0.0] * 5,
                                    K=[cam.fx, 0, cam.cx, 0, cam.fy, cam.cy, 0, 0, 1],
                                    R=[1, 0, 0, 0, 1, 0, 0, 0, 1],
                                    P=[cam.fx, 0, cam.cx, 0, 0, cam.fy, cam.cy, 0, 0, 0, 1, 0],
                                    timestamp=ts)
            out.append((view_topic(self.session, "calibration"), CameraCalibration,
                        cal.SerializeToString()))
        tf = FrameTransform(parent_frame_id=schemas.level_frame_id(self.session, n),
                            child_frame_id=self._fid(n), timestamp=ts,
                            rotation=self._quat(cam))  # p_level = R p_cam
        out.append((view_topic(self.session, "tf"), FrameTransform, tf.SerializeToString()))
        return out

    def _quat(self, cam) -> Quaternion:
        q = self._quats.get(id(cam))
        if q is None or q[0] is not cam:
            q = self._quats[id(cam)] = (cam, _quat_from_matrix(cam.R_level_from_cam))
        return q[1]

    def _hypothesisset(self, hs, t):
        ann = ImageAnnotations()
        cols = _palette(len(hs.hypotheses))
        ts = self._ts(hs.index, t)
        d = PIXEL_TO_VIEWER
        for i, h in enumerate(hs.hypotheses):
            pts = h.polyline.points
            if len(pts) < 2:
                continue
            p = ann.points.add(type=PointsAnnotation.LINE_STRIP, thickness=3.0 if i == 0 else 2.0,
                               outline_color=cols[i], timestamp=ts)
            for q in pts:
                p.points.add(x=q.u + d, y=q.v + d)
            u, v = _label_anchor(pts, hs.width, hs.height, 0.08 + 0.84 * ((i * 0.618034) % 1.0))
            tx = ann.texts.add(text=str(h.rank), font_size=16.0, text_color=cols[i],
                               background_color=_BLACK, timestamp=ts)
            tx.position.x, tx.position.y = u + d, v + d
        return [(view_topic(self.session, "hypotheses"), ImageAnnotations,
                 ann.SerializeToString())]

    def _scene(self, sc, t):
        pts = sc.polyline.points
        if len(pts) < 2:
            return []
        ann = ImageAnnotations()
        d = PIXEL_TO_VIEWER
        p = ann.points.add(type=PointsAnnotation.LINE_STRIP, thickness=5.0,
                           outline_color=Color(r=1.0, g=0.85, b=0.0, a=1.0))
        p.timestamp.CopyFrom(self._ts(sc.index, t))
        for q in pts:
            p.points.add(x=q.u + d, y=q.v + d)
        u, v = _label_anchor(pts, sc.camera.intrinsics.width or 640,
                             sc.camera.intrinsics.height or 480, 0.5)
        tx = ann.texts.add(text=f"chosen: {sc.rank}", font_size=16.0,
                           text_color=Color(r=1.0, g=0.85, b=0.0, a=1.0),
                           background_color=Color(r=0, g=0, b=0, a=0.7))
        tx.timestamp.CopyFrom(self._ts(sc.index, t))
        tx.position.x, tx.position.y = u + d, v + d
        return [(view_topic(self.session, "boundary"), ImageAnnotations, ann.SerializeToString())]

    def _measurereply(self, rep, t):
        if rep.error or not rep.points:
            return []
        ann = ImageAnnotations()
        d = PIXEL_TO_VIEWER
        pts = ann.points.add(type=PointsAnnotation.POINTS, thickness=8.0,
                             outline_color=Color(r=1.0, g=0.2, b=0.8, a=1.0))
        pts.timestamp.CopyFrom(self._ts(rep.index, t))
        for i, p in enumerate(rep.points):
            pts.points.add(x=p.pixel.u + d, y=p.pixel.v + d)
            text = f"{i + 1}" + (f" ({p.xyz.x:.2f}, {p.xyz.y:.2f}, {p.xyz.z:.2f})"
                                 if not p.error else ": no 3D")
            tx = ann.texts.add(text=text, font_size=14.0, text_color=Color(r=1, g=1, b=1, a=1),
                               background_color=Color(r=0.5, g=0, b=0.4, a=0.8))
            tx.timestamp.CopyFrom(self._ts(rep.index, t))
            tx.position.x, tx.position.y = p.pixel.u + d + 6, p.pixel.v + d - 6
        for dist in rep.distances:
            if dist.error or dist.a >= len(rep.points) or dist.b >= len(rep.points):
                continue
            a, b = rep.points[dist.a].pixel, rep.points[dist.b].pixel
            ln = ann.points.add(type=PointsAnnotation.LINE_LIST, thickness=2.0,
                                outline_color=Color(r=1.0, g=0.2, b=0.8, a=1.0))
            ln.timestamp.CopyFrom(self._ts(rep.index, t))
            ln.points.add(x=a.u + d, y=a.v + d)
            ln.points.add(x=b.u + d, y=b.v + d)
            tx = ann.texts.add(text=f"{dist.distance_m:.3f} {'m' if rep.metric else 'h'}",
                               font_size=14.0, text_color=Color(r=1, g=1, b=1, a=1),
                               background_color=Color(r=0.5, g=0, b=0.4, a=0.8))
            tx.timestamp.CopyFrom(self._ts(rep.index, t))
            tx.position.x, tx.position.y = (a.u + b.u) / 2 + d, (a.v + b.v) / 2 + d
        return [(view_topic(self.session, "measured"), ImageAnnotations, ann.SerializeToString())]

    def _pose(self, pose, t):
        p = schemas.pose_to_foxglove(pose, self.session)
        tf = schemas.pose_to_frame_transform(pose, self.session)
        return [(view_topic(self.session, "pose"), PoseInFrame, p.SerializeToString()),
                (view_topic(self.session, "tf"), FrameTransform, tf.SerializeToString())]

    def _trajectory(self, tr, t):
        # A trajectory grows with the session and is republished often: encode each pose
        # once and concatenate the encoded entries (repeated field 3 of PosesInFrame).
        head = PosesInFrame(frame_id=schemas.level_frame_id(self.session, 0),
                            timestamp=schemas.ns_to_timestamp(tr.time_ns or t))
        entries = []
        for pose in tr.poses:
            k = (pose.x_m, pose.z_m, pose.yaw_rad)
            e = self._pose_entries.get(k)
            if e is None:
                body = schemas.pose_to_foxglove(pose, self.session).pose.SerializeToString()
                e = self._pose_entries[k] = _POSES_TAG + _varint(len(body)) + body
                if len(self._pose_entries) > 100_000:
                    self._pose_entries.pop(next(iter(self._pose_entries)))
            entries.append(e)
        data = head.SerializeToString() + b"".join(entries)
        return [(view_topic(self.session, "trajectory"), PosesInFrame, data)]


class McapRecording:
    """One session's MCAP file: bus messages as they were, plus the view channels.

    Not thread-safe: the recorder calls it under its lock.
    """

    def __init__(self, path: Path, session: str, *, compression: str = "zstd",
                 chunk_size: int = 4 * 1024 * 1024, views: bool = True,
                 metadata: dict[str, str] | None = None):
        self.path, self.session = Path(path), session
        self._file = open(self.path, "wb")  # noqa: SIM115 - closed in close()
        self._w = Writer(self._file, chunk_size=chunk_size, compression=_COMPRESSION[compression])
        self._w.start(profile="", library=VERSION)
        self._w.add_metadata("findme", {"session": session, "schema_version": schemas.VERSION,
                                        "recorder": VERSION, **(metadata or {})})
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}
        self._seq: dict[int, int] = {}
        self.view = FoxgloveView(session) if views else None
        self.messages = 0
        self.dirty = False
        self.last_write = time.monotonic()
        self.closed = False

    def _schema(self, cls) -> int:
        name = cls.DESCRIPTOR.full_name
        sid = self._schemas.get(name)
        if sid is None:
            sid = self._w.register_schema(name=name, encoding="protobuf",
                                          data=build_file_descriptor_set(cls).SerializeToString())
            self._schemas[name] = sid
        return sid

    def _channel(self, topic: str, cls, meta: dict[str, str]) -> int:
        cid = self._channels.get(topic)
        if cid is None:
            if cls is None:
                cid = self._w.register_channel(topic=topic, message_encoding="application/octet-stream",
                                               schema_id=0, metadata=meta)
            else:
                cid = self._w.register_channel(topic=topic, message_encoding="protobuf",
                                               schema_id=self._schema(cls), metadata=meta)
            self._channels[topic] = cid
        return cid

    def _add(self, cid: int, data: bytes, t: int) -> None:
        seq = self._seq.get(cid, 0)
        self._seq[cid] = seq + 1
        self._w.add_message(channel_id=cid, log_time=t, publish_time=t, data=data, sequence=seq)
        self.messages += 1

    def write(self, key: str, payload: bytes, log_time: int) -> None:
        """Record one bus message (and what the view channels derive from it)."""
        k = bus.parse_key(key)
        msg, name = parse(payload)
        if msg is not None and key_of(k.session, msg) == key:
            cid = self._channel(kind_topic(k.session, k.kind), type(msg),
                                {CHANNEL: "bus", KIND: k.kind})
        else:  # the key does not follow from the payload: keep the exact key as the topic
            cid = self._channel(key, type(msg) if msg is not None else None,
                                {CHANNEL: "bus-exact", KIND: k.kind})
        self._add(cid, payload, log_time)
        if msg is not None and self.view is not None:
            try:
                derived = self.view.derive(name, msg, log_time)
            except Exception as e:  # noqa: BLE001 - a view is optional; never lose the bus message
                log.warning("recorder: no view of %s: %s: %s", key, type(e).__name__, e)
                derived = []
            for topic, cls, data in derived:
                cid = self._channel(topic, cls, {CHANNEL: "view"})
                self._add(cid, data, log_time)
        self.dirty = True
        self.last_write = time.monotonic()

    def flush(self) -> None:
        """Close the open chunk and hand everything to the OS (survives SIGKILL, not power loss)."""
        if self.dirty and not self.closed:
            self._w.flush()
            self.dirty = False

    def close(self) -> None:
        """Write the summary (indexes, statistics) and close the file."""
        if self.closed:
            return
        self.closed = True
        try:
            self._w.finish()
        finally:
            self._file.close()


class RecorderHandler(Handler):
    """Writes every message of every session to ``<out>/<session>.mcap``."""

    name = "recorder"
    inputs = (Input(f"{bus.ROOT}/*/**", None),)
    drain_on_stop = True

    def __init__(self, out_dir: str | Path = "recordings", *, flush_s: float = FLUSH_S,
                 compression: str = "zstd", chunk_size: int = 4 * 1024 * 1024,
                 views: bool = True, max_open: int = 64, idle_close_s: float | None = None,
                 clock=time.time_ns):
        if compression not in _COMPRESSION:
            raise ValueError(f"compression must be one of {sorted(_COMPRESSION)}")
        self.out = Path(out_dir)
        self.flush_s, self.compression, self.chunk_size = flush_s, compression, chunk_size
        self.views, self.max_open, self.idle_close_s = views, max_open, idle_close_s
        self.clock = clock
        self.files: dict[str, McapRecording] = {}
        self.paths: dict[str, list[Path]] = {}     # session -> every file written for it
        self.recorded = 0
        self.write_errors = 0
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._flusher: threading.Thread | None = None
        self.opened = threading.Condition(self._lock)  # notified when a file is opened

    # ------------------------------------------------------------------ files
    def path_of(self, session: str) -> Path | None:
        """The file a session is being (or was last) recorded to."""
        with self._lock:
            p = self.paths.get(session)
            return p[-1] if p else None

    def _open(self, session: str) -> McapRecording:
        if len(self.files) >= self.max_open:  # close the least recently written
            oldest = min(self.files.values(), key=lambda r: r.last_write)
            self._close(oldest.session)
        self.out.mkdir(parents=True, exist_ok=True)
        path = recording_path(self.out, session)
        rec = McapRecording(path, session, compression=self.compression,
                            chunk_size=self.chunk_size, views=self.views,
                            metadata={"flush_s": f"{self.flush_s:g}",
                                      "started_ns": str(self.clock())})
        self.files[session] = rec
        self.paths.setdefault(session, []).append(path)
        log.info("recorder: session %s -> %s", session, path)
        self.opened.notify_all()
        if self._flusher is None:
            self._flusher = threading.Thread(target=self._flush_loop, name="recorder-flush",
                                             daemon=True)
            self._flusher.start()
        return rec

    def _close(self, session: str) -> None:
        rec = self.files.pop(session, None)
        if rec is not None:
            try:
                rec.close()
            except OSError as e:
                self.write_errors += 1
                log.error("recorder: cannot finish %s: %s", rec.path, e)

    def _flush_loop(self) -> None:
        while not self._stop.wait(self.flush_s):
            self.flush()

    def flush(self) -> None:
        """Flush every open file (the flusher thread does this every ``flush_s``)."""
        now = time.monotonic()
        with self._lock:
            for session, rec in list(self.files.items()):
                try:
                    rec.flush()
                except OSError as e:
                    self.write_errors += 1
                    log.error("recorder: cannot flush %s: %s", rec.path, e)
                if self.idle_close_s is not None and now - rec.last_write > self.idle_close_s:
                    self._close(session)

    # ------------------------------------------------------------------ handler
    def on_message(self, key, payload):
        t = self.clock()
        try:
            session = bus.parse_key(key).session
        except FindmeError as e:
            log.warning("recorder: not recorded: %s", e)
            return []
        with self._lock:
            try:
                rec = self.files.get(session) or self._open(session)
                rec.write(key, payload, t)
                self.recorded += 1
            except (OSError, ValueError) as e:
                self.write_errors += 1
                log.error("recorder: cannot record %s: %s", key, e)
        return []

    def close(self) -> None:
        """Finish every file (summary and indexes): they are then valid without recovery."""
        self._stop.set()
        if self._flusher is not None:
            self._flusher.join(5.0)
        with self._lock:
            for session in list(self.files):
                self._close(session)

    def counters(self):
        with self._lock:
            return {"recorded": self.recorded, "open_files": len(self.files),
                    "write_errors": self.write_errors}


def make_recorder(args) -> RecorderHandler:
    """``findme serve recorder --out DIR``: recordings go to DIR (default: recordings/)."""
    out = getattr(args, "out", None)
    return RecorderHandler(out if out and out != "." else "recordings")


# ------------------------------------------------------------------------------ reading
class RecordingError(FindmeError):
    """A recording cannot be read (not MCAP, unfinished, corrupt)."""


@dataclass(frozen=True)
class Recorded:
    """One message of a recording.

    key: the bus key it was on (for bus channels), else the view topic; topic: its channel;
    channel: "bus", "bus-exact" or "view"; schema: its schema name ("" if none);
    payload: the bytes as recorded; log_time: when the recorder received it (ns).
    """

    key: str
    topic: str
    channel: str
    schema: str
    payload: bytes
    log_time: int

    def message(self):
        """The decoded Find Me message (validated), or None for view / foreign channels."""
        if self.schema not in schemas.MESSAGE_TYPES:
            return None
        return schemas.decode(schemas.MESSAGE_TYPES[self.schema], self.payload, check=False)


def _open_mcap(path):
    p = Path(path)
    if not p.is_file():
        raise RecordingError(f"{p}: no such recording")
    f = open(p, "rb")  # noqa: SIM115 - the caller's context closes it
    if f.read(8) != MCAP_MAGIC:
        f.close()
        raise RecordingError(f"{p}: not an MCAP file")
    f.seek(0)
    return f


def read_recording(path, views: bool = False) -> list[Recorded]:
    """Every bus message of a finished recording in file (= arrival) order; view channels
    too with ``views``.

    Raises:
        RecordingError: not MCAP, or unfinished (its recorder died: ``findme recover``).
    """
    from mcap.exceptions import McapError
    from mcap.stream_reader import StreamReader
    from mcap.records import Channel, Footer, Message, Schema
    out: list[Recorded] = []
    schema_names: dict[int, str] = {0: ""}
    channels: dict[int, Channel] = {}
    ended = False
    with _open_mcap(path) as f:
        try:
            for r in StreamReader(f, validate_crcs=True).records:
                if isinstance(r, Schema):
                    schema_names[r.id] = r.name
                elif isinstance(r, Channel):
                    channels[r.id] = r
                elif isinstance(r, Message):
                    rec = _recorded(channels[r.channel_id], schema_names, r, views)
                    if rec is not None:
                        out.append(rec)
                elif isinstance(r, Footer):
                    ended = True
        except (McapError, struct.error, ValueError, KeyError, OSError) as e:
            raise RecordingError(
                f"{path}: the recording is unfinished or damaged ({type(e).__name__}: {e}); "
                f"salvage it with: findme recover {path} -o FIXED.mcap") from None
    if not ended:
        raise RecordingError(f"{path}: the recording has no end (its recorder died?); "
                             f"salvage it with: findme recover {path} -o FIXED.mcap")
    return out


def _recorded(ch, schema_names, m, views: bool) -> Recorded | None:
    kind = ch.metadata.get(CHANNEL, "")
    name = schema_names.get(ch.schema_id, "")
    if kind == "view":
        if not views:
            return None
        return Recorded(ch.topic, ch.topic, "view", name, m.data, m.log_time)
    key = ch.topic
    if kind == "bus":
        msg, _ = parse(m.data)
        try:
            session = bus.parse_key(ch.topic).session
        except FindmeError:
            return None
        key = key_of(session, msg) if msg is not None else None
        if key is None:
            return None
    elif kind != "bus-exact":  # a foreign MCAP: its topic is the key if it looks like one
        try:
            bus.parse_key(ch.topic)
        except FindmeError:
            return None
        kind = "bus-exact"
    return Recorded(key, ch.topic, kind, name, m.data, m.log_time)


def recording_session(path) -> str:
    """The session id a recording is of (its ``findme`` metadata, else its first key)."""
    from mcap.reader import make_reader
    with _open_mcap(path) as f:
        try:
            for md in make_reader(f).iter_metadata():
                if md.name == "findme" and md.metadata.get("session"):
                    return md.metadata["session"]
        except Exception:  # noqa: BLE001 - fall back to the messages
            pass
    for r in read_recording(path):
        return bus.parse_key(r.key).session
    raise RecordingError(f"{path}: an empty recording (no Find Me messages)")


# ------------------------------------------------------------------------------ recovery
@dataclass
class Salvage:
    """What ``recover`` kept: messages and chunks copied, whether the source was complete,
    and how many bytes at its end could not be used (an incomplete chunk)."""

    messages: int = 0
    bus_messages: int = 0     # of those, on bus channels (the rest: view channels)
    chunks: int = 0
    complete: bool = False
    dropped_bytes: int = 0
    reason: str = ""


def recover(src, dst) -> Salvage:
    """Rewrite the readable part of ``src`` (e.g. a recording whose writer was killed: no
    summary, a torn last chunk) into a valid, finished MCAP ``dst``: every whole chunk
    (CRC-checked), schemas, channels, metadata. Streams; memory ~ one chunk.

    Raises:
        RecordingError: ``src`` is not MCAP.
    """
    from mcap.exceptions import McapError
    from mcap.records import (Attachment, Channel, Chunk, DataEnd, Footer, Header, Message,
                              Metadata, Schema)
    from mcap.stream_reader import StreamReader, breakup_chunk
    src, dst = Path(src), Path(dst)
    if src.resolve() == dst.resolve():
        raise RecordingError("recover writes a new file: give another -o path")
    out = Salvage()
    size = src.stat().st_size
    with _open_mcap(src) as f, open(dst, "wb") as g:
        w = Writer(g, compression=CompressionType.ZSTD, chunk_size=4 * 1024 * 1024)
        started = False
        sids: dict[int, int] = {0: 0}
        cids: dict[int, int] = {}
        on_bus: set[int] = set()
        good_end = 8

        def take(r) -> None:
            if isinstance(r, Schema):
                if r.id not in sids:
                    sids[r.id] = w.register_schema(name=r.name, encoding=r.encoding, data=r.data)
            elif isinstance(r, Channel):
                if r.id not in cids and r.schema_id in sids:
                    if r.metadata.get(CHANNEL) != "view":
                        on_bus.add(r.id)
                    cids[r.id] = w.register_channel(topic=r.topic, message_encoding=r.message_encoding,
                                                    schema_id=sids[r.schema_id],
                                                    metadata=dict(r.metadata))
            elif isinstance(r, Message):
                if r.channel_id in cids:
                    w.add_message(channel_id=cids[r.channel_id], log_time=r.log_time,
                                  publish_time=r.publish_time, data=r.data, sequence=r.sequence)
                    out.messages += 1
                    out.bus_messages += r.channel_id in on_bus

        reader = StreamReader(f, emit_chunks=True, record_size_limit=size)
        it = iter(reader.records)
        while True:
            try:
                r = next(it)
            except StopIteration:
                out.complete = True
                break
            except (McapError, struct.error, ValueError, OSError, MemoryError) as e:
                out.reason = f"{type(e).__name__}: {e}" if str(e) else type(e).__name__
                break
            if isinstance(r, Header):
                w.start(profile=r.profile, library=r.library or VERSION)
                started = True
            elif not started:
                raise RecordingError(f"{src}: no MCAP header")
            elif isinstance(r, Chunk):
                try:
                    inner = breakup_chunk(r, validate_crc=True)
                except Exception as e:  # noqa: BLE001 - a torn or corrupt chunk ends the salvage
                    out.reason = f"damaged chunk ({type(e).__name__}: {e})"
                    break
                for x in inner:
                    take(x)
                out.chunks += 1
            elif isinstance(r, Metadata):
                w.add_metadata(r.name, dict(r.metadata))
            elif isinstance(r, Attachment):
                w.add_attachment(create_time=r.create_time, log_time=r.log_time, name=r.name,
                                 media_type=r.media_type, data=r.data)
            elif isinstance(r, (DataEnd, Footer)):
                pass  # the summary is rebuilt
            else:
                take(r)
            good_end = f.tell()
        if not started:
            w.start(profile="", library=VERSION)
        w.finish()
    out.dropped_bytes = 0 if out.complete else max(0, size - good_end)
    return out
