"""Whether a floor plan is one room its photos agree on, or a drawing that must not be shown.

A plan is refused (``check`` gives the reason) when it contradicts its own photos:

* ``cameras_outside``: a placed photo's camera lies outside the outline by more than
  ``outside_m``. The user stood in the room, so an outline that leaves a camera outside was
  drawn from photos placed wrongly, or from boundaries that were not the room's walls (two
  photos of a garage once made a 0.8 m2 triangle beside the camera). Nothing of it stands;
* ``walls_seen_past``: the photos saw past one of its walls, wider than a door
  (``seen_past``: floor, and a wall's base 0.3-1.0 m further out), on a line seen from
  several spots, which the outline could not be drawn without. The photos disagree about
  the room's walls, not about where they stand. On the dev rooms (2026-11-30, a phone's
  gravity) this refused the kitchen zr_r06 (IoU 0.41: a hallway seen through an opening
  taken in, its long wall drawn through the kitchen), whose 12 placed photos were right
  within 0.26 m and 0.74 deg, each within 1.6 sigma. Only the outline is refused.

Frames and units as ``floorplan``: the room frame's (x, z), metres. Pure numpy + OpenCV's
point-in-polygon test.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from findme_core.plan import seen_past


@dataclass(frozen=True)
class ConsistencyParams:
    """Attributes:
        outside_m: a camera this far outside the outline refuses the plan (a person stands
            at least a body's half-width from a wall; poses are known to ~0.1 m).
    """

    outside_m: float = 0.25


def camera_depths(polygon: np.ndarray, poses: np.ndarray) -> np.ndarray:
    """(N,) signed distance of each pose's camera (x, z) inside the outline, metres (> 0
    inside, < 0 outside; NaN for a photo not placed or without an outline)."""
    P = np.asarray(polygon, np.float32).reshape(-1, 1, 2)
    out = np.full(len(poses), np.nan)
    if len(P) < 3:
        return out
    for i, p in enumerate(np.asarray(poses, float).reshape(-1, 3)):
        if np.isfinite(p[0]):
            out[i] = cv2.pointPolygonTest(P, (float(p[0]), float(p[1])), True)
    return out


def check(plan, params: ConsistencyParams = ConsistencyParams(), names=None, evidence=None,
          seen: seen_past.SeenPastParams = seen_past.SeenPastParams()) -> str | None:
    """Why ``plan`` (a ``floorplan.Plan``) must not be shown, or None: ``cameras_outside``,
    then ``walls_seen_past``. ``names`` name the photos in the reason (default: their
    numbers from 1); ``evidence``: the placed photos' wall samples at the plan's poses
    (``walls.evidence``), for the seen-past test with ``seen`` (without it, only the
    cameras are checked)."""
    return cameras_outside(plan, params, names) or (
        None if evidence is None else walls_seen_past(plan, evidence, seen, names))


def _who(names, i: int) -> str:
    return names[i] if names is not None else f"photo {i + 1}"


def cameras_outside(plan, params: ConsistencyParams = ConsistencyParams(),
                    names=None) -> str | None:
    """Why ``plan`` must not be shown because its outline leaves a camera outside, or None.
    Photos placed wrongly do that as often as wrong walls: neither the outline nor the poses
    hold (the rendered sessions of ``tools/rendered_sessions.py``, 2026-12-01: the 6 plans it
    refused had 22 of 65 placed photos confidently wrong)."""
    d = camera_depths(plan.polygon, plan.poses)
    bad = np.flatnonzero(d < -params.outside_m)
    if not len(bad):
        return None
    i = int(bad[np.argmin(d[bad])])
    return (f"the outline leaves {len(bad)} camera(s) outside the room ({_who(names, i)}'s by "
            f"{-d[i]:.2f} m): the photos do not agree on one room (walls that are not the "
            "room's, or photos placed wrongly); take photos that show the floor meeting "
            "the walls, each overlapping the one before (turn less than the photo's width)")


def walls_seen_past(plan, evidence, seen: seen_past.SeenPastParams = seen_past.SeenPastParams(),
                    names=None) -> str | None:
    """Why ``plan``'s outline must not be shown because its photos saw past one of its walls
    (``seen_past``), or None. Its cameras stand inside it: the walls are what the photos
    contradict, so the poses may stand (``session.plan`` keeps them: ``OutlineRefused``)."""
    if len(plan.polygon) < 3:
        return None
    length, which = seen_past.seen_through(plan.polygon, evidence.points,
                                           evidence.cams[evidence.photo], seen)
    k = int(np.argmax(length))
    if length[k] <= seen.min_m:
        return None
    photos = np.unique(evidence.photo[which[k]])
    by = ", ".join(_who(names, i) for i in photos[:3]) + (", ..." if len(photos) > 3 else "")
    wall = seen_past.wall_lengths(plan.polygon)[k]
    return (f"the outline puts a wall where {len(photos)} photo(s) ({by}) saw past it: "
            f"floor and a wall {seen.behind_m[0]:g}-{seen.behind_m[1]:g} m further out, "
            f"along {length[k]:.1f} m of its {wall:.1f} m, wider than a door. The outline does "
            "not follow the room's walls there; take photos that show the floor meeting each "
            "wall")
