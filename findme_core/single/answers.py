"""What a located pixel's answer says to the user: the answer (``Located``), why it has none
(``Reason``, ``REASONS``), what to know of it (``NOTES``), and the surfaces a point can be on
(``SURFACES``).

The texts reach the CLI, the services' ``MeasuredPoint.error`` / ``note`` and the phone page
unchanged, so each says what happened and what to do. ``said_codes`` checks what a caller
said of each pixel. No I/O.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

import numpy as np

from findme_core.errors import InputError


class Reason(IntEnum):
    """Why a pixel has no 3D position (``scene.Scene.locate_level``'s codes; 0: it has one)."""

    ABOVE_HORIZON = 1
    PARALLEL_RAY = 2
    BEHIND = 3
    NO_FLOOR = 4
    OUTSIDE = 5
    NOT_FINITE = 6
    LOOSE = 7
    LOOSE_GRAVITY = 8
    NOT_WALL = 9
    UNSEEN = 10
    NO_FLOOR_VIEW = 11
    TOP_ON_FLOOR = 12
    NO_TOP_EDGE = 13
    NO_LINES = 14
    TOP_ABOVE = 15
    TOP_TOO_DEEP = 16
    FACE_OR_TOP = 17
    FLOOR_OR_FACE = 18


#: Why a pixel has no 3D position, for the user. A point said to be on a wall that the
#: boundary puts on the floor, or on a wall nobody saw the base of, is not answered from the
#: next hypothesis that would place it: measured 2026-11-30 (dev split, a phone's gravity),
#: such answers held 0.60 and 0.79 of the points within 3 sigma.
REASONS = {
    Reason.ABOVE_HORIZON:
        "the pixel is at or above the horizon, so it is not on the floor, and no wall is known "
        "in its direction",
    Reason.PARALLEL_RAY: "the pixel's ray runs parallel to the wall: it never meets it",
    Reason.BEHIND:
        "the wall's plane lies behind the camera in this direction: the point would be behind "
        "the camera",
    Reason.NO_FLOOR:
        "no floor is visible in this direction under the chosen boundary, so the wall's "
        "distance is unknown",
    Reason.OUTSIDE: "the pixel is outside the image",
    Reason.NOT_FINITE: "the pixel is not finite",
    Reason.LOOSE:
        "the boundary places this point too loosely (its 1-sigma exceeds the allowed share of "
        "its distance): the wall's base is barely seen or lies near the horizon",
    Reason.NOT_WALL:
        "the chosen boundary puts the floor under this pixel, not a wall: choose a hypothesis "
        "whose floor line runs below it",
    Reason.LOOSE_GRAVITY:
        "gravity is too uncertain to place this point (its 1-sigma, mostly from which way is "
        "down, exceeds the allowed share of its distance): the photo does not show it clearly; "
        "give the phone's gravity",
    Reason.UNSEEN:
        "the base of the wall in this direction is outside the photo (the chosen boundary runs "
        "below or above the image there), so its distance is inferred, not measured: take the "
        "photo with the floor meeting this wall in view",
    Reason.NO_FLOOR_VIEW:
        "the photo shows almost no floor under the chosen boundary, so the foot of its walls is "
        "not seen and their distances would be a guess: step back or tilt the phone down so "
        "that the photo shows the floor meeting the walls",
    Reason.TOP_ON_FLOOR:
        "the chosen floor line runs above this point you said is on top of something, so it "
        "puts the point on the floor: a top is measured on the thing whose foot the floor line "
        "follows below it (a counter, a cabinet, furniture in front of a wall); choose a "
        "hypothesis whose line runs along that foot (a table on legs, with floor seen under "
        "it, has no such line and is not measured)",
    Reason.NO_TOP_EDGE:
        "no front edge of a top was found between this point and the floor line below it (a "
        "straight line, level and parallel to the face standing on that floor line, lower than "
        "the camera), so the top's height is not known: say wall to measure the face itself",
    Reason.NO_LINES:
        "the photo's straight lines did not come with its hypotheses, so the front edge of a "
        "top cannot be looked for here",
    Reason.TOP_TOO_DEEP:
        "on the top whose front edge was found below it, this point would lie farther behind "
        "that edge than a table's or a counter's top reaches, so the line found is likely not "
        "a top's edge (a level line on a wall, a sill): say wall to measure the face itself",
    Reason.TOP_ABOVE:
        "the pixel is at or above the horizon: a top seen there is not below the camera, and "
        "only tops the camera looks down on are measured",
    Reason.FACE_OR_TOP:
        "a level edge runs below this point, the front edge of a top (a counter, a cabinet, a "
        "table) or a line on the wall: on the face below it and on that top the point lies too "
        "far apart to give one position; say top or wall to measure it on one",
    Reason.FLOOR_OR_FACE:
        "this point lies beside an edge where the floor line steps back (the side of a "
        "cabinet, a door frame, a wall's end): on the floor behind it and on the face of what "
        "stands in front, the point lies too far apart to give one position; say floor or "
        "wall to measure it on one",
}

#: What the user should know of an answered point (``scene.Located.note``), by code. A point
#: said floor where the boundary puts a wall (or no floor) is put on the floor, and the floor
#: seen there means the line is wrong in that direction. Measured 2026-11-30 (dev split, a
#: phone's gravity, surfaces said; ``tools/surface_coverage.py``): in the 86 ZInD views with a
#: floor point noted, 8.7 % of the wall points lie beyond 3 sigma; 2.0 % in the other 85.
FLOOR_PAST_LINE = 1
#: A point nobody said the surface of, read on a face with a top's front edge below it
#: (``tops.face_or_top``): its 1-sigma spans the face and the top.
FACE_OR_TOP_NOTE = 2
#: A point nobody said the surface of, read on the floor just beside a step of the floor line
#: (``steps.floor_or_face``): its 1-sigma is widened toward the face in front.
FLOOR_OR_FACE_NOTE = 3
NOTES = {
    FLOOR_PAST_LINE:
        "the chosen floor line runs below this point you said is on the floor: if the floor "
        "reaches here, the wall in this direction stands beyond it and the line is wrong there "
        "(walls measured in this direction come out too near); choose a hypothesis whose floor "
        "line runs above this point",
    FACE_OR_TOP_NOTE:
        "a level edge runs below this point, the front edge of a top (a counter, a cabinet, a "
        "table) or a line on the wall: the point is given on the face below it, as the floor "
        "line has it, and its 1-sigma spans where it would be on that top; if it is on the top "
        "or beyond it, say top (or floor) to measure it there",
    FLOOR_OR_FACE_NOTE:
        "this point lies beside an edge where the floor line steps back (the side of a "
        "cabinet, a door frame, a wall's end): it is given on the floor behind, as the floor "
        "line has it, and its 1-sigma is widened toward where it would be on the face in "
        "front; if it is on that face, say wall to measure it there",
}

#: The surfaces a located point can be on (and a user can say it is on), by code 1, 2, 3:
#: the floor, a wall (or the face of anything standing on the floor line), the top of
#: something standing on it (a table, a counter, a cabinet: ``tops``). A point is on a top
#: only when said to be: nothing in the boundary tells a top from the wall above it (a point
#: read on a face with a top's edge below it has a 1-sigma that spans both, ``tops``).
SURFACES = ("floor", "wall", "top")
SURFACE_NAMES = dict(enumerate(SURFACES, 1))
SURFACE_CODES = {name: code for code, name in SURFACE_NAMES.items()}


def said_codes(surfaces, n: int) -> np.ndarray:
    """(n,) the ``SURFACE_CODES`` of what was said of each of n pixels (0: nothing said;
    ``surfaces`` None: nothing said of any).

    Raises:
        InputError: ``surfaces`` is not one entry per pixel, or names no surface.
    """
    if surfaces is None:
        return np.zeros(n, int)
    said = list(surfaces)
    if len(said) != n:
        raise InputError(f"{len(said)} surfaces said for {n} pixels: say one per pixel "
                         "(None where nothing is said)")
    bad = [x for x in said if x is not None and x not in SURFACE_CODES]
    if bad:
        raise InputError(f"surface {bad[0]!r} is none of {', '.join(SURFACES)} (or None)")
    return np.array([SURFACE_CODES.get(x, 0) for x in said], int)


@dataclass(frozen=True)
class Located:
    """3D position of one tapped pixel.

    Attributes:
        pixel: (u, v).
        surface: "floor", "wall" or "top" (only when said), None when there is no answer.
        xyz: (3,) camera-frame point in metres, None when there is no answer.
        sigma_m: 1-sigma radius of the point in metres: the root sum of squares of
            ``sigma_parts`` ("boundary": the boundary off by its sigma, "height": the camera
            height off by its sigma, "pixel": the tap off by one pixel, "gravity": gravity's
            tilt off by its covariance, "surface": nobody having said its surface, how far the
            point would be on the top whose front edge runs below it, ``tops.face_or_top``, or
            on the face in front of a step of the boundary beside it, ``steps.floor_or_face``).
        error: why there is no answer, else None.
        gravity_jac: (2, 3) camera-frame displacement of the point (metres) for a 1-sigma
            tilt of gravity along each principal axis of its covariance (every point of a
            photo moves together: ``distances`` uses it), None when gravity is exact.
        note: what the user should know of an answered point (``NOTES``), else None.
    """

    pixel: tuple[float, float]
    surface: str | None
    xyz: np.ndarray | None
    sigma_m: float | None = None
    sigma_parts: dict | None = None
    error: str | None = None
    gravity_jac: np.ndarray | None = None
    note: str | None = None
