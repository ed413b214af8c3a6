"""Two photos -> their planar motion: the pipeline shared by ``findme motion``, ``findme
eval``, the odometry service and the benchmark.

Per photo, once (``Photo``, ``photo_of`` / ``prepare``): ORB features, the scene of the chosen
hypothesis (for lifting matched points), the layouts of its candidate hypotheses (the chosen
one first) and the room's orientation from its straight lines. A photo then takes part in
every motion it belongs to (``motion_photos``; the odometry service chains many) without
being computed again. ``methods.estimate`` gives (x, z, yaw) of photo B in photo A's level
frame (metres, radians). ``clock`` is injected (the core reads no clock itself); the default
``time.perf_counter`` only times stages.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace

import numpy as np

from findme_core.errors import FindmeError, HypothesisError, MotionError
from findme_core.geometry.camera import Camera
from findme_core.geometry.orientation import Orientation, orientation as room_orientation
from findme_core.geometry.provenance import INPUT_GRAVITY_SIGMA_DEG
from findme_core.motion import features, gravity_spread, lifting, pair_gravity, photometric
from findme_core.motion.methods import MotionParams, PlanarMotion, estimate
from findme_core.motion.photo_lines import line_segments, photo_lines
from findme_core.single import layout
from findme_core.single.methods import hypothesize
from findme_core.single.scene import Scene


@dataclass
class PairResult:
    """A motion with what produced it (counts, milliseconds per stage; ``gravity``: how the
    photos' gravities were checked against each other, None when the sensors gave both;
    ``photos``: (A, B) as the motion used them, an unsure one under the agreed gravity;
    ``gravity_spread``: how far the motion moved under the gravity errors of photos whose
    gravity came from their lines, already in its sigmas; None when none did)."""

    motion: PlanarMotion
    matches: int
    keypoints: tuple[int, int]
    timing_ms: dict
    gravity: pair_gravity.PairGravity | None = None
    photos: tuple = ()
    gravity_spread: gravity_spread.Spread | None = None


@dataclass
class Photo:
    """One photo's part in its motions, computed once.

    Attributes:
        camera: intrinsics and gravity; height: camera height above the floor, metres.
        features: its keypoints (None until ``with_features``).
        scene: the chosen hypothesis' scene (lifts matched points), None without one.
        layouts: ``layout.Layout`` of the candidate hypotheses, the chosen one first.
        orientation: the room's orientation from its lines, None without usable lines.
        surface: its pixels placed on the floor and walls of the chosen layout
            (``photometric``; none without a layout: then only looked up).
        timing_ms: milliseconds per stage of its preparation.
        hypotheses: ((rank, polyline, kinds), ...) its layouts came from, the chosen first
            (lifted again under a corrected gravity: ``relift``).
        segments: (N, 4) its straight lines (the orientation's).
        gravity_sigma: 1-sigma (radians) of a gravity found in the photo's own lines, which
            its motions check against the other photo's (``pair_gravity``); infinite when
            level was assumed; None for a gravity given by the phone's sensors.
        rank: the chosen hypothesis (1-based; its scene lifts the matched points).
        gravity_alternatives: ((3,) vector, ...) other vertical directions the photo's lines
            support nearly as well (with ``gravity_sigma``; ``pair_gravity.agree``).
    """

    camera: Camera
    height: float
    features: features.Features | None = None
    scene: Scene | None = None
    layouts: list = field(default_factory=list)
    orientation: Orientation | None = None
    timing_ms: dict = field(default_factory=dict)
    surface: photometric.Surface | None = None
    hypotheses: tuple = ()
    segments: np.ndarray | None = None
    gravity_sigma: float | None = None
    rank: int = 0
    gravity_alternatives: tuple = ()


def prepare(image, camera: Camera, height: float, hypotheses=(), rank: int = 1,
            segments=None, max_layouts: int = 1,
            feature_params: features.FeatureParams = features.FeatureParams(),
            clock=time.perf_counter, gravity_sigma: float | None = None,
            gravity_alternatives: tuple = ()) -> Photo:
    """A photo ready for its motions.

    Args:
        image: (H, W, 3) BGR or (H, W) grey uint8, the size of ``camera``.
        hypotheses: ranked hypotheses (objects with ``polyline`` and ``kinds``), best first.
        rank: the chosen one (1-based); its scene lifts the matched points and its layout
            comes first; the next best ranks follow, ``max_layouts`` in all.
        segments: (N, 4) image line segments (e.g. ``HypothesisSet.lines.ends``); detected
            (LSD) when None.
        gravity_sigma: 1-sigma (radians) of a gravity from the photo's own lines (checked
            against the other photo's in each motion); None when the sensors gave it;
            ``gravity_alternatives`` its alternatives ((3,) vectors).
    """
    t0 = clock()
    grey = features._grey(image)   # once, for the features and the surface
    f = features.detect(grey, feature_params)
    t1 = clock()
    hyps = list(hypotheses)
    order = ([rank - 1] if 1 <= rank <= len(hyps) else []) + \
        [i for i in range(len(hyps)) if i != rank - 1]
    chosen = tuple((i + 1, hyps[i].polyline, hyps[i].kinds) for i in order[:max_layouts])
    if segments is None:
        segments = line_segments(image)
    photo = _lifted(Photo(camera, float(height), f, hypotheses=chosen,
                          segments=np.asarray(segments, float), gravity_sigma=gravity_sigma,
                          rank=rank, gravity_alternatives=tuple(gravity_alternatives)), grey)
    photo.timing_ms.update({"features": 1e3 * (t1 - t0), "layout": 1e3 * (clock() - t1)})
    return photo


def relift(photo: Photo, gravity, gravity_sigma: float) -> Photo:
    """``photo`` under another gravity ((3,) camera frame, 1-sigma radians): its scene,
    layouts, orientation and surface lifted again from the same hypotheses (image polylines)
    and lines; its features kept."""
    return _lifted(replace(photo, camera=photo.camera.with_gravity(gravity),
                           gravity_sigma=gravity_sigma, gravity_alternatives=(),
                           timing_ms=dict(photo.timing_ms)), surf=photo.surface)


def _lifted(photo: Photo, grey=None, surf=None) -> Photo:
    """``photo`` with the scene of its chosen ``rank``, the layouts of its ``hypotheses``,
    its orientation and surface under its camera (from ``grey``, else ``surf``'s
    thumbnail)."""
    camera, scene, lays = photo.camera, None, []
    for r, poly, kinds in photo.hypotheses:
        try:
            if r == photo.rank:
                scene = Scene(camera, photo.height, poly, kinds)
            lays.append(layout.from_hypothesis(camera, photo.height, poly, kinds, r))
        except FindmeError:   # e.g. a level-camera polyline crossing a tilted horizon
            continue
    o = room_orientation(photo.segments, camera)
    top = lays[0] if lays else None
    sf = (photometric.surface(grey, camera, top) if surf is None
          else photometric.replaced(surf, camera, top))
    return replace(photo, scene=scene, layouts=lays, orientation=o, surface=sf)


def photo_of(image, camera: Camera, height: float, rank: int = 1,
             hypothesis_method: str = "findme", which: str = "A", max_layouts: int = 1,
             feature_params: features.FeatureParams = features.FeatureParams(),
             clock=time.perf_counter, gravity_sigma: float | None = None,
             gravity_alternatives: tuple = ()) -> Photo:
    """``prepare`` with the photo's own hypotheses (``methods.hypothesize``, timed as
    "hypotheses"); a rank beyond the hypotheses found is a bad input (HypothesisError)."""
    t0 = clock()
    hs = hypothesize(image, camera, hypothesis_method, max(rank, max_layouts, 1),
                     camera_height=height)
    ms = 1e3 * (clock() - t0)
    if rank < 1 or rank > max(1, len(hs.hypotheses)):
        raise HypothesisError(f"hypothesis {rank} of photo {which} does not exist: it has "
                              f"{len(hs.hypotheses)} hypotheses"
                              + (f" ({hs.reason})" if hs.reason else ""))
    photo = prepare(image, camera, height, hs.hypotheses, rank,
                    photo_lines(hs, image), max_layouts,
                    feature_params, clock, gravity_sigma, gravity_alternatives)
    photo.timing_ms["hypotheses"] = ms
    return photo


def scene_of(image, camera: Camera, height: float, rank: int = 1,
             hypothesis_method: str = "findme", which: str = "A", clock=time.perf_counter):
    """(Scene of the photo under its ``rank``-th hypothesis, milliseconds). None when the
    photo has no hypothesis at all (the motion then says whether it can do without); a rank
    beyond the hypotheses found is a bad input (HypothesisError)."""
    t0 = clock()
    # the first ``rank`` hypotheses do not depend on how many more are asked for (greedy
    # duplicate suppression keeps them in order): build no more than needed
    hs = hypothesize(image, camera, hypothesis_method, rank if rank >= 1 else 10,
                     camera_height=height)
    ms = 1e3 * (clock() - t0)
    if rank < 1 or rank > max(1, len(hs.hypotheses)):
        raise HypothesisError(f"hypothesis {rank} of photo {which} does not exist: it has "
                              f"{len(hs.hypotheses)} hypotheses"
                              + (f" ({hs.reason})" if hs.reason else ""))
    if not hs.hypotheses:
        return None, ms
    h = hs.hypotheses[rank - 1]
    return Scene(camera, height, h.polyline, h.kinds), ms


def motion_photos(pa: Photo, pb: Photo, methods=("findme",),
                  feature_params: features.FeatureParams = features.FeatureParams(),
                  params: MotionParams = MotionParams(), clock=time.perf_counter) -> dict:
    """Matches of two prepared photos and the motion by each method of ``methods``.

    Returns {method: PairResult or the FindmeError raised}; errors of the matching stage
    are raised (they concern every method)."""
    t1 = clock()
    m = features.match(pa.features, pb.features, feature_params)
    pa, pb, pg = agreed_gravity(pa, pb, m)
    t2 = clock()
    out = {}
    for method in methods:
        spent = [0.0]
        s = clock()
        try:
            mo = _estimate(m, pa, pb, method, params, clock, spent)
        except FindmeError as e:
            out[method] = e
            continue
        total, lift = clock() - s, spent[0]
        mo, sp = _gravity_spread(m, pa, pb, mo, method, params, clock, spent)
        timing = {
            "features": pa.timing_ms.get("features", 0.0) + pb.timing_ms.get("features", 0.0),
            "layout": pa.timing_ms.get("layout", 0.0) + pb.timing_ms.get("layout", 0.0),
            "matching": 1e3 * (t2 - t1), "lift": 1e3 * lift, "motion": 1e3 * (total - lift)}
        if sp is not None:
            timing["gravity_tilts"] = 1e3 * (clock() - s - total)
        out[method] = PairResult(mo, len(m), (len(pa.features), len(pb.features)), timing, pg,
                                 (pa, pb), sp)
    return out


def _estimate(m, pa: Photo, pb: Photo, method: str, params: MotionParams, clock, spent):
    """The motion of two prepared photos by ``method`` (the time spent lifting added to
    ``spent[0]``, seconds)."""

    def lifter(scene, px):
        if scene is None:
            return None

        def lift(idx):
            s = clock()
            res = lifting.lift(scene, px, idx)
            spent[0] += clock() - s
            return res
        return lift

    return estimate(m, pa.camera, pb.camera, pa.height, pb.height,
                    lifter(pa.scene, m.ua), lifter(pb.scene, m.ub), method, params,
                    layouts=(pa.layouts, pb.layouts),
                    orientations=(pa.orientation, pb.orientation),
                    surfaces=(pa.surface, pb.surface))


def _gravity_spread(m, pa: Photo, pb: Photo, mo: PlanarMotion, method: str,
                    params: MotionParams, clock, spent):
    """(``mo`` widened by its photos' gravity errors, ``gravity_spread.Spread`` or None when
    no photo's gravity came from its lines): ``gravity_spread``."""
    photos = (pa, pb)

    def under(i, axis, angle):
        p = photos[i]
        try:
            q = relift(p, gravity_spread.tilted(p.camera, axis, angle), p.gravity_sigma)
            return _estimate(m, *((q, pb) if i == 0 else (pa, q)), method, params, clock, spent)
        except FindmeError:
            return None

    sp = gravity_spread.spread(mo, (pa.gravity_sigma, pb.gravity_sigma), under)
    if not sp.tilts:
        return mo, None
    return gravity_spread.widened(mo, sp), sp


def agreed_gravity(pa: Photo, pb: Photo, m: features.Matches,
                   params: pair_gravity.PairGravityParams = pair_gravity.PairGravityParams()):
    """(A, B, ``pair_gravity.PairGravity`` or None): when a photo's gravity from its own
    lines is unsure, the two photos' gravities checked against each other through their
    matches and, where they agree, the unsure photo lifted again under the combined gravity;
    None (the photos as they are) when neither photo's gravity is unsure.

    Raises:
        MotionError: two gravities from the photos' lines disagree beyond their sigmas: one
            is wrong, the pair cannot tell which, and a motion lifted on it would be too.
    """
    given = math.radians(INPUT_GRAVITY_SIGMA_DEG)
    sa, sb = (given if p.gravity_sigma is None else max(p.gravity_sigma, 1e-6)
              for p in (pa, pb))
    if not any(p.gravity_sigma is not None and pair_gravity.unsure(s, params)
               for p, s in ((pa, sa), (pb, sb))):
        return pa, pb, None
    pg = pair_gravity.agree(m, pa.camera, pb.camera, sa, sb, params,
                            (pa.gravity_alternatives, pb.gravity_alternatives),
                            (pa.gravity_sigma is None, pb.gravity_sigma is None))
    if pg.status == "disagree":
        raise MotionError(f"the photos disagree on which way is down: {pg.reason}, and the "
                          "pair cannot tell which; a motion lifted on it would be wrong (give "
                          "the phone's gravity)")
    if pg.status != "agreed":
        return pa, pb, pg
    return (pa if pg.sigma_a == sa else relift(pa, pg.gravity_a, pg.sigma_a),
            pb if pg.sigma_b == sb else relift(pb, pg.gravity_b, pg.sigma_b), pg)


def motion_pair(image_a, image_b, cam_a: Camera, cam_b: Camera, scene_a, scene_b,
                h_a: float, h_b: float, methods=("findme",),
                feature_params: features.FeatureParams = features.FeatureParams(),
                params: MotionParams = MotionParams(), clock=time.perf_counter) -> dict:
    """Features, matches and the motion by each method of ``methods``, from the images and
    each photo's chosen scene (its layout is the only one; the orientations come from lines
    detected here). ``motion_photos`` reuses prepared photos instead.

    Returns {method: PairResult or the FindmeError raised}; errors of the features stage
    are raised (they concern every method)."""
    photos = []
    for image, cam, scene, h in ((image_a, cam_a, scene_a, h_a), (image_b, cam_b, scene_b, h_b)):
        hyps = [] if scene is None else [_Hyp(scene.polyline, scene.kinds)]
        photos.append(prepare(image, cam, h, hyps, 1, None, 1, feature_params, clock))
    return motion_photos(*photos, methods, feature_params, params, clock)


@dataclass(frozen=True)
class _Hyp:
    polyline: object
    kinds: object
