"""Tests of findme_core.synth.render: pose conventions, exact ground truth, rendering behaviour."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from findme_core.geometry.camera import Camera
from findme_core.errors import GeometryError, InputError
from findme_core.synth.render import (BOX_BASE, CEILING, FLOOR, WALL_BASE, Box, Pose, Room,
                                      planar_motion, relative_transform, render)

PITCH_ROLL = [(0, 0), (10, 0), (0, 10), (-15, 7), (25, -12), (40, 30), (-30, -45), (60, 80)]
BOX = Box(1.2, 1.3, 0.8, 0.5, 0.9, 20)


def _level(pose: Pose) -> np.ndarray:
    return Camera.from_hfov(60, 64, 48, gravity=pose.gravity_cam).R_level_from_cam


def _world(view, pts):
    """(N, 3) camera-frame points of ``view`` -> world frame (float64)."""
    R, C = view.pose.R_cam_from_world, view.pose.centre_world
    return np.asarray(pts, float) @ R + C


# ---------------------------------------------------------------------------- conventions
@pytest.mark.parametrize("pitch,roll", PITCH_ROLL)
@pytest.mark.parametrize("yaw", [0.0, 37.0, -120.0])
def test_gravity_gives_pitch_and_roll(yaw, pitch, roll):
    pose = Pose(0.0, 0.0, 1.5, yaw, pitch, roll)
    R, g = pose.R_cam_from_world, pose.gravity_cam
    assert np.allclose(R @ R.T, np.eye(3), atol=1e-12) and np.linalg.det(R) == pytest.approx(1)
    assert np.linalg.norm(g) == pytest.approx(1.0, abs=1e-12)
    assert math.degrees(math.asin(g[2])) == pytest.approx(pitch, abs=1e-9)
    assert math.degrees(math.atan2(g[0], g[1])) == pytest.approx(roll, abs=1e-9)
    cam = Camera.from_hfov(60, 64, 48, gravity=g)
    assert (cam.pitch_deg, cam.roll_deg) == (pytest.approx(pitch), pytest.approx(roll))
    # the camera's level frame is the pose's yaw-only frame: z = heading, y = world down
    L = cam.R_level_from_cam @ R
    s, c = math.sin(math.radians(yaw)), math.cos(math.radians(yaw))
    assert np.allclose(L, [[c, 0, -s], [0, 1, 0], [s, 0, c]], atol=1e-12)


def test_axes_and_signs():
    R = Pose(0, 0, 1.5, yaw_deg=30).R_cam_from_world
    assert np.allclose(R[2], (0.5, 0, math.sqrt(3) / 2)) and np.allclose(R[1], (0, 1, 0))
    assert Pose(0, 0, 1.5, pitch_deg=20).R_cam_from_world[2, 1] > 0  # optical axis goes down
    assert Pose(0, 0, 1.5, roll_deg=20).R_cam_from_world[0, 1] > 0  # camera x goes down
    assert np.allclose(Pose(1, 2, 1.5).centre_world, (1, -1.5, 2))


def _random_pose(rng) -> Pose:
    return Pose(rng.uniform(-2, 2), rng.uniform(-2, 2), rng.uniform(1, 2),
                rng.uniform(-180, 180), rng.uniform(-40, 40), rng.uniform(-30, 30))


def test_planar_motion_matches_relative_transform():
    rng = np.random.default_rng(1)
    for _ in range(50):
        a, b = _random_pose(rng), _random_pose(rng)
        T = relative_transform(a, b)
        Pw = rng.uniform(-3, 3, 3)
        Xa = a.R_cam_from_world @ (Pw - a.centre_world)
        Xb = b.R_cam_from_world @ (Pw - b.centre_world)
        assert np.allclose(T @ np.append(Xb, 1), np.append(Xa, 1), atol=1e-12)
        La, Lb = _level(a), _level(b)
        centre = La @ T[:3, 3]
        fwd = La @ T[:3, :3] @ Lb.T @ (0, 0, 1)
        assert abs(fwd[1]) < 1e-12 and centre[1] == pytest.approx(a.height - b.height)
        x, z, yaw = planar_motion(a, b)
        assert (x, z) == (pytest.approx(centre[0], abs=1e-12), pytest.approx(centre[2], abs=1e-12))
        d = yaw - math.degrees(math.atan2(fwd[0], fwd[2]))
        assert abs((d + 180) % 360 - 180) < 1e-9 and -180 < yaw <= 180


def test_planar_motion_signs():
    a = Pose(0.3, -0.2, 1.5, 30, 10, 5)
    assert planar_motion(a, Pose(0.3, -0.2, 1.5, 45, -5, 0))[2] == pytest.approx(15)
    assert planar_motion(a, Pose(0.3, -0.2, 1.5, 10))[2] == pytest.approx(-20)
    assert planar_motion(Pose(0, 0, 1, 170), Pose(0, 0, 1, -170))[2] == pytest.approx(20)
    s, c = 0.5, math.sqrt(3) / 2
    x, z, _ = planar_motion(a, Pose(0.3 + 0.5 * s, -0.2 + 0.5 * c, 1.4, 30))
    assert z == pytest.approx(0.5) and x == pytest.approx(0, abs=1e-12)
    x, z, _ = planar_motion(a, Pose(0.3 + 0.3 * c, -0.2 - 0.3 * s, 1.5, 30))
    assert x == pytest.approx(0.3) and z == pytest.approx(0, abs=1e-12)


# ---------------------------------------------------------------------------- rendered views
SCENES = {
    "level": (dict(boxes=[BOX]), Pose(-0.4, -0.8, 1.45, 25, 0, 0)),
    "tilted": (dict(boxes=[BOX]), Pose(-0.5, -1.2, 1.5, 20, 15, 5)),
    "steep": (dict(), Pose(0.3, -0.5, 1.6, -35, 38, -9)),
    "wide": (dict(), Pose(0.9, 0.7, 1.3, -140, 5, 12)),
}


@pytest.fixture(scope="module", params=sorted(SCENES))
def view(request):
    kw, pose = SCENES[request.param]
    return render(Room.rectangle(5.0, 4.0, **kw), pose, seed=5)


def test_view_basics(view):
    H, W = 480, 640
    assert view.image.shape == (H, W, 3) and view.image.dtype == np.uint8
    assert view.labels.shape == (H, W) and view.labels.dtype == np.uint8
    assert view.points_cam.shape == (H, W, 3) and view.points_cam.dtype == np.float32
    assert np.isfinite(view.points_cam).all() and len(view.boundary_v) == W
    assert np.allclose(view.camera.gravity, view.pose.gravity_cam)
    assert view.camera_height == view.pose.height and view.image.std() > 10


def test_floor_and_ceiling_points_are_level(view):
    L = view.camera.R_level_from_cam
    fl = view.points_cam[view.labels == FLOOR].astype(float) @ L.T
    assert len(fl) > 1000
    assert np.allclose(fl[:, 1], view.camera_height, rtol=1e-6, atol=0)
    ce = view.points_cam[view.labels == CEILING].astype(float) @ L.T
    assert np.allclose(ce[:, 1], view.camera_height - view.room.ceiling_height, rtol=1e-6, atol=0)


def test_wall_and_box_points_lie_on_their_surfaces(view):
    room = view.room
    seen = 0
    for i in range(room.n_walls):
        P = _world(view, view.points_cam[view.labels == WALL_BASE + i])
        seen += len(P)
        (ax, az), (bx, bz) = room.wall_segment(i)
        e = np.array([bx - ax, bz - az]) / math.hypot(bx - ax, bz - az)
        off = P[:, [0, 2]] - (ax, az)
        assert np.all(np.abs(off[:, 0] * e[1] - off[:, 1] * e[0]) < 2e-6)
        s = off @ e / math.hypot(bx - ax, bz - az)
        assert np.all((s > -1e-6) & (s < 1 + 1e-6))
        assert np.all((P[:, 1] < 1e-6) & (P[:, 1] > -room.ceiling_height - 1e-6))
    assert seen > 20000
    for j, box in enumerate(room.boxes):
        P = _world(view, view.points_cam[view.labels == BOX_BASE + j])
        lx, lz = box.to_local(P[:, 0] - box.x, P[:, 2] - box.z)
        q = np.abs(np.stack([lx, P[:, 1] + box.height / 2, lz], 1)) / (
            np.array([box.width, box.height, box.depth]) / 2)
        assert len(P) > 100 and np.all(np.abs(q.max(axis=1) - 1) < 1e-5)


def test_points_reproject_to_pixel_centres(view):
    H, W = view.labels.shape
    uv, front = view.camera.project_cam(view.points_cam.reshape(-1, 3).astype(float))
    vv, uu = np.mgrid[0:H, 0:W]
    assert front.all()
    assert np.abs(uv - np.column_stack([uu.ravel(), vv.ravel()])).max() < 1e-3


def test_boundary_v_matches_labels(view):
    for u, bv in enumerate(view.boundary_v):
        col = view.labels[:, u]
        if bv is None:
            assert not np.any(col == FLOOR)
        else:
            assert col[bv] == FLOOR and not np.any(col[:bv] == FLOOR)


def test_polyline_is_exact_and_matches_boundary_v(view):
    pl = view.ground_truth_boundary_polyline()
    H, W = view.labels.shape
    assert pl[0, 0] == 0 and pl[-1, 0] == W - 1 and np.all(np.diff(pl[:, 0]) > 0)
    for u, v in pl[pl[:, 0] == np.round(pl[:, 0])]:
        bv = view.boundary_v[int(u)]
        if np.isnan(v):
            assert bv is None
            continue
        row = max(0, math.floor(v) + 1)
        assert bv == (row if row < H else None)
    if not view.room.boxes:  # every point is on the floor line of a wall
        rays = view.camera.rays_level(pl)
        Pw = _world(view, (rays * (view.camera_height / rays[:, 1:2])) @ view.camera.R_level_from_cam)
        assert np.all(np.abs(Pw[:, 1]) < 1e-9)
        dist = np.min([np.abs(np.abs(Pw[:, 0]) - 2.5), np.abs(np.abs(Pw[:, 2]) - 2.0)], axis=0)
        assert dist.max() < 1e-9
        # the visible corners are vertices of the polyline
        for X, Z in view.room.floor_polygon:
            uv, front = view.camera.project_cam(
                view.pose.R_cam_from_world @ ((X, 0, Z) - view.pose.centre_world))
            if front[0] and 0 <= uv[0, 0] <= W - 1:
                assert np.min(np.hypot(*(pl - uv).T)) < 1e-6


def test_render_is_deterministic_and_seeded():
    room, pose = Room.rectangle(4, 3, floor_style="carpet"), Pose(0.2, -0.5, 1.4, 10, 12, 3)
    a = render(room, pose, 160, 120, seed=3)
    b = render(room, pose, 160, 120, seed=3)
    c = render(room, pose, 160, 120, seed=4)
    assert np.array_equal(a.image, b.image)
    assert np.abs(a.image.astype(int) - c.image).mean() > 3
    assert np.array_equal(a.labels, c.labels) and np.array_equal(a.points_cam, c.points_cam)
    clean = render(room, pose, 160, 120, seed=3, noise_sigma=0)
    assert np.std(a.image.astype(float) - clean.image) == pytest.approx(2.0, abs=0.3)


def test_adjacent_walls_are_shaded_differently():
    view = render(Room.rectangle(5, 4), Pose(-1, -1, 1.5, 45), 320, 240, seed=2, noise_sigma=0)
    grey = cv2.cvtColor(view.image, cv2.COLOR_BGR2GRAY)
    m1, m2 = (np.median(grey[view.labels == WALL_BASE + i]) for i in (1, 2))
    assert abs(m1 - m2) > 4


def _visible_walls(room: Room, pose: Pose, cam: Camera) -> set:
    """Walls with a sample point in the image whose sight line crosses no other wall
    (independent of the renderer: 2D segment tests in XZ)."""
    out = set()
    P, Q = room.floor_polygon, np.roll(room.floor_polygon, -1, axis=0)
    for i in range(room.n_walls):
        s, y = np.meshgrid(np.linspace(0.02, 0.98, 60), np.linspace(-2.4, -0.1, 12))
        X = P[i, 0] + s.ravel() * (Q[i, 0] - P[i, 0])
        Z = P[i, 1] + s.ravel() * (Q[i, 1] - P[i, 1])
        pts = np.column_stack([X, y.ravel(), Z])
        uv, front = cam.project_cam((pts - pose.centre_world) @ pose.R_cam_from_world.T)
        ok = front & (uv[:, 0] > 2) & (uv[:, 0] < cam.width - 3) & (uv[:, 1] > 2) & (
            uv[:, 1] < cam.height - 3)
        d = pts[:, [0, 2]] - (pose.x, pose.z)
        for j in range(room.n_walls):
            if j == i:
                continue
            e, w = Q[j] - P[j], P[j] - (pose.x, pose.z)
            den = d[:, 0] * e[1] - d[:, 1] * e[0]
            with np.errstate(divide="ignore", invalid="ignore"):
                t = (w[0] * e[1] - w[1] * e[0]) / den
                u = (w[0] * d[:, 1] - w[1] * d[:, 0]) / den
            ok &= ~((t > 0) & (t < 1 - 1e-9) & (u >= 0) & (u <= 1))
        if ok.any():
            out.add(i)
    return out


@pytest.mark.parametrize("pose", [Pose(-2.0, -1.8, 1.4, 40, 5, 0), Pose(-2.2, 1.5, 1.5, 100, 10, 3),
                                  Pose(2.0, -1.5, 1.6, -20, 20, -6)])
def test_l_shaped_room_shows_exactly_its_visible_walls(pose):
    room = Room.l_shape(6, 5, 2.5, 2.0)
    view = render(room, pose, 320, 240, hfov_deg=100, seed=1)
    walls = {int(x) - WALL_BASE for x in np.unique(view.labels) if WALL_BASE <= x < BOX_BASE}
    expected = _visible_walls(room, pose, view.camera)
    assert len(expected) >= 3 and walls == expected
    # no floor or wall point is seen through another wall
    Pw = _world(view, view.points_cam[(view.labels == FLOOR) | (view.labels >= WALL_BASE)]
                .reshape(-1, 3))
    d = Pw[:, [0, 2]] - (pose.x, pose.z)
    P, Q = room.floor_polygon, np.roll(room.floor_polygon, -1, axis=0)
    for j in range(room.n_walls):
        e, w = Q[j] - P[j], P[j] - (pose.x, pose.z)
        den = d[:, 0] * e[1] - d[:, 1] * e[0]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (w[0] * e[1] - w[1] * e[0]) / den
            u = (w[0] * d[:, 1] - w[1] * d[:, 0]) / den
        assert not np.any((t > 1e-9) & (t < 1 - 1e-6) & (u > 1e-9) & (u < 1 - 1e-9))


def test_box_occludes_floor():
    pose = Pose(-0.5, -1.2, 1.5, 20, 15, 5)
    with_box = render(Room.rectangle(5, 4, boxes=[BOX]), pose, 320, 240, seed=2)
    without = render(Room.rectangle(5, 4), pose, 320, 240, seed=2)
    m = with_box.labels == BOX_BASE
    assert m.sum() > 2000 and np.all(without.labels[m] != BOX_BASE)
    hidden = m & (without.labels == FLOOR)
    assert hidden.sum() > 0.3 * m.sum()  # the rest hides the walls
    assert np.all(with_box.points_cam[hidden, 2] < without.points_cam[hidden, 2])
    assert np.abs(with_box.image[m].astype(int) - without.image[m]).mean() > 20
    assert np.array_equal(with_box.labels[~m], without.labels[~m])


def test_features_match_between_views():
    room = Room.rectangle(5, 4)
    pa, pb = Pose(-0.5, -1.0, 1.5, 15, 20, 2), Pose(0.0, -0.7, 1.5, 0, 22, -3)
    a, b = render(room, pa, seed=9), render(room, pb, seed=9)
    orb = cv2.ORB_create(1500)
    ka, da = orb.detectAndCompute(a.image, None)
    kb, db = orb.detectAndCompute(b.image, None)
    matches = cv2.BFMatcher(cv2.NORM_HAMMING, crossCheck=True).match(da, db)
    assert len(matches) > 100
    pa_uv = np.array([ka[m.queryIdx].pt for m in matches])
    pb_uv = np.array([kb[m.trainIdx].pt for m in matches])
    Xa = a.points_cam[np.rint(pa_uv[:, 1]).astype(int), np.rint(pa_uv[:, 0]).astype(int)]
    T = np.linalg.inv(relative_transform(pa, pb))  # b from a
    uv, front = b.camera.project_cam(Xa.astype(float) @ T[:3, :3].T + T[:3, 3])
    good = front & (np.hypot(*(uv - pb_uv).T) < 3)
    assert good.sum() > 80 and good.mean() > 0.6


def test_intrinsics_and_errors():
    room = Room.rectangle(4, 3)
    v = render(room, Pose(0, 0, 1.4), 64, 48, intrinsics=(50.0, 52.0, 30.0, 25.0), supersample=1)
    assert np.allclose(v.camera.K, [[50, 0, 30], [0, 52, 25], [0, 0, 1]])
    with pytest.raises(GeometryError):
        render(room, Pose(3, 0, 1.4), 64, 48)
    with pytest.raises(GeometryError):
        render(room, Pose(0, 0, 2.6), 64, 48)
    with pytest.raises(GeometryError):
        render(Room.rectangle(4, 3, boxes=[Box(0, 0, 1, 1, 1.5)]), Pose(0, 0, 1.4), 64, 48)
    with pytest.raises(InputError):
        render(room, Pose(0, 0, 1.4), 64, 48, hfov_deg=60, intrinsics=(50, 50, 32, 24))
    with pytest.raises(InputError):
        Room([(0, 0), (1, 1), (1, 0), (0, 1)])  # self-intersecting
