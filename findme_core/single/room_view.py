"""Whether a photo looks like a room view: the judgement that lets a photo that is not one
(no floor-wall boundary, taken from above, an object filling the view) say so, with the
reason, instead of offering confident hypotheses.

From what the hypotheses were made with, nothing else: the hypothesis set (its best
boundary, or why it has none), the photo's camera (its gravity: how far it looks down) and,
when known, the camera height (only to say distances in metres). Cues, in this order:

1. no hypotheses at all: the set's own reason;
2. taken from above: the optical axis at least ``top_down_deg`` below the horizontal;
3. no floor in view: fewer than ``min_floor_columns`` of the photo's columns show at least
   ``min_floor_fraction`` of its height of floor under the best boundary (it lies below
   the photo, or hugs its bottom edge, or has no floor segment);
4. an object filling the view: the floor under the best boundary ends near the camera all
   across the photo: its median distance under ``near_median_h`` camera heights and its
   farthest under ``near_farthest_h`` (horizontal distances in the level frame; floor
   running past the photo's top, or a boundary at or above the horizon, counts as far).

The thresholds were set on rendered scenes (a box 0.5-0.7 m in front of a phone held
1.4 m up: median 0.48-0.60 h, farthest 0.73-0.83 h; a top-down photo: 88 deg) against the
dev split of findme-eval, every view of which is a room view: pitch at most 42.5 deg; the
smallest median 0.79 h. With the views' gravity 21 of its 234 views are judged to show no
floor: 13 with none in the ground truth, 5 with a sliver (2-5 % of the image), 3 where the
best boundary misses 11-17 % of floor (20 with gravity withheld); none is judged taken from
above or filled by an object.

Frames and units as ``camera``: pixels of the photo, level frame y down; distances in
camera heights (h) unless ``camera_height`` (metres) is given. Degenerate cases: an empty
set is not a room view (cue 1); a boundary with no wall, step or open segment over floor in
the photo's columns has no distance (cue 4 does not apply).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from findme_core.geometry.camera import Camera
from findme_core.single.hypotheses import HypothesisSet
from findme_core.single.search import SegKind
from findme_core.single.seen import (FLOOR_COLUMNS_SAMPLED, MIN_FLOOR_COLUMNS, MIN_FLOOR_FRACTION,
                                     floor_under)


@dataclass(frozen=True)
class RoomViewParams:
    top_down_deg: float = 65.0        # dev split: every view looks down at most 42.5 deg
    min_floor_fraction: float = MIN_FLOOR_FRACTION  # of the photo's height, in one column
    min_floor_columns: float = MIN_FLOOR_COLUMNS    # of the photo's columns
    near_median_h: float = 0.7        # camera heights: 1 m for a phone held 1.4 m up
    near_farthest_h: float = 1.0
    columns: int = FLOOR_COLUMNS_SAMPLED  # columns sampled across the photo


@dataclass(frozen=True)
class RoomView:
    """The judgement: ``ok`` (a room view), else ``reason`` for the user; ``cues``: the
    measured cues (pitch_deg, floor_columns, farthest_h; NaN when not measured)."""

    ok: bool
    reason: str | None = None
    cues: dict = field(default_factory=dict)


def judge(hs: HypothesisSet, camera: Camera, camera_height: float | None = None,
          params: RoomViewParams = RoomViewParams()) -> RoomView:
    """Whether the photo behind ``hs`` (made with ``camera``) looks like a room view."""
    cues = {"pitch_deg": float(camera.pitch_deg), "floor_columns": float("nan"),
            "farthest_h": float("nan"), "median_h": float("nan")}
    if not hs.hypotheses:
        return RoomView(False, f"no floor-wall boundary found ({hs.reason or 'no hypothesis'})",
                        cues)
    if camera.pitch_deg >= params.top_down_deg:
        return RoomView(False, f"the camera looks {camera.pitch_deg:.0f}° down: a photo taken "
                        "from above shows no walls (hold the phone upright, tilted down just "
                        "enough to see the floor and the foot of the walls)", cues)
    best = hs.hypotheses[0]
    W, H = hs.width, hs.height
    us, vs, kinds, floor = floor_under(best.polyline, best.kinds, W, H, params.columns)
    cues["floor_columns"] = float(np.mean(floor >= params.min_floor_fraction))
    if cues["floor_columns"] < params.min_floor_columns:
        where = ("no floor is in the photo" if np.mean(kinds == SegKind.NONE) >= 0.5 else
                 "its best boundary lies below the photo" if np.median(vs) >= H else
                 "the photo shows almost no floor under its best boundary")
        return RoomView(False, f"no floor-wall boundary in view: {where} (step back or tilt "
                        "the phone down so that the photo shows the floor and the foot of "
                        "the walls)", cues)
    on = (kinds == SegKind.WALL) | (kinds == SegKind.STEP) | (kinds == SegKind.OPEN)
    on &= floor >= params.min_floor_fraction
    if np.any(on):
        r = camera.rays_level(np.column_stack([us[on], np.clip(vs[on], 0.0, H - 1)]))
        with np.errstate(divide="ignore", invalid="ignore"):
            d = np.where(r[:, 1] > 1e-9, np.hypot(r[:, 0], r[:, 2]) / r[:, 1], np.inf)
        d[kinds[on] == SegKind.OPEN] = np.inf    # the floor runs on past the photo's top
        cues["farthest_h"] = float(d.max())
        cues["median_h"] = float(np.median(d))
        if (cues["median_h"] < params.near_median_h
                and cues["farthest_h"] < params.near_farthest_h):
            far = (f"{cues['median_h'] * camera_height:.1f} m" if camera_height else
                   f"{cues['median_h']:.1f} camera heights")
            return RoomView(False, f"something fills the view: the floor ends {far} from the "
                            "camera all across the photo (an object right in front of it?); "
                            "step back so that the photo shows the room's walls", cues)
    return RoomView(True, None, cues)
