"""Tests of the layout registration (findme_core.motion.register) and of the default motion
estimator on rendered rooms: textureless walls (no feature match at all) give the motion
from the layouts alone, exactly when the layouts are; a symmetric room gives its ambiguity as
several candidates, unless the walls' appearance tells the twins apart; and every
degenerate pair (one wall, parallel walls only, no common wall) is an explicit error."""

from __future__ import annotations

import math

import numpy as np
import pytest

from findme_core.errors import MotionError
from findme_core.motion import features, lifting, photometric as motion_photometric, register
from findme_core.motion.methods import MotionParams, estimate
from findme_core.single.layout import _simplify, from_hypothesis
from findme_core.single.scene import Scene
from findme_core.single.search import SegKind
from findme_core.synth.render import Box, Pose, Room, planar_motion, render
from tests.core.layout_rooms import exact_orientation, exact_polyline, no_matches, view_layout

L_ROOM = Room.l_shape()
L_POSES = (Pose(-1.5, -1.5, 1.45, yaw_deg=30.0, pitch_deg=25.0),
           Pose(-0.5, -1.9, 1.45, yaw_deg=10.0, pitch_deg=28.0, roll_deg=3.0))


def _layout_only(room, pa, pb, hfov=70.0, orient=True, perturb=None):
    (va, la), (vb, lb) = view_layout(room, pa, hfov=hfov), view_layout(room, pb, hfov=hfov)
    if perturb is not None:
        la, lb = perturb(va, pa), perturb(vb, pb)
    o = (exact_orientation(pa), exact_orientation(pb)) if orient else (None, None)
    return estimate(no_matches(), va.camera, vb.camera, pa.height, pb.height, None, None,
                    layouts=([la], [lb]), orientations=o)


def _err(m, pa, pb):
    x, z, yaw = planar_motion(pa, pb)
    return math.hypot(m.x - x, m.z - z), abs((math.degrees(m.yaw) - yaw + 180) % 360 - 180)


@pytest.mark.parametrize("orient", [True, False])
def test_textureless_walls_give_the_exact_motion_from_the_layouts(orient):
    m = _layout_only(L_ROOM, *L_POSES, orient=orient)
    dt, dyaw = _err(m, *L_POSES)
    assert dt < 1e-6 and dyaw < 1e-5
    assert m.n_inliers == 0 and m.inliers.shape == (0,)
    lay = m.layout
    assert lay.rms_m < 1e-6 and lay.violations == 0 and lay.samples > 50
    assert len(lay.walls) >= 2 and lay.corners      # two walls and their corner matched
    assert 0 < m.sigma_x < 0.5 and 0 < m.sigma_z < 0.5 and 0 < m.sigma_yaw < math.radians(5)


@pytest.mark.parametrize("seed", range(3))
def test_noisy_layouts_give_the_motion_within_its_sigma(seed):
    """Each straight piece of the boundary off by a pixel or so (as a hypothesis is)."""
    rng = np.random.default_rng(seed)

    def noisy(view, pose):
        poly, kinds = _simplify(*exact_polyline(view), 1.0)
        poly = poly + np.column_stack([np.zeros(len(poly)), rng.normal(0.0, 1.0, len(poly))])
        return from_hypothesis(view.camera, pose.height, poly, kinds)
    m = _layout_only(L_ROOM, *L_POSES, perturb=noisy)
    dt, dyaw = _err(m, *L_POSES)
    assert dt < 0.1 and dyaw < 1.5
    x, z, yaw = planar_motion(*L_POSES)
    assert abs(m.x - x) < 3 * m.sigma_x and abs(m.z - z) < 3 * m.sigma_z
    assert abs(math.degrees(m.yaw) - yaw) < 3 * math.degrees(m.sigma_yaw)


def test_symmetric_room_gives_the_ambiguity_as_candidates():
    """A square room: photo A sees the far wall and both far corners, photo B one corner.
    B's corner fits either of A's (a quarter turn apart) equally well, and no feature match
    tells them apart: both come out, ranked, each with its evidence."""
    pa, pb = Pose(0.0, -1.5, 1.45, 0.0, 25.0), Pose(1.2, 1.0, 1.45, 45.0, 30.0)
    m = _layout_only(Room.rectangle(5.0, 5.0), pa, pb)
    cands = [m, *m.alternatives]
    assert len(cands) >= 2
    errs = [_err(c, pa, pb) for c in cands]
    assert min(e[0] for e in errs) < 1e-6 and min(e[1] for e in errs) < 1e-5   # the truth
    yaws = sorted(math.degrees(c.yaw) for c in cands[:2])
    assert abs(yaws[1] - yaws[0] - 90.0) < 0.01                                 # and its twin
    assert all(c.layout is not None and c.layout.samples > 20 for c in cands)
    assert all(c.score >= MotionParams().alternative_ratio * m.score for c in m.alternatives)
    # the answer's 1-sigma spans its twin: a quarter turn away, nearly as likely
    assert math.degrees(m.sigma_yaw) > 30.0


def _square_room(walls: str):
    """The square room's two photos (A sees the far wall and both far corners, B one
    corner): poses, (view, layout) each, and each photo's surfaces (``photometric``) with
    its rendered image or ("blank") a uniform grey one."""
    pa, pb = Pose(0.0, -1.5, 1.45, 0.0, 25.0), Pose(1.2, 1.0, 1.45, 45.0, 30.0)
    room = Room.rectangle(5.0, 5.0)
    (va, la), (vb, lb) = view_layout(room, pa), view_layout(room, pb)
    surfaces = [motion_photometric.surface(np.full_like(v.image, 128) if walls == "blank"
                                           else v.image, v.camera, lay)
                for v, lay in ((va, la), (vb, lb))]
    return pa, pb, (va, la), (vb, lb), surfaces


@pytest.mark.parametrize("walls", ["blank", "painted"])
def test_symmetric_room_ambiguity_resolved_by_appearance_only_when_the_walls_show_it(walls):
    """The square room above with each photo's surfaces (``photometric``) and still no
    feature match: blank walls and floor say nothing, so both quarter-turn twins remain
    (sigma over 30 deg); the rendered floor and pictures on the walls look right only under
    the true motion, which then comes out alone, its 1-sigma a degree or two."""
    pa, pb, (va, la), (vb, lb), surfaces = _square_room(walls)
    m = estimate(no_matches(), va.camera, vb.camera, 1.45, 1.45, None, None,
                 layouts=([la], [lb]), orientations=(exact_orientation(pa), exact_orientation(pb)),
                 surfaces=surfaces)
    cands = [m, *m.alternatives]
    errs = [_err(c, pa, pb) for c in cands]
    assert min(e[0] for e in errs) < 1e-6 and min(e[1] for e in errs) < 1e-5   # the truth
    assert all(c.appearance[1] > 1000 for c in cands)
    if walls == "blank":
        assert len(cands) >= 2 and math.degrees(m.sigma_yaw) > 30.0
        assert all(c.appearance[0] == pytest.approx(0.0, abs=1e-6) for c in cands)
    else:
        assert len(cands) == 1 and errs[0][0] < 1e-6 and errs[0][1] < 1e-5
        assert m.appearance[0] > 0.1 and math.degrees(m.sigma_yaw) < 2.0


def test_one_wall_only_is_an_error():
    wide = Room.rectangle(14.0, 6.0)
    with pytest.raises(MotionError, match="share one wall"):
        _layout_only(wide, Pose(-0.5, 0.5, 1.45, 0.0, 35.0), Pose(0.6, 1.0, 1.45, 8.0, 38.0),
                     hfov=50.0)


def test_parallel_walls_only_is_an_error():
    corridor = Room.rectangle(2.4, 30.0)
    with pytest.raises(MotionError, match="only parallel walls"):
        _layout_only(corridor, Pose(0.2, -10.0, 1.45, 0.0, 40.0),
                     Pose(-0.3, -8.5, 1.45, 5.0, 42.0))


def test_no_common_wall_is_an_error():
    """Photo B sees only floor (the far wall is above its top border) and no match."""
    big = Room.rectangle(12.0, 12.0)
    pa, pb = Pose(0.0, -2.0, 1.45, 0.0, 25.0), Pose(0.5, -1.0, 1.45, 10.0, 60.0)
    (va, la), (vb, lb) = view_layout(big, pa), view_layout(big, pb)
    assert len(lb.walls) == 0 and (lb.kind == SegKind.OPEN).all()
    with pytest.raises(MotionError, match="share no wall"):
        estimate(no_matches(), va.camera, vb.camera, 1.45, 1.45, None, None,
                 layouts=([la], [lb]), orientations=(exact_orientation(pa), exact_orientation(pb)))
    with pytest.raises(MotionError, match="no boundary hypothesis"):
        estimate(no_matches(), va.camera, vb.camera, 1.45, 1.45, None, None,
                 layouts=([la], []), orientations=(exact_orientation(pa), None))


def test_layout_score_prefers_the_truth_and_punishes_seen_floor():
    (va, la), (vb, lb) = (view_layout(L_ROOM, p) for p in L_POSES)
    x, z, yaw = planar_motion(*L_POSES)
    yaw = math.radians(yaw)
    moves = np.array([[x, z], [x + 0.3, z], [x, z - 0.5]])
    s = register.scores(la, lb, np.full(3, yaw), moves)
    assert s[0] > s[1] and s[0] > s[2] and s[0] > 5
    a = register.agreement(la, lb, yaw, [x, z - 0.5])       # B's walls on A's floor
    assert a.violations > 0


def test_rendered_pair_with_features_and_layouts():
    """Real features (with their wrong matches) plus exact layouts: the default estimator is
    at least as close as the feature-only one."""
    room = Room.rectangle(5.0, 6.0, floor_style="carpet",
                          boxes=(Box(1.0, 1.6, 0.8, 0.5, 0.9, 20),))
    pa, pb = Pose(0.2, -1.6, 1.45, -5.0, 22.0, 2.0), Pose(0.6, -1.0, 1.45, 12.0, 25.0, -2.0)
    va, vb = (render(room, p, 640, 480, hfov_deg=70.0, seed=3, supersample=1) for p in (pa, pb))
    m = features.match(features.detect(va.image), features.detect(vb.image))
    polys = [exact_polyline(v) for v in (va, vb)]
    scenes = [Scene(v.camera, 1.45, *pk) for v, pk in zip((va, vb), polys)]
    lays = [from_hypothesis(v.camera, 1.45, *pk) for v, pk in zip((va, vb), polys)]
    lifts = [(lambda s, px: (lambda i: lifting.lift(s, px, i)))(s, px)
             for s, px in zip(scenes, (m.ua, m.ub))]
    out = {}
    for method in ("findme", "features"):
        out[method] = estimate(m, va.camera, vb.camera, 1.45, 1.45, *lifts, method,
                               layouts=([lays[0]], [lays[1]]),
                               orientations=(exact_orientation(pa), exact_orientation(pb)))
    dt, dyaw = _err(out["findme"], pa, pb)
    assert dt < 0.02 and dyaw < 0.2
    assert out["findme"].n_inliers >= 20 and out["findme"].layout.samples > 50
    assert dt <= _err(out["features"], pa, pb)[0] + 0.005


def test_prepared_photos_serve_every_motion_even_without_a_single_keypoint(monkeypatch):
    """Three photos of textureless walls (a uniform image for the features: no keypoint at
    all) prepared once each; photo B takes part in two motions; the layouts give both."""
    from types import SimpleNamespace

    from findme_core.motion import pair
    from findme_core.single.lines import detect_segments
    poses = (*L_POSES, Pose(-0.9, -1.0, 1.45, yaw_deg=0.0, pitch_deg=26.0))
    detected = []
    real = features.detect
    monkeypatch.setattr(features, "detect", lambda *a, **k: detected.append(1) or real(*a, **k))
    photos = []
    for pose in poses:
        v = render(L_ROOM, pose, 320, 240, hfov_deg=70.0, seed=1, supersample=1)
        poly, kinds = exact_polyline(v)
        blank = np.full_like(v.image, 128)
        photos.append(pair.prepare(blank, v.camera, pose.height,
                                   [SimpleNamespace(polyline=poly, kinds=kinds)],
                                   segments=detect_segments(v.image)))
    assert len(detected) == 3 and all(len(p.features) == 0 for p in photos)
    for i, j in ((0, 1), (1, 2)):
        out = pair.motion_photos(photos[i], photos[j], ("findme", "features"))
        assert isinstance(out["features"], MotionError)          # the matches alone: no
        dt, dyaw = _err(out["findme"].motion, poses[i], poses[j])
        assert dt < 0.02 and dyaw < 0.5 and out["findme"].matches == 0
    assert len(detected) == 3                                    # nothing computed again


@pytest.mark.parametrize("walls", ["blank", "painted"])
def test_a_rival_the_photos_cannot_rule_out_is_an_alternative_whatever_its_score(walls):
    """The square room's quarter-turn twins with the score rule switched off (no motion
    scores 1.01 times the best): the twin still comes out, and the answer's 1-sigma spans
    it, when neither the matches (none here) nor the photos' appearance prefers the answer
    (blank walls: both correlate 0); with painted walls the appearance rules the twin out
    and the answer stands alone. With the rival rule off too, a blank room's answer would
    claim a degree or two it does not have."""
    pa, pb, (va, la), (vb, lb), surfaces = _square_room(walls)

    def run(**p):
        return estimate(no_matches(), va.camera, vb.camera, 1.45, 1.45, None, None,
                        layouts=([la], [lb]), surfaces=surfaces,
                        orientations=(exact_orientation(pa), exact_orientation(pb)),
                        params=MotionParams(alternative_ratio=1.01, **p))
    m, off = run(), run(rival_sep_deg=180.0)
    assert not off.alternatives
    if walls == "blank":
        assert math.degrees(off.sigma_yaw) < 5.0                  # what the rule corrects
        (twin,) = m.alternatives
        turn = abs((math.degrees(twin.yaw - m.yaw) + 180) % 360 - 180)
        assert abs(turn - 90.0) < 0.5 and math.degrees(m.sigma_yaw) > 30.0
        assert min(_err(c, pa, pb)[1] for c in (m, twin)) < 1e-5   # the truth is one of them
    else:
        assert not m.alternatives and math.degrees(m.sigma_yaw) < 2.0
        assert _err(m, pa, pb)[1] < 1e-5


def test_each_turn_is_tested_as_a_rival_not_only_the_best_scoring():
    """``Registration._rivals`` on scored candidates (yaw, score): the answer at 0 deg, a half
    turn scoring best of the others, then a quarter turn, a second copy of the half turn and
    the other quarter turn. The half turn is ruled out (as when few matches agree with it);
    the quarter turns are still tested, each once, and one the photos cannot rule out is an
    alternative. Before, only the best-scoring turn was tested, so nothing was."""
    from types import SimpleNamespace

    from findme_core.motion.alternatives import MAX_RIVALS
    from findme_core.motion.estimator import Registration
    cy = np.radians([0.0, 180.0, 90.0, 178.0, -90.0, 2.0])
    total = np.array([10.0, 9.0, 8.0, 8.5, 7.0, 9.5])
    tested = []

    def judge(i, best, alts, cy_, ct, which):
        tested.append(round(math.degrees(cy_[i])))
        return () if round(math.degrees(cy_[i])) == 180 else (SimpleNamespace(yaw=cy_[i]),)
    fake = SimpleNamespace(p=MotionParams(), _rival=judge)
    best = SimpleNamespace(yaw=0.0)
    out = Registration._rivals(fake, best, (), cy, np.zeros((6, 3)), total, np.zeros(6))
    assert tested == [180, 90, -90] and len(tested) <= MAX_RIVALS
    assert [round(math.degrees(o.yaw)) for o in out] == [90, -90]
