"""A whole findme-eval dataset into predictions files (``evaluate``, ``findme eval``): every
view (``views.predict_view``), pair (``pairs.predict_pair``) and room set
(``rooms.predict_rooms``), in worker processes, in the format ``shared/eval/score.py`` reads.
"""

from __future__ import annotations

import json
import multiprocessing as mp
import os
import sys
from concurrent.futures import ProcessPoolExecutor

from tqdm import tqdm

from findme_core.errors import InputError

from .pairs import predict_pair
from .rooms import predict_rooms
from .views import DATASET_HEIGHT_SIGMA_M, GravityInput, predict_view


def evaluate(dataset: str, out: str, method: str, max_n: int, motion_methods: list[str],
             gravity: GravityInput, workers: int, room_spots: str,
             height_sigma: float = DATASET_HEIGHT_SIGMA_M, declared: bool = False) -> None:
    """Predictions of every view, pair and room of ``dataset`` (a findme-eval folder) into
    ``out`` (the first motion method's pairs; each other one's into ``OUT.<name>.json``),
    in ``workers`` processes; prints what it wrote and the first failures. ``declared``:
    each query point is located on the surface a user who tapped it would say
    (``views.declared_surfaces``).

    Raises:
        InputError: ``dataset`` has no index.json.
    """
    idx_path = os.path.join(dataset, "index.json")
    try:
        with open(idx_path) as f:
            index = json.load(f)
    except OSError:
        raise InputError(f"{dataset}: no index.json (not a findme-eval dataset)") from None
    view_dir = os.path.join(dataset, index.get("views_dir", "views"))
    views = sorted({v for ss in index["subsets"].values() for v in ss.get("views", [])})
    preds = {"views": {}, "pairs": {}, "method": method, "gravity": gravity.describe(),
             "height_sigma_m": height_sigma, "declared_surface": declared}
    failures = []
    jobs = [(view_dir, v, method, max_n, gravity, height_sigma, declared) for v in views]
    bar = tqdm(total=len(jobs), desc=f"views ({method})", unit="view", file=sys.stderr)
    if workers > 1:
        with ProcessPoolExecutor(workers, mp_context=mp.get_context("spawn")) as ex:
            for vid, pred, err in ex.map(predict_view, jobs, chunksize=2):
                _collect(preds, failures, vid, pred, err)
                bar.update()
    else:
        for job in jobs:
            _collect(preds, failures, *predict_view(job))
            bar.update()
    bar.close()
    pair_dir = os.path.join(dataset, index.get("pairs_dir", "pairs"))
    pairs = sorted({p for ss in index["subsets"].values() for p in ss.get("pairs", [])})
    by_method = {m: {} for m in motion_methods}
    pair_failures = {m: [] for m in motion_methods}
    jobs = [(pair_dir, view_dir, p, method, motion_methods, gravity) for p in pairs]
    bar = tqdm(total=len(jobs), desc=f"pairs ({','.join(motion_methods)})", unit="pair",
               file=sys.stderr)

    def collect(pid, pred, err):
        for m in motion_methods:
            if m in pred:
                by_method[m][pid] = pred[m]
            else:
                pair_failures[m].append((pid, err.get(m, "no estimate")))
        bar.update()

    if workers > 1 and len(jobs) > 1:
        with ProcessPoolExecutor(workers, mp_context=mp.get_context("spawn")) as ex:
            for res in ex.map(predict_pair, jobs, chunksize=2):
                collect(*res)
    else:
        for job in jobs:
            collect(*predict_pair(job))
    bar.close()
    preds["rooms_refused"] = {}   # room id -> why its plan was refused (not scored)
    preds["rooms"] = predict_rooms(dataset, index, view_dir, room_spots, workers, gravity,
                                   preds["rooms_refused"])
    stem, ext = os.path.splitext(out)
    for i, m in enumerate(motion_methods):
        path = out if i == 0 else f"{stem}.{m}{ext or '.json'}"
        with open(path, "w") as f:
            json.dump({**preds, "pairs": by_method[m], "motion_method": m}, f)
        print(f"wrote {path}: {len(preds['views'])} views"
              + (f", {len(failures)} failed" if failures else "")
              + (f"; {len(by_method[m])} of {len(pairs)} pairs ({m})" if pairs else ""))
    for vid, err in failures[:10]:
        print(f"  {vid}: {err}", file=sys.stderr)
    for m in motion_methods:
        for pid, err in pair_failures[m][:10]:
            print(f"  {pid} ({m}): {err}", file=sys.stderr)


def _collect(preds, failures, vid, pred, err):
    if err:
        failures.append((vid, err))
    else:
        preds["views"][vid] = pred
