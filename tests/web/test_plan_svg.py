"""``findme plan --svg``'s drawing (findme_io/plan_svg.py) measured in headless Chromium with
its real fonts: no wall label covers its wall's line, whatever the wall's direction, and
every label lies inside the drawing."""

from __future__ import annotations

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
