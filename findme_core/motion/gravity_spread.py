"""Another motion under a gravity tilted within its 1-sigma: an alternative the photos cannot
rule out when a photo's gravity came from its own lines.

A motion lifts each photo's matches and boundary on that photo's gravity. A gravity from the
photo's lines (no sensor) carries a 1-sigma s, and a tilt of s can tip the evidence to another
motion: the depths of far floor points and the walls' directions tilt with it. Measured
2026-12-01 on the dev pairs with gravity withheld: KITTI 13 -> 14, driving 1.19 m forward,
came out 0.37 +- 0.04 m (its lines' roll 1.5 deg off the road's at +-0.5 deg; with the
dataset's level gravity 1.29 m), and the pairs' 1-sigmas were those stated with an exact
gravity (median ratio 1.00): a gravity's sigma never reached its motion.

So the motion is estimated again with each such photo's gravity tilted by +s and -s about
each of its level axes (pitch: about x, roll: about z), everything else as it was (the
matches, the boundaries in the image): the sigma points of the gravity's error, as an
unscented transform places them. A tilted estimate that is another motion (``alternatives.
same``: more than 3 deg of yaw or 0.1 m + 10 % of the baseline apart) is one the photos
allow unless their matches rule it out: fewer of them agree with it than with the answer, by
more than the counts' standard error (``alternatives.more_agree``; under a wrong gravity the
lifted matches fit a planar motion worse). Per axis the mean square of the two tilts' moves,
((m+ - m)^2 + (m- - m)^2) / 2 (a move that is the same motion or ruled out counting 0), is
added to the variance of x, z and yaw (a jump on one side: half its square). Smaller moves
are the model errors' part: those were fitted (``MotionParams``) on TUM pairs whose gravity
is itself about 1 deg off their floor, and a full propagation of every move put 1.00 of the
TUM pairs within 1 sigma (0.84 before).
A tilt under which no motion is found adds nothing and is counted. Ruling out by the matches
(2026-12-02, no constant): 32 of the 51 dev pairs the tilts widened with gravity withheld
narrow again, TUM within 1 sigma 0.90 / 0.91 / 0.85 -> 0.89 / 0.89 / 0.83 (x / z / yaw), and
the pairs beyond 3 sigma stay the same 2. KITTI 13 -> 14 keeps the tilts that move it to
1.01 and 0.98 m forward (truth 1.19): 913 matches agree with them, 883 with the answer.

Frames and units: gravity (3,) unit vectors in the camera frame (x right, y down, z forward);
tilts radians about the photo's level x and z axes; motions as ``model.PlanarMotion`` (x, z
metres in photo A's level frame, yaw radians). Pure numpy; the estimates are the caller's.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable

import numpy as np

from findme_core.geometry.camera import Camera
from findme_core.geometry.planar import wrap
from findme_core.geometry.uncertainty import tilted_gravity
from findme_core.motion.alternatives import more_agree, same
from findme_core.motion.model import PlanarMotion

AXES = ("pitch", "roll")


def tilted(camera: Camera, axis: int, angle: float) -> np.ndarray:
    """(3,) ``camera``'s gravity turned by ``angle`` radians about its level frame's x axis
    (``axis`` 0: pitch) or z axis (1: roll), as ``uncertainty.tilted_gravity`` tilts it."""
    return tilted_gravity(camera, (1.0, 0.0) if axis == 0 else (0.0, 1.0), angle)


@dataclass(frozen=True)
class Tilt:
    """One sigma point: photo ``photo`` (0: A, 1: B) with its gravity tilted by ``angle``
    radians about level axis ``axis`` (``AXES``), the ``motion`` then estimated (None: none
    found), whether it is ``another`` motion than the answer (``alternatives.same``) that the
    sigmas cover, or a different one the photos' matches rule out (``ruled_out``: fewer of
    them agree with it, ``alternatives.more_agree``)."""

    photo: int
    axis: int
    angle: float
    motion: PlanarMotion | None
    another: bool = False
    ruled_out: bool = False


@dataclass(frozen=True)
class Spread:
    """What a motion's gravity sigma points did: ``tilts`` (``Tilt``, ...) and ``var`` (3,)
    the variances they add to x (m^2), z (m^2) and yaw (rad^2)."""

    tilts: tuple
    var: np.ndarray

    @property
    def failed(self) -> int:
        """Tilts under which no motion was found."""
        return sum(t.motion is None for t in self.tilts)

    def others(self, m: PlanarMotion) -> list[Tilt]:
        """The tilts that gave another motion than ``m`` (the answer they were made for)."""
        return [t for t in self.tilts if t.another]


def spread(m: PlanarMotion, sigmas, estimate_under: Callable) -> Spread:
    """The sigma points of ``m``'s gravity errors.

    Args:
        m: the motion as estimated.
        sigmas: (s_A, s_B) 1-sigma (radians) of each photo's gravity from its lines; None
            (a sensor's, which the motion's model errors hold), not finite (level assumed
            and not completed by the other photo: no scale for a tilt) or 0 leaves that
            photo's gravity as it is.
        estimate_under: (photo 0 | 1, level axis 0 | 1, tilt radians) -> the motion estimated
            again with that photo's gravity tilted so (``PlanarMotion``), None when none.
    """
    tilts, var = [], np.zeros(3)
    for i, s in enumerate(sigmas):
        if s is None or not np.isfinite(s) or s <= 0:
            continue
        for axis in (0, 1):
            sq = np.zeros(3)
            for sign in (1.0, -1.0):
                o = estimate_under(i, axis, sign * s)
                other = o is not None and not same(m.yaw, (m.x, m.z), o.yaw, (o.x, o.z))
                ruled = other and more_agree(m.n_inliers, o.n_inliers)
                another = other and not ruled
                tilts.append(Tilt(i, axis, sign * s, o, another, ruled))
                if another:
                    sq += np.array([o.x - m.x, o.z - m.z, float(wrap(o.yaw - m.yaw))]) ** 2
            var += sq / 2.0
    return Spread(tuple(tilts), var)


def widened(m: PlanarMotion, s: Spread) -> PlanarMotion:
    """``m`` with the spread's variances added to its sigmas (``m`` itself when they are 0)."""
    if not s.var.any():
        return m
    return replace(m, sigma_x=float(np.sqrt(m.sigma_x ** 2 + s.var[0])),
                   sigma_z=float(np.sqrt(m.sigma_z ** 2 + s.var[1])),
                   sigma_yaw=float(np.sqrt(m.sigma_yaw ** 2 + s.var[2])))
