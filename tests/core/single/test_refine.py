import numpy as np
import pytest

from findme_core.geometry.camera import Camera
from findme_core.single.appearance import to_lab
from findme_core.single.refine import SnapParams, _band_end, _offsets, prefetch, snap_polyline
from findme_core.single.methods import hypothesize
from findme_core.single.search import SegKind
from findme_core.synth.render import render
from findme_core.synth.room import Pose, Room


def _scene(band_bgr, floor_bgr=(120, 130, 140), planks_bgr=None):
    """Wall above row 400, a 14 px band (a 12 cm baseboard seen from 1.4 m), then floor; a
    level camera (horizon at row 239.5). ``planks_bgr``: every other 6 rows of the floor
    take this colour (floorboards along the wall: a floor colour that never settles)."""
    img = np.zeros((480, 640, 3), np.uint8)
    img[:400] = (235, 235, 235)
    img[400:414] = band_bgr
    img[414:] = floor_bgr
    if planks_bgr is not None:
        for r in range(420, 480, 12):
            img[r:r + 6] = planks_bgr
    rng = np.random.default_rng(0)
    img = np.clip(img + rng.normal(0, 2, img.shape), 0, 255).astype(np.uint8)
    return to_lab(img), Camera.from_hfov(70, 640, 480)


def test_snaps_to_the_bottom_of_a_baseboard():
    lab, cam = _scene((40, 60, 110))  # brown wood
    out = snap_polyline(lab, cam, np.array([[0, 400.0], [639, 400.0]]), np.array([SegKind.WALL]))
    assert out[:, 1] == pytest.approx([414.0, 414.0], abs=1.5)


def test_snaps_to_the_bottom_of_a_baseboard_over_floorboards():
    """Floorboards along the wall: the floor's colour changes every 6 rows and never settles
    within the search; the uniform grey band under the line still ends at the floor."""
    lab, cam = _scene((95, 100, 105), floor_bgr=(60, 100, 150), planks_bgr=(40, 75, 120))
    out = snap_polyline(lab, cam, np.array([[0, 400.0], [639, 400.0]]), np.array([SegKind.WALL]))
    assert out[:, 1] == pytest.approx([414.0, 414.0], abs=1.5)


def test_a_rendered_wall_base_behind_a_baseboard_on_a_wood_floor():
    """The test suite's rendered room (8 cm baseboard, wood floor), a photo facing the back
    wall 1.8 m away, 30 deg down: the best boundary is the wall's base, not the baseboard's
    top edge 14 px above it (which puts the wall 10 cm too far)."""
    v = render(Room.rectangle(5.0, 4.0), Pose(0.3, -0.2, 1.4, 180.0, 30.0, 0.0), 640, 480,
               hfov_deg=70.0, supersample=1)
    poly = hypothesize(v.image, v.camera, "findme", 1).hypotheses[0].polyline
    rows = np.interp(np.arange(640), poly[:, 0], poly[:, 1])
    truth = np.asarray(v.boundary_v, float)
    ok = np.isfinite(truth)
    assert ok.sum() > 600
    assert np.median(np.abs(rows[ok] - truth[ok])) < 2.5


def test_leaves_a_contact_shadow_alone():
    lab, cam = _scene((70, 78, 85))   # the floor's colour, darker
    poly = np.array([[0, 400.0], [639, 400.0]])
    assert np.array_equal(snap_polyline(lab, cam, poly, np.array([SegKind.WALL])), poly)


def test_leaves_a_clean_boundary_and_other_segments_alone():
    lab, cam = _scene((120, 130, 140))  # no band: the floor starts at row 300
    poly = np.array([[0, 400.0], [639, 400.0]])
    assert np.array_equal(snap_polyline(lab, cam, poly, np.array([SegKind.WALL])), poly)
    lab2, _ = _scene((40, 60, 110))
    assert np.array_equal(snap_polyline(lab2, cam, poly, np.array([SegKind.OPEN])), poly)


def test_prefetching_every_lines_band_at_once_snaps_as_one_by_one():
    """``prefetch`` measures the bands of all the hypotheses' lines in one remap; snapping
    from its cache gives, bit for bit, what snapping each polyline alone gives, including a
    line whose first segment is too short to tell and a later one of it is long enough."""
    lab, cam = _scene((40, 60, 110))
    W = int(SegKind.WALL)
    polys = [   # (polyline, kinds, the image line of each segment)
        (np.array([[0, 400.0], [639, 400.0]]), np.array([W]), [0]),
        (np.array([[0, 430.0], [8, 400.0], [639, 400.0]]), np.array([W, W]), [1, 0]),
        (np.array([[0, 400.0], [6, 400.0], [639, 450.0]]), np.array([W, W]), [2, 3]),
        (np.array([[0, 400.0], [300, 400.0], [639, 400.0]]), np.array([W, W]), [2, 0]),
    ]
    alone, cache_a = [], {}
    for poly, kinds, keys in polys:
        alone.append(snap_polyline(lab, cam, poly, kinds, cache=cache_a, keys=keys))
    cache_b: dict = {}
    prefetch(lab, cam, polys, SnapParams(), cache_b)
    assert 2 not in cache_b            # its first segment (6 px) is too short to tell
    batched = [snap_polyline(lab, cam, poly, kinds, cache=cache_b, keys=keys)
               for poly, kinds, keys in polys]
    for a, b in zip(alone, batched):
        assert np.array_equal(a, b)
    assert cache_a == cache_b
    assert batched[0][:, 1] == pytest.approx([414.0, 414.0], abs=1.5)


@pytest.mark.parametrize("band_len, band, edge_at, expect", [
    (4, (80.0, 128.0, 134.0), None, 7),     # a grey band 4 samples long: ends at index 7
    (1, (80.0, 128.0, 134.0), None, None),  # one sample is no band
    (4, (88.0, 134.0, 144.0), None, None),  # the floor's own colour: not a baseboard
    (4, (80.0, 128.0, 134.0), 0.20, None),  # its lower edge beyond max_rel (0.16)
])
def test_a_band_below_the_line_ends_at_its_lower_edge_or_is_none(band_len, band, edge_at,
                                                                 expect):
    """``_band_end`` on a profile: wall above the line (index ``start``), then a band of
    ``band_len`` samples, then a floor of planks whose colour alternates and never settles."""
    p = SnapParams()
    s = _offsets(p)
    start = int(np.searchsorted(s, 0.0))
    n_band = band_len if edge_at is None else int(round(edge_at / p.s_step))
    prof = np.empty((len(s), 3), np.float32)
    prof[:start + 1] = (160.0, 129.0, 139.0)
    prof[start + 1:start + 1 + n_band] = band
    planks = np.array([(102.0, 136.0, 146.0), (78.0, 134.0, 142.0)], np.float32)
    first = start + 1 + n_band
    for i in range(first, len(s)):
        prof[i] = planks[((i - first) // 2) % 2]
    floor = np.array([88.0, 134.0, 144.0], np.float32)
    assert _band_end(prof, s, start, floor, p) == expect
