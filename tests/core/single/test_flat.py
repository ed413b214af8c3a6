"""A boundary that separates nothing or runs over no floor (``single.flat``): the colour step
across it, measured in integers, the texture under it, and "no floor visible" put first when
the best boundary is the same colour above and below along most of its length, or, in a photo
whose horizon is in view, smooth below along most of it. Synthetic Lab images with known
steps and synthetic textures; rendered level photos of walls with posters, where the best
boundary followed a poster's edge across the blank wall and put the wall below it on the
floor, metres off at +-0.1 m; rendered level photos of a kitchen counter, whose best boundary
followed the counter top's back edge and put the wall 2-3x too far."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from findme_core.single import flat
from findme_core.single.hypotheses import Hypothesis
from findme_core.single.methods import hypothesize
from findme_core.single.room_view import judge
from findme_core.single.scene import Scene, boundary_sigma_px
from findme_core.single.search import SegKind
from findme_core.synth.render import Pose, Room, render
from findme_core.synth.room import Box

W, H = 640, 480
WALL, NONE = SegKind.WALL, SegKind.NONE


def _lab(top, bottom, row=300):
    """(H, W, 3) uint8 Lab: colour ``top`` above ``row``, ``bottom`` from it down."""
    img = np.empty((H, W, 3), np.uint8)
    img[:row], img[row:] = top, bottom
    return img


def _share(lab, poly=((0.0, 300.0), (W - 1.0, 300.0)), kinds=(WALL,)):
    return flat.flat_share(lab, np.array(poly), np.array(kinds))


def test_one_colour_on_both_sides_is_flat_everywhere():
    assert _share(_lab((150, 128, 128), (150, 128, 128))) == 1.0


@pytest.mark.parametrize("dl,is_flat", [(2, True), (3, False), (20, False)])
def test_a_step_is_flat_only_under_three_units(dl, is_flat):
    """A step of exactly FLAT_STEP (3 units of L) is a step: the integer comparison has no
    rounding to tip it."""
    share = _share(_lab((150, 128, 128), (150 + dl, 128, 128)))
    assert share == (1.0 if is_flat else 0.0)


def test_a_step_in_colour_alone_counts():
    assert _share(_lab((150, 128, 128), (150, 140, 128))) == 0.0


def test_only_wall_columns_inside_the_bands_are_measured():
    """The left half is WALL, the right half NONE: only the left half is measured; a boundary
    so close to the photo's bottom that no band fits below it is not measured (0)."""
    lab = _lab((150, 128, 128), (150, 128, 128))
    lab[:, W // 2:] = (60, 128, 128)     # a step in the NONE half would not count anyway
    poly = ((0.0, 300.0), (W / 2, 300.0), (W - 1.0, 300.0))
    assert _share(lab, poly, (WALL, NONE)) == 1.0
    assert _share(lab, ((0.0, 470.0), (W - 1.0, 470.0))) == 0.0


def test_too_few_columns_are_not_judged():
    """A WALL piece 40 px wide gives 10 strips, under MIN_COLUMNS: not judged."""
    lab = _lab((150, 128, 128), (150, 128, 128))
    poly = ((0.0, 300.0), (40.0, 300.0), (W - 1.0, 300.0))
    assert _share(lab, poly, (WALL, NONE)) == 0.0


def test_flat_share_is_the_share_of_flat_columns():
    lab = _lab((150, 128, 128), (150, 128, 128))
    lab[300:, : W // 4] = (100, 128, 128)     # a real step along the left quarter
    assert abs(_share(lab) - 0.75) < 0.02


def _hyp(row, kind=WALL, score=1.0):
    return Hypothesis(np.array([[0.0, row], [W - 1.0, row]]), np.array([kind]), score, 0.5)


def test_no_floor_first_only_when_the_best_separates_nothing():
    """The best boundary, at row 300, is measured: across a step it stays first; on one
    colour "no floor visible" goes first with its score, it second, the others after (the
    NONE among them not twice)."""
    keep = [_hyp(300), _hyp(350)]
    got = flat.no_floor_first(keep, _lab((150, 128, 128), (110, 128, 128)), 10)
    assert [h.polyline[0, 1] for h in got] == [300, 350] and got[0].flat == 0.0
    lab = _lab((150, 128, 128), (150, 128, 128))
    got = flat.no_floor_first([_hyp(300, score=2.0), _hyp(350), _hyp(H - 0.5, NONE, -0.8)],
                              lab, 3)
    assert [tuple(h.kinds) for h in got] == [(NONE,), (WALL,), (WALL,)]
    assert got[0].score == 2.0 and got[0].flat == 0.0 and got[1].flat == 1.0
    np.testing.assert_array_equal(got[0].polyline, [[0.0, H - 0.5], [W - 1.0, H - 0.5]])
    assert [h.polyline[0, 1] for h in got[1:]] == [300, 350]
    assert len(flat.no_floor_first([_hyp(300), _hyp(350)], lab, 2)) == 2
    assert flat.no_floor_first([], lab, 10) == []


#: (room width, depth, wall, distance m): level photos 1.4 m up facing a wall with posters,
#: whose best boundary followed a poster's lower edge across the blank wall before
POSTERS = [((5.0, 4.0), 1, 1.0), ((5.0, 4.0), 2, 1.3), ((8.0, 6.0), 1, 1.3), ((8.0, 6.0), 2, 0.8)]


@pytest.mark.parametrize("size,wall,distance", POSTERS)
def test_a_blank_wall_with_posters_shows_no_floor(size, wall, distance):
    """The photo shows no floor. Its best boundary is now "no floor visible": the photo is
    not a room view and no point on it is measured. The boundary that was best comes second,
    flat along most of it; under it the wall below was floor, metres off at +-0.1 m."""
    room = Room.rectangle(*size)
    (x0, z0), (x1, z1) = room.wall_segment(wall)
    n = room.inward_normal(wall)[[0, 2]]
    c = np.array([(x0 + x1) / 2, (z0 + z1) / 2]) + distance * n
    v = render(room, Pose(c[0], c[1], 1.4, math.degrees(math.atan2(-n[0], -n[1])), 0.0, 0.0),
               W, H, hfov_deg=70.0, supersample=1)
    image = cv2.imdecode(cv2.imencode(".jpg", v.image, [cv2.IMWRITE_JPEG_QUALITY, 95])[1],
                         cv2.IMREAD_COLOR)
    hs = hypothesize(image, v.camera, "findme", 10, camera_height=1.4)
    top, second = hs.hypotheses[0], hs.hypotheses[1]
    assert np.all(top.kinds == NONE) and flat.separates_nothing(second.flat)
    view = judge(hs, v.camera, 1.4)
    assert not view.ok and "no floor is in the photo" in view.reason
    us, vs = np.meshgrid(np.arange(20, W, 40), np.arange(20, H, 40))
    px = np.column_stack([us.ravel(), vs.ravel()]).astype(float)
    px = px[(v.labels[px[:, 1].astype(int), px[:, 0].astype(int)] >= 10)]   # on walls
    kw = dict(boundary_sigma_px=boundary_sigma_px(W, H), height_sigma=0.0)
    assert all(p.xyz is None for p in Scene(v.camera, 1.4, top.polyline, top.kinds,
                                            **kw).locate(px))
    was = Scene(v.camera, 1.4, second.polyline, second.kinds, **kw).locate(px)
    z = [np.linalg.norm(p.xyz - v.points_cam[int(p.pixel[1]), int(p.pixel[0])]) / p.sigma_m
         for p in was if p.xyz is not None]
    assert sum(x > 3.0 for x in z) >= 0.25 * len(px)    # what it said before: confident, wrong


def _texture(value):
    """A band texture (``support.EdgeField.band_texture``'s signature) of ``value`` grey
    levels per pixel everywhere, or ``value(rows, cols)``; it records the rows it is asked."""
    asked = []

    def texture(rows, cols, offset, band):
        assert (offset, band) == (flat.TEXTURE_OFFSET, flat.TEXTURE_BAND)
        asked.append(np.asarray(rows, float))
        return value(rows, cols) if callable(value) else np.full(len(rows), float(value))
    texture.asked = asked
    return texture


def _smooth(texture, top_row=200, poly=((0.0, 300.0), (W - 1.0, 300.0)), kinds=(WALL,)):
    return flat.smooth_share(texture, top_row, np.array(poly), np.array(kinds), W, H, 1.0)


def test_smooth_share_counts_strips_smoother_than_the_limit():
    assert _smooth(_texture(0.5)) == 1.0
    assert _smooth(_texture(1.0)) == 0.0                  # the limit itself is not smooth
    assert _smooth(_texture(2.0)) == 0.0
    left = _texture(lambda rows, cols: np.where(cols < W // 4, 0.3, 1.7))
    assert abs(_smooth(left) - 0.25) < 0.01
    assert np.allclose(left.asked[0], 300.0)              # the boundary's rows, unrounded


def test_smooth_share_is_not_judged_looking_down_or_on_too_few_strips():
    """A photo whose horizon is not in view (``horizon_top_row`` 0) looks down at the floor:
    not judged, the texture not even asked; only WALL strips with the band inside the photo
    are measured, and fewer than ``MIN_COLUMNS`` are not judged."""
    t = _texture(0.5)
    assert _smooth(t, top_row=0) == 0.0 and t.asked == []
    half = ((0.0, 300.0), (W / 2, 300.0), (W - 1.0, 300.0))
    assert _smooth(_texture(lambda r, c: np.where(c < W // 2, 0.5, 9.0)), poly=half,
                   kinds=(WALL, NONE)) == 1.0
    low = _texture(0.5)
    assert _smooth(low, poly=((0.0, H - 20.0), (W - 1.0, H - 20.0))) == 0.0
    assert low.asked == []                                 # no band fits under it
    assert _smooth(_texture(0.5), poly=((0.0, 300.0), (40.0, 300.0), (W - 1.0, 300.0)),
                   kinds=(WALL, NONE)) == 0.0


def test_no_floor_first_when_the_best_runs_over_no_floor():
    """Same colours across the boundary at row 300 (not flat), but smooth under it in a
    photo that looks across the room: "no floor visible" first; textured under it, or the
    horizon out of view, it stays first. Its ``smooth`` is kept either way."""
    lab = _lab((150, 128, 128), (110, 128, 128))
    got = flat.no_floor_first([_hyp(300), _hyp(350)], lab, 10, _texture(0.4), 200)
    assert tuple(got[0].kinds) == (NONE,) and got[1].smooth == 1.0 and got[1].flat == 0.0
    for texture, top_row in ((_texture(1.6), 200), (_texture(0.4), 0)):
        got = flat.no_floor_first([_hyp(300), _hyp(350)], lab, 10, texture, top_row)
        assert tuple(got[0].kinds) == (WALL,) and got[0].polyline[0, 1] == 300
    assert flat.no_floor_first([_hyp(300)], lab, 10)[0].smooth == 0.0   # not measured


def _kitchen(seed, back=0.8, counter=True, style="wood"):
    """A level photo 1.45 m up facing the far wall of a 5 x 6 m room, ``back`` m in front of
    a counter 0.9 m high, 3 m long and 0.7 m deep standing against it (or, without the
    counter, 3.2 m from that wall, the floor in view)."""
    boxes = (Box(0.0, 2.65, 3.0, 0.7, 0.9),) if counter else ()
    z = 2.3 - back if counter else -0.2
    v = render(Room.rectangle(5.0, 6.0, floor_style=style, boxes=boxes),
               Pose(0.2, z, 1.45, yaw_deg=3.0, pitch_deg=0.0), W, H, hfov_deg=70.0, seed=seed)
    image = cv2.imdecode(cv2.imencode(".jpg", v.image, [cv2.IMWRITE_JPEG_QUALITY, 95])[1],
                         cv2.IMREAD_COLOR)
    return v, hypothesize(image, v.camera, "findme", 10, camera_height=1.45)


@pytest.mark.parametrize("seed,back", [(1, 0.8), (4, 0.8), (9, 1.0)])
def test_a_level_photo_of_a_counter_shows_no_floor(seed, back):
    """No floor is in the photo, only the counter's top and the wall. The best boundary is
    "no floor visible": no point is measured. The boundary that was best comes second: the
    counter top's back edge, smooth below, not flat across (the counter and the paint
    differ); on it the wall's points came out 2.6x too far, the truth about 3 sigma off."""
    v, hs = _kitchen(seed, back)
    assert not (v.labels == 0).any()                      # the premise: no floor in view
    top, second = hs.hypotheses[0], hs.hypotheses[1]
    assert np.all(top.kinds == NONE)
    assert flat.runs_over_no_floor(second.smooth) and not flat.separates_nothing(second.flat)
    view = judge(hs, v.camera, 1.45)
    assert not view.ok and "no floor is in the photo" in view.reason
    us, vs = np.meshgrid(np.arange(20, W, 40), np.arange(20, H, 40))
    px = np.column_stack([us.ravel(), vs.ravel()]).astype(float)
    px = px[(v.labels[px[:, 1].astype(int), px[:, 0].astype(int)] >= 10)
            & (v.labels[px[:, 1].astype(int), px[:, 0].astype(int)] < 50)]   # on walls
    kw = dict(boundary_sigma_px=boundary_sigma_px(W, H), height_sigma=0.0)
    assert all(p.xyz is None for p in Scene(v.camera, 1.45, top.polyline, top.kinds,
                                            **kw).locate(px))
    was = Scene(v.camera, 1.45, second.polyline, second.kinds, **kw).locate(px)
    got = [(np.linalg.norm(p.xyz), np.linalg.norm(v.points_cam[int(p.pixel[1]),
                                                               int(p.pixel[0])]), p.sigma_m)
           for p in was if p.xyz is not None]
    assert len(got) >= 0.5 * len(px)
    # 2.6x too far (1.45 / 0.55: the counter top's height taken for the floor's), with a
    # 1-sigma that puts the truth about 3 sigma off
    assert all(d > 2.4 * t and d - t > 2.5 * s for d, t, s in got)


@pytest.mark.parametrize("style,seed", [("wood", 1), ("carpet", 4), ("wood", 9)])
def test_a_level_photo_of_a_floor_is_judged_as_before(style, seed):
    """The same room without the counter, 3.2 m from the wall: the floor's grain is under the
    best boundary, which is not smooth and stays first (a wall on the floor's edge)."""
    v, hs = _kitchen(seed, counter=False, style=style)
    top = hs.hypotheses[0]
    assert np.all(top.kinds != NONE) and not flat.runs_over_no_floor(top.smooth)
    assert judge(hs, v.camera, 1.45).ok
