"""The measurement service: the scene model of each selected photo, and 3D on request.

    frame/<n> + hypotheses/<n> + selection/<n>  ->  findme/<session>/scene/<n>
    query findme/<session>/measure (MeasureRequest)  ->  MeasureReply

The camera height comes from the selection (if the user gave one there), else the frame,
else h = 1 (results up to scale, ``metric`` false).
"""

from __future__ import annotations

import time

import schemas
from findme_io.imageio import image_size
from findme_core.errors import HypothesisError
from findme_core.provenance import Provenance
from findme_core.scene import Scene, boundary_sigma_px

from ..runtime import bus
from findme_io.convert import (camera_msg, frame_camera, measure_reply_msg, msg_camera,
                               msg_hypotheses, msg_provenance)
from ..runtime.handler import Handler, Input, Output, UnknownSession

DEFAULT_HEIGHT_SIGMA_M = 0.03


class MeasurementHandler(Handler):
    name = "measurement"
    cache_keys = ("findme/*/scene/*",)
    inputs = (Input("findme/*/frame/*", schemas.Frame),
              Input("findme/*/hypotheses/*", schemas.HypothesisSet),
              Input("findme/*/selection/*", schemas.Selection))
    queries = (Input("findme/*/measure", schemas.MeasureRequest),)

    def __init__(self):
        self.frames: dict[tuple[str, int], tuple] = {}   # (session, n) -> (camera, h, sigma)
        self.hsets: dict[tuple[str, int], object] = {}
        self.scenes: dict[tuple[str, int], tuple] = {}   # -> (Scene, rank, metric)
        self.sessions: set[str] = set()
        self.answered = 0

    def on_message(self, key, msg):
        k = bus.parse_key(key)   # the key names session and n, never the payload
        self.sessions.add(k.session)
        if isinstance(msg, schemas.Frame):
            self._frame(k.session, k.index(), msg)
            return []
        if isinstance(msg, schemas.HypothesisSet):
            self.hsets[(k.session, k.index())] = msg
            return []
        return self._select(k.session, k.index(), msg)

    def _frame(self, session, n, f):
        w, h = image_size(f.image.data, f"frame {n}")
        cam = frame_camera(f, w, h)
        height = f.camera_height_m if f.HasField("camera_height_m") else None
        sigma = (f.camera_height_sigma_m if f.HasField("camera_height_sigma_m")
                 else DEFAULT_HEIGHT_SIGMA_M)
        self.frames[(session, n)] = (cam, height, sigma)

    def _select(self, session, n, sel):
        if (session, n) not in self.frames:
            self._frame(session, n, self.need(bus.key(session, "frame", n), schemas.Frame))
        if (session, n) not in self.hsets:
            self.hsets[(session, n)] = self.need(bus.key(session, "hypotheses", n),
                                                 schemas.HypothesisSet)
        hyps = msg_hypotheses(self.hsets[(session, n)])
        if not 1 <= sel.rank <= len(hyps):
            raise HypothesisError(f"selection of hypothesis {sel.rank} of photo {n}, which has "
                                  f"{len(hyps)} hypotheses")
        cam, height, sigma = self.frames[(session, n)]
        hset = self.hsets[(session, n)]
        prov = msg_provenance(hset.camera) if hset.HasField("camera") else None
        if prov is not None:   # the camera the hypotheses were built with (estimated gravity)
            cam = msg_camera(hset.camera)
        else:
            prov = Provenance()
        if sel.HasField("camera_height_m"):
            height = sel.camera_height_m
            sigma = sel.camera_height_sigma_m if sel.HasField("camera_height_sigma_m") else sigma
        metric = height is not None
        h = hyps[sel.rank - 1]
        scene = Scene(cam, height if metric else 1.0, h.polyline, h.kinds,
                      height_sigma=sigma if metric else 0.0, gravity_cov=prov.gravity_cov,
                      boundary_sigma_px=boundary_sigma_px(cam.width, cam.height))
        self.scenes[(session, n)] = (scene, sel.rank, metric)
        msg = schemas.Scene(session=session, index=n, rank=sel.rank,
                            camera=camera_msg(cam, prov),
                            camera_height_m=scene.height, camera_height_sigma_m=scene.height_sigma,
                            metric=metric, polyline=schemas.polyline_to_msg(h.polyline, h.kinds),
                            time_ns=time.time_ns())
        return [Output(bus.key(session, "scene", n), msg)]

    def on_query(self, key, req):
        k = bus.parse_key(key)
        if req.session != k.session:
            raise UnknownSession(f"{key} carries a request for session {req.session!r}")
        if (k.session, req.index) not in self.scenes:
            # not seen here (e.g. this service restarted): rebuild it from the bus
            try:
                sel = self.need(bus.key(k.session, "selection", req.index), schemas.Selection)
            except HypothesisError:
                if k.session not in self.sessions:
                    raise UnknownSession(f"session {k.session!r} is not known") from None
                raise HypothesisError(f"photo {req.index} of session {k.session!r} has no "
                                      "selected hypothesis yet") from None
            self.sessions.add(k.session)
            self._select(k.session, req.index, sel)
        scene, rank, metric = self.scenes[(k.session, req.index)]
        located = scene.locate(schemas.msg_to_pixels(req.pixels))
        self.answered += 1
        return measure_reply_msg(k.session, req.index, rank, metric, located, scene.height,
                                 scene.height_sigma)

    def counters(self):
        return {"scenes": len(self.scenes), "measure_queries": self.answered}
