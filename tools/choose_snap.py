"""Choose how far a wall line may be off the room's axes and still be snapped onto them when
the photos' gravity is not exact (``PlanParams.inexact_snap_deg``), leaving one room out.

    python tools/choose_snap.py ../shared/data/findme-eval [--jobs 2]

A phone's gravity is off by a degree or so, and the image's own estimate as much: a tilt error
turns each photo's floor lines its own way, so the lines one room's photos find scatter by
degrees about its axes. Every dev room (``zind-rooms``, spots from the ids, as ``findme eval``)
is planned under each candidate tolerance, with gravity withheld (``--no-gravity``) and with a
phone's (the dataset's tilted by a seeded N(0, 1.5 deg) per axis, declared at 1.5 deg and
refined by the photo's lines: ``--gravity-noise 1.5 --gravity-sigma 1.5 --gravity-refine``),
and scored by the shared scorer (``score_room``): walls ok (within 10 % and 0.15 m; a refused
outline has none), views localised (within 0.25 m and 5 deg), IoU, corners. The value kept is
the one with the most walls ok plus views localised, summed over both gravities and the
rooms; a tie goes to the smaller tolerance (the exact-gravity value, 2 deg, snaps the
fewest). Leave one room out: each room is scored at the value chosen on the others. Plans
with the dataset's exact gravity keep ``WallParams.snap_deg``. Reads the dataset's ground
truth: a tool, not the product.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
sys.path.insert(0, os.path.dirname(__file__))
from calibrate_plan import GRAVITIES as ALL_GRAVITIES, INEXACT  # noqa: E402
from findme.evaluation.rooms import room_ids, room_photos, room_prediction  # noqa: E402
from findme_core.errors import FindmeError  # noqa: E402
from findme_core.plan import session  # noqa: E402

#: candidate tolerances, degrees (the first: ``WallParams.snap_deg``, today's for every gravity)
CANDIDATES = (2.0, 3.0, 4.0, 5.0, 6.0, 8.0)
#: the gravities that are not exact, as ``calibrate_plan --gravity inexact`` pools them
GRAVITIES = {g: ALL_GRAVITIES[g] for g in INEXACT}


def _scorer(dataset: str):
    sys.path.insert(0, os.path.join(dataset, "..", "..", "eval"))
    import score  # noqa: E402  (../shared/eval/score.py, beside the dataset)
    return score


def plan_room(args) -> tuple[str, str, list]:
    """(room, gravity, [per candidate: {"ok", "loc", "iou", "corner", "manhattan",
    "refused"}]) of one room under one gravity."""
    dataset, rid, gname = args
    score = _scorer(dataset)
    room = json.load(open(os.path.join(dataset, "rooms", rid + ".json")))
    views, photos = room_photos(os.path.join(dataset, "rooms"), os.path.join(dataset, "views"),
                                rid, GRAVITIES[gname])
    out = []
    for c in CANDIDATES:
        params = session.SessionParams()
        try:
            pred = room_prediction(views, photos, "ids", replace(
                params, plan=replace(params.plan, inexact_snap_deg=c)))
        except FindmeError as e:   # refused whole (a camera outside the outline)
            pred = {"refused": str(e)}
        s = score.score_room(room, pred)
        out.append({"ok": s["wall_frac_ok"] or 0.0, "loc": s["loc_success_rate"] or 0.0,
                    "iou": s["iou"], "corner": s["corner_err_m"],
                    "manhattan": bool(pred.get("manhattan")), "refused": "refused" in pred})
    return rid, gname, out


def _row(cells: list) -> str:
    corners = [c["corner"] for c in cells if c["corner"] is not None]
    return (f"walls ok {np.mean([c['ok'] for c in cells]):.3f}  localised "
            f"{np.mean([c['loc'] for c in cells]):.3f}  IoU med "
            f"{np.median([c['iou'] for c in cells]):.3f}  corner med "
            f"{np.median(corners) if corners else float('nan'):.3f} m  Manhattan "
            f"{sum(c['manhattan'] for c in cells)}  refused {sum(c['refused'] for c in cells)}"
            f"  (n {len(cells)})")


def choose(res: dict, rooms) -> int:
    """Index into ``CANDIDATES`` with the most walls ok plus views localised over ``rooms``
    (both gravities); the smallest of a tie."""
    tot = [sum(res[r, g][k]["ok"] + res[r, g][k]["loc"] for r in rooms for g in GRAVITIES)
           for k in range(len(CANDIDATES))]
    best = max(tot)
    return next(k for k, t in enumerate(tot) if t >= best - 1e-9)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dataset")
    ap.add_argument("--jobs", type=int, default=2)
    a = ap.parse_args(argv)
    idx = json.load(open(os.path.join(a.dataset, "index.json")))
    rooms = room_ids(idx)
    jobs = [(a.dataset, r, g) for r in rooms for g in GRAVITIES]
    with ProcessPoolExecutor(max(1, a.jobs)) as ex:
        res = {(r, g): out for r, g, out in ex.map(plan_room, jobs)}
    print(f"{len(rooms)} rooms x {len(GRAVITIES)} gravities ({', '.join(GRAVITIES)}), in sample:")
    for k, c in enumerate(CANDIDATES):
        print(f"  {c:4.1f} deg  " + _row([res[r, g][k] for r in rooms for g in GRAVITIES]))
        for g in GRAVITIES:
            print(f"      {g:9s}" + _row([res[r, g][k] for r in rooms]))
    k_all = choose(res, rooms)
    print(f"chosen on all rooms: {CANDIDATES[k_all]:g} deg")
    held, base = [], []
    for r in rooms:
        k = choose(res, [q for q in rooms if q != r])
        print(f"  without {r}: {CANDIDATES[k]:g} deg")
        held += [res[r, g][k] for g in GRAVITIES]
        base += [res[r, g][0] for g in GRAVITIES]
    print("leave one room out: " + _row(held))
    print(f"at {CANDIDATES[0]:g} deg (before): " + _row(base))
    return 0


if __name__ == "__main__":
    sys.exit(main())
