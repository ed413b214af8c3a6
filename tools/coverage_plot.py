"""Do the stated 1-sigmas hold, as a picture: the share of answers beyond k sigma against k.

    python tools/coverage_plot.py DATASET_DIR PREDICTIONS.json --out coverage.svg
        [--title TEXT]

One panel per family of stated quantities (points, distances and plans, pair motion,
gravity). Each curve is one quantity of ``sigma_coverage``'s table: the share of its answered
items whose error lies beyond k times the stated 1-sigma, for k from 0 to 4, on a log scale
so that the tail shows (solid: as stated; dotted: leave-one-room-out, each room's sigmas
scaled by the factor fitted on the other rooms, ``sigma_coverage.loro``). The dashed black
curve is a Gaussian's share, 1 - erf(k / sqrt 2): a calibrated sigma follows it. The green
bars are the goal (0.20-0.40 beyond 1 sigma, at most 0.03 beyond 3). A curve below the
Gaussian at 1 sigma states its sigma too wide; one that levels off above 0.03 at 3 sigma has
a tail of answers metres off (a wrong boundary), which no Gaussian sigma covers. Quantities
with fewer than 10 items are left out; a share of 0 is drawn at the bottom (``FLOOR``).
Writes one SVG file (no plotting library); reads the dataset's ground truth: a tool, not
the product.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from html import escape

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import sigma_coverage as sc  # noqa: E402

#: panels: (title, words one of which a quantity's name holds), first match wins
FAMILIES = (("points", ("points",)),
            ("distances and plans", ("distances", "plan", "wall length")),
            ("pair motion", ("motion",)),
            ("gravity from the image", ("gravity",)))
COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2",
           "#17becf", "#7f7f7f", "#bcbd22")
K_MAX = 4.0
MIN_ITEMS = 10
#: the lowest share drawn (a share of 0, none beyond, is drawn there)
FLOOR = 1e-3
#: panel size and margins, pixels
PW, PH, ML, MT, MB, LEGEND = 300, 220, 44, 28, 34, 330


def beyond(z: np.ndarray, ks: np.ndarray) -> np.ndarray:
    """(K,) share of the normalised errors ``z`` (|error| / sigma, any length > 0) beyond
    each multiple ``ks`` (K,) of sigma."""
    z = np.sort(np.asarray(z, float))
    return 1.0 - np.searchsorted(z, ks, side="right") / len(z)


def gaussian(ks: np.ndarray) -> np.ndarray:
    """(K,) share of a Gaussian's errors beyond ``ks`` sigma: 1 - erf(k / sqrt(2))."""
    return np.array([math.erfc(k / math.sqrt(2.0)) for k in ks])


def _y(share: float, y0: float) -> float:
    """The image row of a share on the panel's log axis (``FLOOR`` at the bottom)."""
    f = math.log10(max(share, FLOOR)) / math.log10(FLOOR)   # 0 at share 1, 1 at FLOOR
    return y0 + f * PH


def families(collected: dict) -> list[tuple[str, list[str]]]:
    """[(panel title, its quantities sorted)] of ``collect``'s {quantity: items}, each
    quantity with at least ``MIN_ITEMS`` items in the first family whose words its name
    holds; empty families dropped."""
    out = []
    taken: set = set()
    for title, words in FAMILIES:
        names = sorted(k for k, v in collected.items() if len(v) >= MIN_ITEMS
                       and k not in taken and any(w in k for w in words))
        taken.update(names)
        if names:
            out.append((title, names))
    return out


def _path(xs, ys, x0, y0, colour, width=1.6, dash=None) -> str:
    pts = " ".join(f"{x0 + x * PW / K_MAX:.1f},{_y(y, y0):.1f}" for x, y in zip(xs, ys))
    d = f' stroke-dasharray="{dash}"' if dash else ""
    return (f'<polyline points="{pts}" fill="none" stroke="{colour}" '
            f'stroke-width="{width}"{d}/>')


def panel(title: str, curves: list[tuple[str, np.ndarray, np.ndarray]], x0: float,
          y0: float) -> list[str]:
    """SVG elements of one panel whose plot area's top left corner is (x0, y0): axes, the
    Gaussian, the goal bars and each (name, z as stated, z left out) curve, with a legend."""
    ks = np.linspace(0.0, K_MAX, 161)
    el = [f'<text x="{x0}" y="{y0 - 10}" font-weight="bold">{escape(title)}</text>',
          f'<rect x="{x0}" y="{y0}" width="{PW}" height="{PH}" fill="none" stroke="#999"/>']
    for k in range(1, int(K_MAX) + 1):
        x = x0 + k * PW / K_MAX
        el.append(f'<line x1="{x}" y1="{y0}" x2="{x}" y2="{y0 + PH}" stroke="#eee"/>')
        el.append(f'<text x="{x}" y="{y0 + PH + 14}" text-anchor="middle">{k}</text>')
    for f in (1.0, 0.32, 0.1, 0.03, 0.01, 0.003, FLOOR):
        y = _y(f, y0)
        el.append(f'<line x1="{x0}" y1="{y}" x2="{x0 + PW}" y2="{y}" stroke="#eee"/>')
        el.append(f'<text x="{x0 - 4}" y="{y + 4}" text-anchor="end">{f:g}</text>')
    el.append(f'<text x="{x0 + PW / 2}" y="{y0 + PH + 28}" text-anchor="middle">'
              'k: error beyond k x the stated 1-sigma</text>')
    for k, lo, hi in ((1.0, 0.20, 0.40), (3.0, FLOOR, 0.03)):   # the goal
        x = x0 + k * PW / K_MAX
        el.append(f'<rect x="{x - 3}" y="{_y(hi, y0):.1f}" width="6" '
                  f'height="{_y(lo, y0) - _y(hi, y0):.1f}" fill="#2ca02c" opacity="0.35"/>')
    el.append(_path(ks, gaussian(ks), x0, y0, "#000", 1.2, "5,3"))
    for i, (name, z_in, z_out) in enumerate(curves):
        c = COLOURS[i % len(COLOURS)]
        el.append(_path(ks, beyond(z_out, ks), x0, y0, c, 1.0, "1.5,2.5"))
        el.append(_path(ks, beyond(z_in, ks), x0, y0, c))
        ly = y0 + 8 + 15 * i
        el.append(f'<line x1="{x0 + PW + 12}" y1="{ly - 4}" x2="{x0 + PW + 30}" '
                  f'y2="{ly - 4}" stroke="{c}" stroke-width="2"/>')
        c1, c3 = float(np.mean(z_in <= 1)), float(np.mean(z_in <= 3))
        el.append(f'<text x="{x0 + PW + 34}" y="{ly}">{escape(name)} ({len(z_in)}): '
                  f'{c1:.2f} / {c3:.2f}</text>')
    return el


def svg(collected: dict, title: str = "") -> str:
    """The whole figure of ``sigma_coverage.collect``'s {quantity: [(group, |error|,
    sigma)]}: one panel per family, two panels a row."""
    fams = families(collected)
    if not fams:
        raise SystemExit("no quantity has a stated sigma on 10 items or more: nothing to draw")
    cell_w, cell_h = ML + PW + LEGEND, MT + PH + MB + 12
    rows = -(-len(fams) // 2)
    width, height = 2 * cell_w + 10, rows * cell_h + 56
    el = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" '
          f'font-family="sans-serif" font-size="11">',
          f'<rect width="{width}" height="{height}" fill="white"/>',
          f'<text x="10" y="18" font-size="13" font-weight="bold">{escape(title)}</text>',
          '<text x="10" y="34">share of answers beyond k sigma, log scale (legend: n, within '
          '1 / 3 sigma as stated); solid: as stated, dotted: leave one room out; dashed '
          'black: a Gaussian; green: the goal</text>']
    for i, (name, names) in enumerate(fams):
        x0, y0 = ML + (i % 2) * cell_w, 56 + MT + (i // 2) * cell_h
        curves = []
        for q in names:
            items = collected[q]
            z = np.array([e / s for _, e, s in items], float)
            curves.append((q, z, sc.loro(items)))
        el += panel(name, curves, x0, y0)
    return "\n".join(el + ["</svg>"]) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dataset")
    ap.add_argument("predictions")
    ap.add_argument("--out", required=True, metavar="OUT.svg")
    ap.add_argument("--title", default="Do the stated 1-sigmas hold?")
    a = ap.parse_args(argv)
    with open(a.predictions) as f:
        preds = json.load(f)
    text = svg(sc.collect(a.dataset, preds), a.title)
    with open(a.out, "w") as f:
        f.write(text)
    print(f"wrote {a.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
