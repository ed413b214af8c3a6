import math

import numpy as np
import pytest

from findme_core.geometry.camera import Camera
from findme_core.single.paths import path_features, path_pieces, path_rows
from findme_core.single.search import ADDITIVE, FORBIDDEN, Events, best_paths, farness


def _cam(pitch_deg=0.0):
    p = math.radians(pitch_deg)
    return Camera.from_hfov(80, 640, 480, [0.0, math.cos(p), math.sin(p)])


def test_farness_from_the_depression_below_the_horizon():
    cam = _cam()
    u = np.arange(640, dtype=float)
    # rows whose rays at the centre column point 2, 6 and 12 deg below the horizon
    rows = np.array([cam.cy + cam.fy * math.tan(math.radians(d)) for d in (2.0, 6.0, 12.0)])
    f = farness(np.repeat(rows[:, None], 640, 1), cam, 6.0)
    c = int(round(cam.cx))
    assert f[0, c] == pytest.approx(1 - math.sin(math.radians(2)) / math.sin(math.radians(6)),
                                    abs=1e-3)
    assert f[1, c] == pytest.approx(0.0, abs=1e-3) and f[2].max() == 0.0
    # a row reads as farther towards the image sides (the ray is longer): never nearer
    assert (np.diff(f[0, c:]) >= -1e-12).all()
    # degenerate: at and above the horizon, and far outside the image, stay in [0, 1]
    g = farness(np.array([[cam.cy] * 640, [cam.cy - 100] * 640, [1e7] * 640]), cam, 6.0)
    assert (g[0] == 1.0).all() and (g[1] == 1.0).all() and (g[2] == 0.0).all()
    # a camera looking 30 deg down sees its image centre row 30 deg below the horizon
    assert farness(np.full((1, 640), 239.5), _cam(30), 6.0).max() == 0.0


def _events(rows):
    """Events from (src, dst, col, step) rows."""
    a = np.array(rows, float).reshape(-1, 4)
    return Events(a[:, 0].astype(int), a[:, 1].astype(int), a[:, 2].astype(int),
                  a[:, 2] - 0.5, a[:, 3].astype(bool))


def test_best_paths_through_corners_and_pieces():
    """Three tracks over 10 columns: track 0 rewarded on the left, track 1 on the right,
    track 2 ("no floor") flat; a corner 0 -> 1 at column 5 gives the best path."""
    W = 10
    gain = np.zeros((3, W))
    gain[0, :5] = 1.0
    gain[1, 5:] = 1.0
    A = np.zeros((3, W + 1))
    A[:, 1:] = np.cumsum(gain, axis=1)
    valid = np.ones((3, W), bool)
    valid[1, :2] = False   # track 1 is above the horizon in the first two columns
    ev = _events([(0, 1, 5, 0), (1, 0, 7, 0), (0, 2, 3, 1)])
    paths = best_paths(A, valid, ev, corner_cost=0.5, step_cost=1.0)
    assert paths[0] == (pytest.approx(10 - 0.5), 0, (0,))
    totals = [p[0] for p in paths]
    assert totals == sorted(totals, reverse=True) and len({p[1:] for p in paths}) == len(paths)
    assert all(t > -FORBIDDEN / 2 for t in totals)          # nothing through column 0 of track 1
    assert (0.0 + 5.0, 0, ()) in [(round(p[0], 6), p[1], p[2]) for p in paths]  # track 0 alone
    pieces = path_pieces(paths, ev, W)
    rows = np.array([np.full(W, 100.0), np.full(W, 200.0), np.full(W, 479.5)])
    R = path_rows(pieces, rows, len(paths))
    assert (R[0, :5] == 100).all() and (R[0, 5:] == 200).all()
    F = np.zeros((len(ADDITIVE), 3, W + 1))
    F[0] = A   # the first additive feature: the reward itself
    feats = path_features(pieces, F, len(paths))
    assert feats.shape == (len(paths), len(ADDITIVE) + 2)
    assert feats[0, 0] == pytest.approx(10.0) and feats[0, -2:].tolist() == [1.0, 0.0]
    # degenerate: no events at all leaves the single spanning tracks only
    none = best_paths(A, valid, _events([]), 0.5, 1.0)
    assert sorted(p[1] for p in none) == [0, 2] and all(p[2] == () for p in none)
    assert path_pieces([], ev, W)[0].shape == (0,)


def test_the_search_and_the_ranking_name_the_same_additive_features():
    from findme_core.single.ranking import FEATURES, N_ADDITIVE
    assert tuple(FEATURES[:N_ADDITIVE]) == ADDITIVE


def test_only_lines_across_the_view_count_as_far():
    """Two lines 2 deg below the horizon of a level camera: the one across the view (a wall
    facing the camera ~30 camera heights away) is far, a receding one is not."""
    from findme_core.single.search import SearchParams, track_tables
    from findme_core.single.support import SupportTable
    cam = _cam()
    W = cam.width
    v = np.full((2, W), cam.cy + cam.fy * math.tan(math.radians(2.0)))
    z = np.zeros((2, W + 1))
    F, valid = track_tables(SupportTable(z, z, z, v), cam, SearchParams(),
                            front=np.array([True, False]))
    far = F[ADDITIVE.index("far")]
    assert far[0, -1] > 0.5 * W and (far[1] == 0).all() and (far[2:] == 0).all()
    assert valid[:2].all() and valid[-1].all()
    F_all, _ = track_tables(SupportTable(z, z, z, v), cam, SearchParams())
    assert F_all[ADDITIVE.index("far"), 1, -1] == far[0, -1]   # default: every line counts


def test_far_is_waived_over_textured_ground():
    """A front line 2 deg below the horizon counts as far over a smooth band (a counter
    top, a sill) and not over ground textured like a street's."""
    from findme_core.single.search import SearchParams, track_tables
    from findme_core.single.support import SupportTable
    cam, p = _cam(), SearchParams()
    W = cam.width
    v = np.full((3, W), cam.cy + cam.fy * math.tan(math.radians(2.0)))
    z = np.zeros((3, W + 1))
    tex = np.array([0.5, 5.0, (p.smooth_texture + p.ground_texture) / 2])
    asked = []

    def texture(rows, cols):   # asked at every far (line, column), line by line
        asked.append((len(rows), cols[:3].tolist()))
        return np.repeat(tex, W)
    F, _ = track_tables(SupportTable(z, z, z, v), cam, p, texture=texture)
    assert asked == [(3 * W, [0, 1, 2])]
    far = F[ADDITIVE.index("far"), :3, -1]
    F0, _ = track_tables(SupportTable(z, z, z, v), cam, p)
    full = F0[ADDITIVE.index("far"), 0, -1]
    assert far[0] == pytest.approx(full) and far[1] == 0.0
    assert far[2] == pytest.approx(0.5 * full)


def test_band_texture_is_the_mean_gradient_below_a_row():
    from findme_core.single.support import EdgeField, SupportParams
    rng = np.random.default_rng(0)
    img = np.full((120, 160, 3), 100, np.uint8)
    img[60:] = rng.integers(0, 255, (60, 160, 3), dtype=np.uint8)    # texture from row 60
    f = EdgeField(img, SupportParams())
    rows = np.array([np.full(160, 20.0), np.full(160, 70.0), np.full(160, 118.0)])
    t = f.band_texture(rows, offset_px=3, band_px=24)
    assert np.allclose(f.band_texture(rows[1, :5], np.arange(5)), t[1, :5])
    mag = np.sqrt(f.gx ** 2 + f.gy ** 2)
    assert np.allclose(t[1], mag[73:97].mean(0), rtol=1e-5)
    assert t[0].mean() < 0.2 * t[1].mean()            # rows 23-46: plain grey (blur reach)
    assert np.allclose(t[2], 0.0)                     # the band is below the image
