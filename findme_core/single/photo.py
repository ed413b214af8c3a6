"""A photo's gravity and hypotheses from one detection of its lines.

With an exact gravity a photo goes straight to ``methods.hypothesize``. Without gravity, or
with a sensor's (``gravity_fusion.with_sensor``: steps 1-2 near the sensor's tilt, combined
with it):

1. the whole-frame segments at the working size are detected once
   (``segments.photo_segments``);
2. their vanishing directions give gravity (``vanishing.estimate_gravity``), or "level"
   when they cannot tell;
3. the hypotheses take the segments' part below that gravity's horizon (no second
   detection);
4. knowing the best boundary, gravity is estimated again without the pull of the lines
   lying on the floor (``floor_gravity.with_floor``); when it moved by more than
   ``rehypothesize_deg`` the hypotheses are made again under it (the same segments).

Frames and units as ``methods``: pixels of the photo, gravity in camera coordinates.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from findme_core.geometry.camera import Camera
from findme_core.single.gravity_fusion import FUSED, fused
from findme_core.single.hypotheses import HypothesisSet
from findme_core.single.methods import hypothesize
from findme_core.single.segments import WORK_SIZE
from findme_core.single.floor_gravity import with_floor
from findme_core.single.vanishing import (GravityEstimate, GravityParams, estimate_gravity,
                                          with_alternatives)

#: a joint estimate that moves gravity less than this keeps the first hypotheses, degrees
REHYPOTHESIZE_DEG = 0.25


def hypothesize_estimated(image: np.ndarray, camera: Camera, est: GravityEstimate,
                          method: str = "findme", max_n: int = 10,
                          work_size: int = WORK_SIZE, clock=None,
                          params: GravityParams = GravityParams(),
                          rehypothesize_deg: float = REHYPOTHESIZE_DEG,
                          camera_height: float | None = None
                          ) -> tuple[HypothesisSet, GravityEstimate]:
    """Steps 3-4 for a photo whose gravity ``est`` came from its own image.

    Args:
        image: (H, W, 3) uint8 BGR, the size of ``camera``.
        camera: the photo's intrinsics (its gravity is replaced by the estimate's).
        est: ``estimate_gravity`` of this photo, or ``gravity_fusion.with_sensor`` (its
            segments are reused; a re-estimate is combined with the sensor's again).
        camera_height: metres, when known (``methods.hypothesize``: the walls behind
            kitchen counters).
    Returns:
        (hypotheses under the final gravity, the final estimate).
    """
    hs = hypothesize(image, camera.with_gravity(est.vector), method, max_n, work_size, clock,
                     segments=est.segments, camera_height=camera_height)
    if not hs.hypotheses or est.source not in ("image", FUSED):
        return hs, est
    t0 = clock() if clock else 0.0
    joint = with_floor(est, hs.hypotheses[0].polyline, params)
    if joint is not est and est.prior is not None:
        joint = fused(joint, est.prior)    # the sensor's gravity still counts
    timing = dict(hs.timing_ms)
    if clock:
        timing["gravity_floor"] = 1e3 * (clock() - t0)
    if joint is not est:
        moved = math.degrees(math.acos(float(np.clip(joint.vector @ est.vector, -1.0, 1.0))))
        if moved > rehypothesize_deg:
            again = hypothesize(image, camera.with_gravity(joint.vector), method, max_n,
                                work_size, clock, segments=est.segments,
                                camera_height=camera_height)
            timing = {k: timing.get(k, 0.0) + again.timing_ms.get(k, 0.0)
                      for k in [*timing, *(k for k in again.timing_ms if k not in timing)]}
            hs = again
        else:   # not worth new hypotheses: keep them consistent (and what the floor told)
            joint = with_alternatives(est, joint.alternatives, params.alternative_weight)
    return replace(hs, timing_ms=timing), joint


def hypothesize_without_gravity(image: np.ndarray, camera: Camera, method: str = "findme",
                                max_n: int = 10, work_size: int = WORK_SIZE, clock=None,
                                params: GravityParams = GravityParams(),
                                camera_height: float | None = None
                                ) -> tuple[HypothesisSet, GravityEstimate]:
    """Steps 1-4: hypotheses and gravity of a photo that came without gravity.

    Returns:
        (hypotheses, gravity estimate: source "image", or "level" with the reason).
    """
    t0 = clock() if clock else 0.0
    est = estimate_gravity(image, camera, params)
    ms = 1e3 * (clock() - t0) if clock else None
    hs, est = hypothesize_estimated(image, camera, est, method, max_n, work_size, clock, params,
                                    camera_height=camera_height)
    if ms is not None:
        hs = replace(hs, timing_ms={"gravity": ms, **hs.timing_ms})
    return hs, est
