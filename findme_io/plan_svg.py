"""A floor plan as an SVG drawing: walls with their lengths (metres or feet), walls not seen
dashed, openings, each photo's position and heading; optionally a truth outline under it.

Seen from above: x to the right, z up the page (the room frame's forward axis).
"""

from __future__ import annotations

import math
from xml.sax.saxutils import escape

import numpy as np

from findme_core.plan.floorplan import Plan

FT_PER_M = 3.280839895
FONT_PX = 12
#: a label's box, estimated (no font metrics here): width per character and height, px;
#: generous for sans-serif at FONT_PX
CHAR_W_PX, TEXT_H_PX = 0.62 * FONT_PX, FONT_PX
#: clearance between a wall's line (its stroke included) and its label's box, px
LABEL_GAP_PX = 5.0


def length_text(m: float, feet: bool = False) -> str:
    """'3.42 m' or "11' 2\"" (feet and inches)."""
    if not feet:
        return f"{m:.2f} m"
    inches = round(m * FT_PER_M * 12)
    return f"{inches // 12}' {inches % 12}\""


def label_box(mid_px, outward, text: str) -> tuple[float, float, float, float]:
    """(x, y baseline, width, height) of a wall label in page pixels: horizontal text whose
    estimated box lies ``LABEL_GAP_PX`` beyond the wall's line on the ``outward`` side (a
    unit page-pixel direction), so that it never covers the line whatever the wall's slope.
    The text is centred on x (``text-anchor="middle"``); its baseline is y."""
    w, h = CHAR_W_PX * len(text), TEXT_H_PX
    nx, ny = outward
    reach = LABEL_GAP_PX + abs(nx) * w / 2 + abs(ny) * h / 2   # box centre's distance
    cx, cy = mid_px[0] + nx * reach, mid_px[1] + ny * reach
    return cx, cy + 0.35 * h, w, h


def plan_svg(plan: Plan, names=None, truth=None, feet: bool = False, px_per_m: float = 80.0,
             title: str | None = None) -> str:
    """SVG text of the plan. ``truth``: (T, 2) outline drawn in grey underneath."""
    pts = [plan.polygon] + ([np.asarray(truth, float)] if truth is not None else [])
    fin = plan.poses[np.isfinite(plan.poses[:, 0])]
    if len(fin):
        pts.append(fin[:, :2])
    allp = np.concatenate(pts)
    longest = max((len(length_text(w.length_m, feet)) + 11 for w in plan.walls), default=0)
    margin = max(0.8, (LABEL_GAP_PX + CHAR_W_PX * longest + 4) / px_per_m)   # room for labels
    lo, hi = allp.min(0) - margin, allp.max(0) + margin
    W, H = (hi - lo) * px_per_m

    def P(p):
        return f"{(p[0] - lo[0]) * px_per_m:.1f},{(hi[1] - p[1]) * px_per_m:.1f}"

    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W:.0f}" height="{H + 24:.0f}" '
           f'viewBox="0 0 {W:.0f} {H + 24:.0f}" font-family="sans-serif" '
           f'font-size="{FONT_PX}">',
           '<rect width="100%" height="100%" fill="white"/>']
    if title:
        out.append(f'<text x="6" y="{H + 18:.0f}" fill="#333">{escape(title)}</text>')
    if truth is not None:
        out.append(f'<polygon points="{" ".join(P(p) for p in truth)}" fill="none" '
                   'stroke="#999" stroke-width="6" stroke-opacity="0.6"/>')
    out.append(f'<polygon points="{" ".join(P(p) for p in plan.polygon)}" fill="#eef5ff" '
               'stroke="none"/>')
    for w in plan.walls:
        dash = "" if w.seen else ' stroke-dasharray="6,5"'
        out.append(f'<line x1="{P(w.a).split(",")[0]}" y1="{P(w.a).split(",")[1]}" '
                   f'x2="{P(w.b).split(",")[0]}" y2="{P(w.b).split(",")[1]}" '
                   f'stroke="{"#1a4f9c" if w.seen else "#c0392b"}" stroke-width="3"{dash}/>')
        u = (w.b - w.a) / max(w.length_m, 1e-9)
        for f0, f1 in w.apertures:
            a, b = w.a + f0 * u, w.a + f1 * u
            out.append(f'<line x1="{P(a).split(",")[0]}" y1="{P(a).split(",")[1]}" '
                       f'x2="{P(b).split(",")[0]}" y2="{P(b).split(",")[1]}" stroke="#f5a623" '
                       'stroke-width="5"/>')
        label = length_text(w.length_m, feet) + ("" if w.seen else " (not seen)")
        mid = [float(c) for c in P((w.a + w.b) / 2).split(",")]
        # outside a CCW outline: right of a -> b seen from above; the page's y runs down
        x, y, _, _ = label_box(mid, (u[1], u[0]), label)
        out.append(f'<text x="{x:.1f}" y="{y:.1f}" text-anchor="middle" fill="#222" '
                   f'class="wall-label">{escape(label)}</text>')
    for v, sg in zip(plan.polygon, plan.corner_sigma):   # where a measured corner may be
        if np.all(np.isfinite(sg)):
            x, y = P(v).split(",")
            out.append(f'<ellipse class="corner-sigma" cx="{x}" cy="{y}" '
                       f'rx="{sg[0] * px_per_m:.1f}" ry="{sg[1] * px_per_m:.1f}" fill="#f5a623" '
                       'fill-opacity="0.3" stroke="#b26a00" stroke-width="1"/>')
    for k, p in enumerate(plan.poses):
        if not np.isfinite(p[0]):
            continue
        f = p[:2] + 0.35 * np.array([math.sin(p[2]), math.cos(p[2])])
        x0, y0 = P(p[:2]).split(",")
        x1, y1 = P(f).split(",")
        out.append(f'<line x1="{x0}" y1="{y0}" x2="{x1}" y2="{y1}" stroke="#2e7d32" '
                   'stroke-width="1.5"/>')
        out.append(f'<circle cx="{x0}" cy="{y0}" r="3.5" fill="#2e7d32">'
                   f'<title>{escape(str(names[k]) if names else str(k))}</title></circle>')
    out.append("</svg>")
    return "\n".join(out)
