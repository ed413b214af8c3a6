"""``findme eval``: run over a dataset in the findme-eval layout and write predictions in
the format ``shared/eval/score.py`` reads.

Only inputs are used: the image, ``intrinsics``, ``gravity_cam``, ``camera_height_m`` and the
query pixels (``px`` of ``floor_points`` / ``wall_points`` / ``nonfloor_points``); the
result is the same on a copy of the dataset with its ground truth removed.
"""

from __future__ import annotations

import json
import os
import sys
from concurrent.futures import ProcessPoolExecutor

import multiprocessing as mp

import cv2
from tqdm import tqdm

from findme_core.camera import Camera
from findme_core.errors import FindmeError, InputError
from findme_core.methods import METHODS, hypothesize
from findme_core.scene import Scene

from .imageio import read_image

POINT_KINDS = ("floor_points", "wall_points", "nonfloor_points")


def register(sub) -> None:
    p = sub.add_parser("eval", help="predictions for a findme-eval dataset",
                       description=__doc__)
    p.add_argument("dataset", metavar="DATASET_DIR")
    p.add_argument("--out", required=True, metavar="PREDICTIONS.json")
    p.add_argument("--method", default="findme", choices=METHODS)
    p.add_argument("--max", type=int, default=10, metavar="N", help="hypotheses per view (10)")
    p.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="worker processes")
    p.set_defaults(func=cmd_eval)


def view_inputs(meta: dict) -> tuple[Camera, float, dict]:
    """Camera, camera height and query pixels of a view; nothing else is read."""
    k = meta["intrinsics"]
    cam = Camera(k["fx"], k["fy"], k["cx"], k["cy"], k["width"], k["height"],
                 meta.get("gravity_cam"))
    queries = {kind: [q["px"] for q in meta.get(kind) or []] for kind in POINT_KINDS}
    return cam, float(meta.get("camera_height_m") or 1.0), queries


def predict_view(args) -> tuple[str, dict | None, str | None]:
    """Prediction for one view: ranked polylines and the 3D of each query pixel."""
    view_dir, vid, method, max_n = args
    cv2.setNumThreads(1)
    try:
        with open(os.path.join(view_dir, vid + ".json")) as f:
            meta = json.load(f)
        cam, h, queries = view_inputs(meta)
        image = read_image(os.path.join(view_dir, meta["image"]))
        hs = hypothesize(image, cam, method, max_n)
        pred = {"hypotheses": [h_.polyline.round(3).tolist() for h_ in hs.hypotheses]}
        if hs.hypotheses and any(queries.values()):
            top = hs.hypotheses[0]
            scene = Scene(cam, h, top.polyline, top.kinds)
            for kind, px in queries.items():
                if px:
                    pred[kind] = [None if p.xyz is None else p.xyz.round(5).tolist()
                                  for p in scene.locate(px)]
        return vid, pred, None
    except FindmeError as e:
        return vid, None, str(e)


def cmd_eval(args) -> int:
    idx_path = os.path.join(args.dataset, "index.json")
    try:
        with open(idx_path) as f:
            index = json.load(f)
    except OSError:
        raise InputError(f"{args.dataset}: no index.json (not a findme-eval dataset)") from None
    view_dir = os.path.join(args.dataset, index.get("views_dir", "views"))
    views = sorted({v for ss in index["subsets"].values() for v in ss.get("views", [])})
    preds = {"views": {}, "pairs": {}, "method": args.method}
    failures = []
    jobs = [(view_dir, v, args.method, args.max) for v in views]
    bar = tqdm(total=len(jobs), desc=f"views ({args.method})", unit="view", file=sys.stderr)
    if args.jobs > 1:
        with ProcessPoolExecutor(args.jobs, mp_context=mp.get_context("spawn")) as ex:
            for vid, pred, err in ex.map(predict_view, jobs, chunksize=2):
                _collect(preds, failures, vid, pred, err)
                bar.update()
    else:
        for job in jobs:
            _collect(preds, failures, *predict_view(job))
            bar.update()
    bar.close()
    with open(args.out, "w") as f:
        json.dump(preds, f)
    print(f"wrote {args.out}: {len(preds['views'])} views"
          + (f", {len(failures)} failed" if failures else ""))
    for vid, err in failures[:10]:
        print(f"  {vid}: {err}", file=sys.stderr)
    return 0


def _collect(preds, failures, vid, pred, err):
    if err:
        failures.append((vid, err))
    else:
        preds["views"][vid] = pred
