"""The Foxglove view of a session: the view channels a recording carries beside the bus
channels, derived from its bus messages (``FoxgloveView``), for Foxglove Studio and Rerun's
MCAP loader.

Pure: a bus message in, (topic, message class, serialised message) out, on the topics
``findme/<session>/foxglove/<name>``: ``image`` (foxglove.CompressedImage: the Frame's
``image`` field), ``calibration`` (foxglove.CameraCalibration), ``hypotheses``
(foxglove.ImageAnnotations: numbered line strips), ``boundary`` (the chosen boundary),
``measured`` (tapped pixels), ``pose`` (foxglove.PoseInFrame), ``trajectory``
(foxglove.PosesInFrame), ``tf`` (foxglove.FrameTransform) and ``plan`` (foxglove.SceneUpdate:
``foxglove_plan``).

Frames: ``tf`` carries level frame of photo 0 -> level frame of photo n (from the poses)
and level frame n -> camera n (from gravity: ``R_level_from_cam``, p_level = R p_cam);
poses and trajectories are in the level frame of photo 0. Pixels: bus pixels have (0, 0) at
the centre of the top-left pixel, Foxglove annotations at its top-left corner: annotations
add ``PIXEL_TO_VIEWER``. Timestamps: a photo's capture time, else when it was received (ns).
"""

from __future__ import annotations

import functools
import math

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

import schemas
from findme_core.errors import FindmeError

from .mcap_layout import view_topic


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
    from findme_io.overlay import palette
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
        from findme_io.imageio import image_size

        from findme_io.frame_photo import frame_camera
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
                           background_color=_BLACK)
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

    def _plan(self, plan, t):
        from .foxglove_plan import plan_view
        return plan_view(self.session, plan, t)

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

