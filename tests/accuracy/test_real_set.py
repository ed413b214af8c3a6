"""Accuracy on the real evaluation set (dev split), scored by the set's own scorer.

Skips with the reason when ../shared is absent (a user's fresh clone). The thresholds are
regression guards a little above the figures measured when they were set; the goals and the
current figures are in the README's accuracy table.
"""

import importlib.util
import json
import shutil

import pytest

from tests.cli.conftest import run_findme
from tests.conftest import EVAL_DIR, SCORER, needs_eval_data

GT_FIELDS = ("labels", "label_legend", "floor_fraction", "valid_fraction", "boundary_v",
             "boundary_ignore_cols", "oracle_polyline_v", "oracle_polyline_pixel_error",
             "source")


@pytest.fixture(scope="module")
def scored(tmp_path_factory):
    needs_eval_data()
    out = tmp_path_factory.mktemp("eval") / "pred.json"
    # the whole dev split (views, pairs and room plans): minutes on a loaded 2-core machine
    run_findme("eval", EVAL_DIR, "--out", out, timeout=1200)
    spec = importlib.util.spec_from_file_location("findme_eval_score", SCORER)
    score = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(score)
    return score.score(str(EVAL_DIR), json.loads(out.read_text()))["subsets"]


# subset: (top-1 median, best-of-5 median) floor pixel error guards
PIXEL = {"zind-level": (0.02, 0.02), "zind-tilted": (0.04, 0.03),
         "zind-pairs-tilted": (0.06, 0.04), "tum-cabinet": (0.13, 0.11)}
# subset: {kind: median relative error guard, percent}
POINTS = {"zind-level": {"floor": 0.5, "wall": 4.0}, "zind-tilted": {"floor": 0.5, "wall": 4.0},
          "zind-pairs-tilted": {"floor": 0.5, "wall": 7.0}, "tum-cabinet": {"floor": 1.5}}


@pytest.mark.parametrize("subset", sorted(PIXEL))
def test_floor_pixel_error(scored, subset):
    s = scored[subset]["single_image"]
    assert s["coverage"] == 1.0
    top1, best5 = PIXEL[subset]
    assert s["pixel_error_top1"]["median"] <= top1
    assert s["pixel_error_best_of_5"]["median"] <= best5


#: share of the query points answered: a photo judged to show no floor answers none
#: (zind-pairs-tilted: 0.88 -> 0.80 when a smooth band under the line was tested, 2026-12-02:
#: 4 of its kitchen photos, 2 of them with a sliver of floor, ``single/flat``)
MIN_ANSWERED = 0.75


@pytest.mark.parametrize("subset", sorted(POINTS))
def test_3d_points(scored, subset):
    pts = scored[subset]["points_3d"]
    for kind, guard in POINTS[subset].items():
        assert pts[kind]["coverage"] > MIN_ANSWERED
        assert pts[kind]["rel_err_pct_median"] <= guard, (kind, pts[kind])


def test_same_result_without_ground_truth(tmp_path):
    """eval reads only inputs: a copy of some views with every ground-truth field and label
    map removed gives identical predictions."""
    needs_eval_data()
    index = json.loads((EVAL_DIR / "index.json").read_text())
    views = index["subsets"]["zind-tilted"]["views"][:3] + index["subsets"]["tum-cabinet"]["views"][:2]
    (tmp_path / "full" / "views").mkdir(parents=True)
    (tmp_path / "bare" / "views").mkdir(parents=True)
    for v in views:
        meta = json.loads((EVAL_DIR / "views" / f"{v}.json").read_text())
        for d in ("full", "bare"):
            shutil.copy(EVAL_DIR / "views" / meta["image"], tmp_path / d / "views")
        (tmp_path / "full" / "views" / f"{v}.json").write_text(json.dumps(meta))
        bare = {k: val for k, val in meta.items() if k not in GT_FIELDS}
        for kind in ("floor_points", "wall_points", "nonfloor_points"):
            if kind in bare:
                bare[kind] = [{"px": q["px"]} for q in bare[kind]]
        (tmp_path / "bare" / "views" / f"{v}.json").write_text(json.dumps(bare))
    mini = {"subsets": {"mini": {"type": "single", "views": views}}}
    preds = []
    for d in ("full", "bare"):
        (tmp_path / d / "index.json").write_text(json.dumps(mini))
        run_findme("eval", tmp_path / d, "--out", tmp_path / f"{d}.json", "--jobs", "1")
        preds.append(json.loads((tmp_path / f"{d}.json").read_text()))
    assert preds[0]["views"] == preds[1]["views"] and len(preds[0]["views"]) == len(views)
    for p in preds[0]["views"].values():     # each answered point says which surface it is on
        for kind in ("floor_points", "wall_points", "nonfloor_points"):
            assert len(p.get(kind + "_surface") or []) == len(p.get(kind) or [])
            for x, surface in zip(p.get(kind) or [], p.get(kind + "_surface") or []):
                assert (surface in ("floor", "wall")) == (x is not None), (kind, x, surface)
