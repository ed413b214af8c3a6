"""Tests of findme_core.single.layout: a photo's walls, corners, scan and room orientation from an
exact boundary of a rendered room, and every degenerate input."""

from __future__ import annotations

import math

import numpy as np
import pytest

from findme_core.single import layout
from findme_core.geometry.orientation import orientation
from findme_core.geometry.camera import Camera
from findme_core.errors import HypothesisError
from findme_core.single.layout import End
from findme_core.single.lines import detect_segments
from findme_core.single.search import SegKind
from findme_core.synth.render import Box, Pose, Room, render
from tests.core.layout_rooms import exact_polyline, to_level, view_layout

ROOM = Room.rectangle(5.0, 6.0, boxes=(Box(1.0, 1.6, 0.8, 0.5, 0.9, 20),))
TILTED = Pose(-0.4, -1.8, 1.4, yaw_deg=-20.0, pitch_deg=30.0, roll_deg=4.0)


def _on_segment(p, a, b, tol):
    d = b - a
    t = np.clip((p - a) @ d / (d @ d), 0, 1)
    return np.linalg.norm(p - (a + t * d)) < tol


def test_walls_corner_and_occluding_edge_are_exact():
    v, L = view_layout(ROOM, TILTED, (640, 480))
    corners_true = to_level(TILTED, ROOM.floor_polygon)
    box_true = to_level(TILTED, ROOM.boxes[0].corners_xz())
    assert len(L.walls) == 3
    # the far-left corner of the room, where walls 2 and 3 meet, and nothing else
    assert np.allclose(L.corners, corners_true[3:4], atol=2e-3)
    assert L.ends[0].tolist() == [End.OPEN, End.CORNER] and L.ends[1, 0] == End.CORNER
    for w in L.walls[:2]:   # room walls: both ends on the room's edges
        assert any(_on_segment(w[0], corners_true[i], corners_true[(i + 1) % 4], 2e-3)
                   and _on_segment(w[1], corners_true[i], corners_true[(i + 1) % 4], 2e-3)
                   for i in range(4))
    # the right wall disappears behind the cabinet (open end), whose face starts at an edge
    assert L.ends[1, 1] == End.OPEN and L.ends[2, 0] == End.EDGE
    assert any(_on_segment(L.walls[2, 0], box_true[i], box_true[(i + 1) % 4], 2e-3)
               for i in range(4))


def test_scan_ranges_are_the_true_distances():
    v, L = view_layout(ROOM, TILTED, (640, 480))
    wall = L.kind == SegKind.WALL
    assert wall.sum() > 50 and np.all(np.diff(L.azimuth) > 0)
    # every wall sample lies on its wall segment
    for p, k in zip(L.points[wall], L.wall[wall]):
        assert _on_segment(p, *L.walls[k], 1e-6)
    # and on the floor under the rendered boundary: its range is the ray's floor distance
    rays = v.camera.rays_level(exact_polyline(v)[0])
    az = np.arctan2(rays[:, 0], rays[:, 2])
    rng = 1.4 * np.hypot(rays[:, 0], rays[:, 2]) / rays[:, 1]
    assert np.allclose(np.interp(L.azimuth[wall], az, rng), L.range[wall], rtol=2e-3)
    # sigma grows with the distance (a pixel is worth more far away)
    o = np.argsort(L.range[wall])
    assert L.sigma[wall][o[-1]] > L.sigma[wall][o[0]] > 0


def test_open_and_none_columns_bound_the_range():
    cam = Camera.from_hfov(70, 640, 480, gravity=TILTED.gravity_cam)
    poly = np.array([[0, 300], [200, 300], [200.5, -0.5], [400, -0.5], [400.5, 479.5],
                     [639, 479.5]])
    kinds = [SegKind.WALL, SegKind.STEP, SegKind.OPEN, SegKind.STEP, SegKind.NONE]
    L = layout.from_hypothesis(cam, 1.4, poly, kinds)

    def row_range(us, v):   # floor distances of the rays through row v
        r = cam.rays_level(np.column_stack([us, np.full(len(us), v)]))
        return 1.4 * np.hypot(r[:, 0], r[:, 2]) / r[:, 1]
    top, bottom = row_range(np.arange(201, 400), -0.5), row_range(np.arange(401, 640), 479.5)
    opn, none = L.kind == SegKind.OPEN, L.kind == SegKind.NONE
    assert opn.any() and none.any() and len(L.walls) == 1
    # floor seen at least as far as the top row; something stands nearer than the bottom row
    assert np.all((L.range[opn] >= top.min() - 1e-9) & (L.range[opn] <= top.max() + 1e-9))
    assert np.all((L.range[none] >= bottom.min() - 1e-9) & (L.range[none] <= bottom.max() + 1e-9))
    assert L.ends[0].tolist() == [End.OPEN, End.EDGE]    # border; the near side of a step
    assert (L.wall[opn] == -1).all() and (L.wall[L.kind == SegKind.WALL] == 0).all()


def test_nearly_collinear_segments_are_one_wall():
    cam = Camera.from_hfov(70, 640, 480, gravity=TILTED.gravity_cam)
    L = layout.from_hypothesis(cam, 1.4, [[0, 300], [320, 302], [639, 304]])
    assert len(L.walls) == 1 and len(L.corners) == 0
    L = layout.from_hypothesis(cam, 1.4, [[0, 250], [320, 400], [639, 250]])
    assert len(L.walls) == 2 and len(L.corners) == 1


def test_normals_point_to_the_camera():
    _, L = view_layout(ROOM, TILTED, (640, 480))
    n = L.normals
    assert np.allclose(np.linalg.norm(n, axis=1), 1.0)
    assert np.all(np.einsum("ij,ij->i", n, L.walls[:, 0]) < 0)   # the camera (origin) is in front


@pytest.mark.parametrize("yaw", [0.0, 17.0, -38.0])
def test_orientation_from_the_lines_of_a_rendered_room(yaw):
    pose = Pose(0.3, -1.2, 1.45, yaw_deg=yaw, pitch_deg=15.0, roll_deg=2.0)
    v = render(Room.rectangle(5.0, 6.0), pose, 640, 480, hfov_deg=70.0, seed=1, supersample=1)
    o = orientation(detect_segments(v.image), v.camera)
    truth = (-math.radians(yaw)) % (math.pi / 2)
    err = (o.angle - truth + math.pi / 4) % (math.pi / 2) - math.pi / 4
    assert abs(math.degrees(err)) < 0.5 and o.support > 0.5 and 0 <= o.angle < math.pi / 2


def test_orientation_without_usable_lines_is_none():
    cam = Camera.from_hfov(70, 640, 480)
    assert orientation(np.zeros((0, 4)), cam) is None
    # only vertical lines: their plane holds gravity, no horizontal direction is known
    assert orientation([[100, 50, 100, 400], [500, 80, 500, 300]], cam) is None


@pytest.mark.parametrize("poly, kinds, match", [
    ([[0, 300]], None, "at least 2"),
    ([[0, 300], [639, np.nan]], None, "at least 2 finite"),
    ([[0, 300], [639, 300]], [SegKind.WALL, SegKind.WALL], "2 segment kinds"),
    ([[0, 100], [639, 100]], None, "horizon"),
])
def test_bad_hypotheses_are_errors(poly, kinds, match):
    cam = Camera.from_hfov(70, 640, 480)
    with pytest.raises(HypothesisError, match=match):
        layout.from_hypothesis(cam, 1.4, poly, kinds)


def test_bad_height_is_an_error():
    cam = Camera.from_hfov(70, 640, 480)
    with pytest.raises(HypothesisError, match="camera height"):
        layout.from_hypothesis(cam, 0.0, [[0, 300], [639, 300]])
