"""A floor point beside a step of the boundary (``steps.floor_or_face``): its 1-sigma is widened
toward the face in front (the face reading within 2.5 of it), or it asks which surface.

The exact scene, in the level frame (x right, y down, z forward; metres): a cabinet whose
front face stands at z = 2 from x = 0.5 to 1.1, its left side face on the plane x = 0.5 from
z = 2 to 2.5, in front of a wall at z = 5. The boundary is the detector's failure on such a
cabinet (rendered below, and TUM's cabinet): it steps at the front corner, so the side face,
between the step and the wall's foot behind, lies on the floor's side of the line.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from findme_core.single import hypotheses, steps
from findme_core.single.answers import FLOOR_OR_FACE_NOTE, NOTES, REASONS, Reason
from findme_core.single.scene import Scene
from findme_core.single.search import SegKind
from tests.core.level_lines import camera

H_CAM, FACE_Z, WALL_Z, X0, X1, SIDE_Z = 1.3, 2.0, 5.0, 0.5, 1.1, 2.5
WINDOW = 34.0


def _foot(cam, x, z):
    uv, _ = cam.project_level(np.array([[x, H_CAM, z]]))
    return uv[0]


def _scene(cam, **kw):
    """The boundary stepping at the cabinet's front corners (module doc)."""
    a, b = _foot(cam, -3.0, WALL_Z), _foot(cam, X0 * WALL_Z / FACE_Z, WALL_Z)
    c, d = _foot(cam, X0, FACE_Z), _foot(cam, X1, FACE_Z)
    e, f = _foot(cam, X1 * WALL_Z / FACE_Z, WALL_Z), _foot(cam, 3.0, WALL_Z)
    # the floor lines run on to the image's edges (a straight line's image is straight)
    left = a + (b - a) * (0.0 - a[0]) / (b[0] - a[0])
    right = e + (f - e) * (639.0 - e[0]) / (f[0] - e[0])
    poly = np.array([left, b, c, d, e, right])
    kinds = [SegKind.WALL, SegKind.STEP, SegKind.WALL, SegKind.STEP, SegKind.WALL]
    kw.setdefault("boundary_sigma_px", WINDOW)
    return Scene(cam, H_CAM, poly, kinds, **kw)


def _side_face(cam, n=6):
    """(n, 2) pixels on the cabinet's left side face and their (n, 3) level-frame truth."""
    z = np.linspace(FACE_Z + 0.05, SIDE_Z - 0.05, n)
    P = np.column_stack([np.full(n, X0), H_CAM - np.linspace(0.1, 0.6, n), z])
    uv, _ = cam.project_level(P)
    return uv, P


@pytest.mark.parametrize("pitch,roll", [(25.0, 0.0), (35.0, 3.0)])
def test_a_floor_point_beside_a_step_is_widened_toward_the_face(pitch, roll):
    """The side face's pixels are read on the floor behind, as the boundary has them; the
    1-sigma gains sqrt(w) times the distance to the face reading (the foot's horizontal
    range), w = Phi(-d / sigma) for a pixel d px sideways of the step's line, and the truth
    lies within 2.5 of it, where the floor reading's own 1-sigma puts it beyond 5."""
    cam = camera(pitch, roll)
    sc = _scene(cam, max_rel_sigma=None)    # every answer, however loose (refusal: below)
    px, truth = _side_face(cam)
    got = sc.locate(px)
    foot = np.hypot(X0, FACE_Z)
    c = _foot(cam, X0, FACE_Z)
    up = cam.up_direction([c])[0]           # the image of the vertical through the foot
    R = cam.R_level_from_cam
    for (u, v), p, q in zip(px, got, truth):
        assert p.surface == "floor" and p.note == NOTES[FLOOR_OR_FACE_NOTE]
        d = abs(u - (c[0] + (v - c[1]) * up[0] / up[1]))
        w = 0.5 * math.erfc(d / (math.sqrt(2.0) * WINDOW))
        assert 0.158 < w <= 0.5                     # within the window
        P = R @ p.xyz                               # camera -> level frame
        face = P * foot / np.hypot(P[0], P[2])      # the same ray at the foot's range
        assert p.sigma_parts["surface"] == pytest.approx(math.sqrt(w) * np.linalg.norm(P - face))
        assert np.linalg.norm(P - q) <= 2.5 * p.sigma_m
    own = [np.sqrt(p.sigma_m ** 2 - p.sigma_parts["surface"] ** 2) for p in got]
    z_own = [np.linalg.norm(R @ p.xyz - q) / s for p, q, s in zip(got, truth, own)]
    assert max(z_own) > 5.0


def test_floor_away_from_the_step_or_in_front_of_its_foot_keeps_its_sigma():
    """A floor pixel twice the window left of the step, and one below the foot's row beside
    it (the floor in front of the cabinet), keep their 1-sigma, with no note."""
    cam = camera()
    sc = _scene(cam)
    c = _foot(cam, X0, FACE_Z)
    far_off = c + (-2 * WINDOW, -20.0)
    in_front = c + (-5.0, 15.0)
    for p in sc.locate(np.array([far_off, in_front])):
        assert p.surface == "floor" and p.sigma_parts["surface"] == 0 and p.note is None


def test_what_was_said_and_the_lifting_take_no_spread():
    cam = camera()
    sc = _scene(cam)
    px, _ = _side_face(cam)
    said = sc.locate(px, ["floor"] * len(px))
    assert all(p.surface == "floor" and p.sigma_parts["surface"] == 0 and p.note is None
               for p in said)
    assert all(p.error == REASONS[Reason.NOT_WALL] for p in sc.locate(px, ["wall"] * len(px)))
    _, surface, _, parts, _ = sc.locate_level(px)
    assert np.all(surface == 1) and np.all(parts["surface"] == 0)


def test_readings_too_far_apart_are_refused_with_the_reason():
    """Where the floor and the face put the point farther apart than the allowed share of its
    distance (here a fifth), it has no answer, and the reason says why."""
    cam = camera()
    px, _ = _side_face(cam)
    loose = _scene(cam, max_rel_sigma=None).locate(px)
    far = np.array([p.sigma_m > 0.2 * np.linalg.norm(p.xyz) for p in loose])
    assert far.any() and not far.all()
    for p, q, f in zip(_scene(cam, max_rel_sigma=0.2).locate(px), loose, far):
        assert (p.error == REASONS[Reason.FLOOR_OR_FACE]) if f else (p.sigma_m == q.sigma_m)
    # said floor, the user has decided: the same pixels are answered on the floor
    said = _scene(cam, max_rel_sigma=0.2).locate(px, ["floor"] * len(px))
    assert all(p.surface == "floor" for p in said)


def test_a_step_whose_foot_does_not_go_down_gives_no_face_reading():
    """Degenerate: a step's lower end at the horizon (a boundary with no floor there) has no
    floor point, so the pixels beside it keep the floor reading alone."""
    cam = camera(0.0)
    horizon = cam.cy
    poly = np.array([[0.0, 400.0], [300.0, 400.0], [300.0, horizon], [302.0, horizon],
                     [302.0, 420.0], [639.0, 420.0]])
    kinds = [SegKind.WALL, SegKind.STEP, SegKind.NONE, SegKind.STEP, SegKind.WALL]
    sc = Scene(cam, H_CAM, poly, kinds, boundary_sigma_px=WINDOW)
    got = sc.locate(np.array([[280.0, 430.0], [320.0, 440.0]]))
    assert all(p.surface == "floor" and p.sigma_parts["surface"] == 0 for p in got)


def test_the_rendered_cabinets_side_with_the_detectors_own_boundary(side_view):
    """The detector's best boundary: every cabinet pixel it leaves on the floor lies within
    3 of its 1-sigma (within 3 of the floor reading's own 1-sigma, 15 % did)."""
    v = side_view
    h = hypotheses.generate(v.image, v.camera, 10).hypotheses[0]
    sc = Scene(v.camera, v.camera_height, h.polyline, h.kinds, boundary_sigma_px=WINDOW)
    on = np.flatnonzero(v.labels.ravel() == 50)[::7]
    px = np.column_stack([on % 640, on // 640]).astype(float)
    truth = v.points_cam.reshape(-1, 3)[on]
    got = sc.locate(px)
    floor = [i for i, p in enumerate(got) if p.surface == "floor"]
    assert len(floor) >= 100         # the premise: the side face is on the floor's side
    err = np.array([np.linalg.norm(got[i].xyz - truth[i]) for i in floor])
    sig = np.array([got[i].sigma_m for i in floor])
    spread = np.array([got[i].sigma_parts["surface"] for i in floor])
    assert np.mean(spread > 0) >= 0.95
    assert np.mean(err <= 3 * sig) >= 0.97
    assert np.mean(err <= 3 * np.sqrt(sig ** 2 - spread ** 2)) < 0.3


def test_pixels_meet_the_steps_in_blocks_with_the_same_answer(monkeypatch):
    """Memory is bounded by blocks of pixel x step pairs; the answer does not depend on them."""
    cam = camera()
    sc = _scene(cam)
    rng = np.random.default_rng(1)
    px = np.column_stack([rng.uniform(0, 639, 300), rng.uniform(0, 479, 300)])
    args = (sc, np.ones(len(px), bool), px, cam.rays_level(px))
    t, surface, reason = sc._solve(sc._pieces, args[3])
    ref = steps.floor_or_face(*args, t, surface, reason, WINDOW)
    assert (ref > 0).sum() >= 5
    for block in (1, 3, 7, 500):
        monkeypatch.setattr(steps, "BLOCK", block)
        np.testing.assert_array_equal(steps.floor_or_face(*args, t, surface, reason, WINDOW),
                                      ref)
