"""``findme eval`` leave-one-room-out: every view, pair and room predicted with ranking weights
fitted WITHOUT its own room (ZInD) or frame block (TUM), so its figures are what a room the
project never saw gets.

    python tools/fit_ranker.py ../shared/data/findme-eval --loro-out folds.json
    python tools/loro_eval.py ../shared/data/findme-eval --folds folds.json --out loro.json
    python ../shared/eval/score.py ../shared/data/findme-eval loro.json

The predictions have ``findme eval``'s format (score them with the split's scorer, their
sigmas with ``tools/sigma_coverage.py``). The ranking weights are the only parameters fitted
by optimisation on the dev split; the groups are ``fit_ranker.group_of``'s (ZInD: one room;
TUM: 6 frames; a TUM pair takes the fold of its first frame, whose training may hold its
second frame's block). KITTI is never used for fitting: its views take the shipped weights.
The other constants (sigma terms, thresholds) are chosen as their modules say; their own
leave-one-room-out figures are ``tools/sigma_coverage.py``'s and ``tools/calibrate_plan.py``'s.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import sys
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
sys.path.insert(0, os.path.dirname(__file__))
from fit_ranker import group_of  # noqa: E402
from findme.evaluation.pairs import predict_pair  # noqa: E402
from findme.evaluation.views import predict_view  # noqa: E402
from findme.evaluation.rooms import room_job  # noqa: E402
from findme_core.single import hypotheses  # noqa: E402
from findme_core.single.ranking import FEATURES, RankWeights  # noqa: E402

_GENERATE = hypotheses.generate


def _use(weights: dict | None) -> None:
    """Rank with ``weights`` ({name: w}; None: the shipped ones) in this worker."""
    if weights is None:
        hypotheses.generate = _GENERATE
        return
    w = RankWeights.from_vector([weights[f] for f in FEATURES])

    def generate(image, camera, max_n=10, params=None, *args, **kw):
        params = replace(params or hypotheses.HypothesisParams(), weights=w)
        return _GENERATE(image, camera, max_n, params, *args, **kw)
    hypotheses.generate = generate


def _job(task):
    kind, weights, args = task
    _use(weights)
    return kind, {"view": predict_view, "pair": predict_pair, "room": room_job}[kind](args)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dataset")
    ap.add_argument("--folds", required=True, metavar="FOLDS.json")
    ap.add_argument("--out", required=True, metavar="PREDICTIONS.json")
    ap.add_argument("--jobs", type=int, default=2)
    a = ap.parse_args(argv)
    folds = json.load(open(a.folds))
    idx = json.load(open(os.path.join(a.dataset, "index.json")))
    vdir = os.path.join(a.dataset, idx.get("views_dir", "views"))
    pdir = os.path.join(a.dataset, idx.get("pairs_dir", "pairs"))
    rdir = os.path.join(a.dataset, idx.get("rooms_dir", "rooms"))
    views = sorted({v for ss in idx["subsets"].values() for v in ss.get("views", [])})
    pairs = sorted({p for ss in idx["subsets"].values() for p in ss.get("pairs", [])})
    rooms = sorted({r for ss in idx["subsets"].values() for r in ss.get("rooms", [])})
    fold = lambda item: folds.get(group_of(item))  # noqa: E731  (None: shipped weights)
    tasks = ([("view", fold(v), (vdir, v, "findme", 10, True)) for v in views]
             + [("pair", fold(p), (pdir, vdir, p, "findme", ["findme"], True)) for p in pairs]
             + [("room", fold(r + "_"), (rdir, vdir, r, "ids")) for r in rooms])
    preds = {"views": {}, "pairs": {}, "rooms": {}, "method": "findme",
             "gravity": "given", "ranking": "leave-one-room-out (tools/loro_eval.py)"}
    with ProcessPoolExecutor(a.jobs, mp_context=mp.get_context("spawn")) as ex:
        for kind, res in ex.map(_job, tasks, chunksize=2):
            if kind == "view":
                vid, pred, err = res
                if pred is not None:
                    preds["views"][vid] = pred
            elif kind == "pair":
                pid, pred, _ = res
                if "findme" in pred:
                    preds["pairs"][pid] = pred["findme"]
            else:
                rid, pred, err = res
                if pred is not None:
                    preds["rooms"][rid] = pred
                else:
                    print(f"  {rid}: {err}", file=sys.stderr)
    json.dump(preds, open(a.out, "w"))
    print(f"wrote {a.out}: {len(preds['views'])} views, {len(preds['pairs'])} pairs, "
          f"{len(preds['rooms'])} rooms")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
