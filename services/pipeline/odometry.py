"""The odometry service: motion between successive selected photos of a session, and the
session's trajectory.

    frame/<n> + hypotheses/<n> + selection/<n>  ->  findme/<session>/motion/<m>/<n>,
                                                    findme/<session>/pose/<n>,
                                                    findme/<session>/trajectory

Photo m is the nearest lower photo of the session that has a pose; the first selected
photo of a session is its origin (the session frame is the level frame of photo 0, or of
the first photo that was selected). Selections may arrive in any order: a photo waits while
a lower photo of the session is known (its frame or hypotheses arrived) but not yet done. A motion that cannot be estimated is published with its error
(no numbers) and the photo gets no pose; later photos chain from the last one that did.
Instances share the load by session (``shard``). Same pipeline as ``findme motion``
(``findme_core.pair``), so the numbers are equal for the same photos.
"""

from __future__ import annotations

import math
import time

import schemas
from findme_io.imageio import decode_image
from findme_core.errors import FindmeError, HypothesisError
from findme_core.pair import motion_photos, prepare
from findme_core.trajectory import PlanarPose, compose

from ..runtime import bus
from findme_io.convert import frame_camera, msg_camera, msg_hypotheses
from ..runtime.handler import Handler, Input, Output


class _Session:
    def __init__(self):
        self.frames: dict[int, object] = {}       # n -> Frame message
        self.hsets: dict[int, object] = {}        # n -> HypothesisSet message
        self.selected: dict[int, object] = {}     # n -> Selection message
        self.poses: dict[int, PlanarPose] = {}
        self.photos: dict[int, tuple] = {}        # n -> (rank, height, prepared photo)
        self.times: dict[int, int] = {}
        self.failed: set[int] = set()
        self.origin: int | None = None


class OdometryHandler(Handler):
    name = "odometry"
    cache_keys = ("findme/*/motion/*/*", "findme/*/pose/*", "findme/*/trajectory")
    inputs = (Input("findme/*/frame/*", schemas.Frame),
              Input("findme/*/hypotheses/*", schemas.HypothesisSet),
              Input("findme/*/selection/*", schemas.Selection))
    shard = True

    def __init__(self, method: str = "findme"):
        self.method = method
        self.sessions: dict[str, _Session] = {}
        self.motions = 0

    def shard_key(self, key, msg):
        return bus.parse_key(key).session  # a session's photos stay on one instance

    def on_message(self, key, msg):
        k = bus.parse_key(key)   # the key names session and n, never the payload
        st = self.sessions.setdefault(k.session, _Session())
        n = k.index()
        if isinstance(msg, schemas.Frame):
            st.frames[n] = msg
            return []
        if isinstance(msg, schemas.HypothesisSet):
            st.hsets[n] = msg
            return []
        if n not in st.hsets:
            st.hsets[n] = self.need(bus.key(k.session, "hypotheses", n), schemas.HypothesisSet)
        count = len(st.hsets[n].hypotheses)
        if not 1 <= msg.rank <= count:
            raise HypothesisError(f"selection of hypothesis {msg.rank} of photo {n}, which has "
                                  f"{count} hypotheses")
        st.selected[n] = msg
        return self._advance(k.session, st)

    # ------------------------------------------------------------------ chaining
    def _advance(self, session: str, st: _Session) -> list[Output]:
        out: list[Output] = []
        known = set(st.frames) | set(st.hsets) | set(st.selected)
        if st.origin is None:
            first = min(m for m in known if not (m in st.hsets and not st.hsets[m].hypotheses))
            if first not in st.selected:
                return out   # the session's first photo is not selected yet
            st.origin = first
            st.poses[first] = PlanarPose(0.0, 0.0, 0.0, 0.0)
            st.times[first] = self._frame(session, st, first).capture_time_ns
            out.append(self._pose_out(session, st, first))
        for n in sorted(st.selected):
            if n in st.poses or n in st.failed or n < st.origin:
                continue
            # a lower photo that is known but not done yet (e.g. not selected yet) comes
            # first, unless it can never be selected (no hypotheses)
            pending = [m for m in known if m < n and m not in st.poses and m not in st.failed
                       and not (m in st.hsets and not st.hsets[m].hypotheses)]
            if pending:
                break
            done = [m for m in st.poses if m < n]
            out.extend(self._step(session, st, max(done), n))
        if out:
            out.append(Output(bus.key(session, "trajectory"), self._trajectory(session, st)))
        return out

    def _step(self, session, st, a: int, b: int) -> list[Output]:
        m = schemas.Motion(session=session, index_a=a, index_b=b, method=f"{self.method}/findme.v1",
                           time_ns=time.time_ns())
        try:
            pa, pb = self._photo(session, st, a), self._photo(session, st, b)
            res = motion_photos(pa, pb, (self.method,))[self.method]
            if isinstance(res, FindmeError):
                raise res
        except FindmeError as e:
            st.failed.add(b)
            m.error = str(e).splitlines()[0][:500] or type(e).__name__
            return [Output(bus.key(session, "motion", a, b), m)]
        mo = res.motion
        m.x_m, m.z_m, m.yaw_rad = mo.x, mo.z, mo.yaw
        m.sigma_x_m, m.sigma_z_m, m.sigma_yaw_rad = mo.sigma_x, mo.sigma_z, mo.sigma_yaw
        m.inliers, m.matches = mo.n_inliers, res.matches
        cov = [[mo.sigma_x ** 2, 0, 0], [0, mo.sigma_z ** 2, 0], [0, 0, mo.sigma_yaw ** 2]]
        st.poses[b] = compose(st.poses[a], mo.x, mo.z, mo.yaw, mo.dy, cov)
        st.times[b] = self._frame(session, st, b).capture_time_ns
        self.motions += 1
        return [Output(bus.key(session, "motion", a, b), m), self._pose_out(session, st, b)]

    def _frame(self, session, st, n):
        if n not in st.frames:
            st.frames[n] = self.need(bus.key(session, "frame", n), schemas.Frame)
        return st.frames[n]

    def _photo(self, session, st, n):
        """Photo n prepared once for all its motions (features, the layouts of its selected
        hypothesis and the next ranks, its room orientation); at most the last 4 are kept."""
        sel = st.selected[n]
        cached = st.photos.get(n)
        if cached is not None and cached[0] == sel.rank:
            return cached[2]
        image, cam, hyps, rank, h = self._inputs(session, st, n)
        photo = prepare(image, cam, h, hyps, rank)
        st.photos[n] = (rank, h, photo)
        for old in sorted(st.photos)[:-4]:
            del st.photos[old]
        return photo

    def _inputs(self, session, st, n):
        """(image, camera, hypotheses, selected rank, camera height) of photo n."""
        f = self._frame(session, st, n)
        if n not in st.hsets:
            st.hsets[n] = self.need(bus.key(session, "hypotheses", n), schemas.HypothesisSet)
        image = decode_image(f.image.data, f"frame {n}")
        hset = st.hsets[n]   # the camera the hypotheses were built with (estimated gravity)
        cam = (msg_camera(hset.camera) if hset.HasField("camera")
               else frame_camera(f, image.shape[1], image.shape[0]))
        sel = st.selected[n]
        h = (sel.camera_height_m if sel.HasField("camera_height_m") else
             f.camera_height_m if f.HasField("camera_height_m") else 1.0)
        hyps = msg_hypotheses(st.hsets[n])
        if not 1 <= sel.rank <= len(hyps):
            raise HypothesisError(f"selection of hypothesis {sel.rank} of photo {n}, which has "
                                  f"{len(hyps)} hypotheses")
        return image, cam, hyps, sel.rank, h

    def _pose_msg(self, session, st, n):
        p = st.poses[n]
        return schemas.Pose(session=session, index=n, x_m=p.x, z_m=p.z, yaw_rad=p.yaw,
                            time_ns=st.times.get(n, 0), sigma_x_m=math.sqrt(max(p.cov[0, 0], 0)),
                            sigma_z_m=math.sqrt(max(p.cov[1, 1], 0)),
                            sigma_yaw_rad=math.sqrt(max(p.cov[2, 2], 0)))

    def _pose_out(self, session, st, n):
        return Output(bus.key(session, "pose", n), self._pose_msg(session, st, n))

    def _trajectory(self, session, st):
        t = schemas.Trajectory(session=session, time_ns=time.time_ns())
        for n in sorted(st.poses):
            pose = self._pose_msg(session, st, n)
            pose.ClearField("schema")
            pose.ClearField("session")
            t.poses.append(pose)
        return t

    def counters(self):
        return {"sessions": len(self.sessions), "motions": self.motions}
