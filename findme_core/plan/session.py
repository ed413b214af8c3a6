"""A mapping session: photos in capture order -> the room's floor plan (``floorplan.Plan``).

Per photo: boundary hypotheses (``methods.hypothesize``), the rank-1 layout on the floor of
its level frame (``layout.from_hypothesis``), ORB features. Between photos: rotation-only
yaws of photos of one spot (``spot.rotation_yaw``), feature matches and two-photo motions
across spots (``motion.estimate``). Then ``fuse.place`` poses the photos in the level frame
of photo 0 and ``floorplan.build`` draws the plan.

Spots: photos with one spot label were taken standing at one place (the page's "new spot",
or ``findme plan --spots``); without labels (``auto_spots``), a photo that shares a
rotation-only yaw with any photo of the current spot (the one before it, or an earlier one
when the photos in between were left out or the turn came round) joins it, and every other
photo starts a new one.

Units: metres, radians. Pure: images in, numbers out; no I/O. ``clock`` is injected.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from findme_core.errors import CameraError, FindmeError, GeometryError, OutlineRefused
from findme_core.geometry import planar
from findme_core.geometry.camera import Camera
from findme_core.geometry.provenance import GRAVITY_KINDS
from findme_core.motion import features, lifting, methods as motion
from findme_core.plan import consistency, find_spot, floorplan, fuse, heading, spot, walls
from findme_core.plan.pose import spread
from findme_core.plan.spot import auto_spots  # noqa: F401  (it began here)
from findme_core.single import layout
from findme_core.single.methods import hypothesize
from findme_core.single.scene import Scene


@dataclass(frozen=True)
class SessionParams:
    """Stages' parameters and the pairs worth a two-photo motion.

    Attributes:
        method: hypothesis method.
        min_motion_matches: pairs across spots with at least this many matches get a
            two-photo motion (a candidate pose).
    """

    method: str = "findme"
    min_motion_matches: int = 40
    fuse: fuse.FuseParams = field(default_factory=fuse.FuseParams)
    plan: floorplan.PlanParams = field(default_factory=floorplan.PlanParams)
    features: features.FeatureParams = field(default_factory=features.FeatureParams)
    consistency: consistency.ConsistencyParams = field(
        default_factory=consistency.ConsistencyParams)


@dataclass
class Photo:
    """One photo's per-photo results: its layout (None without a usable hypothesis, with
    the reason), scene and features; what its gravity's error is like
    (``Provenance.gravity_kind``: "exact", "sensor" or "image"), which the plan's sigmas
    must show (``PlanParams.image_gravity_models``), and its tilt's 1-sigma per axis
    (radians, ``Provenance.gravity_sigma``), which the plan's refinement marginalises in
    the photo's matches unless the gravity is "exact" (its pose model was fitted with
    gravity taken as it is); the phone's heading when it was taken
    ((radians, 1-sigma[, reference]), ``heading``; None: unknown)."""

    camera: Camera
    height: float
    layout: layout.Layout | None
    scene: Scene | None
    features: features.Features
    reason: str | None = None
    gravity: str = "exact"
    heading: tuple | None = None
    gravity_sigma: float = 0.0

    def __post_init__(self):
        if not (math.isfinite(self.gravity_sigma) and self.gravity_sigma >= 0):
            raise CameraError(f"a photo's gravity 1-sigma must be >= 0 radians, got "
                              f"{self.gravity_sigma!r}")
        if self.gravity not in GRAVITY_KINDS:
            raise CameraError(f"a photo's gravity kind must be one of {GRAVITY_KINDS}, got "
                              f"{self.gravity!r}")
        self.heading = heading.check(self.heading)


def analyse(image, camera: Camera, height: float, params: SessionParams = SessionParams(),
            feats: features.Features | None = None, gravity: str = "exact",
            gravity_sigma: float = 0.0) -> Photo:
    """Per-photo stage: hypotheses, rank-1 layout and scene, features (``feats`` when
    already detected with ``params.features``); ``gravity``, ``gravity_sigma``: the kind
    of the camera's gravity and its tilt's 1-sigma (``Photo``)."""
    hs = hypothesize(image, camera, params.method, 1, camera_height=height)
    L, sc, why = None, None, hs.reason
    if hs.hypotheses:
        h = hs.hypotheses[0]
        try:
            L = layout.from_hypothesis(camera, height, h.polyline, h.kinds, 1)
            sc = Scene(camera, height, h.polyline, h.kinds)
        except FindmeError as e:
            L, sc, why = None, None, str(e)
    return Photo(camera, float(height), L, sc,
                 feats if feats is not None else features.detect(image, params.features), why,
                 gravity=gravity, gravity_sigma=float(gravity_sigma))


class Relations(NamedTuple):
    """What ties a session's photos together, as ``fuse.place`` takes it.

    Attributes:
        links: ``fuse.Link`` rotation-only yaws between photos of one spot.
        matches: {(i, j): (a (M, 3), b (M, 3))} level-frame bearings of feature matches.
        motions: ``fuse.Link`` two-photo motions (with ``t``) between photos of two spots.
        spots: (N,) spot label per photo (given, or found by ``auto_spots``).
    """

    links: list
    matches: dict
    motions: list
    spots: list


def relate(photos, spots=None, params: SessionParams = SessionParams(), *, cache=None,
           ids=None) -> Relations:
    """Links (rotation-only yaws), feature matches and motions between the photos, and the
    spot labels (``spots``, or found by ``auto_spots`` when None).

    Args:
        cache: a dict the caller keeps between calls (a mapper that relates each new photo
            once): the matches, rotation-only yaws and motions of each pair are kept there,
            keyed by (kind, id_i, id_j). A caller that changes a photo's layout deletes the
            ("motion", ...) entries of that photo (motions lift with its scene).
        ids: (N,) a stable id per photo for ``cache`` (default: the positions).
    """
    n = len(photos)
    cache = {} if cache is None else cache
    ids = list(range(n)) if ids is None else list(ids)

    def memo(kind, i, j, make):
        key = (kind, ids[i], ids[j])
        if key not in cache:
            cache[key] = make()
        return cache[key]

    def match(i, j):
        return memo("match", i, j, lambda: features.match(photos[i].features,
                                                          photos[j].features, params.features))

    def turn(i, j):
        return memo("turn", i, j, lambda: spot.rotation_yaw(match(i, j), photos[i].camera,
                                                            photos[j].camera))

    lab, links = auto_spots(photos, match, turn) if spots is None else (list(spots), [])
    matches, motions = {}, []
    for i in range(n):
        for j in range(i + 1, n):
            m = match(i, j)
            if lab[i] == lab[j]:
                if spots is None:   # linked once, by auto_spots
                    continue
                r = turn(i, j)
                if r is not None:
                    links.append(fuse.Link(i, j, r.yaw, r.sigma))
                continue
            bear, link = _across(i, j, photos[i], photos[j], m, params, lambda: memo(
                "motion", i, j, lambda: _motion(photos[i], photos[j], m)))
            if bear is not None:
                matches[(i, j)] = bear
            if link is not None:
                motions.append(link)
    return Relations(links, matches, motions, lab)


def _across(i, j, pa: Photo, pb: Photo, m, params: SessionParams, motion_of):
    """What the matches ``m`` of photos i and j, taken at different spots, give: (their level
    bearings (a (M, 3), b (M, 3)) with 8 matches or more, else None; a ``fuse.Link`` of
    their two-photo motion (``motion_of()``: the estimate or None) with
    ``min_motion_matches``, else None)."""
    if len(m) < 8:
        return None, None
    bear = (planar.bearings(pa.camera, m.ua), planar.bearings(pb.camera, m.ub))
    mo = motion_of() if len(m) >= params.min_motion_matches else None
    return bear, None if mo is None else fuse.Link(i, j, mo.yaw, mo.sigma_yaw, (mo.x, mo.z))


def _motion(pa: Photo, pb: Photo, m):
    def lifter(p, px):
        return None if p.scene is None else (lambda idx: lifting.lift(p.scene, px, idx))
    try:
        return motion.estimate(m, pa.camera, pb.camera, pa.height, pb.height,
                               lifter(pa, m.ua), lifter(pb, m.ub))
    except FindmeError:
        return None


def relate_to(photos, new, params: SessionParams = SessionParams()):
    """Feature matches and two-photo motions between each of N photos and K new ones
    (indices N .., in the order of ``new``), and the rotation-only links between the new
    ones (taken at one place): ({(i, j): (a, b) bearings}, [``fuse.Link`` (i, j, ..., t)],
    [``fuse.Link`` (j1, j2, yaw, sigma)]), as ``find_spot.place`` takes them."""
    n, matches, motions = len(photos), {}, []
    for q, pn in enumerate(new):
        for i, p in enumerate(photos):
            m = features.match(p.features, pn.features, params.features)
            bear, link = _across(i, n + q, p, pn, m, params, lambda: _motion(p, pn, m))
            if bear is not None:
                matches[(i, n + q)] = bear
            if link is not None:
                motions.append(link)
    return matches, motions, _rotation_links(new, n, params)


def turn(photos, params: SessionParams = SessionParams()) -> tuple[np.ndarray, np.ndarray]:
    """(block (K,), rel_yaw (K,)) of K photos taken at one place: the photos joined by
    rotation-only yaws (``spot.rotation_yaw`` of every pair) and each one's yaw relative to
    its block's first photo, radians (``fuse.blocks``)."""
    return fuse.blocks(len(photos), _rotation_links(photos, 0, params))


def _rotation_links(photos, first: int, params: SessionParams) -> list:
    """``fuse.Link`` s (indices ``first`` + k) of every pair of ``photos`` with a
    rotation-only yaw (taken at one place)."""
    links = []
    for j in range(len(photos)):
        for i in range(j):
            rot = spot.rotation_yaw(features.match(photos[i].features, photos[j].features,
                                                   params.features),
                                    photos[i].camera, photos[j].camera)
            if rot is not None:
                links.append(fuse.Link(first + i, first + j, rot.yaw, rot.sigma))
    return links


def find(photos, poses, new, params: SessionParams = SessionParams()):
    """"Find me" with the session's photos: where ``new`` (one ``Photo``, or several taken
    at one place, a user turning round) was taken, given the analysed photos of a plan and
    their poses (N, 3) in its frame (``find_spot.place``). Photos with a heading of one
    reference (``Photo.heading``) keep the candidates that turn as the phone says.

    Returns:
        (poses, scores (C,)), best first: poses (C, 3) for one photo, (C, K, 3) for K.

    Raises:
        GeometryError: it cannot be placed, with the reason.
    """
    one = isinstance(new, Photo)
    group = [new] if one else list(new)
    matches, motions, links = relate_to(photos, group, params)
    cands, scores = find_spot.place([p.layout for p in photos], poses,
                                    [p.layout for p in group], links, matches, motions,
                                    params.fuse, heading.table([p.heading for p in photos]
                                                               + [p.heading for p in group]))
    return (cands[:, 0], scores) if one else (cands, scores)


def plan(photos, spots=None, params: SessionParams = SessionParams(), clock=time.perf_counter,
         relations=None):
    """The floor plan of analysed photos (``analyse``), capture order. ``relations``: what
    ``relate`` gives for these photos (``Relations``), when the caller already has it (a
    mapper that relates each new photo once); its spots then stand for ``spots``.

    Returns:
        (plan, placement, timing_ms).
    Raises:
        GeometryError: no photo, no placed photo saw any floor, or the outline leaves a
            camera outside (``consistency.cameras_outside``: the reason says how).
        OutlineRefused: the photos saw past a wall of the outline
            (``consistency.walls_seen_past``); it carries the plan, whose poses and their
            1-sigmas stand (a caller may show where the photos were taken) and whose
            outline must not be shown.
    """
    if not photos:
        raise GeometryError("a plan needs at least one photo")
    t0 = clock()
    links, matches, motions, spots = (relate(photos, spots, params) if relations is None
                                      else relations)
    t1 = clock()
    layouts = [p.layout for p in photos]
    pl = fuse.place(layouts, links, spots, matches, motions, params.fuse,
                    heading.table([p.heading for p in photos]))
    t2 = clock()
    notes = [(pl.reasons[b] if not np.isfinite(q[0]) else None) or (
        f"no layout: {p.reason}" if p.layout is None else None)
        for p, q, b in zip(photos, pl.poses, pl.block)]
    amb = [float(pl.ambiguity[b] / pl.scores[b]) if pl.scores[b] > 0 else float("nan")
           for b in pl.block]
    plan_params = params.plan.for_gravity(
        p.gravity for p, q in zip(photos, pl.poses) if np.isfinite(q[0]))
    result = floorplan.build(   # poses other poses fit alike: their 1-sigma covers them
        layouts, pl.poses, plan_params, notes, amb, spot=pl.spot, links=links,
        matches=matches, focal=np.array([p.camera.fx for p in photos]),
        spread=np.array([spread(pl.alternatives[b]) for b in pl.block]),
        tilt=np.array([0.0 if p.gravity == "exact" else p.gravity_sigma for p in photos]))
    why = consistency.cameras_outside(result, params.consistency)
    if why:        # placed wrongly as often as walls wrong: nothing of it stands
        raise GeometryError(why)
    why = consistency.walls_seen_past(result, walls.evidence(layouts, result.poses),
                                      plan_params.seen_past)
    t3 = clock()
    timing = {"relate": 1e3 * (t1 - t0), "place": 1e3 * (t2 - t1), "plan": 1e3 * (t3 - t2)}
    if why:
        raise OutlineRefused(why, result, pl, timing)
    return result, pl, timing
