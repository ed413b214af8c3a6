"""The hypotheses service: a frame in, its ranked ground-wall boundary hypotheses out.

    findme/<session>/frame/<n>  ->  findme/<session>/hypotheses/<n>

Several instances share the load (``shard``): each handles the frames that hash to it.
Every frame is answered: its hypotheses, or an Error naming it (OVERLOADED when its
session's queue is full, TOO_LARGE, MALFORMED, ...); ``policy="latest"`` keeps only the
newest ones (live video) and answers each skipped frame OVERLOADED. A frame published
while no instance was up is picked up from the store when one starts (``runtime.recovery``).
"""

from __future__ import annotations

import time

import schemas
from ..runtime import authority, bus
from findme_core.motion.photo_lines import photo_lines, segment_lines
from findme_core.single.methods import to_photo
from findme_io.camera_source import hypothesize_photo
from findme_io.convert import hypothesis_set_msg
from findme_io.frame_photo import frame_work_photo
from ..runtime.handler import Handler, Input, Output


class HypothesesHandler(Handler):
    name = "hypotheses"
    cache_keys = ("findme/*/hypotheses/*",)
    shard = True
    threads = 2     # stateless: a small photo is not held up by a 12 MP one in progress
    # served in its own process (``findme up``): the first stage yields the CPU to the
    # stages after it, so that on a saturated machine the photos already in the pipeline
    # are posed first and new ones wait (and are refused early, OVERLOADED, when they
    # wait too long) instead of being half done and refused downstream. At nice 4 (CPU
    # weight 423 against 1024) it still took ~30 % of the CPU at saturation and odometry
    # refused ~1 in 4 of the photos it had hypothesised; at 10 (weight 110) it runs on what
    # the later stages leave (bench_load --scenario peak: 1,070 hypothesis sets for 807
    # posed -> 908 for 880; posed 10.4 -> 12.1 photos/s)
    nice = 10
    # the photos' first stage: under a standing queue, photos more than 1 s old are refused
    # (``Handler.fresh_wait_s``) so that those answered are answered while they are fresh
    fresh_wait_s = 1.0

    def __init__(self, method: str = "findme", max_n: int = 10, policy: str = "all",
                 depth: int = 64):
        self.method, self.max_n = method, max_n
        self.inputs = (Input("findme/*/frame/*", schemas.Frame, policy, depth,
                             answers=("findme/{session}/hypotheses/{n}",), once=True),)
        self.done = 0

    def on_message(self, key, frame):
        t0 = time.perf_counter()
        authority.check(key, frame)   # the key, not the payload, names session and n
        k = bus.parse_key(key)
        n = k.index()
        # decoded once, at the working size (a 12 MP JPEG at a quarter: DCT scaling), the
        # camera scaled to match; gravity estimated when not given
        wp = frame_work_photo(frame)
        image, cam, prov = wp.image, wp.camera, wp.provenance
        t1 = time.perf_counter()
        est = prov.estimate   # gravity from (or refined by) the image: its whole-frame lines
        # a frame's camera height (> 0, checked with the frame) makes the counters' height
        # metric (``counters``)
        h = frame.camera_height_m if frame.HasField("camera_height_m") else None
        hs, cam, prov = hypothesize_photo(image, cam, prov, self.method, self.max_n,
                                          camera_height=h,
                                          clock=time.perf_counter)
        self.done += 1
        # the photo's lines, for odometry's room orientation: the hypotheses' own, or (when
        # they took only those below the horizon) the gravity estimate's whole detection
        lines = (photo_lines(hs, image) if est is None else
                 segment_lines(est.segments, image) if est.segments is not None else None)
        if wp.scale != 1.0:   # the answer is in the photo's pixels, whatever size it was read at
            hs = to_photo(hs, wp.scale, wp.full.width, wp.full.height)
            cam = wp.to_photo(cam)
            lines = None if lines is None else wp.points_to_photo(lines)
        msg = hypothesis_set_msg(k.session, n, hs, f"{self.method}/findme.v1", cam, prov, lines)
        # the frame's height travels with its hypotheses: a reader of the set (measurement)
        # then needs no frame, so it need not take in every photo's bytes. Set even when the
        # frame gave no height: its presence says "passed on" (an older set asks the frame)
        msg.frame_height.SetInParent()
        for f in ("camera_height_m", "camera_height_sigma_m"):
            if frame.HasField(f):
                setattr(msg.frame_height, f, getattr(frame, f))
        msg.timing_ms["decode"] = 1e3 * (t1 - t0)
        msg.timing_ms["handler_total"] = 1e3 * (time.perf_counter() - t0)
        return [Output(bus.key(k.session, "hypotheses", n), msg)]

    def counters(self):
        return {"hypothesis_sets": self.done}
