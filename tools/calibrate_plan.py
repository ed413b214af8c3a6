"""Fit the floor plan's model-error terms so that its 1-sigma values mean what they say, and
show how they hold on a room left out of the fit.

    python tools/calibrate_plan.py ../shared/data/findme-eval [--gravity given|withheld]
                                   [--json OUT.json]

Plans every dev room (``zind-rooms``, spots from the ids, as ``findme eval``) with the raw
sigmas (``PlanParams.pose_sigma_model`` = (1, 0, 1, 0), ``length_sigma_model`` and
``corner_sigma_model`` = (1, 0): the joint refinement's covariance alone), matches every seen
wall to the truth, every placed photo to its true pose and every scored true corner to the
nearest vertex, then fits each term as ``sigma = hypot(k * raw, floor)``
(``sigma_coverage.fit_model``: the coverage within 1 and 3 sigma nearest the goal, then a
Gaussian's; ``rule_key``):

* on all rooms: the values to put in ``PlanParams`` (findme_core/plan/floorplan.py:
  ``pose_sigma_model``, ``length_sigma_model`` and ``corner_sigma_model`` from ``--gravity
  given``, ``image_gravity_models``: its length model from ``--gravity withheld``, where each
  photo's gravity comes from its own lines, agreed spot by spot; its pose and corner models,
  which serve a phone's gravity too, from ``--gravity inexact``: withheld and a phone's
  pooled);
* leaving each room out in turn: the coverage the left-out room gets from the values fitted
  on the others (what a room never seen gets), next to the in-sample coverage.

A plan whose outline the session refuses (``OutlineRefused``) has no walls to fit; its
photos' poses, which the product still publishes, are fitted. Reads the dataset's ground
truth: a tool, not the product.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
sys.path.insert(0, os.path.dirname(__file__))
import sigma_coverage as sc  # noqa: E402
from findme.evaluation.views import GravityInput  # noqa: E402
from findme.evaluation.rooms import room_photos, room_prediction  # noqa: E402
from findme_core.errors import FindmeError  # noqa: E402
from findme_core.plan import session  # noqa: E402

#: how each ``--gravity`` reaches the plans (``phone``: the dataset's tilted by a seeded
#: N(0, 1.5 deg) per axis, declared at 1.5 deg and refined by the photos' lines, as
#: ``findme eval --gravity-noise 1.5 --gravity-sigma 1.5 --gravity-refine``)
GRAVITIES = {"given": GravityInput(given=True), "withheld": GravityInput(given=False),
             "phone": GravityInput(noise_deg=1.5, sigma_deg=1.5, refine=True)}
#: ``--gravity inexact``: both gravities ``image_gravity_models``' pose model serves, pooled
INEXACT = ("withheld", "phone")

RAW = dict(pose_sigma_model=(1.0, 0.0, 1.0, 0.0), length_sigma_model=(1.0, 0.0),
           corner_sigma_model=(1.0, 0.0),
           image_gravity_models=((1.0, 0.0, 1.0, 0.0), (1.0, 0.0), (1.0, 0.0)))


def raw_plan(job) -> tuple[str, dict | None, str | None]:
    """(room id, the plan's dict with raw sigmas, or None and why)."""
    dataset, rid, gravity = job
    import cv2
    cv2.setNumThreads(1)
    try:
        views, photos = room_photos(os.path.join(dataset, "rooms"), os.path.join(dataset, "views"),
                                    rid, GRAVITIES[gravity])
        p = session.SessionParams()
        # a refused outline: its poses, which are published, without the outline
        return rid, room_prediction(views, photos, "ids",
                                    replace(p, plan=replace(p.plan, **RAW))), None
    except FindmeError as e:
        return rid, None, str(e)


def items(dataset: str, plans: dict) -> dict:
    """{quantity: [(room, |error|, raw sigma)]} of the plans' seen walls and poses (plans
    keyed "gravity/room"; a room's items under every gravity share its group)."""
    out = {}
    for g in sorted({k.split("/")[0] for k in plans}):
        preds = {"rooms": {k.split("/")[1]: d for k, d in plans.items()
                           if d and k.startswith(g + "/")}}
        for q, v in sc.collect(dataset, preds).items():
            if q.startswith(("plan pose", "wall length (seen)", "plan corner")):
                out.setdefault(q, []).extend(v)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dataset")
    ap.add_argument("--gravity", choices=(*GRAVITIES, "inexact"), default="given",
                    help="inexact: withheld and phone pooled, a room's items one group")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--json", metavar="OUT.json")
    ap.add_argument("--cache", metavar="PLANS.json",
                    help="the raw plans: read from this file when it exists, else made and "
                         "written to it (refit without planning again)")
    a = ap.parse_args(argv)
    idx = json.load(open(os.path.join(a.dataset, "index.json")))
    rooms = idx["subsets"]["zind-rooms"]["rooms"]
    if a.cache and os.path.exists(a.cache):
        plans = json.load(open(a.cache))
    else:
        gs = INEXACT if a.gravity == "inexact" else (a.gravity,)
        jobs = [(a.dataset, r, g) for g in gs for r in rooms]
        with ProcessPoolExecutor(a.jobs) as ex:
            plans = {f"{j[2]}/{r}": d for j, (r, d, why) in zip(jobs, ex.map(raw_plan, jobs))
                     if d is not None or print(f"  {r}: refused: {why}", file=sys.stderr)}
        if a.cache:
            json.dump(plans, open(a.cache, "w"))
    out = {}
    for k, its in sorted(items(a.dataset, plans).items()):
        err = np.array([i[1] for i in its], float)
        raw = np.array([i[2] for i in its], float)
        model = sc.fit_model(err, raw)
        z_loro, folds = sc.loro_model(its)
        out[k] = {"n": len(its), "model": model, "raw": sc.coverage(err / raw),
                  "in": sc.coverage(err / np.hypot(model[0] * raw, model[1])),
                  "loro": sc.coverage(z_loro), "folds": folds}
        unit = "deg" if "yaw" in k else "m"
        if k == "plan pose x, z":   # fitted on sigma_xz (a radius): per axis floor / sqrt 2
            unit += f" (per axis {model[1] / math.sqrt(2):.4f})"
        print(f"{k:22s} n={len(its):3d}  k={model[0]:.2f} floor={model[1]:.4f} {unit}   raw "
              + " / ".join(f"{c:.2f}" for c in out[k]["raw"]) + "   fitted in sample "
              + " / ".join(f"{c:.2f}" for c in out[k]["in"]) + "   leave-one-room-out "
              + " / ".join(f"{c:.2f}" for c in out[k]["loro"]))
        for g, (kk, ff) in sorted(folds.items()):
            print(f"    without {g}: k={kk:.2f} floor={ff:.4f}")
    if a.json:
        json.dump(out, open(a.json, "w"), indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
