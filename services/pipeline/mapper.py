"""The mapper service: a session's floor plan, recomputed as its photos arrive.

    frame/<n> + hypotheses/<n> + selection/<n>  ->  findme/<session>/plan   (findme.v1.Plan)

Per photo, once, when its frame arrives: its camera and ORB features (the image is then dropped).
When its hypotheses and selection are in (in any order: what is missing is fetched from the bus
when someone caches it, else awaited): its layout under the selected boundary, with the camera
the hypotheses were built with (their gravity: the frame's refined by the image, or the image's
own; a new selection rebuilds it); a photo whose hypothesis set is empty takes part without a
layout. Between photos, as ``findme plan`` relates them (``session.relate``): spots found from
the photos (``session.auto_spots``: a photo joins a spot when it turned from any photo of it, so
a turn with left-out views stays one spot), feature matches and two-photo motions; each pair's
matches, turn and motion are computed once and kept (a motion again when one of its photos gets a
new layout). Then ``session.plan`` (placement of every photo, outline, walls, joint refinement)
over the session's photos in index order; each placed photo's 1-sigma is the refinement's, else
``pose.covariance``. The plan frame is the level frame of the first photo with a layout
(``Plan.origin_index``; photo 0 normally).

Cost, bounded per session: at most ``max_photos`` photos per plan (the first ones; later
ones are listed LEFT_OUT), a new plan after every ``every`` newly ready photos or when no
photo is left waiting (a count, not a time: a replay gives the same plans), and the pair
relations of those photos only. On the bus, a plan also waits while more of its session's
messages are queued (``Handler.backlog``): a burst, or a mapper that fell behind a user's
photos (a plan of 24 photos costs seconds), gets one plan per drained queue, not one per
photo, so the mapper keeps up; the last plan of a session is the same either way. State: at
most ``max_sessions`` sessions (the least recently active one is dropped first) and a
session idle for ``idle_s`` seconds is dropped.

Errors: a photo that cannot be placed is NOT_PLACED with its reason in the Plan, one that
cannot be read is LEFT_OUT with the reason; a session whose photos cannot make an outline
yet gets a Plan with the reason. An outline whose walls its photos saw past
(``OutlineRefused``) is not sent: the Plan says why and keeps the poses with their
1-sigmas; one that leaves a camera outside places no photo (its poses may be as wrong as
its walls). Camera height: the selection's, else the frame's, else 1 (``metric`` false:
lengths in camera heights). Instances share the load by session. Plain photos agree on
gravity spot by spot; gravity not exact widens pose sigmas (``mapper_gravity``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import schemas
from findme_core.errors import FindmeError, HypothesisError, InputError, OutlineRefused
from findme_core.motion import features
from findme_core.plan import heading, session as plan_session
from findme_core.single import layout
from findme_core.single.scene import Scene
from findme_io.convert import msg_camera, msg_hypotheses
from findme_io.frame_photo import frame_camera, frame_heading
from findme_core.single.segments import WORK_SIZE
from findme_io.imageio import decode_photo, encode_jpeg

from ..runtime import bus
from . import mapper_gravity
from .mapper_message import fill
from ..runtime.handler import Handler, Input, Output


@dataclass
class _Photo:
    """One photo's inputs: camera and features (from the frame), its hypotheses and
    selection, and the analysed photo (``session.Photo``) once it is ready."""

    camera: object = None
    features: object = None
    frame_height: float | None = None
    bad: str | None = None            # why the frame cannot be used
    hset: object = None
    selection: object = None
    photo: plan_session.Photo | None = None
    key: tuple = ()                   # (rank, height) the photo was analysed with
    plain: object = None              # a frame without gravity: ``mapper_gravity.Plain``
    heading: tuple | None = None      # the phone's (heading, 1-sigma, reference), radians


@dataclass
class _Session:
    photos: dict = field(default_factory=dict)      # n -> _Photo
    pairs: dict = field(default_factory=dict)       # session.relate's cache: (kind, i, j) -> ...
    planned: int = -1                                # ready photos at the last plan
    signature: tuple = ()
    seen: float = 0.0                                # clock of the last message


class MapperHandler(Handler):
    name = "mapper"
    cache_keys = ("findme/*/plan",)
    inputs = (Input("findme/*/frame/*", schemas.Frame, state=True),   # fetched again if skipped
              Input("findme/*/hypotheses/*", schemas.HypothesisSet, state=True),
              Input("findme/*/selection/*", schemas.Selection))
    shard = True
    nice, background = 19, True   # background work (``Handler``): poses and measurements first
    # a plan of many photos takes seconds while the photos keep coming: room for a session's
    # messages meanwhile (still bounded by the bytes a session may have waiting), and a
    # plan may come late rather than a photo be left out
    queue_depth = 256
    max_wait_s = 300.0

    def __init__(self, max_photos: int = 32, every: int = 1, max_sessions: int = 16,
                 idle_s: float = 3600.0, params: plan_session.SessionParams | None = None,
                 clock=time.monotonic, wall_clock=time.time_ns):
        self.max_photos, self.every = int(max_photos), max(1, int(every))
        self.max_sessions, self.idle_s = int(max_sessions), float(idle_s)
        self.params = params or plan_session.SessionParams()
        self.clock, self.wall_clock = clock, wall_clock
        self.sessions: dict[str, _Session] = {}
        self.plans = 0

    def shard_key(self, key, msg):
        return bus.parse_key(key).session   # a session's photos stay on one instance

    # ------------------------------------------------------------------ inputs
    def _session(self, sid: str) -> _Session:
        now = self.clock()
        for s in [s for s, st in self.sessions.items() if now - st.seen > self.idle_s]:
            del self.sessions[s]
        st = self.sessions.get(sid)
        if st is None:
            while len(self.sessions) >= self.max_sessions:
                del self.sessions[min(self.sessions, key=lambda s: self.sessions[s].seen)]
            st = self.sessions[sid] = _Session()
        st.seen = now
        return st

    def on_message(self, key, msg):
        k = bus.parse_key(key)
        n = msg.index
        if msg.session != k.session or str(n) != (k.parts[0] if k.parts else ""):
            raise InputError(f"{key} carries photo {n} of session {msg.session!r}")
        st = self._session(k.session)
        if n >= self.max_photos and n not in st.photos:
            st.photos.setdefault(n, _Photo(bad=f"over the limit of {self.max_photos} photos "
                                               "per plan"))
            return []
        ph = st.photos.setdefault(n, _Photo())
        if isinstance(msg, schemas.Frame):
            self._frame(ph, msg)
        elif isinstance(msg, schemas.HypothesisSet):
            ph.hset = msg
        else:   # the inputs it needs may still be on their way: fetched if cached, else awaited
            ph.hset = ph.hset or self._fetch(bus.key(k.session, "hypotheses", n),
                                             schemas.HypothesisSet)
            if ph.hset is not None and not 1 <= msg.rank <= len(ph.hset.hypotheses):
                raise HypothesisError(f"selection of hypothesis {msg.rank} of photo {n}, which "
                                      f"has {len(ph.hset.hypotheses)} hypotheses")
            if ph.camera is None and ph.bad is None:
                f = self._fetch(bus.key(k.session, "frame", n), schemas.Frame)
                if f is not None:
                    self._frame(ph, f)
            ph.selection = msg
        self._analyse(st, n, ph)
        return self._maybe_plan(k.session, st)

    def _fetch(self, key: str, cls):
        """A message this mapper has not received, from whoever caches it, or None."""
        try:
            return self.need(key, cls)
        except HypothesisError:
            return None

    def _frame(self, ph: _Photo, f) -> None:
        if ph.camera is not None:
            return
        try:   # decoded once at the working size (a 12 MP JPEG at a quarter); the
            # keypoints in the photo's pixels, where its camera and hypotheses are
            photo = decode_photo(f.image.data, f"frame {f.index}", reduce_to=WORK_SIZE)
            ph.camera = frame_camera(f, photo.width, photo.height)
            ph.features = _in_photo(features.detect(photo.image, self.params.features),
                                    photo.scale, photo.width, photo.height)
            if not f.HasField("gravity"):   # its spot may correct its gravity
                ph.plain = mapper_gravity.Plain(encode_jpeg(photo.image, 95), photo.scale)
            ph.heading = heading.check(frame_heading(f, photo.exif))
        except FindmeError as e:
            ph.bad = f"its photo cannot be used: {str(e).splitlines()[0][:200]}"
            ph.camera = None
        ph.frame_height = f.camera_height_m if f.HasField("camera_height_m") else None

    def _analyse(self, st: _Session, n: int, ph: _Photo) -> None:
        """(Re)build photo n's layout when its frame, hypotheses and selection are in."""
        if ph.camera is None or ph.hset is None:
            return
        hyps = msg_hypotheses(ph.hset)
        if hyps and (ph.selection is None or not 1 <= ph.selection.rank <= len(hyps)):
            return   # not selected yet (or a selection of a rank it does not have)
        sel = ph.selection
        height = (sel.camera_height_m if sel is not None and sel.HasField("camera_height_m")
                  else ph.frame_height)
        rank = sel.rank if sel is not None else 0
        if ph.photo is not None and ph.key == (rank, height):
            return
        h = 1.0 if height is None else float(height)
        # the camera the hypotheses were built with: its gravity is the one the boundary was
        # found under (estimated from the image, or the frame's refined by it)
        cam = ph.camera
        L, sc, why = None, None, ph.hset.reason or "no hypotheses"
        try:
            if ph.hset.HasField("camera"):
                cam = msg_camera(ph.hset.camera)
        except FindmeError as e:
            hyps, why = [], f"its hypotheses' camera: {str(e).splitlines()[0][:200]}"
        if hyps:
            hyp = hyps[rank - 1]
            try:
                L = layout.from_hypothesis(cam, h, hyp.polyline, hyp.kinds, 1)
                sc = Scene(cam, h, hyp.polyline, hyp.kinds)
                why = None
            except FindmeError as e:
                why = str(e).splitlines()[0][:200]
        kind, sigma = mapper_gravity.gravity_of(ph.hset)
        ph.photo = plan_session.Photo(cam, h, L, sc, ph.features, why, heading=ph.heading,
                                      gravity=kind, gravity_sigma=sigma)
        ph.key = (rank, height)
        for pk in [pk for pk in st.pairs if pk[0] == "motion" and n in pk[1:]]:
            del st.pairs[pk]   # motions lift with the scene; matches and turns stay

    # ------------------------------------------------------------------ planning
    def _maybe_plan(self, sid: str, st: _Session) -> list[Output]:
        if self.backlog is not None and self.backlog(sid) > 0:
            return []   # more of the session is queued: the plan after it covers this too
        ready = [n for n in sorted(st.photos) if st.photos[n].photo is not None]
        sig = tuple((n, st.photos[n].key) for n in ready)
        if sig == st.signature or not st.photos:
            return []
        waiting = any(ph.photo is None and ph.bad is None for ph in st.photos.values())
        grown = len(ready) - max(st.planned, 0)
        if st.planned >= 0 and 0 < grown < self.every and waiting:
            return []
        st.signature, st.planned = sig, len(ready)
        self.plans += 1
        return [Output(bus.key(sid, "plan"), self._plan(sid, st, ready))]

    def _plan(self, sid: str, st: _Session, ready: list[int]):
        msg = schemas.Plan(session=sid, time_ns=self.wall_clock(), camera_height_m=1.0)
        first = next((n for n in ready if st.photos[n].photo.layout is not None), None)
        order = [n for n in ready if first is not None and n >= first]
        status = {}
        for n, ph in st.photos.items():
            if n in order:
                continue
            status[n] = schemas.PlanPhoto(index=n, status=schemas.PLAN_PHOTO_STATUS_LEFT_OUT,
                                          reason=_left_out(ph, first))
        if order:
            msg.up_to_index, msg.photos, msg.origin_index = max(order), len(order), order[0]
            photos = mapper_gravity.agreed(st, order, self.params)
            msg.camera_height_m = photos[0].height
            msg.metric = all(st.photos[n].key[1] is not None for n in order)
            try:
                t0 = time.perf_counter()
                rel = plan_session.relate(photos, None, self.params, cache=st.pairs,
                                          ids=order)
                t_rel = 1e3 * (time.perf_counter() - t0)
                plan, pl, timing = plan_session.plan(photos, None, self.params, relations=rel)
                timing["relate"] = t_rel   # the new pairs' share: the others were cached
            except OutlineRefused as e:   # where the photos stand holds; the outline does not
                msg.reason = str(e).splitlines()[0][:500]
                fill(msg, e.plan, e.placement, {**e.timing_ms, "relate": t_rel}, photos,
                     order, status, outline=False)
            except FindmeError as e:
                msg.reason = str(e).splitlines()[0][:500]
                for n in order:
                    status[n] = schemas.PlanPhoto(index=n, reason=msg.reason,
                                                  status=schemas.PLAN_PHOTO_STATUS_NOT_PLACED)
            else:
                fill(msg, plan, pl, timing, photos, order, status)
        else:
            msg.reason = ("no photo with a floor boundary yet" if status else "no photo yet")
        msg.poses.extend(status[n] for n in sorted(status))
        return msg

    def counters(self):
        return {"sessions": len(self.sessions), "plans": self.plans}


def _left_out(ph: _Photo, first: int | None) -> str:
    """Why a photo is not in the plan's input."""
    if ph.bad:
        return ph.bad
    if ph.photo is not None:   # ready, but before the first photo with a floor boundary
        return f"no floor boundary ({ph.photo.reason}); the plan starts at a photo with one"
    if ph.camera is None:
        return "waiting for its frame"
    return "waiting for its hypotheses" if ph.hset is None else "waiting for its selection"


def make_mapper(args) -> MapperHandler:
    """``findme serve mapper``: the defaults (32 photos per plan, a plan per new photo)."""
    return MapperHandler()


def _in_photo(f: features.Features, s: float, width: int, height: int) -> features.Features:
    """Keypoints found in the photo decoded ``s`` times its size, in the photo's pixels
    (pixel-centre convention) and with its size; ``s`` 1: as they are."""
    if s == 1.0:
        return f
    return replace(f, pixels=(f.pixels + 0.5) / s - 0.5, sizes=f.sizes / s, width=width,
                   height=height)
