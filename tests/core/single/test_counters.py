"""``counters``: a boundary on a kitchen counter's front edge is seen through to the wall.

The scenes are built in the level frame (x right, y down, z forward; floor y = h) and
projected with the camera, so the answer is known exactly: a wall at z = 3.0 m, a counter
0.9 m high and 0.6 m deep in front of it (front edge z = 2.4), cabinet door edges on its
face, the counter's back edge where the top meets the wall.
"""

from __future__ import annotations

import numpy as np
import pytest

from findme_core.single import counters
from findme_core.single.hypotheses import Hypothesis, HypothesisSet
from findme_core.single.lines import Lines
from findme_core.single.scene import Scene
from findme_core.single.search import SegKind
from tests.core.level_lines import camera, hline, seg

H_CAM, WALL_Z, TOP, DEPTH = 1.45, 3.0, 0.9, 0.6
FRONT_Z = WALL_Z - DEPTH
XS = (-1.5, 1.5)


def _hline(cam, z, height, xs=XS):
    """A horizontal 3D line along x at depth z, ``height`` above the floor."""
    return hline(cam, H_CAM, z, height, xs)


def _row_at(line, u):
    """Row at column ``u`` of the image line through the segment ``line`` (4,)."""
    return line[1] + (u - line[0]) * (line[3] - line[1]) / (line[2] - line[0])


def _polyline(cam, seg):
    """A one-segment WALL hypothesis on the image line of ``seg``, across the image."""
    (u1, v1, u2, v2) = seg
    at = lambda u: v1 + (u - u1) * (v2 - v1) / (u2 - u1)  # noqa: E731
    return Hypothesis(np.array([[0.0, at(0.0)], [639.0, at(639.0)]]),
                      np.array([SegKind.WALL]), 1.0, 1.0)


def _kitchen(cam, doors=True, back=True, foot=True, back_z=WALL_Z):
    """(hypothesis on the counter's front edge, lines of the scene)."""
    lines = [_hline(cam, FRONT_Z, TOP),                      # the front edge itself
             _hline(cam, FRONT_Z + 0.03, TOP)]               # the nosing's back line
    if back:
        lines.append(_hline(cam, back_z, TOP))               # where the top meets the wall
    if doors:
        for x in (-1.2, -0.7, -0.2, 0.3, 0.8, 1.3):          # door edges on the face
            lines.append(seg(cam, (x, H_CAM - TOP + 0.05, FRONT_Z),
                              (x, H_CAM - 0.15, FRONT_Z)))
    if foot:
        lines.append(_hline(cam, FRONT_Z, 0.0))              # the cabinets' foot
    return _polyline(cam, lines[0]), np.array(lines)


@pytest.mark.parametrize("pitch,roll", [(25.0, 0.0), (35.0, 3.0), (15.0, -2.0)])
def test_the_wall_behind_a_counter_is_found(pitch, roll):
    cam = camera(pitch, roll)
    hyp, lines = _kitchen(cam)
    found = counters.find(cam, H_CAM, hyp, lines)
    assert len(found) == 1
    c = found[0]
    assert c.segment == 0 and c.doors >= 2
    assert c.depth_m == pytest.approx(DEPTH, abs=0.01)
    assert c.wall_m == pytest.approx(WALL_Z, abs=0.01)      # the wall faces the camera (+z)
    # behind(): the WALL segment is now the image of the wall's base
    new = counters.behind(cam, H_CAM, hyp, found)
    assert list(new.kinds) == [SegKind.STEP, SegKind.WALL, SegKind.STEP]
    base = _hline(cam, WALL_Z, 0.0)
    for u, v in new.polyline[1:3]:
        assert v == pytest.approx(_row_at(base, u), abs=0.05)
    # a point on the wall above the counter (the backsplash) lands on the wall, not ~3x too far
    px = cam.project_level(np.array([[0.4, H_CAM - 0.95, WALL_Z]]))[0]
    before = Scene(cam, H_CAM, hyp.polyline, hyp.kinds).locate_level(px)[0][0]
    after = Scene(cam, H_CAM, new.polyline, new.kinds).locate_level(px)[0][0]
    assert after[2] == pytest.approx(WALL_Z, abs=0.02)
    assert before[2] > WALL_Z + 0.5


def test_a_floor_line_with_a_sill_above_is_no_counter():
    """A wall's base with a window sill at 0.6 m: the sill lies in the depth range once
    lifted at counter height, but no door hangs from the floor line."""
    cam = camera()
    base = _hline(cam, WALL_Z, 0.0)
    lines = np.array([base, _hline(cam, WALL_Z, 0.6)])
    assert counters.find(cam, H_CAM, _polyline(cam, base), lines) == []


@pytest.mark.parametrize("what", ["doors", "back", "foot"])
def test_each_part_of_the_counter_is_needed(what):
    """No doors, no back edge, or (where the photo shows it) no foot: no counter."""
    cam = camera()
    hyp, lines = _kitchen(cam, **{what: False})
    assert counters.find(cam, H_CAM, hyp, lines) == []


def test_a_back_edge_outside_a_counters_depth_is_not_taken():
    cam = camera()
    hyp, lines = _kitchen(cam, back_z=FRONT_Z + 1.5)
    assert counters.find(cam, H_CAM, hyp, lines) == []


def test_a_level_photo_need_not_show_the_foot():
    """Looking level, the cabinets' foot is below the image: the counter is found from
    its doors and its back edge alone."""
    cam = camera(pitch=0.0)
    hyp, lines = _kitchen(cam, foot=False)
    assert cam.project_level(np.array([[0.0, H_CAM, FRONT_Z]]))[0][0, 1] > cam.height
    found = counters.find(cam, H_CAM, hyp, lines)
    assert len(found) == 1 and found[0].depth_m == pytest.approx(DEPTH, abs=0.01)


def test_floor_lines_at_right_angles_to_the_boundary_are_not_doors():
    """Floorboards running from the wall toward the camera's foot look vertical in the
    image (near the nadir); they must not count as cabinet doors. A level-ish photo, so
    that the foot check (below the image here) cannot be what rejects them."""
    cam = camera(pitch=10.0)
    base = _hline(cam, WALL_Z, 0.0)
    planks = [seg(cam, (x, H_CAM, WALL_Z), (x, H_CAM, 2.0)) for x in (-0.03, 0.0, 0.03)]
    lines = np.array([base, _hline(cam, WALL_Z, 0.55), *planks])
    assert counters.find(cam, H_CAM, _polyline(cam, base), lines) == []


def test_a_camera_below_the_counter_top_finds_none():
    cam = camera()
    hyp, lines = _kitchen(cam)
    assert counters.find(cam, 0.95, hyp, lines) == []
    assert counters.find(cam, H_CAM, hyp, np.zeros((0, 4))) == []


def test_apply_puts_the_wall_first_and_keeps_the_counters_edge():
    cam = camera()
    hyp, lines = _kitchen(cam)
    other = Hypothesis(hyp.polyline + [0.0, 20.0], hyp.kinds, 0.5, 0.5)
    ls = Lines(lines, np.zeros((len(lines), 3)), np.ones(len(lines)))
    hs = HypothesisSet(640, 480, [hyp, other], ls, np.zeros(len(lines), int))
    assert counters.apply(hs, cam, None) is hs                 # no height: not metric
    out = counters.apply(hs, cam, H_CAM)
    assert len(out.hypotheses) == 2                            # as many as before
    assert list(out.hypotheses[0].kinds) == [SegKind.STEP, SegKind.WALL, SegKind.STEP]
    assert out.hypotheses[1] is hyp
    assert len(counters.apply(hs, cam, H_CAM, max_n=3).hypotheses) == 3
    plain = HypothesisSet(640, 480, [other], ls, np.zeros(len(lines), int))
    assert counters.apply(plain, cam, H_CAM, lines=lines[:1]) is plain   # nothing found


def test_apply_sees_behind_the_counter_put_second_by_no_floor_visible():
    """"No floor visible" first (``flat.no_floor_first``: the counter top smooth under its
    edge), the counter's edge second: the wall behind it goes first, then both as found; a
    NONE first with no boundary after it, or two NONEs, are left as they are."""
    cam = camera()
    hyp, lines = _kitchen(cam)
    none = Hypothesis(np.array([[0.0, 479.5], [639.0, 479.5]]), np.array([SegKind.NONE]), 1.0)
    ls = Lines(lines, np.zeros((len(lines), 3)), np.ones(len(lines)))
    hs = HypothesisSet(640, 480, [none, hyp], ls, np.zeros(len(lines), int))
    out = counters.apply(hs, cam, H_CAM, max_n=3)
    assert list(out.hypotheses[0].kinds) == [SegKind.STEP, SegKind.WALL, SegKind.STEP]
    assert out.hypotheses[1] is none and out.hypotheses[2] is hyp
    for hyps in ([none], [none, none, hyp]):
        alone = HypothesisSet(640, 480, hyps, ls, np.zeros(len(lines), int))
        assert counters.apply(alone, cam, H_CAM) is alone


def test_segments_that_cannot_be_a_counter_are_not_tested():
    """Not a WALL (an occluding step), narrower than ``min_segment_px``, or above the
    horizon (no floor line): none is a counter, whatever the lines say."""
    cam = camera()
    hyp, lines = _kitchen(cam)
    step = Hypothesis(hyp.polyline, np.array([SegKind.STEP]), 1.0, 1.0)
    assert counters.find(cam, H_CAM, step, lines) == []
    narrow = Hypothesis(np.array([[0.0, 300.0], [10.0, 300.0], [639.0, 300.0]]),
                        np.array([SegKind.WALL, SegKind.NONE]), 1.0, 1.0)
    assert counters.find(cam, H_CAM, narrow, lines) == []
    sky = Hypothesis(np.array([[0.0, 5.0], [639.0, 5.0]]), np.array([SegKind.WALL]), 1.0, 1.0)
    assert cam.rays_level(sky.polyline)[:, 1].max() < 0          # above the horizon
    assert counters.find(cam, H_CAM, sky, lines) == []
    assert counters.behind(cam, H_CAM, hyp, []) is hyp


def _split(cam, hyp, x_break=0.0, dv=0.0):
    """``hyp``'s front edge as two WALL segments meeting where x = ``x_break`` on it (the
    boundary search breaks a front edge where the face below changes), the meeting vertex
    moved ``dv`` pixels down."""
    u, v = cam.project_level(np.array([[x_break, H_CAM - TOP, FRONT_Z]]))[0][0]
    (u0, v0), (u1, v1) = hyp.polyline
    return Hypothesis(np.array([[u0, v0], [u, v + dv], [u1, v1]]),
                      np.array([SegKind.WALL, SegKind.WALL]), 1.0, 1.0)


def _dishwasher_kitchen(cam):
    """A counter whose left half stands on a dishwasher (no door edges) under the only
    stretch of back edge the photo's lines show, and whose right half has cabinet doors
    and no back edge line: (hypothesis broken at x = 0, lines)."""
    lines = [_hline(cam, FRONT_Z, TOP), _hline(cam, WALL_Z, TOP, xs=(-1.5, -0.1)),
             _hline(cam, FRONT_Z, 0.0)]
    for x in (0.3, 0.8, 1.3):
        lines.append(seg(cam, (x, H_CAM - TOP + 0.05, FRONT_Z), (x, H_CAM - 0.15, FRONT_Z)))
    return _split(cam, _polyline(cam, lines[0])), np.array(lines)


def test_a_front_edge_broken_in_two_is_tested_whole():
    """Neither half passes alone (one has no doors, the other no back edge above it); the
    two are one straight edge at the counter's height, and that passes: one counter over
    both segments, the wall behind it where it is, drawn as one base segment."""
    cam = camera()
    hyp, lines = _dishwasher_kitchen(cam)
    assert counters.runs(cam, H_CAM, hyp) == [(0, 1)]
    for k in (0, 1):
        one = Hypothesis(hyp.polyline[k:k + 2], hyp.kinds[k:k + 1], 1.0, 1.0)
        assert counters.find(cam, H_CAM, one, lines) == []
    found = counters.find(cam, H_CAM, hyp, lines)
    assert len(found) == 1
    c = found[0]
    assert (c.segment, c.last, c.doors) == (0, 1, 3)
    assert c.wall_m == pytest.approx(WALL_Z, abs=0.01)
    new = counters.behind(cam, H_CAM, hyp, found)
    assert list(new.kinds) == [SegKind.STEP, SegKind.WALL, SegKind.STEP]
    base = _hline(cam, WALL_Z, 0.0)
    for u, v in new.polyline[1:3]:
        assert v == pytest.approx(_row_at(base, u), abs=0.05)


def test_segments_off_one_line_are_not_one_run():
    """A kink of 20 px at the meeting vertex puts it ~0.1 m off the line at the counter's
    height (more than ``collinear_m``): two runs, each tested alone, and this counter
    (which needs both halves) is not found."""
    cam = camera()
    hyp, lines = _dishwasher_kitchen(cam)
    kinked = _split(cam, _polyline(cam, lines[0]), dv=20.0)
    assert counters.runs(cam, H_CAM, kinked) == [(0, 0), (1, 1)]
    assert counters.find(cam, H_CAM, kinked, lines) == []
    steps = Hypothesis(hyp.polyline, np.array([SegKind.WALL, SegKind.STEP]), 1.0, 1.0)
    assert counters.runs(cam, H_CAM, steps) == [(0, 0)]


def test_a_run_that_fails_whole_keeps_a_part_that_passes():
    """The boundary's left end lies 0.08 m in front of the edge (its middle vertex 0.04 m
    off the chord, within ``collinear_m``: one run), and the back edge shows above the
    right half only, 0.79 m behind. Measured from the run's chord it lies 0.81 m behind,
    past a counter's depth, and the whole run fails; the right half alone, on the edge
    itself, is the counter it is."""
    cam = camera()
    y = H_CAM - TOP
    ends = cam.project_level(np.array([[-1.5, y, FRONT_Z - 0.08], [0.0, y, FRONT_Z],
                                       [1.5, y, FRONT_Z]]))[0]
    hyp = Hypothesis(ends, np.array([SegKind.WALL, SegKind.WALL]), 1.0, 1.0)
    lines = [_hline(cam, FRONT_Z, TOP), _hline(cam, FRONT_Z + 0.79, TOP, xs=(0.1, 1.5)),
             _hline(cam, FRONT_Z, 0.0, xs=(-1.5, -0.1)), _hline(cam, FRONT_Z, 0.0, xs=(0.1, 1.5))]
    for x in (0.3, 0.8, 1.3):
        lines.append(seg(cam, (x, y + 0.05, FRONT_Z), (x, H_CAM - 0.15, FRONT_Z)))
    lines = np.array(lines)
    assert counters.runs(cam, H_CAM, hyp) == [(0, 1)]
    whole = Hypothesis(ends[[0, 2]], np.array([SegKind.WALL]), 1.0, 1.0)
    assert counters.find(cam, H_CAM, whole, lines) == []
    found = counters.find(cam, H_CAM, hyp, lines)
    assert [(c.segment, c.last) for c in found] == [(1, 1)]
    assert found[0].depth_m == pytest.approx(0.79, abs=0.01)


def test_lines_on_the_top_nearer_than_a_counter_is_deep_are_passed_over():
    """A sink's rim 0.16 m behind the front edge lies between it and the back edge: the
    back edge, the first line at a counter's depth, is still found."""
    cam = camera()
    hyp, lines = _kitchen(cam)
    rim = _hline(cam, FRONT_Z + 0.16, TOP, xs=(-0.8, 0.2))
    found = counters.find(cam, H_CAM, hyp, np.vstack([lines, rim]))
    assert len(found) == 1 and found[0].depth_m == pytest.approx(DEPTH, abs=0.01)
