"""``findme plan --svg``'s drawing (findme_io/plan_svg.py) measured in headless Chromium with
its real fonts: no wall label covers its wall's line, whatever the wall's direction, and
every label lies inside the drawing; each measured corner is drawn with its 1-sigma."""

from __future__ import annotations

import re
from dataclasses import replace

import numpy as np
import pytest

from findme_core.plan.floorplan import Plan, Wall
from findme_io.plan_svg import plan_svg

pytestmark = pytest.mark.timeout(120)


def _plan(polygon, seen) -> Plan:
    P = np.asarray(polygon, float)
    walls = []
    for k, ok in enumerate(seen):
        a, b = P[k], P[(k + 1) % len(P)]
        walls.append(Wall(a, b, float(np.linalg.norm(b - a)), 0.05, ok))
    return Plan(P, tuple(walls), 12.0, np.array([[0.5, 0.5, 0.3]]), False)


PLANS = {
    "rectangle": _plan([(0, 0), (4, 0), (4, 3), (0, 3)], (True, False, True, True)),
    "slanted": _plan([(0, 0), (3, -0.5), (4.5, 1.5), (2.5, 3.6), (-0.4, 2.2)],
                     (True, True, False, True, True)),
    "small": _plan([(0, 0), (0.9, 0), (0.9, 0.7), (0, 0.7)], (True,) * 4),
}


def _dist_to_box(a, b, box) -> float:
    """Distance from segment a-b to an axis-aligned box (x, y, w, h); 0 when they meet."""
    x0, y0, x1, y1 = box["x"], box["y"], box["x"] + box["width"], box["y"] + box["height"]
    ts = np.linspace(0.0, 1.0, 400)
    pts = a[None] + ts[:, None] * (b - a)[None]
    dx = np.maximum.reduce([x0 - pts[:, 0], np.zeros(len(ts)), pts[:, 0] - x1])
    dy = np.maximum.reduce([y0 - pts[:, 1], np.zeros(len(ts)), pts[:, 1] - y1])
    return float(np.hypot(dx, dy).min())


@pytest.mark.parametrize("name", sorted(PLANS))
@pytest.mark.parametrize("feet", [False, True])
def test_wall_labels_clear_their_lines(browser, name, feet):
    svg = plan_svg(PLANS[name], ["p0"], feet=feet)
    page = browser.new_page()
    page.set_content(f"<!doctype html><body style='margin:0'>{svg}</body>")
    got = page.evaluate("""() => {
        const svg = document.querySelector('svg');
        const lines = [...svg.querySelectorAll('line[stroke-width="3"]')].map(l =>
            [+l.getAttribute('x1'), +l.getAttribute('y1'), +l.getAttribute('x2'), +l.getAttribute('y2')]);
        const labels = [...svg.querySelectorAll('text.wall-label')].map(t => {
            const b = t.getBBox(); return {x: b.x, y: b.y, width: b.width, height: b.height,
                                           text: t.textContent}; });
        const vb = svg.viewBox.baseVal;
        return {lines, labels, w: vb.width, h: vb.height}; }""")
    page.close()
    assert len(got["lines"]) == len(got["labels"]) == len(PLANS[name].walls)
    for (x1, y1, x2, y2), box in zip(got["lines"], got["labels"]):
        d = _dist_to_box(np.array([x1, y1]), np.array([x2, y2]), box)
        assert d > 1.5 + 1.0, f"{box['text']!r} is {d:.1f} px from its wall (stroke 3 px)"
        assert box["x"] >= 0 and box["y"] >= 0, box
        assert box["x"] + box["width"] <= got["w"] and box["y"] + box["height"] <= got["h"], box


def test_each_measured_corner_is_drawn_with_its_sigma():
    """Corners with a 1-sigma get an ellipse of that size (80 px a metre) at the corner; the
    two ends of the wall nobody saw, inferred, get none."""
    sig = np.array([[0.05, 0.1], [np.nan, np.nan], [np.nan, np.nan], [0.2, 0.04]])
    # rectangle: wall 1 (vertex 1 to 2) not seen, so corners 1 and 2 are inferred
    svg = plan_svg(replace(PLANS["rectangle"], corner_sigma=sig), ["p0"])
    got = [tuple(float(v) for v in m) for m in re.findall(
        r'<ellipse class="corner-sigma" cx="([\d.]+)" cy="([\d.]+)" rx="([\d.]+)" '
        r'ry="([\d.]+)"', svg)]
    assert [g[2:] for g in got] == [(4.0, 8.0), (16.0, 3.2)]
    # at corners (0, 0) and (0, 3): the same x, 3 m = 240 px apart (the page's y runs down)
    assert got[0][0] == got[1][0] and got[0][1] - got[1][1] == pytest.approx(240.0, abs=0.2)
    assert "corner-sigma" not in plan_svg(PLANS["rectangle"], ["p0"])
