"""Tests of the photometric agreement of two photos under a planar motion
(findme_core.motion.photometric) on rendered rooms with exact layouts: the true motion
correlates, a wrong one (moved, or turned a quarter) does not; an exposure change does not
matter; blank walls say nothing; a photo without layout is only looked up."""

from __future__ import annotations

import math

import numpy as np
import pytest

from findme_core.motion import photometric as mp
from findme_core.single.layout import from_hypothesis
from findme_core.synth.render import Box, Pose, Room, planar_motion, render
from tests.core.layout_rooms import exact_polyline

ROOM = Room.rectangle(5.0, 6.0, floor_style="carpet", boxes=(Box(1.0, 1.6, 0.8, 0.5, 0.9, 20),))
POSES = (Pose(0.2, -1.6, 1.45, -5.0, 22.0, 2.0), Pose(0.6, -1.0, 1.45, 12.0, 25.0, -2.0))


def _surfaces(images=None):
    out = []
    for k, pose in enumerate(POSES):
        v = render(ROOM, pose, 320, 240, hfov_deg=70.0, seed=3, supersample=1)
        lay = from_hypothesis(v.camera, pose.height, *exact_polyline(v))
        img = v.image if images is None else images[k](v.image)
        out.append(mp.surface(img, v.camera, lay))
    return out


def _truth():
    x, z, yaw = planar_motion(*POSES)
    return math.radians(yaw), np.array([x, 0.0, z])


def test_the_true_motion_correlates_and_wrong_ones_do_not():
    sa, sb = _surfaces()
    yaw, t = _truth()
    moved = t + np.array([0.4, 0.0, -0.3])
    corr, n = mp.agreement(sa, sb, [yaw, yaw, yaw + math.pi / 2], np.stack([t, moved, t]))
    assert n[0] > 1000                                  # both see much of each other
    assert corr[0] > 0.15
    assert corr[1] < 0.5 * corr[0] and corr[2] < 0.5 * corr[0]
    assert corr[0] * n[0] > 3 * max(corr[1] * n[1], corr[2] * n[2])


def test_an_exposure_change_barely_matters():
    """A brightness offset cancels in the local normalisation; lower contrast shrinks only
    the faint texture's values (near the ``flat`` floor)."""
    yaw, t = _truth()
    c0, _ = mp.agreement(*_surfaces(), yaw, t)
    same = lambda im: im  # noqa: E731
    brighter = _surfaces([same, lambda im: (np.minimum(im.astype(int) + 30, 255)).astype(np.uint8)])
    flatter = _surfaces([same, lambda im: (0.6 * im.astype(float) + 40).astype(np.uint8)])
    assert mp.agreement(*brighter, yaw, t)[0][0] == pytest.approx(c0[0], rel=0.05)
    assert mp.agreement(*flatter, yaw, t)[0][0] > 0.7 * c0[0]


def test_blank_walls_say_nothing():
    blank = _surfaces([lambda im: np.full_like(im, 128)] * 2)
    yaw, t = _truth()
    corr, n = mp.agreement(*blank, yaw, t)
    assert n[0] > 1000 and corr[0] == pytest.approx(0.0, abs=1e-6)


def test_a_photo_without_layout_is_only_looked_up():
    """B without a layout (no floor seen, no hypothesis) places no sample of its own, but A's
    samples are still found in B's image (every pixel counts as visible); two photos
    without layouts, or a missing photo, give no evidence."""
    sa, sb = _surfaces()
    v = render(ROOM, POSES[1], 320, 240, hfov_deg=70.0, seed=3, supersample=1)
    bare = mp.surface(v.image, v.camera, None)
    assert len(bare.points) == 0 and bare.layout is None
    yaw, t = _truth()
    c_full, n_full = mp.agreement(sa, sb, yaw, t)
    c_bare, n_bare = mp.agreement(sa, bare, yaw, t)
    assert 0 < n_bare[0] < n_full[0] and c_bare[0] > 0.15
    corr, n = mp.agreement(bare, bare, [0.0], np.zeros((1, 3)))
    assert corr.tolist() == [0.0] and n.tolist() == [0]
    corr, n = mp.agreement(sa, None, [0.0, 0.1], np.zeros((2, 3)))
    assert corr.tolist() == [0.0, 0.0] and n.tolist() == [0, 0]


def _lookup(L, az):
    """The nearest scan sample by a binary search, as the registration looked it up before
    ``Scan``: the reference."""
    n = len(L.azimuth)
    i = np.clip(np.searchsorted(L.azimuth, az), 1, n - 1)
    j = np.where(az - L.azimuth[i - 1] < L.azimuth[i] - az, i - 1, i)
    return j, np.abs(az - L.azimuth[j]) < 1.5 * L.spacing


def test_the_nearest_scan_sample_is_the_registers():
    """``Scan.nearest`` (bins, no search) answers as a binary search: on the samples,
    between them, at its bins' edges and one rounding step either side of them, and beyond
    both ends of the scan; halfway between two samples (a tie, up to rounding) it picks one
    of the two; NaN is never near. Without bins (samples closer than the bins allow) the
    binary search gives the same."""
    from findme_core.single.layout import Layout
    from findme_core.geometry.scan import Scan
    lay = _surfaces()[0].layout
    a = lay.azimuth
    scan = Scan(lay)
    assert scan.bins is not None
    scale, first, n = scan.bins[:3]
    edges = (first + np.arange(n)) / scale
    rng = np.random.default_rng(0)
    az = np.concatenate([a, rng.uniform(a[0] - 0.5, a[-1] + 0.5, 5000), edges,
                         np.nextafter(edges, -9.0), np.nextafter(edges, 9.0),
                         [-math.pi, math.pi, a[0] - 2 * lay.spacing, a[-1] + 2 * lay.spacing]])
    j, near = scan.nearest(az)
    j0, near0 = _lookup(lay, az)
    assert np.array_equal(near, near0) and 1000 < near.sum() < len(az) - 1000
    assert np.array_equal(j[near], j0[near])
    assert not near[-2:].any()
    m = scan.middles
    for ties in (m, np.nextafter(m, -9.0), np.nextafter(m, 9.0)):
        j, near = scan.nearest(ties)
        assert near.all() and set(j - np.arange(len(m))) <= {0, 1}
        assert np.array_equal(j, np.searchsorted(m, ties, side="right"))
    assert not scan.nearest(np.array([np.nan]))[1].any()
    one = scan.nearest(float(a[4]))
    assert np.shape(one[0]) == () and one[0] == 4 and one[1]
    close = Layout(lay.walls, lay.ends, np.concatenate([a[:3], a[3] - [2e-8, 1e-8], a[3:]]),
                   *(np.insert(x, 3, [x[3], x[3]]) for x in (lay.range, lay.kind, lay.sigma,
                                                             lay.wall)), lay.height)
    slow = Scan(close)
    assert slow.bins is None
    j, near = slow.nearest(az)
    j0, near0 = _lookup(close, az)
    assert np.array_equal(near, near0) and np.array_equal(j[near], j0[near])


def test_motions_at_once_as_one_at_a_time():
    """C motions scored together give each motion's own answer (one matrix product for all
    of them), both ways and with a photo without layout."""
    sa, sb = _surfaces()
    yaw, t = _truth()
    yaws = yaw + np.array([0.0, 0.05, -0.3, math.pi / 2])
    ts = t + np.array([[0.0, 0.0, 0.0], [0.2, 0.0, -0.1], [-0.5, 0.0, 0.4], [0.0, 0.0, 0.0]])
    v = render(ROOM, POSES[1], 320, 240, hfov_deg=70.0, seed=3, supersample=1)
    bare = mp.surface(v.image, v.camera, None)
    for a, b in ((sa, sb), (sb, sa), (sa, bare)):
        corr, n = mp.agreement(a, b, yaws, ts)
        for k in range(len(yaws)):
            c1, n1 = mp.agreement(a, b, yaws[k], ts[k])
            assert n1[0] == n[k] and c1[0] == pytest.approx(corr[k], abs=1e-9)
        assert n.max() > 1000
