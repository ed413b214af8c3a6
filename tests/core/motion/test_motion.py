"""Tests of findme_core.motion.methods: minimal solvers, the three estimators on exact synthetic
correspondences (exact motion), with outliers and noise (robust, honest sigma), a rendered
room through the whole pipeline, and every degenerate case."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from findme_core.errors import InputError, MotionError
from findme_core.geometry.camera import Camera
from findme_core.geometry.planar import kabsch_2d, rot_y, solve_gravity_3pt, solve_planar_2pt
from findme_core.motion import features, lifting
from findme_core.motion.features import Matches
from findme_core.motion.lifting import Lifted
from findme_core.motion.estimator import Registration
from findme_core.motion.methods import MotionParams, estimate
from findme_core.single.scene import Scene
from findme_core.synth.render import Box, Pose, Room, planar_motion, render

ROOM = Room.rectangle(6.0, 7.0)


def _bearings(rng, n, t, yaw):
    """Unit bearings (a in A, b in B) of n random points seen from both (level frames)."""
    X = rng.uniform([-3, -1, 2], [3, 1.5, 8], (n, 3))
    XB = (X - t) @ rot_y(yaw)                       # R^T (X - t)
    return (X / np.linalg.norm(X, axis=1, keepdims=True),
            XB / np.linalg.norm(XB, axis=1, keepdims=True))


@pytest.mark.parametrize("seed", range(5))
def test_planar_two_point_solver_is_exact(seed):
    rng = np.random.default_rng(seed)
    yaw, t = rng.uniform(-1, 1), np.array([rng.normal(), 0.0, rng.normal()])
    a, b = _bearings(rng, 2, t, yaw)
    yaws, ts, src = solve_planar_2pt(a[None], b[None])
    i = int(np.argmin(np.abs(yaws - yaw)))
    assert yaws[i] == pytest.approx(yaw, abs=1e-9) and (src == 0).all()
    assert abs(abs(ts[i] @ t / np.linalg.norm(t)) - 1.0) < 1e-9      # up to sign


@pytest.mark.parametrize("seed", range(5))
def test_gravity_three_point_solver_is_exact_with_vertical_motion(seed):
    rng = np.random.default_rng(seed)
    yaw, t = rng.uniform(-1, 1), rng.normal(size=3) * [1.0, 0.4, 1.0]
    a, b = _bearings(rng, 3, t, yaw)
    yaws, ts, _ = solve_gravity_3pt(a[None], b[None])
    i = int(np.argmin(np.abs(yaws - yaw)))
    assert yaws[i] == pytest.approx(yaw, abs=1e-8)
    assert abs(abs(ts[i] @ t / np.linalg.norm(t)) - 1.0) < 1e-8


def test_kabsch_2d_is_exact():
    rng = np.random.default_rng(3)
    B = rng.uniform(-3, 3, (6, 2))
    yaw, t = 0.7, np.array([0.4, -1.2])
    c, s = math.cos(yaw), math.sin(yaw)
    A = np.column_stack([c * B[:, 0] + s * B[:, 1], -s * B[:, 0] + c * B[:, 1]]) + t
    y2, t2 = kabsch_2d(A, B, rng.uniform(0.5, 2, 6))
    assert y2 == pytest.approx(yaw, abs=1e-12) and np.allclose(t2, t, atol=1e-12)


# ---------------------------------------------------------------------------- exact scenes
def _scene_points(rng, n_floor=150, n_wall=150):
    """World points on the floor and on the walls of ROOM."""
    P = ROOM.floor_polygon
    fl = np.column_stack([rng.uniform(-2.9, 2.9, n_floor), np.zeros(n_floor),
                          rng.uniform(-3.4, 3.4, n_floor)])
    walls = []
    for _ in range(n_wall):
        i = rng.integers(len(P))
        p = P[i] + rng.uniform(0.05, 0.95) * (P[(i + 1) % len(P)] - P[i])
        walls.append((p[0], -rng.uniform(0.05, 2.3), p[1]))
    return np.vstack([fl, walls]), np.r_[np.ones(n_floor, bool), np.zeros(n_wall, bool)]


def exact_pair(pose_a: Pose, pose_b: Pose, seed=0, hfov=70.0, sigma=0.01):
    """Matches of points seen by both cameras, and lifters giving their exact 3D (level
    frames) with ``sigma`` metres, as ``features.lift`` would for a perfect hypothesis."""
    rng = np.random.default_rng(seed)
    X, on_floor = _scene_points(rng)
    cams, px, lev = [], [], []
    for pose in (pose_a, pose_b):
        cam = Camera.from_hfov(hfov, 640, 480, gravity=pose.gravity_cam)
        pc = (X - pose.centre_world) @ pose.R_cam_from_world.T
        uv, front = cam.project_cam(pc)
        ok = front & (uv[:, 0] > 0) & (uv[:, 0] < 639) & (uv[:, 1] > 0) & (uv[:, 1] < 479)
        cams.append(cam), px.append((uv, ok)), lev.append((X - pose.centre_world)
                                                          @ pose.R_level_from_world.T)
    keep = px[0][1] & px[1][1]
    n = int(keep.sum())
    m = Matches(px[0][0][keep], px[1][0][keep], np.arange(n), np.arange(n),
                np.linspace(0.3, 0.8, n), n, n)

    def lifter(P):
        def lift(idx):
            out = Lifted.empty(n)
            out.points[idx], out.sigma[idx], out.floor[idx] = P[idx], sigma, on_floor[keep][idx]
            return out
        return lift
    return m, cams, lifter(lev[0][keep]), lifter(lev[1][keep])


def _check(r, pose_a, pose_b, tol_m, tol_deg):
    x, z, yaw = planar_motion(pose_a, pose_b)
    assert r.x == pytest.approx(x, abs=tol_m) and r.z == pytest.approx(z, abs=tol_m)
    assert math.degrees(r.yaw) == pytest.approx(yaw, abs=tol_deg)


POSES = [  # (A, B): level, tilted phone-like, sideways, and different heights (3-point)
    (Pose(0.0, -1.5, 1.4, 10.0), Pose(0.6, -0.4, 1.4, -15.0)),
    (Pose(-0.5, -2.0, 1.45, 5.0, 25.0, 4.0), Pose(0.4, -1.2, 1.45, 30.0, 18.0, -3.0)),
    (Pose(-1.0, -2.5, 1.5, 0.0, 10.0), Pose(0.2, -2.4, 1.5, -5.0, 12.0)),
    (Pose(0.0, -1.5, 1.4, 0.0, 20.0), Pose(0.5, -0.5, 1.25, 20.0, 15.0, 2.0)),
]


# the fit's own covariance, without the model errors the defaults add for real photos
FIT_ONLY = MotionParams(scale_sigma=0.0, direction_sigma_deg=0.0, yaw_sigma_deg=0.0,
                        findme_scale_sigma=0.0, findme_direction_sigma_deg=0.0,
                        findme_yaw_sigma_deg=0.0, findme_position_sigma_m=0.0)


@pytest.mark.parametrize("method", ["findme", "features", "lifted"])
@pytest.mark.parametrize("poses", POSES)
def test_estimators_are_exact_on_noise_free_points(method, poses):
    m, (ca, cb), la, lb = exact_pair(*poses)
    r = estimate(m, ca, cb, poses[0].height, poses[1].height, la, lb, method, FIT_ONLY)
    _check(r, *poses, 1e-6, 1e-5)
    assert r.n_inliers == len(m) if method == "findme" else r.n_inliers >= 2
    # a-priori noise (one pixel, the points' sigma) even when the data happen to be exact;
    # the lifted estimator has only the points' sigma (floor: eq. 2 with a 1 deg gravity error)
    lim_m, lim_deg = (0.1, 1.0) if method == "findme" else (0.3, 5.0)
    assert 0 < r.sigma_x < lim_m and 0 < r.sigma_z < lim_m
    assert 0 < r.sigma_yaw < math.radians(lim_deg)


def test_findme_is_exact_for_pure_rotation():
    pa, pb = Pose(0.0, -1.5, 1.4, 0.0, 15.0), Pose(0.0, -1.5, 1.4, 25.0, 15.0)
    m, (ca, cb), la, lb = exact_pair(pa, pb)
    r = estimate(m, ca, cb, 1.4, 1.4, la, lb)
    _check(r, pa, pb, 1e-6, 1e-5)


def test_a_distance_the_depths_do_not_fix_is_refused():
    """Lifted depths known to 200 % (a far wall under an uncertain gravity): the 1-sigma of
    B's position exceeds the distance and the camera height, so no distance is stated (the
    same photos with depths known to 5 % are answered). A turn on the spot keeps its answer
    with such depths: its position is known to within the camera height."""
    m, (ca, cb), la, lb = exact_pair(*POSES[0])
    r = estimate(m, ca, cb, 1.4, 1.4, _with_rel(la, 0.05), _with_rel(lb, 0.05))
    _check(r, *POSES[0], 0.01, 0.1)
    with pytest.raises(MotionError, match="do not fix how far apart") as e:
        estimate(m, ca, cb, 1.4, 1.4, _with_rel(la, 2.0), _with_rel(lb, 2.0))
    assert "the camera height (1.40, same unit)" in str(e.value)
    pa, pb = Pose(0.0, -1.5, 1.4, 0.0, 15.0), Pose(0.02, -1.5, 1.4, 25.0, 15.0)
    m, (ca, cb), la, lb = exact_pair(pa, pb)
    r = estimate(m, ca, cb, 1.4, 1.4, _with_rel(la, 2.0), _with_rel(lb, 2.0))
    assert math.hypot(r.sigma_x, r.sigma_z) > math.hypot(r.x, r.z)
    _check(r, pa, pb, 0.05, 0.1)


def test_paper_estimator_is_exact_only_without_translation():
    """Eq. 5 averages bearing differences, which equal the yaw only for a pure rotation;
    with a translation the bearings also differ by the parallax (why it is not the default)."""
    pa, pb = Pose(0.0, -1.5, 1.4, 0.0, 15.0), Pose(0.0, -1.5, 1.4, 25.0, 15.0)
    m, (ca, cb), la, lb = exact_pair(pa, pb)
    _check(estimate(m, ca, cb, 1.4, 1.4, la, lb, "paper"), pa, pb, 1e-6, 1e-5)
    pa, pb = POSES[0]
    m, (ca, cb), la, lb = exact_pair(pa, pb)
    r = estimate(m, ca, cb, 1.4, 1.4, la, lb, "paper")
    assert abs(math.degrees(r.yaw) - planar_motion(pa, pb)[2]) > 1.0


@pytest.mark.parametrize("method", ["findme", "lifted"])
def test_estimators_are_robust_to_outliers(method):
    pa, pb = POSES[1]
    m, (ca, cb), la, lb = exact_pair(pa, pb, seed=4)
    rng = np.random.default_rng(9)
    bad = rng.random(len(m)) < 0.35                   # 35 % wrong matches
    ub = m.ub.copy()
    ub[bad] = rng.uniform([0, 0], [639, 479], (bad.sum(), 2))
    m2 = Matches(m.ua, ub, m.ia, m.ib, m.ratio, m.n_a, m.n_b)

    def spoil(lift, pts_from):  # wrong matches also get the 3D of another point
        def out(idx):
            L = lift(idx)
            L.points[bad] = pts_from(L.points)[bad]
            return L
        return out
    lb2 = spoil(lb, lambda P: np.roll(P, 7, axis=0))
    r = estimate(m2, ca, cb, 1.45, 1.45, la, lb2, method)
    if method == "findme":   # the wrong matches are off their epipolar lines: all rejected
        _check(r, pa, pb, 1e-3, 0.02)
        assert np.mean(r.inliers[bad]) < 0.1 and np.mean(r.inliers[~bad]) > 0.8
    else:   # 3-sigma gates on the floor (sigma 1 cm + the gravity error) let a few through
        _check(r, pa, pb, 0.01, 0.3)
        assert np.mean(r.inliers[bad]) < 0.5 and np.mean(r.inliers[~bad]) > 0.8


def test_sigma_covers_the_error_with_noisy_pixels():
    pa, pb = POSES[1]
    m, (ca, cb), la, lb = exact_pair(pa, pb, seed=5, sigma=0.03)
    rng = np.random.default_rng(1)
    m2 = Matches(m.ua + rng.normal(0, 0.7, m.ua.shape), m.ub + rng.normal(0, 0.7, m.ub.shape),
                 m.ia, m.ib, m.ratio, m.n_a, m.n_b)

    def noisy(lift):
        def out(idx):
            L = lift(idx)
            return Lifted(L.points * (1 + rng.normal(0, 0.01, (len(L.points), 1))), L.sigma, L.floor)
        return out
    r = estimate(m2, ca, cb, 1.45, 1.45, noisy(la), noisy(lb), params=FIT_ONLY)
    x, z, yaw = planar_motion(pa, pb)
    assert 0 < r.sigma_x < 0.05 and 0 < r.sigma_z < 0.05 and 0 < r.sigma_yaw < math.radians(1)
    assert abs(r.x - x) < 4 * r.sigma_x + 0.01 and abs(r.z - z) < 4 * r.sigma_z + 0.01
    assert abs(math.degrees(r.yaw) - yaw) < math.degrees(4 * r.sigma_yaw) + 0.1


@pytest.mark.parametrize("method", ["findme", "features", "lifted", "paper"])
def test_model_errors_are_added_along_and_across_the_baseline(method):
    """Defaults = the fit's covariance + (scale_sigma * baseline)^2 along the baseline,
    (direction_sigma * baseline)^2 across it, position_sigma^2 on x and z and yaw_sigma^2
    on the yaw."""
    poses = POSES[1]
    m, (ca, cb), la, lb = exact_pair(*poses)
    p = MotionParams()
    fit = estimate(m, ca, cb, 1.45, 1.45, la, lb, method, FIT_ONLY)
    full = estimate(m, ca, cb, 1.45, 1.45, la, lb, method, p)
    assert (full.x, full.z, full.yaw) == (fit.x, fit.z, fit.yaw)
    base = math.hypot(fit.x, fit.z)
    ux, uz = fit.x / base, fit.z / base
    scale, direction_deg, yaw_deg, position_m = p.model_errors(method)
    along, across = scale * base, math.radians(direction_deg) * base
    assert full.sigma_x ** 2 == pytest.approx(fit.sigma_x ** 2 + (along * ux) ** 2
                                              + (across * uz) ** 2 + position_m ** 2)
    assert full.sigma_z ** 2 == pytest.approx(fit.sigma_z ** 2 + (along * uz) ** 2
                                              + (across * ux) ** 2 + position_m ** 2)
    assert full.sigma_yaw == pytest.approx(math.hypot(fit.sigma_yaw, math.radians(yaw_deg)))


# ---------------------------------------------------------------------------- rendered pair
@pytest.fixture(scope="module")
def rendered_pair():
    room = Room.rectangle(5.0, 6.0, floor_style="carpet", boxes=(Box(1.0, 1.6, 0.8, 0.5, 0.9, 20),))
    pa = Pose(0.2, -1.6, 1.45, -5.0, 22.0, 2.0)
    pb = Pose(0.6, -1.0, 1.45, 12.0, 25.0, -2.0)
    return [render(room, p, 640, 480, hfov_deg=70.0, seed=3, supersample=1) for p in (pa, pb)]


def test_rendered_pair_through_the_pipeline(rendered_pair):
    """Real features (with their wrong matches) and the exact boundary as hypothesis."""
    va, vb = rendered_pair
    fa, fb = features.detect(va.image), features.detect(vb.image)
    m = features.match(fa, fb)
    scenes = [Scene(v.camera, v.camera_height, _boundary(v)) for v in (va, vb)]
    lifts = [(lambda s, px: (lambda i: lifting.lift(s, px, i)))(s, px)
             for s, px in zip(scenes, (m.ua, m.ub))]
    for method, tol_m, tol_deg in (("findme", 0.03, 0.3), ("lifted", 0.08, 1.5)):
        r = estimate(m, va.camera, vb.camera, 1.45, 1.45, *lifts, method)
        _check(r, va.pose, vb.pose, tol_m, tol_deg)
        assert r.n_inliers >= 20 and r.n_scale >= 6


def _boundary(view):
    """The exact ground-wall boundary as a polyline (NaN columns dropped)."""
    poly = view.ground_truth_boundary_polyline()
    return poly[np.isfinite(poly[:, 1])]


# ---------------------------------------------------------------------------- degenerate input
def test_too_few_matches_is_an_error():
    m, (ca, cb), la, lb = exact_pair(*POSES[0])
    few = m.subset(np.arange(5))
    with pytest.raises(MotionError, match=r"only 4 distinct feature matches .*plus 1 copies"):
        estimate(few, ca, cb, 1.4, 1.4, la, lb)


def test_identical_photos_are_an_error(rendered_pair):
    v = rendered_pair[0]
    f = features.detect(v.image)
    m = features.match(f, f)
    with pytest.raises(MotionError, match="identical"):
        estimate(m, v.camera, v.camera, 1.45, 1.45, None, None)


def test_no_common_view_is_an_error():
    m, (ca, cb), la, lb = exact_pair(*POSES[0])
    rng = np.random.default_rng(2)
    junk = Matches(rng.uniform([0, 0], [639, 479], m.ua.shape),
                   rng.uniform([0, 0], [639, 479], m.ub.shape), m.ia, m.ib, m.ratio, m.n_a, m.n_b)
    with pytest.raises(MotionError, match="no common view"):
        estimate(junk, ca, cb, 1.4, 1.4, la, lb, params=MotionParams(min_inliers=20))


def test_no_usable_hypothesis_is_an_error():
    m, (ca, cb), _, _ = exact_pair(*POSES[0])
    with pytest.raises(MotionError, match="floor or on a chosen wall"):
        estimate(m, ca, cb, 1.4, 1.4, None, None)
    with pytest.raises(MotionError, match="3D point in both photos"):
        estimate(m, ca, cb, 1.4, 1.4, None, None, "paper")
    with pytest.raises(MotionError, match="3D point in both photos"):
        estimate(m, ca, cb, 1.4, 1.4, None, None, "lifted")


def test_one_photo_without_hypothesis_still_works_for_the_default():
    m, (ca, cb), la, _ = exact_pair(*POSES[1])
    r = estimate(m, ca, cb, 1.45, 1.45, la, None)
    _check(r, *POSES[1], 1e-5, 1e-4)


def test_unknown_method_is_an_input_error():
    m, (ca, cb), la, lb = exact_pair(*POSES[0])
    with pytest.raises(InputError, match="unknown motion method"):
        estimate(m, ca, cb, 1.4, 1.4, la, lb, "surf")


def test_results_are_reproducible():
    m, (ca, cb), la, lb = exact_pair(*POSES[1])
    r1, r2 = (estimate(m, ca, cb, 1.45, 1.45, la, lb) for _ in range(2))
    assert (r1.x, r1.z, r1.yaw) == (r2.x, r2.z, r2.yaw)


def _with_rel(lift, s):
    """``lift`` with every lifted point's 1-sigma ``s`` times its distance."""
    def out(idx):
        L = lift(idx)
        return Lifted(L.points, s * np.linalg.norm(L.points, axis=1), L.floor)
    return out


def test_the_length_keeps_the_error_it_shares_with_the_lifted_depths():
    """Points lifted with a relative sigma s: however many, the baseline's length is not
    known better than the depths' common error (s / sqrt 2 with both photos' points): it is
    added along the baseline, so each of sigma_x, sigma_z holds at least its share."""
    poses = POSES[0]
    m, (ca, cb), la, lb = exact_pair(*poses)
    assert len(m) > 30
    got = {}
    for s in (0.05, 0.005):
        r = estimate(m, ca, cb, 1.4, 1.4, _with_rel(la, s), _with_rel(lb, s), params=FIT_ONLY)
        base = math.hypot(r.x, r.z)
        share = s / math.sqrt(2) * base
        assert r.sigma_x >= share * abs(r.x) / base - 1e-9
        assert r.sigma_z >= share * abs(r.z) / base - 1e-9
        got[s] = math.hypot(r.sigma_x, r.sigma_z)
    assert got[0.05] > got[0.005]


def test_the_distance_evidence_is_the_score_less_what_every_distance_shares():
    """``Fit.scale_score`` (what ``alternatives.along`` weighs) is the score less the epipolar
    and orientation terms, which see only the yaw and the baseline's direction: along the
    true direction the two differ by one constant. Photo B's points lifted twice as far (a
    wall taken 1 m behind the true one) make a second distance, 2x, score alike."""
    poses = POSES[0]
    m, (ca, cb), la, lb = exact_pair(*poses)
    x, z, yaw = planar_motion(*poses)
    yaw = math.radians(yaw)

    def far(lift):
        def out(idx):
            L = lift(idx)
            return Lifted(L.points * 2.0, L.sigma * 2.0, L.floor)
        return out
    for lift_b, peaks in ((lb, (1.0,)), (far(lb), (1.0, 2.0))):
        reg = Registration(m, ca, cb, 1.4, 1.4, la, lift_b, ([], []), (None, None),
                           MotionParams())
        reg.run()
        s = np.array([0.5, 1.0, 1.5, 2.0, 3.0])
        t3 = np.column_stack([s * x, np.zeros(len(s)), s * z])
        total, part = reg.fit.score(np.full(len(s), yaw), t3)[0], reg.fit.scale_score(
            np.full(len(s), yaw), t3)
        assert np.ptp(total - part) == pytest.approx(0.0, abs=1e-9)
        # every match agrees with the direction at any distance: that part is left out
        assert (total - part)[0] > 0.5 * len(m) and part.max() > 10.0
        # the distances whose lifted points agree score high, the others about nothing
        high = {float(v) for v in s[part > 0.5 * part.max()]}
        assert high == set(peaks)


def test_a_second_distance_the_lifted_points_support_is_an_alternative():
    """Photo B's points lifted twice as far: they put B twice as far along the same way as
    photo A's points do. With only the best candidate refined, the other distance comes from
    ``alternatives.along`` with its own lifted points and the 1-sigma spans both; without it
    (scale_ratio above 1) the answer is stated to centimetres."""
    poses = POSES[0]
    m, (ca, cb), la, lb = exact_pair(*poses)
    x, z, _ = planar_motion(*poses)

    def far(lift):
        def out(idx):
            L = lift(idx)
            return Lifted(L.points * 2.0, L.sigma * 2.0, L.floor)
        return out
    one = replace(MotionParams(), refine_top=1)
    r = estimate(m, ca, cb, 1.4, 1.4, la, far(lb), "findme", one)
    assert math.hypot(r.x, r.z) == pytest.approx(math.hypot(x, z), rel=1e-6)
    (alt,) = r.alternatives
    assert math.hypot(alt.x, alt.z) == pytest.approx(2.0 * math.hypot(x, z), rel=0.02)
    assert alt.n_scale > 0 and alt.score > 0.5 * r.score
    # the other distance lies within 2 sigma of the answer on each axis
    assert abs(alt.x - r.x) < 2.0 * r.sigma_x and abs(alt.z - r.z) < 2.0 * r.sigma_z
    tight = estimate(m, ca, cb, 1.4, 1.4, la, far(lb), "findme", replace(one, scale_ratio=1.1))
    assert tight.alternatives == () and math.hypot(tight.sigma_x, tight.sigma_z) < 0.1
