"""Rendered rooms with exact layouts for the layout, registration and motion tests."""

from __future__ import annotations

import math

import numpy as np

from findme_core.single import layout
from findme_core.geometry.orientation import Orientation
from findme_core.motion.features import Matches
from findme_core.single.search import SegKind
from findme_core.synth.render import Pose, render


def exact_polyline(view):
    """The view's exact ground-wall boundary (``View.ground_truth_boundary_polyline``) as a
    hypothesis would draw it: a one-column jump (an occluding edge) is a STEP; where the
    boundary lies above the top border the floor goes on past it (OPEN, at row -0.5, split
    exactly where it crosses); columns without floor are dropped."""
    poly = view.ground_truth_boundary_polyline()
    poly = poly[np.isfinite(poly[:, 1])]
    top = -0.5
    pts, kinds = [poly[0]], []
    for p, q in zip(poly[:-1], poly[1:]):
        if (p[1] < top) != (q[1] < top):       # crosses the top border: split there
            c = p + (top - p[1]) / (q[1] - p[1]) * (q - p)
            kinds.append(SegKind.OPEN if p[1] < top else SegKind.WALL)
            pts.append(c)
            p = c
        if max(p[1], q[1]) <= top + 1e-9:
            kinds.append(SegKind.OPEN)
        elif q[0] - p[0] <= 1.0 and abs(q[1] - p[1]) > 3.0:
            kinds.append(SegKind.STEP)
        else:
            kinds.append(SegKind.WALL)
        pts.append(q)
    pts = np.array(pts)
    pts[:, 1] = np.maximum(pts[:, 1], top)
    return pts, np.array(kinds)


def exact_orientation(pose: Pose) -> Orientation:
    """The orientation of a room with walls along world X and Z, seen from ``pose``: world X
    has azimuth 90 deg - yaw in the pose's level frame."""
    return Orientation(float((-math.radians(pose.yaw_deg)) % (math.pi / 2)), 1.0, 10)


def view_layout(room, pose: Pose, size=(320, 240), hfov=70.0, rank=1):
    """(rendered view, exact layout) of ``room`` from ``pose``."""
    v = render(room, pose, *size, hfov_deg=hfov, seed=1, supersample=1)
    poly, kinds = exact_polyline(v)
    return v, layout.from_hypothesis(v.camera, pose.height, poly, kinds, rank)


def no_matches() -> Matches:
    """Textureless walls: not a single feature match."""
    return Matches(np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0, int), np.zeros(0, int),
                   np.zeros(0), 0, 0)


def to_level(pose: Pose, xz) -> np.ndarray:
    """World floor points (N, 2) (X, Z) -> (x, z) in the pose's level frame."""
    p = np.asarray(xz, float).reshape(-1, 2) - (pose.x, pose.z)
    c, s = math.cos(math.radians(pose.yaw_deg)), math.sin(math.radians(pose.yaw_deg))
    return np.column_stack([c * p[:, 0] - s * p[:, 1], s * p[:, 0] + c * p[:, 1]])
