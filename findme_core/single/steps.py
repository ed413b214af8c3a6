"""A point beside a step of the boundary: on the floor behind an occluding edge, or on the face
of the thing that stands in front of it.

Where the chosen boundary steps (``SegKind.STEP``: an occluding edge, the side of a cabinet, a
door frame, a wall's end), the floor line jumps from the foot of a near surface up to a farther
one. A pixel the boundary puts on the floor above the step's lower end (its *foot*, where the
near surface meets the floor) is read on the floor behind. The boundary is off by its sigma
(``uncertainty.BOUNDARY_SIGMA_WORK_PX``), and so is a step, sideways: a pixel within that many
pixels of the step's line (the image of the 3D vertical through its foot, at the pixel's row)
may lie on the near thing's face instead (a cabinet's side face, seen obliquely, that a step
at its front corner leaves on the floor's side), metres nearer. The boundary part of the
1-sigma, linearised (the scene under the boundary moved by one pixel), keeps a floor point on
the floor and cannot see that. Dev split (dataset's gravity, nothing said, 2026-12-02): TUM's
points on the cabinet's faces lay 0.82 / 0.84 / 0.85 within 1 / 2 / 3 sigma of the floor
reading with its 1-sigma alone, 0.82 / 0.89 / 0.91 with the spread, and no floor point lost
its answer. The other side (a face point beside a step, perhaps on the floor beyond) showed no
such failures (0.91-1.00 within 3 sigma within 35 px of a step) and gets no spread.

Geometry, in the photo's LEVEL frame (x right, y down along gravity, z forward; metres; the
floor is y = h). The step's foot pixel, lifted onto the floor (eq. 2), is F = (h / f_y) f for
its ray f. The face reading of a pixel with ray r is where r reaches F's horizontal range,

    t_face = |F_xz| / |r_xz|,

the face taken as facing the camera at the foot (the near surface's own plane is unknown
beyond the step). The floor reading is t = h / r_y. The step, off sideways by a Gaussian of
the boundary's sigma s, lies beyond a pixel d pixels from its line with probability
w = Phi(-d / s) (0.16-0.5 within the window d <= s): the point is on the face with that
chance, on the floor otherwise. The spread is the root mean square of the distance from the
floor reading, which the point keeps,

    sqrt(w) |t - t_face| |r|   (metres; where t_face < t),

so that the face reading lies within 1.4-2.5 of it; ``scene.Scene`` adds it to the point's
1-sigma as its "surface" part, and refuses the point (``Reason.FLOOR_OR_FACE``) when that makes
the 1-sigma exceed ``max_rel_sigma`` of its distance. A point said to be on the floor keeps the
floor, with no spread. Taking the whole distance (w = 1) as the spread held the same 0.91 of
the cabinet's faces within 3 sigma, but refused 25 of TUM's 1330 floor points, all of them
right. Pure numpy; no I/O.
"""

from __future__ import annotations

import math

import numpy as np

from findme_core.single.search import SegKind
from findme_core.single.tops import BLOCK

#: elementwise math.erfc (numpy has none; at most a request's 1024 pixels a call)
_erfc = np.frompyfunc(math.erfc, 1, 1)


def step_feet(scene) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The steps of ``scene``'s boundary, in pixels.

    Returns:
        (S, 2) each step's lower end (the foot), pixels; (S,) du / dv of the image of the 3D
        vertical through the foot (the step's line; NaN where that image is level); (S, 3)
        the foot's level-frame floor point (metres; NaN when its ray does not go down).
    """
    poly, kinds, cam = scene.polyline, scene.kinds, scene.camera
    s = np.flatnonzero(kinds == SegKind.STEP)
    a, b = poly[s], poly[s + 1]
    foot = np.where((b[:, 1] >= a[:, 1])[:, None], b, a)
    up = cam.up_direction(foot)
    with np.errstate(divide="ignore", invalid="ignore"):
        slope = np.where(np.abs(up[:, 1]) > 1e-6, up[:, 0] / up[:, 1], np.nan)
        f = cam.rays_level(foot)
        F = np.where(f[:, 1:2] > 0, scene.height / f[:, 1:2] * f, np.nan)
    return foot, slope, F


def floor_or_face(scene, unsaid, px, rays, t, surface, reason, window_px: float) -> np.ndarray:
    """(N,) the spread of each floor point toward its reading on the face of the step beside
    it (0: none).

    Args:
        scene: the ``scene.Scene`` (its polyline, kinds, camera, height).
        unsaid: (N,) bool, nobody said the pixel's surface; px: (N, 2) pixels; rays: (N, 3)
            their level rays; t, surface, reason: (N,) ray parameter, surface code (1 floor)
            and reason code (0 answered) as the boundary gives them.
        window_px: the boundary's sigma, pixels: a pixel up to this far sideways of a step's
            line (at its row) may be on its face.
    Returns:
        (N,) spread, metres, toward the nearest step's face reading (module doc: sqrt(w)
        times the distance), for unsaid pixels the boundary puts on the floor above a step's
        foot, within ``window_px`` of its line, where the face reading is nearer.
    """
    out = np.zeros(len(px))
    floor = np.asarray(unsaid, bool) & (reason == 0) & (surface == 1)
    if not floor.any() or not (scene.kinds == SegKind.STEP).any():
        return out
    foot, slope, F = step_feet(scene)
    idx = np.flatnonzero(floor)
    # pixels x steps in blocks of at most ``tops.BLOCK`` pairs: bounded memory whatever the
    # request (1024 pixels, a boundary of up to 4096 points on the bus)
    block = max(1, BLOCK // len(foot))
    for i in range(0, len(idx), block):
        k = idx[i:i + block]
        out[k] = _nearest_face(px[k], rays[k], t[k], foot, slope, F, window_px)
    return out


def _nearest_face(px, rays, t, foot, slope, F, window_px):
    """``floor_or_face`` of (n, 2) floor pixels, their (n, 3) rays and (n,) floor ray
    parameters, against the steps of ``step_feet``: (n,) spreads, metres."""
    u, v = px[:, :1], px[:, 1:]                                         # (n, 1)
    u_step = foot[:, 0] + (v - foot[:, 1]) * slope                      # (n, S)
    # sideways of the step's line, either side: a pixel the boundary puts on the floor above
    # the foot is on the far floor (the near side's face would have it), whichever side of the
    # line the boundary's own step, not quite vertical, leaves it
    side = np.abs(u - u_step)
    t_face = np.hypot(F[:, 0], F[:, 2])[None, :] / np.hypot(rays[:, :1], rays[:, 2:])
    gap = (t[:, None] - t_face) * np.linalg.norm(rays, axis=1, keepdims=True)
    near = (side <= window_px) & (v < foot[:, 1]) & (gap > 0)
    # of the steps it is beside, the nearest sideways
    d = np.where(near, side, np.inf)
    j = np.argmin(d, axis=1)
    nearest = d.min(1, initial=np.inf)
    beside = np.isfinite(nearest)
    # the chance the step lies beyond the pixel, Phi(-d / window_px) (module doc)
    w = np.zeros(len(nearest))
    w[beside] = 0.5 * _erfc(nearest[beside] / (math.sqrt(2.0) * window_px)).astype(float)
    # (a pixel is beside a step only where its gap is a positive number: no NaN gets through)
    return np.where(beside, np.take_along_axis(gap, j[:, None], 1)[:, 0] * np.sqrt(w), 0.0)
