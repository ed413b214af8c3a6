"""Where the points' sigmas fail: coverage of each point kind split by the surface the
product put the point on, the query's own (a floor point on the floor, a wall point on a
wall, a non-floor point on a wall or a top) or the other one.

    python tools/surface_coverage.py DATASET_DIR PREDICTIONS.json [--markdown]

A point's 1-sigma assumes its surface is right: a floor point's does not depend on the
boundary at all, a wall point's only on the boundary moving by its 1-sigma. A point on the
other surface means the chosen boundary is wrong under it by far more than that (a counter's
top taken for the floor line; floor seen beyond a low cabinet taken for its face). Reads the
dataset's ground truth: a tool, not the product. Needs predictions with ``<kind>_surface``
(``findme eval`` since 2026-11-30).

Second table (with ``--declared-surface`` predictions, which carry ``floor_points_note``): is
the note "the chosen floor line runs below this point you said is on the floor" a warning
worth heeding? The coverage of the wall points of the views where a floor point got it,
against the views where none did.
"""

from __future__ import annotations

import argparse
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from sigma_coverage import POINT_KINDS, coverage, point_errors, views  # noqa: E402

RIGHT = {"floor_points": ("floor",), "wall_points": ("wall",), "nonfloor_points": ("wall", "top")}


def collect(dataset: str, preds: dict) -> dict:
    """{"<kind> (<family>)": {"right": z, "other": z}}, z the (n,) normalised errors
    |error| / sigma of the answered points on the query's own surface and on the other."""
    out: dict = {}
    for _, meta, p, family in views(dataset, preds):
        for k in POINT_KINDS:
            surfaces = p.get(k + "_surface")
            if surfaces is None:
                continue
            row = out.setdefault(f"{k.replace('_', ' ')} ({family})", {"right": [], "other": []})
            for i, err, s in point_errors(meta, p, k):
                row["right" if surfaces[i] in RIGHT[k] else "other"].append(err / s)
    return {k: {s: np.asarray(v, float) for s, v in r.items()} for k, r in out.items()}


def by_note(dataset: str, preds: dict) -> dict:
    """{"wall points (<family>)": {"noted": z, "not": z}}: the normalised errors of the
    answered wall points of the views where at least one floor point carries a note and of
    the views where none does (views without ``floor_points_note`` are left out)."""
    out: dict = {}
    for _, meta, p, family in views(dataset, preds):
        notes = p.get("floor_points_note")
        if notes is None:
            continue
        row = out.setdefault(f"wall points ({family})", {"noted": [], "not": []})
        side = "noted" if any(notes) else "not"
        row[side].extend(err / s for _, err, s in point_errors(meta, p, "wall_points"))
    return {k: {s: np.asarray(v, float) for s, v in r.items()} for k, r in out.items()}


def note_table(res: dict) -> list[str]:
    """One line per family: n and coverage of the noted views' and the other views' points."""
    def cell(z):
        return f"n {len(z)}: " + (" / ".join(f"{c:.3f}" for c in coverage(z)) if len(z) else "–")
    return [f"{k}: views with a floor point noted {cell(r['noted'])}; the other views "
            f"{cell(r['not'])} (within 1 / 2 / 3 sigma)" for k, r in sorted(res.items())
            if len(r["noted"]) + len(r["not"])]


def table(res: dict, markdown: bool = False) -> list[str]:
    """One row per point kind: n, then the share on each surface and its coverage."""
    def cell(z, n):
        if not len(z):
            return "0 | –"
        return (f"{len(z) / n:.2f} | " + " / ".join(f"{c:.2f}" for c in coverage(z)))
    rows = (["| points | n | on its own surface: share | within 1 / 2 / 3 sigma | on the "
             "other surface: share | within 1 / 2 / 3 sigma | all: within 1 / 2 / 3 sigma |",
             "|---|---|---|---|---|---|---|"] if markdown else [])
    for k in sorted(res):
        r = res[k]
        n = len(r["right"]) + len(r["other"])
        every = np.concatenate([r["right"], r["other"]])
        line = (f"| {k} | {n} | {cell(r['right'], n)} | {cell(r['other'], n)} | "
                + " / ".join(f"{c:.2f}" for c in coverage(every)) + " |")
        rows.append(line if markdown else line.replace("|", " ").strip())
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dataset")
    ap.add_argument("predictions")
    ap.add_argument("--markdown", action="store_true")
    a = ap.parse_args(argv)
    with open(a.predictions) as f:
        preds = json.load(f)
    res = collect(a.dataset, preds)
    if not res:
        print("no point carries its surface (<kind>_surface): run findme eval again", file=sys.stderr)
        return 1
    print("\n".join(table(res, a.markdown)))
    noted = by_note(a.dataset, preds)
    if noted:
        print("\n".join(note_table(noted)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
