"""``tools/coverage_plot.py``: the share beyond k sigma of known normalised errors, a
Gaussian's, and the figure's panels and curves from a ``sigma_coverage.collect`` result."""

import math
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tools"))
import coverage_plot as cp  # noqa: E402

SVG = "{http://www.w3.org/2000/svg}"


def test_share_beyond_k_sigma_of_known_errors():
    z = np.array([0.5, 1.0, 1.5, 2.5, 3.5])
    # beyond 0: all five; beyond 1: 1.5, 2.5, 3.5 (1.0 is within); beyond 3: 3.5 alone
    assert np.allclose(cp.beyond(z, np.array([0.0, 1.0, 3.0, 4.0])), [1.0, 0.6, 0.2, 0.0])


def test_gaussian_share_beyond():
    g = cp.gaussian(np.array([0.0, 1.0, 2.0, 3.0]))
    assert g[0] == 1.0
    assert np.allclose(g[1:], [0.3173, 0.0455, 0.0027], atol=1e-4)


def test_shares_map_onto_the_log_axis():
    y0 = 10.0
    assert cp._y(1.0, y0) == y0                       # share 1 at the top
    assert cp._y(cp.FLOOR, y0) == y0 + cp.PH          # the floor at the bottom
    assert cp._y(0.0, y0) == y0 + cp.PH               # none beyond: drawn at the floor
    mid = math.sqrt(cp.FLOOR)                          # halfway on a log scale
    assert cp._y(mid, y0) == pytest.approx(y0 + cp.PH / 2)


def test_figure_has_a_panel_per_family_and_a_curve_pair_per_quantity():
    rng = np.random.default_rng(0)
    items = lambda n, scale: [(f"room{i % 3}", abs(float(e)), 1.0)   # noqa: E731
                              for i, e in enumerate(rng.normal(0, scale, n))]
    collected = {"floor points (zind)": items(60, 1.0), "wall points (zind)": items(60, 3.0),
                 "motion x (zind-pairs-level)": items(12, 1.0),
                 "motion z (zind-pairs-level)": items(9, 1.0)}   # under 10 items: left out
    root = ET.fromstring(cp.svg(collected, "test"))
    texts = [t.text for t in root.iter(SVG + "text")]
    assert "points" in texts and "pair motion" in texts
    assert "distances and plans" not in texts               # no such quantity
    legend = [t for t in texts if t and "(" in t and ":" in t]
    assert any(t.startswith("floor points (zind) (60)") for t in legend)
    assert not any(t.startswith("motion z") for t in legend)
    # per quantity a dotted (left out) and a solid (as stated) curve, plus a Gaussian a panel
    lines = list(root.iter(SVG + "polyline"))
    assert len(lines) == 2 * 3 + 2
    # the wall points' errors are three times their sigma: their solid curve lies above
    # the floor points' beyond 2 sigma (smaller row = larger share)
    solid = [ln for ln in lines if ln.get("stroke-dasharray") is None]
    rows = [[float(p.split(",")[1]) for p in ln.get("points").split()] for ln in solid]
    k2 = int(2.0 / cp.K_MAX * (len(rows[0]) - 1))
    assert rows[1][k2] < rows[0][k2]


def test_nothing_to_draw_says_so():
    with pytest.raises(SystemExit, match="nothing to draw"):
        cp.svg({"floor points (zind)": [("room1", 1.0, 1.0)] * 3})
