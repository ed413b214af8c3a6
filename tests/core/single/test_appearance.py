"""Colour statistics of a floor / not-floor split (``single/appearance``): the Lab image and
the prefix moments are exact, whichever code path computes them."""

from __future__ import annotations

import cv2
import numpy as np

from findme_core.single.appearance import RegionStats, to_lab


def test_to_lab_gives_opencvs_bytes_for_every_colour_and_leaves_the_ipp_switch_alone():
    """to_lab bypasses Intel IPP (faster here): the bytes must be those of a plain cvtColor
    with IPP on, for all 2^24 colours, and the thread's IPP switch must be as it was."""
    v = np.arange(1 << 24, dtype=np.uint32)
    img = np.stack([(v >> 16) & 255, (v >> 8) & 255, v & 255], -1).astype(np.uint8)
    img = img.reshape(4096, 4096, 3)
    before = cv2.ipp.useIPP()
    try:
        cv2.ipp.setUseIPP(True)
        want = cv2.cvtColor(img, cv2.COLOR_BGR2LAB)
        got = to_lab(img)
        assert cv2.ipp.useIPP() is True
        assert np.array_equal(got, want)
    finally:
        cv2.ipp.setUseIPP(before)
    grey = img[:64, :64, 0]
    assert np.array_equal(to_lab(grey), cv2.cvtColor(cv2.cvtColor(grey, cv2.COLOR_GRAY2BGR),
                                                     cv2.COLOR_BGR2LAB))


def test_region_gain_is_the_moments_of_the_pixels_below_each_boundary():
    """gain from the prefix tables equals the gain computed from the sampled pixels
    themselves: a two-colour image split at its colour edge gains, split elsewhere less."""
    rng = np.random.default_rng(0)
    img = np.empty((120, 160, 3), np.uint8)
    img[:70] = (40, 90, 160)
    img[70:] = (150, 120, 60)
    img = np.clip(img + rng.normal(0, 3, img.shape), 0, 255).astype(np.uint8)
    lab = to_lab(img)
    st = RegionStats(lab, n_cols=16, row_step=2)
    rows = np.array([np.full(16, 70.0), np.full(16, 30.0), np.full(16, 100.0)])
    g = st.gain(rows)

    def direct(row):
        x = lab[::2, st.cols].astype(np.float64)           # the sampled pixels (R, C, 3)
        r = np.arange(x.shape[0])[:, None] * 2
        floor = np.broadcast_to(r >= row, x.shape[:2])

        def half_logdet(p):
            return 0.5 * np.linalg.slogdet(np.cov(p.T, bias=True) + 4.0 * np.eye(3))[1]

        a, f, o = x.reshape(-1, 3), x[floor], x[~floor]
        return (half_logdet(a) - len(f) / len(a) * half_logdet(f)
                - len(o) / len(a) * half_logdet(o))

    assert np.allclose(g, [direct(70), direct(30), direct(100)], atol=1e-9)
    assert g[0] > 1.0 and g[0] > 2 * max(g[1], g[2])
