"""Tests of findme_core.motion.features: detection, matching (ratio test, mutual check, grid
spreading), bad input, and lifting matched pixels to 3D under a scene."""

from __future__ import annotations

import numpy as np
import pytest

from findme_core.motion import features
from findme_core.errors import InputError
from findme_core.motion.features import FeatureParams, Lifted, detect, lift, match
from findme_core.single.scene import Scene
from findme_core.synth.render import Box, Pose, Room, render


@pytest.fixture(scope="module")
def views():
    room = Room.rectangle(5.0, 6.0, floor_style="carpet", boxes=(Box(1.0, 1.6, 0.8, 0.5, 0.9, 20),))
    poses = (Pose(0.2, -1.6, 1.45, -5.0, 22.0, 2.0), Pose(0.5, -1.2, 1.45, 8.0, 24.0, -1.0))
    return [render(room, p, 640, 480, hfov_deg=70.0, seed=3, supersample=1) for p in poses]


def _true_pixel_in_b(va, vb, ua):
    """Where the 3D point seen at A's pixels ua appears in B (exact, from the render)."""
    pc = va.points_cam[np.round(ua[:, 1]).astype(int), np.round(ua[:, 0]).astype(int)]
    world = pc.astype(float) @ va.pose.R_cam_from_world + va.pose.centre_world
    return vb.camera.project_cam((world - vb.pose.centre_world) @ vb.pose.R_cam_from_world.T)[0]


def test_detect_gives_spread_keypoints_with_descriptors(views):
    f = detect(views[0].image)
    assert 500 < len(f) <= 3000 and f.detector == "orb" and (f.width, f.height) == (640, 480)
    assert f.descriptors.shape == (len(f), 32) and f.descriptors.dtype == np.uint8
    assert f.pixels.shape == (len(f), 2) and f.sizes.shape == (len(f),)
    assert np.all((f.pixels >= 0) & (f.pixels < [640, 480]))
    # the grid spreads them: more of the 8 x 6 cells get keypoints than with the plain top-N
    cells = lambda px: len({(int(u * 8 / 640), int(v * 6 / 480)) for u, v in px})  # noqa: E731
    plain = detect(views[0].image, FeatureParams(n_features=300, grid=None))
    spread = detect(views[0].image, FeatureParams(n_features=300))
    assert cells(spread.pixels) > cells(plain.pixels)


@pytest.mark.parametrize("matcher", ["auto", "brute"])
def test_matches_are_mostly_right_and_one_to_one(views, matcher):
    va, vb = views
    m = match(detect(va.image), detect(vb.image), FeatureParams(matcher=matcher))
    assert len(m) >= 50 and m.ua.shape == m.ub.shape == (len(m), 2)
    err = np.linalg.norm(_true_pixel_in_b(va, vb, m.ua) - m.ub, axis=1)
    assert np.mean(err < 3.0) > 0.5   # the rest: wrong matches, for RANSAC to reject
    assert len(np.unique(m.ib)) == len(m) and len(np.unique(m.ia)) == len(m)   # mutual
    assert np.all(m.ratio < 0.9)


def test_a_stricter_ratio_test_keeps_a_subset(views):
    fa, fb = detect(views[0].image), detect(views[1].image)
    loose, strict = match(fa, fb), match(fa, fb, FeatureParams(ratio=0.6))
    assert 0 < len(strict) < len(loose)
    assert set(zip(strict.ia, strict.ib)) <= set(zip(loose.ia, loose.ib))


def test_lsh_matching_repeats_and_finds_most_exact_matches(views):
    """LSH (the default for ORB) is approximate; its hash tables are seeded, so the same
    photos give the same matches whatever was matched before, in any thread's history."""
    fa, fb = detect(views[0].image), detect(views[1].image)
    first = match(fa, fb)
    match(fb, fa)                                   # other work in between
    again = match(fa, fb)
    assert np.array_equal(first.ia, again.ia) and np.array_equal(first.ib, again.ib)
    exact = match(fa, fb, FeatureParams(matcher="brute"))
    common = set(zip(first.ia, first.ib)) & set(zip(exact.ia, exact.ib))
    assert len(common) >= 0.6 * len(exact)


def test_sift_works_too(views):
    p = FeatureParams(detector="sift", n_features=500, grid=None)
    fa, fb = detect(views[0].image, p), detect(views[1].image, p)
    assert fa.descriptors.shape[1] == 128 and len(match(fa, fb, p)) > 10


def test_blank_photo_has_no_features_and_no_matches(views):
    blank = np.full((480, 640, 3), 128, np.uint8)
    f = detect(blank)
    assert len(f) == 0 and f.descriptors.shape == (0, 32)
    m = match(f, detect(views[0].image))
    assert len(m) == 0 and m.n_a == 0 and m.n_b > 0


@pytest.mark.parametrize("image", [np.zeros((48, 64), np.float32), np.zeros((48, 64, 4), np.uint8),
                                   "not an image"])
def test_bad_images_are_input_errors(image):
    with pytest.raises(InputError):
        detect(image)


def test_bad_parameters_are_input_errors(views):
    with pytest.raises(InputError, match="surf"):
        FeatureParams(detector="surf")
    with pytest.raises(InputError, match="ratio"):
        FeatureParams(ratio=1.5)
    with pytest.raises(InputError, match="unknown matcher 'kd'"):
        FeatureParams(matcher="kd")
    with pytest.raises(InputError, match="binary descriptors"):
        FeatureParams(detector="sift", matcher="lsh")
    orb = detect(views[0].image)
    sift = detect(views[0].image, FeatureParams(detector="sift", n_features=100, grid=None))
    with pytest.raises(InputError, match="cannot match"):
        match(orb, sift)


def test_lift_floor_pixels_exactly_and_only_the_selected(views):
    v = views[0]
    poly = v.ground_truth_boundary_polyline()
    scene = Scene(v.camera, v.camera_height, poly[np.isfinite(poly[:, 1])])
    rows = np.argwhere(v.labels == 0)[::997][:20]                     # floor pixels (v, u)
    px = rows[:, ::-1].astype(float)
    L = lift(scene, px, np.arange(0, len(px), 2))
    assert isinstance(L, Lifted) and L.points.shape == (len(px), 3)
    chosen = np.arange(len(px)) % 2 == 0
    assert L.valid.tolist() == chosen.tolist() and L.floor[chosen].all()
    truth = v.points_cam[rows[:, 0], rows[:, 1]].astype(float) @ v.camera.R_level_from_cam.T
    assert np.allclose(L.points[chosen], truth[chosen], atol=2e-3)   # float32 render
    assert np.all(np.isinf(L.sigma[~chosen])) and np.all(L.sigma[chosen] > 0)
    assert not lift(None, px).valid.any()


def test_lift_wall_pixels_under_the_right_boundary(views):
    v = views[0]
    poly = v.ground_truth_boundary_polyline()
    scene = Scene(v.camera, v.camera_height, poly[np.isfinite(poly[:, 1])])
    rows = np.argwhere((v.labels >= 10) & (v.labels < 50))[::1999][:15]
    L = lift(scene, rows[:, ::-1].astype(float))
    truth = v.points_cam[rows[:, 0], rows[:, 1]].astype(float) @ v.camera.R_level_from_cam.T
    ok = L.valid & ~L.floor
    assert ok.mean() > 0.8
    assert np.median(np.linalg.norm(L.points[ok] - truth[ok], axis=1)) < 0.05


def test_matches_subset(views):
    m = match(detect(views[0].image), detect(views[1].image))
    s = m.subset(np.arange(3))
    assert len(s) == 3 and (s.n_a, s.n_b) == (m.n_a, m.n_b) and np.all(s.ua == m.ua[:3])
    assert features.DETECTORS == ("orb", "sift")
