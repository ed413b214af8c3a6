"""The odometry service: motion between selected photos of a session, and the session's
trajectory.

    hypotheses/<n> + selection/<n>  ->  findme/<session>/motion/<m>/<n>,
                                        findme/<session>/pose/<n>,
                                        findme/<session>/trajectory

Photo m is the nearest lower photo of the session that has a pose (the nearest higher one
for a photo below the origin); the first selected photo of a session is its origin (the
session frame is the level frame of photo 0, or of the first photo that was selected).
Selections may arrive in any order: a photo waits, at most ``gap_wait_s`` seconds, while a
lower photo that could be its anchor may still get a selection (``OdometrySession.blockers``:
one whose hypotheses came, or a number not heard of yet: photos are numbered from 0 up and
every frame ends as hypotheses or an Error naming it). Then it chains past it, and the gap
is reported as an Error on ``findme/<session>/error`` naming that photo. A photo that will
never be selected (an Error about its frame or hypotheses, or no hypotheses) is not waited
for. A motion that cannot be estimated is published with its error (no numbers) and the
photo gets no pose; later photos chain from the last one that did, and are tried again from
a photo that gets its pose late (``OdometrySession.reopen_after``, at the next tick).

The service takes in no frames: a photo's frame is fetched once from the bus when its
hypotheses come (the store keeps it a minute, a user may select later), held until the photo
is prepared (``odometry_session.keep_frames``) and dropped then. Taking in every frame woke
both sharded instances for each photo, most of them refused at peak before hypotheses.

State is bounded (``odometry_session``) and expires: a session idle for ``idle_s`` is
evicted; when it comes back, its poses are fetched from the bus (the store, the caches).
Instances share the load by session (``shard``). Same pipeline as ``findme motion``
(``findme_core.motion.pair``), so the numbers are equal for the same photos.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np

import schemas
from findme_core.errors import FindmeError, HypothesisError
from findme_core.motion.pair import motion_photos, prepare
from findme_core.motion.trajectory import PlanarPose, compose
from findme_io.convert import msg_gravity_estimate, msg_provenance
from findme_io.motion_msg import set_motion_estimate, set_motion_gravity

from ..runtime import bus
from ..runtime.handler import Handler, Input, Output
from ..runtime.sessions import SessionTable
from .odometry_inputs import photo_inputs
from .odometry_session import OdometrySession

NEVER_SELECTED = {"frame", "hypotheses"}   # an Error about these: the photo gets no selection
OVERLOADED = schemas.ErrorCode.ERROR_CODE_OVERLOADED
FORBIDDEN = schemas.ErrorCode.ERROR_CODE_FORBIDDEN


class OdometryHandler(Handler):
    name = "odometry"
    cache_keys = ("findme/*/motion/*/*", "findme/*/pose/*", "findme/*/trajectory")
    inputs = (Input("findme/*/hypotheses/*", schemas.HypothesisSet, state=True),
              Input("findme/*/selection/*", schemas.Selection,
                    answers=("findme/{session}/pose/{n}", "findme/{session}/motion/*/{n}")),
              Input("findme/*/error", schemas.Error, state=True))
    shard = True
    tick_s = 0.5

    def __init__(self, method: str = "findme", gap_wait_s: float = 5.0, idle_s: float = 600.0,
                 max_sessions: int = 1000, clock=time.monotonic):
        self.method, self.gap_wait_s, self.clock = method, gap_wait_s, clock
        self.sessions = SessionTable(self._open_session, idle_s, max_sessions, clock)
        self._waiting: set[str] = set()    # sessions with a photo waiting on a lower one
        self.motions = self.gaps = 0

    def shard_key(self, key, msg):
        return bus.parse_key(key).session  # a session's photos stay on one instance

    def peers_changed(self):
        """Another instance may have chained some sessions meanwhile (this one was cut off,
        or one came and went): each takes the poses on the bus again when next used."""
        for _, st in self.sessions.items():
            st.stale = True

    def _open_session(self, session: str) -> OdometrySession:
        """A session seen for the first time here: take the poses it already has on the bus
        (published before this instance restarted, or before the session was evicted)."""
        st = OdometrySession()
        st.adopt(*self._bus_poses(session))
        return st

    def _bus_poses(self, session: str):
        """(poses, capture times) of a session's photos from the bus."""
        poses, times = {}, {}
        if self.fetch_all is None:
            return poses, times
        for k, payload in self.fetch_all(bus.key(session, "pose", "*")):
            try:
                p = schemas.decode(schemas.Pose, payload)
            except FindmeError:
                continue
            cov = np.diag([p.sigma_x_m ** 2, p.sigma_z_m ** 2, p.sigma_yaw_rad ** 2])
            poses[p.index] = PlanarPose(p.x_m, 0.0, p.z_m, p.yaw_rad, cov)
            times[p.index] = p.time_ns
        return poses, times

    def on_message(self, key, msg):
        self.check_input(key, msg)
        k = bus.parse_key(key)   # the key names session and n, never the payload
        if isinstance(msg, schemas.Error) and self._dead_photo(k.session, msg) is None:
            return []   # not about a photo that will get no pose: no state for it
        st = self.sessions.get(k.session)
        if st.stale:
            st.stale = False
            st.adopt(*self._bus_poses(k.session))
        now = self.clock()
        if isinstance(msg, schemas.Error):
            return self._error(k.session, st, msg, now)
        n = k.index()
        if n in st.poses or n in st.closed and not isinstance(msg, schemas.Selection):
            return []
        p = st.photo(n, now)
        if isinstance(msg, schemas.HypothesisSet):
            p.hset = msg
            if p.selection is not None:
                self._check_rank(st, n)
            elif not msg.hypotheses:
                st.close(n, "dead")      # nothing to select: nobody waits for it
            elif p.frame is None:   # fetched now: a user may select after the store's minute
                p.hold(self._try(bus.key(k.session, "frame", n), schemas.Frame))
        else:
            if n in st.closed:
                st.closed.pop(n)        # selected after all: it gets a pose now
                p = st.photo(n, now)
            p.selection, p.selected_at = msg, now
            if p.hset is None:          # the bus does not order it after its hypotheses
                p.hset = self._try(bus.key(k.session, "hypotheses", n), schemas.HypothesisSet)
            if p.hset is not None:
                self._check_rank(st, n)
        return self._advance(k.session, st, now)

    def _check_rank(self, st, n) -> None:
        p = st.photos[n]
        count = len(p.hset.hypotheses)
        if not 1 <= p.selection.rank <= count:
            rank = p.selection.rank
            p.selection = None
            raise HypothesisError(f"selection of hypothesis {rank} of photo {n}, which has "
                                  f"{count} hypotheses")

    def _try(self, key, cls):
        """``need`` that says None instead of raising when nobody has it yet."""
        try:
            return self.need(key, cls)
        except HypothesisError:
            return None

    def _dead_photo(self, session, err) -> int | None:
        """The photo of ``session`` an Error says will get no pose, else None: its frame or
        hypotheses failed upstream, or this service's own OVERLOADED refused its selection.
        A FORBIDDEN refusal is about a forged message, not the photo: it is not final."""
        try:
            k = bus.parse_key(err.key)
            n = k.index()
        except FindmeError:
            return None
        ours = err.service.split("/")[0] == self.name
        final = ((k.kind == "selection" and err.code == OVERLOADED) if ours
                 else k.kind in NEVER_SELECTED)
        return n if k.session == session and final and err.code != FORBIDDEN else None

    def _error(self, session, st, err, now):
        """A photo that will get no pose is not waited for (``_dead_photo``)."""
        n = self._dead_photo(session, err)
        if n is not None and n not in st.poses:
            st.close(n, "dead")
            return self._advance(session, st, now)
        return []

    def tick(self, now):
        out = []
        for session in sorted(self._waiting):
            st = self.sessions.peek(session)
            self._waiting.discard(session)
            if st is not None:
                out += self._advance(session, st, now)
        self.sessions.expire(now)
        return out

    # ------------------------------------------------------------------ chaining
    def _advance(self, session: str, st: OdometrySession, now: float) -> list[Output]:
        out: list[Output] = []
        for n in st.pending():
            p, late = st.photos[n], now - st.photos[n].selected_at >= self.gap_wait_s
            if p.hset is None and late:
                p.hset = self._try(bus.key(session, "hypotheses", n), schemas.HypothesisSet)
                if p.hset is None:
                    st.close(n, "failed")
                    out.append(self._gap(session, n, None))
                    continue
                self._check_rank(st, n)
            blockers = st.blockers(n)
            if (blockers or p.hset is None) and not late:
                self._waiting.add(session)
                break                     # n waits for a lower photo's selection, or its hypotheses
            for m in blockers:            # waited long enough: chain past them, say so
                st.close(m, "dead")
                self.gaps += 1
                out.append(self._gap(session, m, n))
            if st.origin is None:
                st.times[n] = self._time(session, st, n)
                st.origin = n
                st.poses[n] = PlanarPose(0.0, 0.0, 0.0, 0.0)
                out.append(self._pose_out(session, st, n))
                continue
            out.extend(self._step(session, st, n))
        if out:
            out.append(Output(bus.key(session, "trajectory"), self._trajectory(session, st)))
        st.prune()
        return out

    def _gap(self, session, m, n):
        """An Error naming photo m: never selected (photo n chains past it), or, n None,
        selected but its hypotheses never came."""
        text = (f"photo {m} has no selected hypothesis after {self.gap_wait_s:g} s: photo {n} "
                "chains past it" if n is not None else
                f"the hypotheses of photo {m} did not come within {self.gap_wait_s:g} s")
        err = schemas.Error(session=session, key=bus.key(session, "selection", m),
                            code=schemas.ErrorCode.ERROR_CODE_NO_SUCH_HYPOTHESIS,
                            message=text, time_ns=time.time_ns(), service=self.name)
        return Output(bus.key(session, "error"), err, cache=False)

    def _step(self, session, st, b: int) -> list[Output]:
        anchors = st.anchor(b)
        a = anchors[0]
        m = schemas.Motion(session=session, index_a=a, index_b=b, method=f"{self.method}/findme.v1",
                           time_ns=time.time_ns())
        try:
            pb = self._photo(session, st, b)
            for a in anchors[:3]:         # an anchor no longer on the bus: the next one
                try:
                    pa = self._photo(session, st, a)
                    break
                except HypothesisError:
                    if a == anchors[:3][-1]:
                        raise
            m.index_a = a
            res = motion_photos(pa, pb, (self.method,))[self.method]
            if isinstance(res, FindmeError):
                raise res
            if res.photos and res.photos[1] is not pb:
                # B's unsure gravity was completed by A's: B's next motions start from it, so
                # a turn of plain photos carries the first sure gravity along
                st.photos[b].prepared = (st.photos[b].prepared[0], res.photos[1])
        except FindmeError as e:
            st.fail(b, a)
            m.error = str(e).splitlines()[0][:500] or type(e).__name__
            return [Output(bus.key(session, "motion", a, b), m)]
        mo = res.motion
        set_motion_estimate(m, mo)
        set_motion_gravity(m, res.gravity)
        m.matches = res.matches
        cov = [[mo.sigma_x ** 2, 0, 0], [0, mo.sigma_z ** 2, 0], [0, 0, mo.sigma_yaw ** 2]]
        st.poses[b] = compose(st.poses[a], mo.x, mo.z, mo.yaw, mo.dy, cov)
        st.times[b] = self._time(session, st, b)
        self.motions += 1
        if st.reopen_after(b):        # photos that failed from an anchor below b: b is nearer
            self._waiting.add(session)
        return [Output(bus.key(session, "motion", a, b), m), self._pose_out(session, st, b)]

    def _frame(self, session, st, n):
        p = st.photo(n, self.clock())
        if p.frame is None:
            p.hold(self.need(bus.key(session, "frame", n), schemas.Frame))
        return p.frame

    def _time(self, session, st, n) -> int:
        """Capture time of photo n (0 when its frame is no longer on the bus)."""
        p = st.photos.get(n)
        if p is not None and p.time_ns is not None:
            return p.time_ns
        try:
            return self._frame(session, st, n).capture_time_ns
        except HypothesisError:
            return 0

    def _photo(self, session, st, n):
        """Photo n prepared once for all its motions (features, the layouts of its selected
        hypothesis and the next ranks, its room orientation); held while the photo is open
        or one of the session's anchors (``odometry_session``)."""
        p = st.photo(n, self.clock())
        if p.selection is None:
            p.selection = self.need(bus.key(session, "selection", n), schemas.Selection)
        if p.prepared is None or p.prepared[0] != p.selection.rank:
            image, cam, hyps, rank, h, lines = self._inputs(session, st, n)
            # the hypotheses' own lines when sent (else detected again); a gravity from the
            # photo's lines is checked against the other photo's in each motion
            c = p.hset.camera if p.hset.HasField("camera") else None
            prov = msg_provenance(c) if c is not None else None
            if prov is not None:
                prov = replace(prov, estimate=msg_gravity_estimate(c))
            p.prepared = (rank, prepare(
                image, cam, h, hyps, rank, lines, gravity_sigma=prov and prov.unsensed_sigma,
                gravity_alternatives=prov.unsensed_alternatives if prov else ()))
            p.frame = None   # what its motions need is prepared (its capture time is kept)
        return p.prepared[1]

    def _inputs(self, session, st, n):
        """``odometry_inputs.photo_inputs`` of photo n, its messages fetched where needed."""
        f = self._frame(session, st, n)
        p = st.photos[n]
        if p.hset is None:
            p.hset = self.need(bus.key(session, "hypotheses", n), schemas.HypothesisSet)
        if p.selection is None:
            p.selection = self.need(bus.key(session, "selection", n), schemas.Selection)
        return photo_inputs(f, p.hset, p.selection, n)

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
        return {"sessions": len(self.sessions), "motions": self.motions, "gaps": self.gaps,
                "evicted": self.sessions.evicted}

