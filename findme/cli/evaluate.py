"""``findme eval``: predictions for a findme-eval dataset (``findme.evaluation``)."""

from __future__ import annotations

import os

from findme_core.errors import InputError
from findme_core.single.methods import METHODS
from findme_core.motion.methods import METHODS as MOTION_METHODS
from findme_core.geometry.provenance import INPUT_GRAVITY_SIGMA_DEG

from ..evaluation.dataset import evaluate
from ..evaluation.views import GravityInput
from .options import gravity_sigma


EVAL_HELP = """\
Predictions for a dataset in the findme-eval layout (index.json, views/, pairs/,
rooms/), in the format its scorer reads: each view's boundary hypotheses and the
3D position and 1-sigma of its query pixels, each pair's motion, each room set's
floor plan. Only a view's inputs are read (image, intrinsics, gravity_cam,
camera_height_m, the query pixels): the answers are the same on a copy without
the ground truth. Each prediction says which gravity it used and where it came
from; the options below withhold, disturb or refine the dataset's gravity.

Example:  findme eval ../shared/data/findme-eval --out p.json --jobs 2
          python ../shared/eval/score.py ../shared/data/findme-eval p.json"""


def register(sub) -> None:
    p = sub.add_parser("eval", help="predictions for a findme-eval dataset, for its scorer",
                       description=EVAL_HELP)
    p.add_argument("dataset", metavar="DATASET_DIR", help="the dataset's folder (index.json)")
    p.add_argument("--out", required=True, metavar="PREDICTIONS.json",
                   help="where the predictions go")
    p.add_argument("--method", default="findme", choices=METHODS,
                   help="hypothesis method: findme (default) or paper (the paper's)")
    p.add_argument("--max", type=int, default=10, metavar="N", help="hypotheses per view (10)")
    p.add_argument("--motion-method", default="findme", metavar="NAME[,NAME...]",
                   help="pair motion estimator(s), comma-separated, among "
                        + ", ".join(MOTION_METHODS) + " (default findme; features: the feature "
                        "matches alone); the first goes to --out, each other one to "
                        "OUT.<name>.json")
    add_gravity_args(p)
    p.add_argument("--jobs", type=int, default=os.cpu_count() or 1,
                   help="worker processes (default: one per CPU)")
    p.add_argument("--room-spots", default="ids", choices=("ids", "auto"),
                   help="rooms: which photos share a spot: 'ids' (the spot token _p<N>_ of "
                        "the view ids, as a capture app marks a new spot) or 'auto' (from "
                        "rotation-only feature matches)")
    p.add_argument("--height-sigma", type=float, default=0.0, metavar="M",
                   help="1-sigma of the views' camera heights in the 3D points' sigmas "
                        "(default 0: a dataset's heights are the ones its truth was made "
                        "with; a height a user types is known to about 0.03 m)")
    p.add_argument("--declared-surface", action="store_true",
                   help="locate each query point on the surface a user who tapped it would say: "
                        "floor and wall points on theirs, TUM's non-floor points on a wall where "
                        "they are vertical (findme locate --point U,V,floor)")
    p.set_defaults(func=cmd_eval)


def add_gravity_args(p) -> None:
    """The flags of ``findme.evaluation.views.GravityInput`` (``--no-gravity``,
    ``--gravity-noise``, ``--gravity-sigma``, ``--gravity-refine``), shared by the tools that
    read views."""
    g = p.add_mutually_exclusive_group()
    g.add_argument("--no-gravity", action="store_true",
                   help="withhold the views' gravity_cam: gravity from the image, else level")
    g.add_argument("--gravity-noise", type=float, default=0.0, metavar="DEG",
                   help="simulate a phone's sensor: tilt every view's gravity by a random "
                        "N(0, DEG) in pitch and roll (seeded by the view id)")
    p.add_argument("--gravity-sigma", type=gravity_sigma, default=None, metavar="DEG",
                   help="declared 1-sigma of the given gravity (default %.1f, a phone held "
                        "still)" % INPUT_GRAVITY_SIGMA_DEG)
    p.add_argument("--gravity-refine", action="store_true",
                   help="combine the given gravity with the photo's vanishing directions, as "
                        "the services do with a phone's")


def _motion_methods(text: str) -> list[str]:
    methods = [m.strip() for m in text.split(",") if m.strip()]
    bad = [m for m in methods if m not in MOTION_METHODS]
    if not methods or bad or len(set(methods)) != len(methods):
        raise InputError(f"--motion-method must be distinct names among "
                         f"{', '.join(MOTION_METHODS)}, got {text!r}")
    return methods


def cmd_eval(args) -> int:
    evaluate(args.dataset, args.out, args.method, args.max, _motion_methods(args.motion_method),
             GravityInput.from_args(args), args.jobs, args.room_spots, args.height_sigma,
             args.declared_surface)
    return 0
