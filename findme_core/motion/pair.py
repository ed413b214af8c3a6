"""Two photos -> their planar motion: the pipeline shared by ``findme motion``, ``findme
eval``, the odometry service and the benchmark.

Per photo, once (``Photo``, ``photo_of`` / ``prepare``): ORB features, the scene of the chosen
hypothesis (for lifting matched points), the layouts of its candidate hypotheses (the chosen
one first) and the room's orientation from its straight lines. A photo then takes part in
every motion it belongs to (``motion_photos``; the odometry service chains many) without
being computed again. ``motion.estimate`` gives (x, z, yaw) of photo B in photo A's level
frame (metres, radians). ``clock`` is injected (the core reads no clock itself); the default
``time.perf_counter`` only times stages.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import cv2
import numpy as np

from findme_core.motion import features, photometric as motion_photometric
from findme_core.single import layout
from findme_core.geometry.orientation import Orientation, orientation as room_orientation
from findme_core.geometry.camera import Camera
from findme_core.errors import FindmeError, HypothesisError
from findme_core.single.hypotheses import HypothesisParams
from findme_core.single.lines import detect_segments, merge_collinear
from findme_core.single.methods import WORK_SIZE, hypothesize
from findme_core.motion.methods import MotionParams, PlanarMotion, estimate
from findme_core.single.scene import Scene


@dataclass
class PairResult:
    """A motion with what produced it (counts, milliseconds per stage)."""

    motion: PlanarMotion
    matches: int
    keypoints: tuple[int, int]
    timing_ms: dict


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
            (``motion_photometric``; none without a layout: then only looked up).
        timing_ms: milliseconds per stage of its preparation.
    """

    camera: Camera
    height: float
    features: features.Features | None = None
    scene: Scene | None = None
    layouts: list = field(default_factory=list)
    orientation: Orientation | None = None
    timing_ms: dict = field(default_factory=dict)
    surface: motion_photometric.Surface | None = None


def prepare(image, camera: Camera, height: float, hypotheses=(), rank: int = 1,
            segments=None, max_layouts: int = 1,
            feature_params: features.FeatureParams = features.FeatureParams(),
            clock=time.perf_counter) -> Photo:
    """A photo ready for its motions.

    Args:
        image: (H, W, 3) BGR or (H, W) grey uint8, the size of ``camera``.
        hypotheses: ranked hypotheses (objects with ``polyline`` and ``kinds``), best first.
        rank: the chosen one (1-based); its scene lifts the matched points and its layout
            comes first; the next best ranks follow, ``max_layouts`` in all.
        segments: (N, 4) image line segments (e.g. ``HypothesisSet.lines.ends``); detected
            (LSD) when None.
    """
    t0 = clock()
    grey = features._grey(image)   # once, for the features and the surface
    f = features.detect(grey, feature_params)
    t1 = clock()
    hyps = list(hypotheses)
    order = ([rank - 1] if 1 <= rank <= len(hyps) else []) + \
        [i for i in range(len(hyps)) if i != rank - 1]
    scene, lays = None, []
    for i in order[:max_layouts]:
        h = hyps[i]
        try:
            if i == rank - 1:
                scene = Scene(camera, height, h.polyline, h.kinds)
            lays.append(layout.from_hypothesis(camera, height, h.polyline, h.kinds, i + 1))
        except FindmeError:   # e.g. a level-camera polyline crossing a tilted horizon
            continue
    if segments is None:
        segments = line_segments(image)
    o = room_orientation(segments, camera)
    surf = motion_photometric.surface(grey, camera, lays[0] if lays else None)
    t4 = clock()
    return Photo(camera, float(height), f, scene, lays, o,
                 {"features": 1e3 * (t1 - t0), "layout": 1e3 * (t4 - t1)}, surf)


def _work_scale(image) -> float:
    """The scale ``methods.hypothesize`` works at for this image (1: full size)."""
    s = min(1.0, WORK_SIZE / max(image.shape[:2]))
    return s if s < 0.95 else 1.0


def _full_size(ends, s: float):
    """Segments (N, 4) found at working scale ``s`` back in the photo's pixels."""
    return ends if s == 1.0 else (np.asarray(ends, float) + 0.5) / s - 0.5


def photo_lines(hs, image) -> np.ndarray:
    """(N, 4) the lines ``methods.hypothesize`` found in ``image`` (its ``HypothesisSet``
    ``hs``, at the working size) in the photo's pixels: what ``line_segments`` detects."""
    return _full_size(np.asarray(hs.lines.ends, float).reshape(-1, 4), _work_scale(image))


def segment_lines(segments, image) -> np.ndarray:
    """(N, 4) the merged lines of a whole-frame detection (``segments.photo_segments``, as a
    gravity estimate carries it) in the photo's pixels: what ``line_segments`` detects,
    without detecting again."""
    return _full_size(merge_collinear(segments.segs).ends, _work_scale(image))


def line_segments(image) -> np.ndarray:
    """(N, 4) the photo's merged straight lines [u1, v1, u2, v2] in its pixels, as
    ``methods.hypothesize`` finds them (same working size, detector and settings), for a
    photo whose hypotheses came without their lines (e.g. over the bus)."""
    s, p = _work_scale(image), HypothesisParams()
    if s < 1.0:
        H, W = image.shape[:2]
        image = cv2.resize(image, (round(W * s), round(H * s)), interpolation=cv2.INTER_AREA)
    segs = detect_segments(image, p.segment_method, p.min_segment_px, lsd_scale=p.lsd_scale)
    return _full_size(merge_collinear(segs).ends, s)


def photo_of(image, camera: Camera, height: float, rank: int = 1,
             hypothesis_method: str = "findme", which: str = "A", max_layouts: int = 1,
             feature_params: features.FeatureParams = features.FeatureParams(),
             clock=time.perf_counter) -> Photo:
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
                    feature_params, clock)
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
    t2 = clock()
    out = {}
    for method in methods:
        spent = [0.0]

        def lifter(scene, px):
            if scene is None:
                return None

            def lift(idx):
                s = clock()
                res = features.lift(scene, px, idx)
                spent[0] += clock() - s
                return res
            return lift

        s = clock()
        try:
            mo = estimate(m, pa.camera, pb.camera, pa.height, pb.height,
                          lifter(pa.scene, m.ua), lifter(pb.scene, m.ub), method, params,
                          layouts=(pa.layouts, pb.layouts),
                          orientations=(pa.orientation, pb.orientation),
                          surfaces=(pa.surface, pb.surface))
        except FindmeError as e:
            out[method] = e
            continue
        total = clock() - s
        out[method] = PairResult(mo, len(m), (len(pa.features), len(pb.features)), {
            "features": pa.timing_ms.get("features", 0.0) + pb.timing_ms.get("features", 0.0),
            "layout": pa.timing_ms.get("layout", 0.0) + pb.timing_ms.get("layout", 0.0),
            "matching": 1e3 * (t2 - t1), "lift": 1e3 * spent[0],
            "motion": 1e3 * (total - spent[0])})
    return out


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
