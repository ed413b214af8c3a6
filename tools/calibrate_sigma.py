"""Fit the model-error terms of the single-photo 1-sigma values on the dev split, and what a
room never seen gets from them (leave one room out).

    findme eval DATASET --out with.json && findme eval DATASET --no-gravity --out without.json
    python tools/calibrate_sigma.py DATASET with.json without.json

Two terms, each chosen by the rule every sigma constant is (``sigma_coverage.fit_factor``,
``rule_key``: the value whose coverage within 1 and 3 sigma comes nearest the goal, 0.60-0.80
and >= 0.97, and of values equally near it the one nearest a Gaussian's, 0.68 and 0.99), on a
log grid:

* ``uncertainty.BOUNDARY_SIGMA_WORK_PX``: how far the chosen boundary is off, in pixels of the
  ~640 px working size. Fitted on the wall / non-floor points of the run WITH the dataset's
  gravity (their sigma's boundary part is linear in it; the other parts are kept).
* ``vanishing.GravityParams.sigma_scale`` (with ``sigma_floor_deg`` kept): the factor on the
  fit's own covariance. Fitted on the pitch and roll errors (each over the per-axis sigma,
  pooled) of the views whose gravity came from the image in the run WITHOUT gravity, but
  KITTI's, whose "true" gravity is nominal (``sigma_coverage.gravity_measured``).

Why not "68 % within 1 sigma" alone (the rule before 2026-11-30): the errors are two
populations (right boundaries: pixels; wrong ones: the whole floor line), and that rule
shrinks the sigma until more of the second lie beyond 3 sigma. Measured 2026-11-30 on the dev
split (wall and non-floor points pooled, within 1 / 2 / 3 sigma): that rule gives 19.9 px,
0.679 / 0.761 / 0.814; the shipped 34 px 0.735 / 0.821 / 0.876; this rule 37.2 px, 0.743 /
0.832 / 0.886, and 0.696 / 0.763 / 0.819 left out (its folds: 13.7 px without room06, the
kitchen whose counters are the wrong boundaries, 37-41 px without any other room). Since
the points on walls not seen, and on every wall of a photo that shows almost no floor, are
refused (``single/seen``): the shipped 0.744 / 0.827 / 0.879, this rule 37.2 px, 0.752 /
0.838 / 0.889, left out 0.698 / 0.758 / 0.802 (11.1 px without room06). For
gravity both rules give 1.36 (0.679 / 0.920 / 0.991; left out 0.676 / 0.911 / 0.987), the
shipped 1.74 0.712 / 0.960 / 0.993. Both shipped values are kept, see their modules.
Measured 2026-12-02 after the kitchen's level photos were refused (``single/flat``): the
Gaussian-nearest rule then gave 13.2 px (0.72 / 0.87 within 1 / 3); the goal-first rule,
the one since, gives 36.5 px (0.834 / 0.897 / 0.932; folds 34.4-37.9 px, 14.6 without
room06; left out 0.803 / 0.858 / 0.895), the shipped 34 px 0.829 / 0.893 / 0.928; for
gravity 1.36 as before.

Prints, for each term: the shipped value and its coverage within 1 / 2 / 3 sigma, the value
fitted on all dev rooms, each fold's value fitted without its room (ZInD: one room; TUM: a
block of 6 frames; ``sigma_coverage.group_of``) and the coverage of every room scored with
the value fitted without it. Put the all-rooms value in the module (the dev split is for
tuning; the hidden split never is).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
from findme.evaluation.views import SIGMA_PARTS  # noqa: E402
from sigma_coverage import (fit_factor, gravity_measured, group_of,  # noqa: E402
                            leave_group_out, pitch_roll, wrap_deg)
from findme_core.geometry.uncertainty import BOUNDARY_SIGMA_WORK_PX  # noqa: E402
from findme_core.single.vanishing import GravityParams  # noqa: E402



def _views(dataset):
    idx = json.load(open(os.path.join(dataset, "index.json")))
    vdir = os.path.join(dataset, idx.get("views_dir", "views"))
    vids = sorted({v for s in idx["subsets"].values() for v in s.get("views", [])})
    return {v: json.load(open(os.path.join(vdir, v + ".json"))) for v in vids}


def _points(views, preds, kinds):
    """(groups (N,), errors (N,), sigma parts (N, 4)) of every predicted point of the given
    kinds."""
    groups, errs, parts = [], [], []
    for v, meta in views.items():
        p = preds["views"].get(v) or {}
        for k in kinds:
            for q, x, sp in zip(meta.get(k) or [], p.get(k) or [], p.get(k + "_sigma_parts_m") or []):
                if x is None or sp is None:
                    continue
                groups.append(group_of(v))
                errs.append(float(np.linalg.norm(np.subtract(x, q["xyz_m"]))))
                parts.append(sp)
    return (np.asarray(groups), np.asarray(errs),
            np.asarray(parts, float).reshape(-1, len(SIGMA_PARTS)))


def _gravity_errors(views, preds, params: GravityParams):
    """(groups (N,), pitch and roll errors (N, 2) deg, the fit's own per-axis sigma (N,) deg
    without the shipped scale and floor) of the views whose gravity came from the image."""
    floor = params.sigma_floor_deg
    groups, errs, raw = [], [], []
    for v, meta in views.items():
        q = preds["views"].get(v) or {}
        if q.get("gravity_source") != "image" or not gravity_measured(meta):
            continue
        (pp, rp), (pt, rt) = pitch_roll(q["gravity_cam"]), pitch_roll(meta["gravity_cam"])
        groups.append(group_of(v))
        errs.append((abs(pp - pt), abs(wrap_deg(rp - rt))))
        s = q["gravity_sigma_deg"]
        raw.append(math.sqrt(max(s * s - floor * floor, 0.0)) / params.sigma_scale)
    return np.asarray(groups), np.asarray(errs, float).reshape(-1, 2), np.asarray(raw)


def _cov(z) -> str:
    return " / ".join(f"{np.mean(np.ravel(z) <= k):.3f}" for k in (1, 2, 3))


def loro_fit(groups: np.ndarray, z_of, grid) -> tuple[float, dict, np.ndarray]:
    """(k fitted on every item, {group: k fitted without it}, the normalised errors of every
    item under its own group's left-out k). ``z_of(k, mask)``: the normalised errors of the
    masked items, (..., n masked)."""
    def fit(mask):
        return fit_factor(lambda k: z_of(k, mask), grid)[1]
    folds, z = leave_group_out(groups, fit, z_of)
    return fit(np.ones(len(groups), bool)), folds, z


def _report(name: str, unit: str, shipped: float, k_all: float, folds: dict, z_shipped,
            z_all, z_out, n: str) -> None:
    print(f"{name}: {n}, {len(folds)} rooms")
    print(f"  shipped {shipped:.2f}{unit}: within 1 / 2 / 3 sigma {_cov(z_shipped)}")
    print(f"  fitted on all dev rooms {k_all:.2f}{unit}: {_cov(z_all)}")
    print("  without each room: " + ", ".join(f"{g} {k:.2f}" for g, k in folds.items()))
    print(f"  leave-one-room-out (each room with the value fitted without it): {_cov(z_out)}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dataset")
    ap.add_argument("with_gravity")
    ap.add_argument("without_gravity")
    a = ap.parse_args(argv)
    views = _views(a.dataset)
    with_g, without_g = json.load(open(a.with_gravity)), json.load(open(a.without_gravity))

    groups, errs, parts = _points(views, with_g, ("wall_points", "nonfloor_points"))
    b = SIGMA_PARTS.index("boundary")

    def z_points(px, mask):
        p = parts[mask].copy()
        p[:, b] *= px / BOUNDARY_SIGMA_WORK_PX
        return errs[mask] / np.sqrt((p ** 2).sum(1))
    px_grid = np.exp(np.linspace(np.log(4.0), np.log(200.0), 201))
    k_all, folds, z_out = loro_fit(groups, z_points, px_grid)
    every = np.ones(len(errs), bool)
    _report("BOUNDARY_SIGMA_WORK_PX", " px", BOUNDARY_SIGMA_WORK_PX, k_all, folds,
            z_points(BOUNDARY_SIGMA_WORK_PX, every), z_points(k_all, every), z_out,
            f"{len(errs)} wall / non-floor points")

    p = GravityParams()
    groups, gerr, raw = _gravity_errors(views, without_g, p)

    def z_gravity(scale, mask):
        return gerr[mask].T / np.hypot(scale * raw[mask], p.sigma_floor_deg)   # (2, n)
    scale_grid = np.exp(np.linspace(np.log(0.5), np.log(5.0), 201))
    k_all, folds, z_out = loro_fit(groups, z_gravity, scale_grid)
    every = np.ones(len(raw), bool)
    _report(f"GravityParams.sigma_scale (floor {p.sigma_floor_deg:g} deg kept)", "",
            p.sigma_scale, k_all, folds, z_gravity(p.sigma_scale, every),
            z_gravity(k_all, every), z_out,
            f"{len(raw)} views' gravity from the image, pitch and roll")


if __name__ == "__main__":
    main()
