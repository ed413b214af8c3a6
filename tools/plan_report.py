"""Per-room floor-plan results on a findme-eval split, with the upper bound the walls allow.

    python tools/plan_report.py DATASET_DIR [--spots ids|auto] [--figures docs/plans]
                                [--cache DIR]

For every room set (zind-rooms): our plan (``findme.evaluation.rooms.room_job``: only the inputs
the dataset README allows), scored by ``shared/eval/score.py``; next to it the plan built
from the same per-photo layouts placed at the TRUE poses (ground truth used on purpose: it
shows what the walls alone allow, i.e. how much of the error comes from the poses). With
--figures, one SVG per room: our plan drawn over the true outline (grey); the truth is read
from the dataset at run time, only our drawing is written. --cache keeps each room's
analysed photos (hypotheses, layouts, features) in DIR between runs (delete it after a change
to the per-photo stage).
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import math
import os
import pickle
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from findme.evaluation.rooms import room_photos, room_prediction  # noqa: E402
from findme_core.plan import floorplan  # noqa: E402
from findme_core.errors import FindmeError  # noqa: E402
from findme_io.plan_svg import plan_svg  # noqa: E402


def _scorer(dataset):
    path = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(dataset))), "eval",
                        "score.py")
    if not os.path.exists(path):
        path = os.path.join(os.path.dirname(os.path.abspath(dataset)), "..", "eval", "score.py")
    spec = importlib.util.spec_from_file_location("score", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def true_pose_plan(room, photos):
    """Plan from the photos' layouts placed at the TRUE planar poses (upper bound)."""
    poses = np.array([(p["x_m"], p["z_m"], math.radians(p["yaw_deg"]))
                      for p in (room["poses_planar"][v] for v in room["views"])])
    return floorplan.build([ph.layout for ph in photos], poses, refine=False)


def cached_photos(rdir, vdir, rid, cache):
    """(views, photos) of a room, from ``cache`` when it has them."""
    path = os.path.join(cache, rid + ".pkl") if cache else None
    if path and os.path.exists(path):
        with open(path, "rb") as f:
            return pickle.load(f)
    out = room_photos(rdir, vdir, rid)
    if path:
        os.makedirs(cache, exist_ok=True)
        with open(path, "wb") as f:
            pickle.dump(out, f)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dataset")
    ap.add_argument("--spots", default="ids", choices=("ids", "auto"))
    ap.add_argument("--figures", metavar="DIR")
    ap.add_argument("--cache", metavar="DIR")
    a = ap.parse_args(argv)
    S = _scorer(a.dataset)
    idx = json.load(open(os.path.join(a.dataset, "index.json")))
    rooms = idx["subsets"]["zind-rooms"]["rooms"]
    rdir, vdir = os.path.join(a.dataset, "rooms"), os.path.join(a.dataset, "views")
    rows = []
    print("| room | IoU | wall len err | walls ok | corner err m | views localised | "
          "IoU (true poses) | wall len err (true poses) | walls ok (true poses) | "
          "corner err m (true poses) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for rid in rooms:
        room = json.load(open(os.path.join(rdir, rid + ".json")))
        views, photos = cached_photos(rdir, vdir, rid, a.cache)
        try:
            pred, err = room_prediction(views, photos, a.spots), None
        except FindmeError as e:
            pred, err = None, str(e)
        ours = S.score_room(room, pred)
        ub_plan = true_pose_plan(room, photos)
        ub = S.score_room(room, {"floor_polygon_m": ub_plan.polygon.tolist(),
                                 "poses": room["poses_planar"]})
        rows.append((ours, ub))

        def f(x, fmt="%.3f"):
            return "-" if x is None else fmt % x
        print(f"| {rid} | {f(ours['iou'])} | {f(ours['wall_len_rel_err_median'])} | "
              f"{f(ours['wall_frac_ok'], '%.2f')} | {f(ours['corner_err_m'])} | "
              f"{f(ours['loc_success_rate'], '%.2f')} | {f(ub['iou'])} | "
              f"{f(ub['wall_len_rel_err_median'])} | {f(ub['wall_frac_ok'], '%.2f')} | "
              f"{f(ub['corner_err_m'])} |" + (f" ({err})" if err else ""))
        if a.figures and pred:
            os.makedirs(a.figures, exist_ok=True)
            plan = floorplan.Plan.from_dict(pred)
            title = (f"{rid}: ours (blue) over the truth (grey); IoU {ours['iou']:.2f}, "
                     f"views localised {ours['loc_success_rate']:.0%}")
            with open(os.path.join(a.figures, rid + ".svg"), "w") as fh:
                fh.write(plan_svg(plan, list(pred["poses"]), truth=room["floor_polygon_m"],
                                  title=title))
    med = lambda k, i: float(np.median([r[i][k] if r[i][k] is not None else np.nan  # noqa: E731
                                        for r in rows]))
    n_views = sum(r[0]["n_views_localised"] for r in rows)
    loc = sum((r[0]["loc_success_rate"] or 0) * r[0]["n_views_localised"] for r in rows) / n_views
    def pooled(i):
        n = sum(r[i]["n_walls_scored"] for r in rows)
        return sum((r[i]["wall_frac_ok"] or 0.0) * r[i]["n_walls_scored"] for r in rows) / n
    print(f"| pooled | | | {pooled(0):.2f} | | {loc:.2f} | | | {pooled(1):.2f} | |")
    print(f"| median | {med('iou', 0):.3f} | {med('wall_len_rel_err_median', 0):.3f} | "
          f"{med('wall_frac_ok', 0):.2f} | {med('corner_err_m', 0):.3f} | {loc:.2f} (pooled) | "
          f"{med('iou', 1):.3f} | {med('wall_len_rel_err_median', 1):.3f} | "
          f"{med('wall_frac_ok', 1):.2f} | {med('corner_err_m', 1):.3f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
