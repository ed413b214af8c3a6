"""The measurement service: the scene model of each selected photo, and 3D on request.

    hypotheses/<n> + selection/<n>  ->  findme/<session>/scene/<n>
    motion/<a>/<b> whose photos agreed on gravity  ->  scene/<n> again, under it
    query findme/<session>/measure (MeasureRequest)  ->  MeasureReply

A request may say the surface each pixel is on (``MeasureRequest.said``): the user knows
whether they tapped the floor or a wall, and a boundary along a cabinet's top puts the floor
beyond it on the cabinet's face. A point said floor is put on the floor whatever the
boundary; one said wall where the boundary puts the floor gets no point, with what to do;
one said on a top (a table's, a counter's) is put on it, its front edge looked for among
the lines the photo's hypotheses came with, which the scene keeps (``Scene.locate``). The
reply repeats what was said of each point, so a replay asks the same.

A photo whose gravity came from its own lines, unsure, may get a better one from a motion:
the odometry's motions carry the gravity two photos agreed on through their matches. Its
scene is then built again under it and its Scene published again (``measurement_gravity``:
a user's boundary lifted again, an automatic one found again in its frame); points are
located under it from then on. Until then, and for a photo no motion completes, its own
gravity and its wide sigma hold.

The camera height comes from the selection (if the user gave one there), else the frame's
(passed on in the HypothesisSet's ``frame_height``), else h = 1 (results up to scale,
``metric`` false). The service takes in no frames: the hypotheses carry the camera and the
frame's height, so a photo's bytes reach it only when it asks for them (a set from a writer
that does not pass the height on; an automatic boundary found again under a new gravity).
At peak, when most photos are refused before they have hypotheses, taking in every frame
cost this process 1.6 of its 2.8 ms of CPU a photo offered (bench_load --scenario peak,
2026-11-29), and woke it 40 times a second.

State is bounded and expires: per session at most ``max_photos`` photos (least recently
used out), a session idle for ``idle_s`` is evicted; anything evicted is rebuilt from the
bus when asked again: from the photo's Scene message (it carries the camera, height and
boundary; this service and the store keep it 15 min, longer than the frame's minute in the
store), else from its selection and hypotheses. A photo's HypothesisSet is held only
until its scene is built.
"""

from __future__ import annotations

import time
from collections import OrderedDict

import schemas
from findme_io.imageio import image_size
from findme_core.errors import FindmeError, HypothesisError
from findme_core.geometry.provenance import Provenance

from ..runtime import bus
from findme_io.convert import (camera_msg, measure_reply_msg, msg_camera, msg_hypotheses,
                               msg_lines, msg_provenance)
from findme_io.motion_msg import msg_agreed_gravities
from findme_io.frame_photo import frame_camera
from ..runtime.handler import Handler, Input, Output, UnknownSession
from ..runtime.sessions import SessionTable
from .measurement_gravity import Held, boundary_under, scene_of, under_agreed

DEFAULT_HEIGHT_SIGMA_M = 0.03


class _Photos:
    """One session's photos: n -> HypothesisSet, ``Held`` scene, the
    gravity a motion agreed on ((3,) unit, 1-sigma radians); at most ``limit`` of each,
    least recently used out."""

    def __init__(self, limit: int):
        self.limit = limit
        self.hsets: OrderedDict[int, object] = OrderedDict()
        self.scenes: OrderedDict[int, Held] = OrderedDict()
        self.agreed: OrderedDict[int, tuple] = OrderedDict()
        self.waiting: dict[int, tuple[object, float]] = {}   # n -> (Selection, since)

    def put(self, table: OrderedDict, n: int, value) -> None:
        table[n] = value
        table.move_to_end(n)
        while len(table) > self.limit:
            table.popitem(last=False)


class MeasurementHandler(Handler):
    name = "measurement"
    cache_keys = ("findme/*/scene/*",)
    inputs = (Input("findme/*/hypotheses/*", schemas.HypothesisSet, state=True),
              Input("findme/*/selection/*", schemas.Selection,
                    answers=("findme/{session}/scene/{n}",)),
              # a skipped motion leaves a photo under its own gravity (its sigma says so)
              Input("findme/*/motion/*/*", schemas.Motion, state=True))
    # a request is taps: MAX_MEASURE_PIXELS pixels are ~21 kB; at most 4 of a session wait
    queries = (Input("findme/*/measure", schemas.MeasureRequest, depth=4,
                     max_bytes=32 * 1024),)
    tick_s = 0.5

    def __init__(self, idle_s: float = 600.0, max_sessions: int = 1000, max_photos: int = 256,
                 wait_s: float = 5.0, clock=time.monotonic):
        self.sessions = SessionTable(lambda s: _Photos(max_photos), idle_s, max_sessions, clock)
        self.wait_s, self.clock = wait_s, clock
        self._waiting: set[str] = set()   # sessions with a selection waiting for its inputs
        self.answered = self.built = self.rebuilt = self.said = 0
        self.regravitated = self.not_regravitated = 0   # under a motion's agreed gravity

    def on_message(self, key, msg):
        self.check_input(key, msg)
        k = bus.parse_key(key)   # the key names session and n, never the payload
        n = k.index()
        st = self.sessions.get(k.session)
        if isinstance(msg, schemas.Motion):
            return self._motion(k.session, st, (n, k.index(1)), msg)
        if isinstance(msg, schemas.HypothesisSet):
            st.put(st.hsets, n, msg)
        else:
            st.waiting[n] = (msg, self.clock())
        if n in st.waiting and self._ready(k.session, st, n, fetch=isinstance(msg, schemas.Selection)):
            return self._select(k.session, st, n, st.waiting.pop(n)[0])
        if st.waiting:
            self._waiting.add(k.session)
        return []

    def _ready(self, session, st, n, fetch: bool) -> bool:
        """The hypotheses of photo n are here (``fetch``: asking the bus for them when
        missing: the bus does not order a selection after the messages it follows)."""
        if n not in st.hsets and fetch:
            try:
                st.put(st.hsets, n, self.need(bus.key(session, "hypotheses", n),
                                              schemas.HypothesisSet))
            except HypothesisError:
                return False   # not on the bus (yet)
        return n in st.hsets

    def tick(self, now):
        """Selections whose hypotheses did not come within ``wait_s``: answered
        with an Error naming them."""
        out = []
        for session in sorted(self._waiting):
            st = self.sessions.peek(session)
            if st is None:
                continue
            for n, (sel, since) in sorted(st.waiting.items()):
                if now - since < self.wait_s:
                    continue
                if self._ready(session, st, n, fetch=True):
                    out += self._select(session, st, n, st.waiting.pop(n)[0])
                    continue
                del st.waiting[n]
                err = schemas.Error(session=session, key=bus.key(session, "selection", n),
                                    code=schemas.ErrorCode.ERROR_CODE_NO_SUCH_HYPOTHESIS,
                                    message=f"the hypotheses of photo {n} did not come "
                                            f"within {self.wait_s:g} s", service=self.name,
                                    time_ns=time.time_ns())
                out.append(Output(bus.key(session, "error"), err, cache=False))
            if not st.waiting:
                self._waiting.discard(session)
        self.sessions.expire(now)
        return out

    def _camera(self, session, n, hset):
        """(camera, provenance, height or None, its 1-sigma) of photo n: the camera the
        hypotheses were built with (an estimated gravity too) and the frame's height they
        passed on; what the set lacks (an older writer's) from the frame, asked for."""
        prov = msg_provenance(hset.camera) if hset.HasField("camera") else None
        frame = None
        if prov is None or not hset.HasField("frame_height"):
            frame = self.need(bus.key(session, "frame", n), schemas.Frame)
        if prov is not None:
            cam = msg_camera(hset.camera)
        else:
            w, h = image_size(frame.image.data, f"frame {n}")
            cam, prov = frame_camera(frame, w, h), Provenance()
        given = frame if frame is not None else hset.frame_height
        height = given.camera_height_m if given.HasField("camera_height_m") else None
        sigma = (given.camera_height_sigma_m if given.HasField("camera_height_sigma_m")
                 else DEFAULT_HEIGHT_SIGMA_M)
        return cam, prov, height, sigma

    def _select(self, session, st, n, sel):
        if n not in st.hsets:
            st.put(st.hsets, n, self.need(bus.key(session, "hypotheses", n), schemas.HypothesisSet))
        hyps = msg_hypotheses(st.hsets[n])
        if not 1 <= sel.rank <= len(hyps):
            raise HypothesisError(f"selection of hypothesis {sel.rank} of photo {n}, which has "
                                  f"{len(hyps)} hypotheses")
        cam, prov, height, sigma = self._camera(session, n, st.hsets[n])
        if sel.HasField("camera_height_m"):
            height = sel.camera_height_m
            sigma = sel.camera_height_sigma_m if sel.HasField("camera_height_sigma_m") else sigma
        metric = height is not None
        h = hyps[sel.rank - 1]
        held = Held(scene_of(cam, prov, height if metric else 1.0, sigma if metric else 0.0,
                             h.polyline, h.kinds, msg_lines(st.hsets[n])),
                    sel.rank, metric, prov, sel.by)
        held = self._agreed(session, st, n, held) or held   # a motion came first
        st.put(st.scenes, n, held)
        st.hsets.pop(n, None)   # the scene is what queries need; another selection of this
        # photo fetches its hypotheses again (the store keeps small results 15 min): a
        # session's memory is then ~1 kB a photo and its lines (~3 kB for 100), not the
        # whole HypothesisSet
        self.built += 1
        return [self._scene_output(session, n, held)]

    @staticmethod
    def _scene_output(session, n, held: Held) -> Output:
        scene = held.scene
        msg = schemas.Scene(session=session, index=n, rank=held.rank,
                            camera=camera_msg(scene.camera, held.prov),
                            camera_height_m=scene.height, camera_height_sigma_m=scene.height_sigma,
                            metric=held.metric,
                            polyline=schemas.polyline_to_msg(scene.polyline, scene.kinds),
                            lines=[] if scene.lines is None else scene.lines.ravel().tolist(),
                            time_ns=time.time_ns())
        return Output(bus.key(session, "scene", n), msg)

    def _motion(self, session, st, pair, msg):
        """A motion's agreed gravities (photo n = the key's a or b; ``measurement_gravity``):
        each photo keeps the tightest; a built scene whose gravity is looser is built again
        under it and its Scene published again."""
        out = []
        for which, g, sigma in msg_agreed_gravities(msg):
            n = pair[0] if which == "a" else pair[1]
            if n in st.agreed and st.agreed[n][1] <= sigma:
                continue
            st.put(st.agreed, n, (g, sigma))
            if n in st.scenes:   # else its selection comes later: ``_select`` takes it then
                held = self._agreed(session, st, n, st.scenes[n])
                if held is not None:
                    st.put(st.scenes, n, held)
                    out.append(self._scene_output(session, n, held))
        return out

    def _agreed(self, session, st, n, held: Held) -> Held | None:
        """``held`` under the gravity a motion agreed on for photo n (``measurement_gravity``),
        or None when there is none better or no boundary under it (counted)."""
        new = under_agreed(st.agreed.get(n), held.scene.camera, held.prov)
        if new is None:
            return None
        by = held.by if held.by is not None else self._fetched(session, "selection", n,
                                                               schemas.Selection, "by")
        frame = (None if by == schemas.SELECTED_BY_USER else
                 self._fetched(session, "frame", n, schemas.Frame))
        sc = held.scene
        try:
            poly, kinds = boundary_under(frame, new[0], sc.height if held.metric else None, by,
                                         sc.polyline, sc.kinds)
            scene = scene_of(*new, sc.height, sc.height_sigma, poly, kinds, sc.lines)
        except FindmeError:   # it stays under its own gravity, whose sigma its answers carry
            self.not_regravitated += 1
            return None
        self.regravitated += 1
        return Held(scene, held.rank, held.metric, new[1], by)

    def _fetched(self, session, kind, n, cls, field=None):
        """Photo n's ``kind`` message from the bus (its ``field``), None when nobody has it."""
        try:
            msg = self.need(bus.key(session, kind, n), cls)
        except HypothesisError:
            return None
        return msg if field is None else getattr(msg, field)

    def on_query(self, key, req):
        k = bus.parse_key(key)
        if req.session != k.session:
            raise UnknownSession(f"{key} carries a request for session {req.session!r}")
        st = self.sessions.peek(k.session)
        known = st is not None
        if st is None or req.index not in st.scenes:
            # not seen here (this service restarted, or evicted it): rebuild it from the bus,
            # from the Scene published for it, else from its selection and inputs
            held = self._published_scene(k.session, req.index)
            if held is not None:
                st = self.sessions.get(k.session)
                st.put(st.scenes, req.index, held)
            else:
                try:
                    sel = self.need(bus.key(k.session, "selection", req.index),
                                    schemas.Selection)
                except HypothesisError:
                    if not known:
                        raise UnknownSession(f"session {k.session!r} is not known") from None
                    raise HypothesisError(f"photo {req.index} of session {k.session!r} has "
                                          "no selected hypothesis yet") from None
                st = self.sessions.get(k.session)
                self._select(k.session, st, req.index, sel)
        else:
            self.sessions.get(k.session)   # used now
        held = st.scenes[req.index]
        st.scenes.move_to_end(req.index)
        said = schemas.msg_to_surfaces(req.said)   # the surface said of each pixel, if any
        located = held.scene.locate(schemas.msg_to_pixels(req.pixels), said)
        self.answered += 1
        self.said += said is not None
        return measure_reply_msg(k.session, req.index, held.rank, held.metric, located,
                                 held.scene.height, held.scene.height_sigma, said)

    def _published_scene(self, session: str, n: int) -> Held | None:
        """Photo n's scene rebuilt from its Scene message on the bus (the same camera,
        height, sigmas and boundary it was built with), or None when nobody has it."""
        try:
            msg = self.need(bus.key(session, "scene", n), schemas.Scene)
        except HypothesisError:
            return None
        cam = msg_camera(msg.camera)
        prov = msg_provenance(msg.camera) or Provenance()
        poly, kinds = schemas.msg_to_polyline(msg.polyline)
        scene = scene_of(cam, prov, msg.camera_height_m, msg.camera_height_sigma_m, poly, kinds,
                         msg_lines(msg))
        self.rebuilt += 1
        return Held(scene, msg.rank, msg.metric, prov, None)

    def counters(self):
        return {"scenes": self.built, "sessions": len(self.sessions),
                "evicted": self.sessions.evicted, "measure_queries": self.answered,
                "measure_queries_said": self.said,
                "scenes_rebuilt": self.rebuilt, "scenes_regravitated": self.regravitated,
                "scenes_not_regravitated": self.not_regravitated}
