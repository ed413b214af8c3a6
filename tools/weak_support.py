"""Would a motion that few feature matches support need a wider translation sigma? A model
term tried and measured, not in the product.

    findme eval DATASET --out exact.json [--jobs 2]
    findme eval DATASET --gravity-noise 1.5 --gravity-sigma 1.5 --gravity-refine --out phone.json
    findme eval DATASET --no-gravity --out without.json
    python tools/weak_support.py DATASET exact.json phone.json without.json

The idea: where fewer than N of a pair's feature matches agree with its motion (the
prediction's ``inliers``), the translation rests on the two photos' walls registered to each
other, and a wrong wall correspondence moves it by a share of the baseline that the fit's
covariance does not see. So add c * |t| (t: the estimated translation, metres) in quadrature
to the 1-sigma of x and of z of those pairs. (N, c) are chosen on a grid (``N_GRID``,
``C_GRID``) by ``sigma_coverage.rule_key`` (the coverage within 1 and 3 sigma nearest the
goal, then a Gaussian's) over the ZInD pairs of every run given, pooled (the term is for
pairs whose translation the walls decide; TUM and KITTI pairs are only scored), and again
leaving each ZInD room out.

Measured 2026-11-30 on the dev split (runs: the dataset's gravity, a phone's, withheld): all
rooms N = 15, c = 0.2; in sample the phone run's tilted pairs go from 0.59 / 0.82 / 0.82 to
0.64 / 0.91 / 0.91 within 1 / 2 / 3 sigma in x and its level pairs' z from 0.58 / 0.79 / 0.89 to
0.63 / 0.89 / 0.95; but the fold without room06 (the kitchen, where most such pairs fail)
picks c = 0, so left out the gain is gone (tilted x 0.68 / 0.82 / 0.82, level z
0.68 / 0.84 / 0.89). In and out disagree, so by the rule of fewer parameters the product
does not have the term. Again on 2026-12-02 by the goal-first rule: all rooms N = 10,
c = 0.15, the folds without room06 and without room17 c = 0; left out no row gains within 3
sigma (a phone's tilted pairs' x 0.90, level pairs' x and z 0.94, withheld level 0.93), so
still not. Reads the dataset's ground truth: a tool, not the product.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from sigma_coverage import coverage, group_of, improves, rule_key  # noqa: E402

N_GRID = (5, 10, 15, 20, 30, 40)
C_GRID = (0.0, 0.05, 0.1, 0.15, 0.2, 0.3, 0.4, 0.5, 0.7, 1.0)


def pairs(dataset: str, predictions: str) -> list[dict]:
    """The answered pairs of one run: subset, group, inliers, |t| (m), |x / z error| (m) and
    the stated sigmas of x and z (m)."""
    idx = json.load(open(os.path.join(dataset, "index.json")))
    subset = {p: n for n, s in idx["subsets"].items() for p in s.get("pairs", [])}
    pdir = os.path.join(dataset, idx.get("pairs_dir", "pairs"))
    out = []
    for pid, q in sorted(json.load(open(predictions)).get("pairs", {}).items()):
        if q.get("x_m") is None or not q.get("sigma_x_m") or not q.get("sigma_z_m"):
            continue
        t = json.load(open(os.path.join(pdir, pid + ".json")))["motion"]
        out.append(dict(subset=subset.get(pid, "?"), group=group_of(pid), n=int(q["inliers"]),
                        b=math.hypot(q["x_m"], q["z_m"]), ex=abs(q["x_m"] - t["x_m"]),
                        ez=abs(q["z_m"] - t["z_m"]), sx=q["sigma_x_m"], sz=q["sigma_z_m"]))
    return out


def z_scores(rows: list[dict], n_max: int, c: float) -> np.ndarray:
    """(len(rows), 2) |error| / sigma of x and z with the term (N = ``n_max``, c) added."""
    extra = np.array([c * r["b"] if r["n"] < n_max else 0.0 for r in rows])
    return np.array([[r["ex"] / math.hypot(r["sx"], e), r["ez"] / math.hypot(r["sz"], e)]
                     for r, e in zip(rows, extra)]).reshape(-1, 2)


def fit(rows: list[dict]) -> tuple[int, float]:
    """(N, c) of least ``rule_key`` over the rows' x and z; ties: smaller c, then N."""
    best, arg = (np.inf, np.inf), (N_GRID[0], 0.0)
    for c in C_GRID:
        for n_max in N_GRID:
            key = rule_key(z_scores(rows, n_max, c).ravel())
            if improves(key, best):
                best, arg = key, (n_max, c)
    return arg


def _cov(z: np.ndarray) -> str:
    return " / ".join(f"{x:.2f}" for x in coverage(z))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dataset")
    ap.add_argument("predictions", nargs="+", help="findme eval outputs, one per gravity run")
    a = ap.parse_args(argv)
    runs = {p: pairs(a.dataset, p) for p in a.predictions}
    zind = [r for rows in runs.values() for r in rows if r["subset"].startswith("zind")]
    if not zind:
        ap.error("no answered ZInD pair in the predictions")
    n_all, c_all = fit(zind)
    folds = {g: fit([r for r in zind if r["group"] != g]) for g in sorted({r["group"] for r in zind})}
    print(f"all rooms: N = {n_all}, c = {c_all:g}; folds: "
          + ", ".join(f"{g} ({n}, {c:g})" for g, (n, c) in folds.items()))
    for path, rows in runs.items():
        print(os.path.basename(path))
        for sub in sorted({r["subset"] for r in rows}):
            sel = [r for r in rows if r["subset"] == sub]
            none, fitted = z_scores(sel, n_all, 0.0), z_scores(sel, n_all, c_all)
            out = np.vstack([z_scores([r], *folds.get(r["group"], (n_all, c_all))) for r in sel])
            print(f"  {sub:22s} n {len(sel):3d}  x: without {_cov(none[:, 0])}  in {_cov(fitted[:, 0])}"
                  f"  out {_cov(out[:, 0])}   z: without {_cov(none[:, 1])}  in {_cov(fitted[:, 1])}"
                  f"  out {_cov(out[:, 1])}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
