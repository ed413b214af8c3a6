"""Fit the motion's model-error terms so its 1-sigma values mean what they say.

    python tools/calibrate_motion.py ../shared/data/findme-eval [--fit tum-cabinet-pairs]
                                     [--method findme]

Runs the estimator (``--method``, default findme) with no model error on every dev pair
(rank-1 hypotheses, as ``findme eval``), then fits the model errors so that the median
normalised error on the ``--fit`` subset equals a calibrated Gaussian's (0.674):

1. the position error (metres on each of x and z, not growing with the baseline) on the
   shortest third of the subset's baselines, along and across pooled;
2. with it, the relative scale error (along the baseline), the direction error (across it,
   degrees) and the yaw error (degrees) on the whole subset.

It prints the coverage (fraction within 1 and 3 sigma along, across and in yaw, and of the
translation within 2 sigma as ``tools/motion_pairs.py`` counts it) of the current and the
fitted values on every pair subset; the other subsets are the held-out check. Then the same
fit left out group by group on the ``--fit`` subset (TUM: blocks of 6 frames): each group's
terms fitted without it, and the coverage of every pair under its own group's terms beside the
in-sample one. Put the fitted
values in ``MotionParams`` (findme_core/motion/model.py: ``findme_*`` for findme, the others
for features, lifted and paper). The last lines fit the same four terms by the rule the other
sigma constants are chosen by (``fit_terms_goal``: the coverage nearest the goal, then a
Gaussian's), in sample and left out, beside the median's.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from findme.evaluation.pairs import pair_inputs  # noqa: E402
from findme_core.errors import FindmeError  # noqa: E402
from findme_core.motion.methods import MotionParams  # noqa: E402
from findme_core.motion.methods import METHODS  # noqa: E402
from findme_core.motion.pair import motion_photos, photo_of  # noqa: E402
from sigma_coverage import fit_factor, group_of, leave_group_out  # noqa: E402

SUBSETS = ("tum-cabinet-pairs", "zind-pairs-tilted", "zind-pairs-level", "kitti06-pairs")
MEDIAN_ABS_Z = 0.6745   # median |z| of a standard normal


def _no_model_error(method: str) -> MotionParams:
    if method == "findme":
        return MotionParams(findme_scale_sigma=0.0, findme_direction_sigma_deg=0.0,
                            findme_yaw_sigma_deg=0.0, findme_position_sigma_m=0.0)
    return MotionParams(scale_sigma=0.0, direction_sigma_deg=0.0, yaw_sigma_deg=0.0,
                        position_sigma_m=0.0)


def raw_motions(split: Path, subset: str, method: str) -> dict:
    """Estimates with their fit sigmas only, and the truth, of the answered pairs: arrays
    x, z (m), yaw (deg), sx, sz (m), sy (deg), gx, gz, gy, and each pair's leave-one-out
    group (``sigma_coverage.group_of``)."""
    index = json.loads((split / "index.json").read_text())
    p0 = _no_model_error(method)
    rows, groups = [], []
    for pid in index["subsets"][subset]["pairs"]:
        pair, photos = pair_inputs(split / "pairs", split / "views", pid)
        try:
            pa, pb = (photo_of(i, c, h, 1, "findme", w, gravity_sigma=pv.unsensed_sigma,
                               gravity_alternatives=pv.unsensed_alternatives)
                      for (i, c, h, pv), w in zip(photos, "AB"))
            r = motion_photos(pa, pb, (method,), params=p0)[method]
        except FindmeError:
            continue
        if isinstance(r, Exception):
            continue
        m, g = r.motion, pair["motion"]
        rows.append((m.x, m.z, math.degrees(m.yaw), m.sigma_x, m.sigma_z,
                     math.degrees(m.sigma_yaw), g["x_m"], g["z_m"], g["yaw_deg"]))
        groups.append(group_of(pid))
    out = dict(zip(("x", "z", "yaw", "sx", "sz", "sy", "gx", "gz", "gy"),
                   np.array(rows).reshape(-1, 9).T))
    return {**out, "group": np.asarray(groups)}


def _variances(a: dict, scale: float, direction_deg: float, position_m: float):
    """(baseline (n,), unit baseline (n, 2), variance along and across it (n,) each) with
    the model errors added as ``feature_motion._model_error`` adds them."""
    base = np.hypot(a["x"], a["z"])
    u = np.stack([a["x"], a["z"]], 1) / np.maximum(base, 1e-12)[:, None]
    v = np.stack([-u[:, 1], u[:, 0]], 1)
    var_u = (u[:, 0] * a["sx"]) ** 2 + (u[:, 1] * a["sz"]) ** 2 + (scale * base) ** 2 \
        + position_m ** 2
    var_v = (v[:, 0] * a["sx"]) ** 2 + (v[:, 1] * a["sz"]) ** 2 \
        + (math.radians(direction_deg) * base) ** 2 + position_m ** 2
    return base, u, var_u, var_v


def normalised(a: dict, scale: float, direction_deg: float, yaw_deg: float,
               position_m: float = 0.0):
    """|error| / sigma along the baseline, across it and in yaw (as ``motion`` adds them)."""
    _, u, var_u, var_v = _variances(a, scale, direction_deg, position_m)
    v = np.stack([-u[:, 1], u[:, 0]], 1)
    e = np.stack([a["x"] - a["gx"], a["z"] - a["gz"]], 1)
    dyaw = (a["yaw"] - a["gy"] + 180.0) % 360.0 - 180.0
    return (np.abs((e * u).sum(1)) / np.sqrt(var_u), np.abs((e * v).sum(1)) / np.sqrt(var_v),
            np.abs(dyaw) / np.hypot(a["sy"], yaw_deg))


def within_two_sigma(a: dict, scale: float, direction_deg: float, yaw_deg: float,
                     position_m: float = 0.0) -> float:
    """Fraction of the translation errors within 2 of their sigma (the rms of the x and z
    sigmas, as ``tools/motion_pairs.py`` counts)."""
    _, _, var_u, var_v = _variances(a, scale, direction_deg, position_m)
    err = np.hypot(a["x"] - a["gx"], a["z"] - a["gz"])
    return float(np.mean(err <= 2 * np.sqrt(0.5 * (var_u + var_v))))


def _subset(a: dict, keep: np.ndarray) -> dict:
    return {k: v[keep] for k, v in a.items()}


def _solve(f, lo: float, hi: float) -> float:
    """Root of a decreasing f on [lo, hi] by bisection (lo when f(lo) <= 0 already: no
    model error needed; hi when f(hi) > 0)."""
    if f(lo) <= 0:
        return lo
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if f(mid) > 0 else (lo, mid)
    return 0.5 * (lo + hi)


def fit_terms(d: dict) -> tuple[float, float, float, float]:
    """(scale, direction deg, yaw deg, position m): the model errors fitted on the pairs ``d``
    (the module docstring's steps 1 and 2)."""
    base = np.hypot(d["x"], d["z"])
    short = _subset(d, base <= np.quantile(base, 1 / 3))
    pos = _solve(lambda m: np.median(np.concatenate(normalised(short, 0, 0, 0, m)[:2]))
                 - MEDIAN_ABS_Z, 0, 1)
    return (_solve(lambda s: np.median(normalised(d, s, 0, 0, pos)[0]) - MEDIAN_ABS_Z, 0, 1),
            _solve(lambda r: np.median(normalised(d, 0, r, 0, pos)[1]) - MEDIAN_ABS_Z, 0, 45),
            _solve(lambda y: np.median(normalised(d, 0, 0, y)[2]) - MEDIAN_ABS_Z, 0, 45), pos)


def _least(z_of, hi: float) -> float:
    """The term in [0, hi] (a grid of 401) of least ``sigma_coverage.rule_key`` of
    ``z_of(term)`` (``sigma_coverage.fit_factor``); ties: the smaller."""
    return fit_factor(z_of, np.linspace(0.0, hi, 401))[1]


def fit_terms_goal(d: dict) -> tuple[float, float, float, float]:
    """``fit_terms``' four terms, in its order and on its pairs, each chosen by the rule the
    other sigma constants are (``sigma_coverage.rule_key``: the coverage within 1 and 3 sigma
    nearest the goal, then a Gaussian's) instead of the median's."""
    base = np.hypot(d["x"], d["z"])
    short = _subset(d, base <= np.quantile(base, 1 / 3))
    pos = _least(lambda m: np.concatenate(normalised(short, 0, 0, 0, m)[:2]), 0.2)
    return (_least(lambda s: normalised(d, s, 0, 0, pos)[0], 0.2),
            _least(lambda r: normalised(d, 0, r, 0, pos)[1], 20.0),
            _least(lambda y: normalised(d, 0, 0, y)[2], 10.0), pos)


def left_out(d: dict, fit=fit_terms) -> tuple[dict, list[np.ndarray]]:
    """Leave one group out on the pairs ``d``: ({group: terms ``fit`` without it}, the
    normalised errors along, across and in yaw of every pair under its own group's terms)."""
    folds, z = leave_group_out(d["group"], lambda m: fit(_subset(d, m)),
                               lambda terms, held: normalised(_subset(d, held), *terms))
    return folds, list(z)


def _cover(zs) -> str:
    return ", ".join(f"{name} {np.mean(z <= 1):.2f} / {np.mean(z <= 2):.2f} / {np.mean(z <= 3):.2f}"
                     for name, z in zip(("along", "across", "yaw"), zs))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("split", type=Path)
    ap.add_argument("--fit", default="tum-cabinet-pairs", choices=SUBSETS)
    ap.add_argument("--method", default="findme", choices=[m for m in METHODS])
    a = ap.parse_args(argv)
    cv2.setNumThreads(1)
    data = {s: raw_motions(a.split, s, a.method) for s in SUBSETS}
    d = data[a.fit]
    fitted, by_rule = fit_terms(d), fit_terms_goal(d)
    p = MotionParams()
    for name, terms in (("current", p.model_errors(a.method)),
                        (f"fitted on {a.fit}", fitted),
                        (f"by the sigma constants' rule on {a.fit}", by_rule)):
        print(f"{name}: scale_sigma {terms[0]:.3f}, direction_sigma_deg {terms[1]:.2f}, "
              f"yaw_sigma_deg {terms[2]:.2f}, position_sigma_m {terms[3]:.3f}")
        for s, dd in data.items():
            cover = [f"{np.mean(z <= 1):.2f} / {np.mean(z <= 3):.2f}"
                     for z in normalised(dd, *terms)]
            print(f"  {s:20s} n={len(dd['x']):3d}  within 1 / 3 sigma: along {cover[0]}, "
                  f"across {cover[1]}, yaw {cover[2]}; translation within 2 sigma "
                  f"{within_two_sigma(dd, *terms):.2f}")
    folds, zs = left_out(d)
    print(f"leave one group out on {a.fit} (TUM: blocks of 6 frames; each group's pairs "
          "with the terms fitted without them):")
    for g, t in folds.items():
        print(f"  without {g}: scale_sigma {t[0]:.3f}, direction_sigma_deg {t[1]:.2f}, "
              f"yaw_sigma_deg {t[2]:.2f}, position_sigma_m {t[3]:.3f}")
    print(f"  in sample, within 1 / 2 / 3 sigma: {_cover(normalised(d, *fitted))}")
    print(f"  left out,  within 1 / 2 / 3 sigma: {_cover(zs)}")
    folds, zs = left_out(d, fit_terms_goal)
    print("  by the sigma constants' rule (folds: " + "; ".join(
        f"{g} {t[0]:.3f} / {t[1]:.2f} / {t[2]:.2f} / {t[3]:.3f}" for g, t in folds.items()) + ")")
    print(f"    in sample, within 1 / 2 / 3 sigma: {_cover(normalised(d, *by_rule))}")
    print(f"    left out,  within 1 / 2 / 3 sigma: {_cover(zs)}")


if __name__ == "__main__":
    main()
