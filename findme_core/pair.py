"""Two photos -> their planar motion: the pipeline shared by ``findme motion``, ``findme
eval``, the odometry service and the benchmark.

Hypotheses of each photo (the chosen rank becomes the photo's scene), ORB features and
matches, then ``motion.estimate`` lifts the matched points under each scene and estimates
(x, z, yaw) of photo B in photo A's level frame (metres, radians). ``clock`` is injected
(the core reads no clock itself); the default ``time.perf_counter`` only times stages.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

from . import features
from .camera import Camera
from .errors import FindmeError, HypothesisError
from .methods import hypothesize
from .motion import MotionParams, PlanarMotion, estimate
from .scene import Scene


@dataclass
class PairResult:
    """A motion with what produced it (counts, milliseconds per stage)."""

    motion: PlanarMotion
    matches: int
    keypoints: tuple[int, int]
    timing_ms: dict


def scene_of(image, camera: Camera, height: float, rank: int = 1,
             hypothesis_method: str = "findme", which: str = "A", clock=time.perf_counter):
    """(Scene of the photo under its ``rank``-th hypothesis, milliseconds). None when the
    photo has no hypothesis at all (the motion then says whether it can do without); a rank
    beyond the hypotheses found is a bad input (HypothesisError)."""
    t0 = clock()
    # the first ``rank`` hypotheses do not depend on how many more are asked for (greedy
    # duplicate suppression keeps them in order): build no more than needed
    hs = hypothesize(image, camera, hypothesis_method, rank if rank >= 1 else 10)
    ms = 1e3 * (clock() - t0)
    if rank < 1 or rank > max(1, len(hs.hypotheses)):
        raise HypothesisError(f"hypothesis {rank} of photo {which} does not exist: it has "
                              f"{len(hs.hypotheses)} hypotheses"
                              + (f" ({hs.reason})" if hs.reason else ""))
    if not hs.hypotheses:
        return None, ms
    h = hs.hypotheses[rank - 1]
    return Scene(camera, height, h.polyline, h.kinds), ms


def motion_pair(image_a, image_b, cam_a: Camera, cam_b: Camera, scene_a, scene_b,
                h_a: float, h_b: float, methods=("findme",),
                feature_params: features.FeatureParams = features.FeatureParams(),
                params: MotionParams = MotionParams(), clock=time.perf_counter) -> dict:
    """Features, matches and the motion by each method of ``methods``.

    Returns {method: PairResult or the FindmeError raised}; errors of the features stage
    are raised (they concern every method)."""
    t0 = clock()
    fa, fb = features.detect(image_a, feature_params), features.detect(image_b, feature_params)
    t1 = clock()
    m = features.match(fa, fb, feature_params)
    t2 = clock()
    out = {}
    for method in methods:
        spent = [0.0]

        def lifter(scene, px):
            if scene is None:
                return None

            def lift(idx):
                s = clock()
                res = features.lift(scene, px, idx)
                spent[0] += clock() - s
                return res
            return lift

        s = clock()
        try:
            mo = estimate(m, cam_a, cam_b, h_a, h_b, lifter(scene_a, m.ua), lifter(scene_b, m.ub),
                          method, params)
        except FindmeError as e:
            out[method] = e
            continue
        total = clock() - s
        out[method] = PairResult(mo, len(m), (len(fa), len(fb)), {
            "features": 1e3 * (t1 - t0), "matching": 1e3 * (t2 - t1),
            "lift": 1e3 * spent[0], "motion": 1e3 * (total - spent[0])})
    return out
