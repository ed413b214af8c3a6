"""A mapping session: photos in capture order -> the room's floor plan (``floorplan.Plan``).

Per photo: boundary hypotheses (``methods.hypothesize``), the rank-1 layout on the floor of
its level frame (``layout.from_hypothesis``), ORB features. Between photos: rotation-only
yaws of photos of one spot (``spot.rotation_yaw``), feature matches and two-photo motions
across spots (``motion.estimate``). Then ``fuse.place`` poses the photos in the level frame
of photo 0 and ``floorplan.build`` draws the plan.

Spots: photos with one spot label were taken standing at one place (the page's "new spot",
or ``findme plan --spots``); without labels, consecutive photos that share a rotation-only
yaw are one spot and every other photo starts a new one.

Units: metres, radians. Pure: images in, numbers out; no I/O. ``clock`` is injected.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from . import features, floorplan, fuse, layout, motion, planar, spot
from .camera import Camera
from .errors import FindmeError, GeometryError
from .methods import hypothesize
from .scene import Scene


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


@dataclass
class Photo:
    """One photo's per-photo results: its layout (None without a usable hypothesis, with
    the reason), scene and features."""

    camera: Camera
    height: float
    layout: layout.Layout | None
    scene: Scene | None
    features: features.Features
    reason: str | None = None


def analyse(image, camera: Camera, height: float, params: SessionParams = SessionParams()
            ) -> Photo:
    """Per-photo stage: hypotheses, rank-1 layout and scene, features."""
    hs = hypothesize(image, camera, params.method, 1)
    L, sc, why = None, None, hs.reason
    if hs.hypotheses:
        h = hs.hypotheses[0]
        try:
            L = layout.from_hypothesis(camera, height, h.polyline, h.kinds, 1)
            sc = Scene(camera, height, h.polyline, h.kinds)
        except FindmeError as e:
            L, sc, why = None, None, str(e)
    return Photo(camera, float(height), L, sc, features.detect(image, params.features), why)


def relate(photos, spots=None, params: SessionParams = SessionParams()):
    """Links (rotation-only yaws), feature matches and motions between the photos.

    Returns:
        (links, matches {(i, j): (a, b) bearings}, motions) as ``fuse.place`` takes them.
    """
    n = len(photos)
    lab = list(range(n)) if spots is None else list(spots)
    links, matches, motions = [], {}, []
    for i in range(n):
        for j in range(i + 1, n):
            same = (j == i + 1) if spots is None else lab[i] == lab[j]
            m = features.match(photos[i].features, photos[j].features, params.features)
            if same:
                r = spot.rotation_yaw(m, photos[i].camera, photos[j].camera)
                if r is not None:
                    links.append(fuse.Link(i, j, r.yaw, r.sigma))
                    continue
                if spots is not None:
                    continue
            if len(m) < 8:
                continue
            matches[(i, j)] = (planar.bearings(photos[i].camera, m.ua),
                               planar.bearings(photos[j].camera, m.ub))
            if len(m) >= params.min_motion_matches:
                mo = _motion(photos[i], photos[j], m)
                if mo is not None:
                    motions.append(fuse.Link(i, j, mo.yaw, mo.sigma_yaw, (mo.x, mo.z)))
    if spots is None:   # one spot per chain of links
        links = [k for k in links if k.j == k.i + 1]
    return links, matches, motions


def _motion(pa: Photo, pb: Photo, m):
    def lifter(p, px):
        return None if p.scene is None else (lambda idx: features.lift(p.scene, px, idx))
    try:
        return motion.estimate(m, pa.camera, pb.camera, pa.height, pb.height,
                               lifter(pa, m.ua), lifter(pb, m.ub))
    except FindmeError:
        return None


def plan(photos, spots=None, params: SessionParams = SessionParams(), clock=time.perf_counter,
         relations=None):
    """The floor plan of analysed photos (``analyse``), capture order. ``relations``: what
    ``relate`` gives for these photos, when the caller already has it (a mapper that
    relates each new photo once).

    Returns:
        (plan, placement, timing_ms).

    Raises:
        GeometryError: no photo, or no placed photo saw any floor.
    """
    if not photos:
        raise GeometryError("a plan needs at least one photo")
    t0 = clock()
    links, matches, motions = relations if relations is not None else relate(photos, spots,
                                                                              params)
    t1 = clock()
    layouts = [p.layout for p in photos]
    pl = fuse.place(layouts, links, spots, matches, motions, params.fuse)
    t2 = clock()
    notes = [pl.reasons[pl.block[i]] if not np.isfinite(pl.poses[i, 0]) else None
             for i in range(len(photos))]
    for i, p in enumerate(photos):
        if p.layout is None and notes[i] is None:
            notes[i] = f"no layout: {p.reason}"
    amb = [float(pl.ambiguity[pl.block[i]] / pl.scores[pl.block[i]])
           if pl.scores[pl.block[i]] > 0 else float("nan") for i in range(len(photos))]
    result = floorplan.build(layouts, pl.poses, params.plan, notes, amb, spot=pl.spot,
                             links=links, matches=matches,
                             focal=np.array([p.camera.fx for p in photos]))
    t3 = clock()
    return result, pl, {"relate": 1e3 * (t1 - t0), "place": 1e3 * (t2 - t1),
                        "plan": 1e3 * (t3 - t2)}
