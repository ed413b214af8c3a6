"""``tops``: a point said to be on top of something standing on the floor is put on that top.

The exact scenes are built in the level frame (x right, y down, z forward; floor y = h) and
projected with the camera: a cabinet 0.6 m high whose face stands at z = 2.0 m on the chosen
boundary, its top 0.5 m deep (back edge z = 2.5), a drawer's edge on the face. The rendered
one is the test suite's cabinet (``box_view``), with the photo's lines as the detector finds
them.
"""

from __future__ import annotations

import numpy as np
import pytest

from findme_core.motion.photo_lines import photo_lines
from findme_core.errors import GeometryError
from findme_core.single import hypotheses, tops
from findme_core.single.answers import FACE_OR_TOP_NOTE, NOTES, REASONS, Reason
from findme_core.single.scene import Scene, distances
from findme_core.single.search import SegKind
from tests.conftest import top_pixels
from tests.core.level_lines import camera, hline, seg

H_CAM, FACE_Z, TOP, BACK_Z = 1.45, 2.0, 0.6, 2.5
XS = (-1.0, 1.0)


def _hline(cam, z, height, xs=XS):
    """A level 3D line along x at depth z, ``height`` above the floor."""
    return hline(cam, H_CAM, z, height, xs)


def _scene(cam, lines, **kw):
    """The scene whose boundary is the cabinet's foot line, across the image."""
    u1, v1, u2, v2 = _hline(cam, FACE_Z, 0.0)
    at = lambda u: v1 + (u - u1) * (v2 - v1) / (u2 - u1)  # noqa: E731
    poly = np.array([[0.0, at(0.0)], [639.0, at(639.0)]])
    return Scene(cam, H_CAM, poly, [SegKind.WALL], lines=lines, **kw)


def _cabinet_lines(cam, front=True):
    lines = [_hline(cam, FACE_Z, 0.0), _hline(cam, FACE_Z, 0.3),   # its foot, a drawer's edge
             _hline(cam, BACK_Z, TOP)]                              # the top's back edge
    if front:
        lines.append(_hline(cam, FACE_Z, TOP))
    return np.array(lines)


def _on_top(cam, n=7):
    """(n, 2) pixels of points on the top and their (n, 3) camera-frame truth."""
    x = np.linspace(-0.6, 0.6, n)
    z = np.linspace(FACE_Z + 0.05, BACK_Z - 0.05, n)
    P = np.column_stack([x, np.full(n, H_CAM - TOP), z])
    uv, _ = cam.project_level(P)
    return uv, P @ cam.R_level_from_cam   # level -> camera frame


@pytest.mark.parametrize("pitch,roll", [(25.0, 0.0), (35.0, 3.0), (15.0, -2.0)])
def test_a_point_said_on_a_top_is_on_it(pitch, roll):
    cam = camera(pitch, roll)
    sc = _scene(cam, _cabinet_lines(cam))
    px, truth = _on_top(cam)
    got = sc.locate(px, ["top"] * len(px))
    assert [p.surface for p in got] == ["top"] * len(px)
    np.testing.assert_allclose([p.xyz for p in got], truth, atol=1e-6)
    assert all(p.sigma_m > 0 and p.error is None for p in got)
    # said wall, the same pixels land on the face: too near by up to the top's depth
    walls = sc.locate(px, ["wall"] * len(px))
    off = np.linalg.norm(np.array([p.xyz for p in walls]) - truth, axis=1)
    assert off.max() > 0.3


def test_the_front_edge_is_the_line_nearest_below_the_point():
    cam = camera()
    sc = _scene(cam, _cabinet_lines(cam))
    px, _ = _on_top(cam, 3)
    rays = cam.rays_level(px)
    k = sc._piece(sc._pieces, rays)
    rows = tops.edge_rows(cam, H_CAM, sc.lines, tops.line_normals(cam, sc.lines), px, sc._pieces[3][k],
                          sc._pieces[4][k])
    u1, v1, u2, v2 = _hline(cam, FACE_Z, TOP)
    np.testing.assert_allclose(rows, v1 + (px[:, 0] - u1) * (v2 - v1) / (u2 - u1), atol=1e-9)


def test_a_top_without_its_front_edge_is_not_measured():
    cam = camera()
    px, _ = _on_top(cam, 3)
    # neither the front edge nor any other level line of the face below the point
    lines = np.array([_hline(cam, BACK_Z, TOP)])
    for sc in (_scene(cam, lines), _scene(cam, np.zeros((0, 4)))):
        assert [p.error for p in sc.locate(px, ["top"] * 3)] == [REASONS[Reason.NO_TOP_EDGE]] * 3
    # an edge that is not parallel to the face (turned 10 deg) is no front edge
    c, s = np.cos(np.radians(10)), np.sin(np.radians(10))
    y = H_CAM - TOP
    skew = seg(cam, (-c, y, FACE_Z - s), (c, y, FACE_Z + s))
    got = _scene(cam, np.vstack([lines, skew])).locate(px, ["top"] * 3)
    assert all(p.error == REASONS[Reason.NO_TOP_EDGE] for p in got)
    # without the photo's lines the edge cannot be looked for
    got = _scene(cam, None).locate(px, ["top"] * 3)
    assert all(p.error == REASONS[Reason.NO_LINES] for p in got)


def test_a_level_line_on_a_wall_is_no_top_below_a_wall_point():
    """A chair rail on the wall (0.9 m up) below a wall pixel said "top": the top it makes
    would put the point metres behind the wall, deeper than any top reaches: refused."""
    cam = camera(15.0)
    rail = _hline(cam, FACE_Z, 0.9)
    P = np.array([[0.2, H_CAM - 1.2, FACE_Z]])          # on the wall, 1.2 m up
    uv, _ = cam.project_level(P)
    got = _scene(cam, np.array([rail])).locate(uv, ["top"])[0]
    assert got.xyz is None and got.error == REASONS[Reason.TOP_TOO_DEEP]
    # the same line under a pixel of a real top's depth is its front edge
    Q = np.array([[0.2, H_CAM - 0.9, FACE_Z + 0.4]])
    uq, _ = cam.project_level(Q)
    ok = _scene(cam, np.array([rail])).locate(uq, ["top"])[0]
    np.testing.assert_allclose(ok.xyz, (Q @ cam.R_level_from_cam)[0], atol=1e-6)


def test_a_top_must_lie_below_thecamera():
    cam = camera(10.0)
    y = H_CAM - 1.6      # a shelf 1.6 m up, above the camera at 1.45 m
    shelf = seg(cam, (-1.0, y, FACE_Z), (1.0, y, FACE_Z))
    u, v = 0.5 * (shelf[:2] + shelf[2:])
    got = _scene(cam, np.array([shelf])).locate([(u, v - 20.0)], ["top"])[0]
    assert got.xyz is None and got.error in (REASONS[Reason.NO_TOP_EDGE],
                                             REASONS[Reason.TOP_ABOVE])


def test_a_point_the_line_puts_on_the_floor_or_above_the_horizon_is_on_no_top():
    cam = camera()
    sc = _scene(cam, _cabinet_lines(cam))
    foot = _hline(cam, FACE_Z, 0.0)
    below = (320.0, 0.5 * (foot[1] + foot[3]) + 40.0)   # under the foot line: floor
    above = (320.0, 5.0)                                 # near the top of a 25-deg photo
    horizon = cam.project_level(np.array([[0.0, 0.0, 10.0]]))[0][0]
    sky = (320.0, horizon[1] - 10.0)
    got = sc.locate([below, sky], ["top", "top"])
    assert got[0].error == REASONS[Reason.TOP_ON_FLOOR]
    assert got[1].error == REASONS[Reason.TOP_ABOVE]
    # nothing said, the same pixels are what the boundary says
    plain = sc.locate([below, above])
    assert plain[0].surface == "floor" and plain[1].surface == "wall"


def test_a_top_points_sigma_moves_with_its_boundary_and_edge():
    cam = camera()
    sc = _scene(cam, _cabinet_lines(cam), boundary_sigma_px=10.0, height_sigma=0.03)
    px, truth = _on_top(cam, 3)
    got = sc.locate(px, ["top"] * 3)
    for p, t in zip(got, truth):
        assert p.sigma_parts["boundary"] > 0.01
        assert p.sigma_parts["height"] == pytest.approx(np.linalg.norm(t) * 0.03 / H_CAM)
        assert p.sigma_parts["pixel"] > 0
    # a wall point on the face at the same column has the boundary part of the same order
    face = sc.locate(px, ["wall"] * 3)
    ratio = [a.sigma_parts["boundary"] / b.sigma_parts["boundary"] for a, b in zip(got, face)]
    assert all(0.5 < r < 3.0 for r in ratio)
    # an uncertain gravity moves the top's point, face and edge together: a finite part,
    # and the displacement a tilt along each axis makes (distances use it)
    tilted = _scene(cam, _cabinet_lines(cam), gravity_cov=np.diag([1e-4, 1e-4])).locate(
        px, ["top"] * 3)
    for p, q in zip(tilted, got):
        assert 0 < p.sigma_parts["gravity"] < 0.5 and q.sigma_parts["gravity"] == 0
        assert p.gravity_jac.shape == (2, 3) and np.all(np.isfinite(p.gravity_jac))
        np.testing.assert_allclose(p.xyz, q.xyz, atol=1e-9)   # the answer is the same


def _rendered_scene(v, **kw):
    """The rendered view's scene under its true boundary, with the lines the detector finds
    in the photo (``kw``: the scene's other arguments)."""
    hs = hypotheses.generate(v.image, v.camera, 10)
    poly = v.ground_truth_boundary_polyline()
    poly = poly[np.isfinite(poly[:, 1])]
    return Scene(v.camera, v.camera_height, poly, None, lines=photo_lines(hs, v.image), **kw)


def test_the_rendered_cabinets_top_from_the_photos_own_lines(box_view):
    """The detector's lines of a rendered photo: every answered point lies on the top."""
    v, cam = box_view, box_view.camera
    sc = _rendered_scene(v)
    R = cam.R_level_from_cam
    level = v.points_cam.reshape(-1, 3) @ R.T
    height = v.camera_height - level[:, 1]
    box = v.room.boxes[0]
    on_top = (v.labels.ravel() == 50) & (np.abs(height - box.height) < 1e-3)
    # the top's pixels at least 4 rows above its front edge in their column
    rows = np.arange(v.labels.size) // v.labels.shape[1]
    cols = np.arange(v.labels.size) % v.labels.shape[1]
    last = np.full(v.labels.shape[1], -1)
    np.maximum.at(last, cols[on_top], rows[on_top])
    pick = np.flatnonzero(on_top & (rows < last[cols] - 4))[::37]
    assert len(pick) >= 30
    px = np.column_stack([cols[pick], rows[pick]]).astype(float)
    got = sc.locate(px, ["top"] * len(px))
    ok = [i for i, p in enumerate(got) if p.xyz is not None]
    assert len(ok) >= 0.6 * len(px)
    assert all(got[i].surface == "top" for i in ok)
    err = np.array([np.linalg.norm(got[i].xyz - v.points_cam.reshape(-1, 3)[pick[i]]) for i in ok])
    sig = np.array([got[i].sigma_m for i in ok])
    assert err.max() < 0.06 and np.all(err < 3 * sig)
    assert all(got[i].error == REASONS[Reason.NO_TOP_EDGE]
               for i in range(len(px)) if i not in ok)


def test_a_vertical_edge_near_a_grazing_faces_vanishing_point_is_no_front_edge():
    """A face seen at a grazing angle (receding 10 deg right of the view, standing 3 m away
    8 deg right) passes the parallel test with any line near its vanishing point: a vertical
    edge 8 deg right too (2 deg from it). Its interpretation plane is vertical: not taken."""
    cam = camera(25.0)
    a, b = np.radians(10.0), np.radians(8.0)
    n = np.array([[np.cos(a), -np.sin(a)]])                    # the face's normal, d at 10 deg
    c = n[0] @ (3.0 * np.array([np.sin(b), np.cos(b)]))        # through 3 m along 8 deg
    x, z = 6.0 * np.sin(b), 6.0 * np.cos(b)
    vert = seg(cam, (x, 0.3, z), (x, 1.0, z))                 # a door frame's edge, 8 deg right
    u = 0.5 * (vert[0] + vert[2])
    v_cross = vert[1] + (u - vert[0]) * (vert[3] - vert[1]) / (vert[2] - vert[0])
    args = (cam, H_CAM, vert[None], tops.line_normals(cam, vert[None]),
            np.array([[u, v_cross - 8.0]]), n, np.array([c]))
    assert np.isfinite(tops.edge_rows(*args, tops.TopParams(not_vertical_deg=0.0))[0])
    assert np.isnan(tops.edge_rows(*args)[0])


@pytest.mark.parametrize("lines", [[1.0, 2.0, 3.0], [[0.0, 1.0, 2.0, np.nan]]])
def test_lines_that_are_not_lines_are_refused_with_what_they_are(lines):
    with pytest.raises(GeometryError, match="4 numbers each"):
        _scene(camera(), lines)


def test_pixels_meet_the_lines_in_blocks_with_the_same_answer(monkeypatch):
    """A request's pixels meet the photo's lines in blocks of at most ``tops.BLOCK`` pairs
    (its memory is bounded whatever its size): blocks of any size give the same rows."""
    cam = camera()
    sc = _scene(cam, np.vstack([_cabinet_lines(cam)] * 40))   # 160 lines
    px, _ = _on_top(cam, 9)
    px = np.vstack([px, [[320.0, 470.0], [5.0, 5.0]]])         # and two that find none
    rays = cam.rays_level(px)
    k = sc._piece(sc._pieces, rays)
    args = (cam, H_CAM, sc.lines, tops.line_normals(cam, sc.lines), px, sc._pieces[3][k], sc._pieces[4][k])
    whole = tops.edge_rows(*args)
    assert np.isfinite(whole[:9]).all() and np.isnan(whole[9:]).all()
    for block in (1, 7, 161, 500):
        monkeypatch.setattr(tops, "BLOCK", block)
        np.testing.assert_array_equal(tops.edge_rows(*args), whole)


def test_a_point_nobody_said_the_surface_of_spans_the_face_and_the_top():
    """Nothing said, a pixel on the cabinet's top is read on the face below it, as the
    boundary has it, and its 1-sigma gains the distance to its top reading: the truth, on the
    top, lies within it, where the face's 1-sigma alone put the top's far side beyond 5."""
    cam = camera()
    sc = _scene(cam, _cabinet_lines(cam), boundary_sigma_px=2.0)
    px, truth = _on_top(cam)
    plain, said_top = sc.locate(px), sc.locate(px, ["top"] * len(px))
    z_face = []
    for p, q, t in zip(plain, said_top, truth):
        assert p.surface == "wall" and p.note == NOTES[FACE_OR_TOP_NOTE]
        assert p.sigma_parts["surface"] == pytest.approx(np.linalg.norm(p.xyz - q.xyz))
        assert p.sigma_m ** 2 == pytest.approx(sum(x * x for x in p.sigma_parts.values()))
        assert np.linalg.norm(p.xyz - t) <= p.sigma_m
        z_face.append(np.linalg.norm(p.xyz - t)
                      / np.sqrt(p.sigma_m ** 2 - p.sigma_parts["surface"] ** 2))
    assert max(z_face) > 5.0     # the face's own 1-sigma: the far side of the top far beyond
    # said wall or top, the user has decided: no spread, no note
    for said in ("wall", "top"):
        got = sc.locate(px, [said] * len(px))
        assert all(p.sigma_parts["surface"] == 0 and p.note is None for p in got)
    # a distance between two such points carries both spreads
    (d, s, _), = distances(plain[:2], H_CAM, 0.0)
    assert s ** 2 >= plain[0].sigma_parts["surface"] ** 2 + plain[1].sigma_parts["surface"] ** 2
    # the motion's lifting reads every face point on its face alone
    _, _, _, parts, _ = sc.locate_level(px)
    assert np.all(parts["surface"] == 0)


def test_a_face_point_with_no_top_edge_below_it_keeps_its_sigma():
    """A wall point 1.2 m up above a chair rail (its top reading metres behind the wall,
    deeper than a top reaches) keeps the face's 1-sigma, with no note."""
    cam = camera(15.0)
    P = np.array([[0.2, H_CAM - 1.2, FACE_Z]])
    uv, _ = cam.project_level(P)
    got = _scene(cam, np.array([_hline(cam, FACE_Z, 0.9)])).locate(uv)[0]
    assert got.surface == "wall" and got.sigma_parts["surface"] == 0 and got.note is None


def test_readings_too_far_apart_are_refused_with_the_reason():
    """Where the face and the top put the point farther apart than the scene's allowed
    share of its distance, it has no answer, and the reason says why and what to say."""
    cam = camera()
    sc = _scene(cam, _cabinet_lines(cam), max_rel_sigma=0.1)
    px, _ = _on_top(cam)
    got = sc.locate(px)
    far = [p for p in got if p.xyz is None]
    assert far and all(p.error == REASONS[Reason.FACE_OR_TOP] for p in far)
    near = [p for p in got if p.xyz is not None]
    assert all(p.sigma_m <= 0.1 * np.linalg.norm(p.xyz) for p in near)
    # said top, the same pixels are answered on the top
    assert all(p.surface == "top" for p in sc.locate(px, ["top"] * len(px)))


def test_the_rendered_cabinets_top_with_nothing_said(box_view):
    """The rendered cabinet, the photo's own lines, nothing said: every pixel of the top
    whose front edge the lines find lies within 1.5 of its 1-sigma, and 95 % of all within 3
    (read on the face with the face's 1-sigma alone, most lie beyond 3)."""
    px, truth = top_pixels(box_view, step=41)
    got = _rendered_scene(box_view, boundary_sigma_px=2.0).locate(px)
    assert all(p.xyz is not None for p in got) and len(got) >= 30
    err = np.array([np.linalg.norm(p.xyz - q) for p, q in zip(got, truth)])
    sig = np.array([p.sigma_m for p in got])
    spread = np.array([p.sigma_parts["surface"] for p in got])
    assert np.mean(spread > 0) >= 0.7
    assert np.all(err[spread > 0] <= 1.5 * sig[spread > 0])
    assert np.mean(err <= 3 * sig) >= 0.95
    assert np.mean(err > 3 * np.sqrt(sig ** 2 - spread ** 2)) > 0.5
