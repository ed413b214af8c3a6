import math

import cv2
import numpy as np
import pytest

from findme_core.errors import InputError
from findme_core.geometry.camera import Camera
from findme_core.single.lines import LineKind, Lines, classify, detect_segments, merge_collinear


def _img_with_lines(segs, size=(480, 640)):
    img = np.full(size, 40, np.uint8)
    for u1, v1, u2, v2 in segs:
        cv2.line(img, (u1, v1), (u2, v2), 220, 3, cv2.LINE_AA)
    return cv2.GaussianBlur(img, (0, 0), 0.8)


@pytest.mark.parametrize("method", ["lsd", "hough"])
def test_detect_finds_drawn_lines(method):
    truth = [(50, 400, 600, 350), (100, 50, 100, 300)]
    segs = detect_segments(_img_with_lines(truth), method)
    assert len(segs) >= 2
    for u1, v1, u2, v2 in truth:
        n = np.array([v2 - v1, u1 - u2], float)
        n /= np.linalg.norm(n)
        # some detected segment lies on this line (both ends within 3 px of it)
        d = np.abs(np.stack([segs[:, :2] - (u1, v1), segs[:, 2:] - (u1, v1)]) @ n).max(0)
        assert (d < 3.0).any()


def test_detect_drops_image_frame_and_rejects_bad_method():
    img = np.full((480, 640), 150, np.uint8)
    img[-1, :] = 20  # a dark bottom row, as left by depth registration
    img[:, -1] = 20
    assert len(detect_segments(img)) == 0
    with pytest.raises(InputError, match="unknown segment method"):
        detect_segments(img, "surf")
    with pytest.raises(InputError, match="HxW"):
        detect_segments(np.zeros((4, 4, 3, 1), np.uint8))


def test_merge_collinear_joins_and_separates():
    segs = np.array([[0, 100, 200, 110], [260, 113, 500, 125],   # collinear, gap between
                     [0, 130, 500, 155],                          # parallel, 20 px lower
                     [300, 0, 310, 200]], float)                  # another direction
    L = merge_collinear(segs)
    assert len(L) == 3
    i = int(np.argmin(np.abs(L.coef @ [250, 112.5, 1])))
    top = L.coef[i]
    assert abs(top @ [0, 100, 1]) < 0.5 and abs(top @ [500, 125, 1]) < 0.5
    assert np.allclose(np.hypot(L.coef[:, 0], L.coef[:, 1]), 1.0)
    assert (L.coef[:, 1] >= 0).all()
    # support is the total member length; lines come heaviest first
    assert L.support[i] == pytest.approx(np.hypot(200, 10) + np.hypot(240, 12), rel=1e-6)
    assert (np.diff(L.support) <= 0).all()
    assert merge_collinear(np.zeros((0, 4))).coef.shape == (0, 3)


def _project(cam, P1, P2):
    """Image segment of the 3D level-frame segment P1-P2."""
    R = cam.R_level_from_cam
    uv, front = cam.project_cam(np.array([P1, P2], float) @ R)
    assert front.all()
    return uv.reshape(-1)


@pytest.mark.parametrize("pitch,roll", [(0, 0), (30, 5), (20, -8)])
def test_classify_in_level_frame(pitch, roll):
    p, r = math.radians(pitch), math.radians(roll)
    g = [math.sin(r) * math.cos(p), math.cos(r) * math.cos(p), math.sin(p)]
    cam = Camera.from_hfov(80, 640, 480, g)
    h = 1.4
    segs = {
        LineKind.FRONT: _project(cam, (-1.0, h, 5.0), (1.0, h, 5.0)),
        LineKind.LEFT: _project(cam, (-1.6, h, 3.0), (-1.6, h, 6.0)),
        LineKind.RIGHT: _project(cam, (1.6, h, 3.0), (1.6, h, 6.0)),
        LineKind.VERTICAL: _project(cam, (0.6, h, 4.0), (0.6, h - 1.0, 4.0)),
        LineKind.ABOVE_HORIZON: _project(cam, (-1.0, -1.0, 6.0), (1.0, -1.0, 6.0)),
    }
    coef = []
    for s in segs.values():
        d = s[2:] - s[:2]
        n = np.array([-d[1], d[0]]) / np.linalg.norm(d)
        n = n if n[1] >= 0 else -n
        coef.append([n[0], n[1], -n @ s[:2]])
    lines = Lines(np.array(list(segs.values())), np.array(coef), np.ones(len(segs)))
    assert classify(lines, cam).tolist() == [int(k) for k in segs]


def _cam(pitch_deg=0.0, roll_deg=0.0):
    p, r = math.radians(pitch_deg), math.radians(roll_deg)
    return Camera.from_hfov(80, 640, 480, [math.sin(r) * math.cos(p), math.cos(r) * math.cos(p),
                                            math.sin(p)])


def test_horizon_top_row():
    from findme_core.single.lines import horizon_top_row
    level = _cam()
    top = horizon_top_row(level, margin_px=8.0)
    assert top % 2 == 0 and level.cy - 8 - 2 < top <= level.cy - 8
    # rolled: the horizon's highest end decides
    rolled = _cam(roll_deg=10)
    a, b, c = rolled.horizon_line()
    highest = min(-(c + a * u) / b for u in (0, 639))
    assert highest - 10 < horizon_top_row(rolled) <= highest - 8
    # degenerate: horizon above the image (looking down), camera looking far up (horizon below
    # the image, the floor outside it), upside down, horizon steeper than 76 deg
    assert horizon_top_row(_cam(pitch_deg=60)) == 0
    assert horizon_top_row(_cam(pitch_deg=-60)) == 478
    assert horizon_top_row(_cam(roll_deg=180)) == 0
    assert horizon_top_row(_cam(roll_deg=80)) == 0


@pytest.mark.parametrize("method", ["lsd", "hough"])
def test_detect_below_a_row_keeps_full_image_coordinates(method):
    truth = [(50, 400, 600, 350), (100, 50, 100, 300), (60, 100, 600, 120)]
    img = _img_with_lines(truth)
    full = detect_segments(img, method)
    assert (np.abs(full[:, [1, 3]] - 110).max(1) < 15).any()
    part = detect_segments(img, method, top_row=200)
    assert len(part) >= 2 and (part[:, [1, 3]] >= 200 - 1e-6).all()
    assert not (np.abs(part[:, [1, 3]] - 110).max(1) < 15).any()   # the line above row 200 is gone
    # the line below is found where the whole-image detector finds it, over the same extent
    u1, v1, u2, v2 = truth[0]
    n = np.array([v2 - v1, u1 - u2], float) / np.hypot(v2 - v1, u1 - u2)
    for segs in (full, part):
        d = np.abs(np.stack([segs[:, :2] - (u1, v1), segs[:, 2:] - (u1, v1)]) @ n).max(0)
        on = segs[d < 3.0]
        assert len(on) and on[:, [0, 2]].min() < u1 + 10 and on[:, [0, 2]].max() > u2 - 10
    # the vertical line (3 px wide: two edges) is cut at row 200 and keeps its column
    vert = part[np.abs(part[:, 0] - part[:, 2]) < 3]
    assert len(vert) and np.allclose(vert[:, [0, 2]], 100, atol=3.5)
    assert vert[:, [1, 3]].min() >= 200 and vert[:, [1, 3]].max() == pytest.approx(300, abs=2)


def _step_edge(a, b, c, size=(480, 640), lo=60.0, hi=180.0):
    """Grey image of the step edge a u + b v + c = 0 (a^2 + b^2 = 1): each pixel's value is
    its area fraction on the bright side (exact for a straight edge, to 1/64 px)."""
    H, W = size
    o = (np.arange(8) + 0.5) / 8 - 0.5
    v, u = np.mgrid[0:H, 0:W].astype(float)
    frac = np.zeros((H, W))
    for dy in o:
        for dx in o:
            frac += (a * (u + dx) + b * (v + dy) + c) > 0
    return (lo + (hi - lo) * frac / 64).astype(np.float32)


def test_snap_to_edges_recovers_a_subpixel_line():
    from findme_core.single.lines import snap_to_edges
    t = np.radians(8.0)
    a, b = -np.sin(t), np.cos(t)                 # an edge 8 deg from horizontal
    c = -(a * 320 + b * 241.3)
    img = _step_edge(a, b, c)
    # a detection 0.8 px off and turned by 0.4 deg
    t2 = t + np.radians(0.4)
    a2, b2 = -np.sin(t2), np.cos(t2)
    c2 = -(a2 * 320 + b2 * 242.1)
    ends = np.array([[60.0, -(c2 + a2 * 60) / b2, 580.0, -(c2 + a2 * 580) / b2]])
    snapped = snap_to_edges(img, Lines(ends, np.array([[a2, b2, c2]]), np.array([520.0])))
    na, nb, nc = snapped.coef[0]
    assert abs(np.degrees(np.arctan2(-na, nb)) - 8.0) < 0.06    # from 0.4 deg off
    assert abs(na * 320 + nb * 241.3 + nc) < 0.1
    assert snapped.support[0] > 0.95 * 520          # a straight edge keeps its weight


def test_snap_to_edges_trusts_two_edges_merged_into_one_less():
    from findme_core.single.lines import snap_to_edges
    img = _step_edge(0.0, 1.0, -240.0)
    img[:, 320:] = _step_edge(0.0, 1.0, -242.0)[:, 320:]    # the right half 2 px lower
    ends = np.array([[20.0, 241.0, 620.0, 241.0]])
    snapped = snap_to_edges(img, Lines(ends, np.array([[0.0, 1.0, -241.0]]), np.array([600.0])))
    assert snapped.support[0] < 0.85 * 600     # the fit tilts between them: rms ~0.5 px
    # too short to refit (fewer than 6 positions): kept as it was
    short = Lines(np.array([[20.0, 241.0, 28.0, 241.0]]), np.array([[0.0, 1.0, -241.0]]),
                  np.array([8.0]))
    assert np.allclose(snap_to_edges(img, short).coef, short.coef)
    assert len(snap_to_edges(img, Lines(np.zeros((0, 4)), np.zeros((0, 3)), np.zeros(0)))) == 0


def test_a_group_of_zero_weight_points_gets_a_finite_line():
    """Degenerate: every point of a group has weight 0 (zero-length segments of a mangled
    image): the group is fitted with equal weights, no NaN and no division warning."""
    import warnings
    from findme_core.single.lines import _fit_lines
    pts = np.array([[0.0, 5.0], [10.0, 5.0], [3.0, 1.0], [3.0, 9.0]])
    w = np.array([0.0, 0.0, 1.0, 2.0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        lines = _fit_lines(pts, w, np.array([0, 0, 1, 1]), 2)
    assert np.isfinite(lines).all()
    for line, group in ((lines[0], pts[:2]), (lines[1], pts[2:])):   # y = 5, x = 3
        assert np.allclose(group @ line[:2] + line[2], 0.0, atol=1e-9)


def _greedy_reference(compat, weight):
    """The grouping written plainly: heaviest first, a group is its seed's compatible
    segments not yet grouped, and the seed."""
    group, g = np.full(len(weight), -1), 0
    for i in np.argsort(-weight, kind="stable"):
        if group[i] < 0:
            members = compat[i] & (group < 0)
            members[i] = True
            group[members] = g
            g += 1
    return group, g


def test_grouping_on_bit_sets_is_the_plain_greedy_grouping():
    from findme_core.single.lines import _group_collinear
    rng = np.random.default_rng(3)
    for n in (0, 1, 7, 8, 9, 64, 150):
        # segments along a few lines, jittered, so that groups form and overlap
        base = rng.integers(0, 4, n)
        t0, t1 = rng.uniform(0, 200, n), rng.uniform(200, 400, n)
        ang = np.radians(base * 40.0 + rng.normal(0, 1.0, n))
        off = base * 30.0 + rng.normal(0, 1.5, n)
        d, nrm = np.column_stack([np.cos(ang), np.sin(ang)]), np.column_stack(
            [-np.sin(ang), np.cos(ang)])
        p1 = t0[:, None] * d + off[:, None] * nrm
        p2 = t1[:, None] * d + off[:, None] * nrm
        w = rng.uniform(1, 50, n)
        got = _group_collinear(p1, p2, w, 2.0, 2.0)
        # the same compatibility the function computes, then the plain loop
        u = (p2 - p1) / np.hypot(*(p2 - p1).T)[:, None]
        nn = np.column_stack([-u[:, 1], u[:, 0]])
        c = -(nn * p1).sum(1)
        dot = lambda a, b: a[:, None, 0] * b[None, :, 0] + a[:, None, 1] * b[None, :, 1]  # noqa: E731
        compat = (np.abs(dot(u, u)) >= np.cos(np.radians(2.0))) & (np.maximum(
            np.abs(dot(nn, p1) + c[:, None]), np.abs(dot(nn, p2) + c[:, None])) <= 2.0)
        want = _greedy_reference(compat, w)
        assert got[1] == want[1] and np.array_equal(got[0], want[0]), n
