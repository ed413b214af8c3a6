"""``findme eval``: predictions for a findme-eval dataset (``findme.evaluation``)."""

from __future__ import annotations

import os

from findme_core.errors import InputError
from findme_core.methods import METHODS
from findme_core.motion import METHODS as MOTION_METHODS
from findme_core.provenance import INPUT_GRAVITY_SIGMA_DEG

from ..evaluation import __doc__ as EVAL_DOC
from ..evaluation.dataset import evaluate
from ..evaluation.views import GravityInput
from .options import gravity_sigma


def register(sub) -> None:
    p = sub.add_parser("eval", help="predictions for a findme-eval dataset",
                       description=EVAL_DOC)
    p.add_argument("dataset", metavar="DATASET_DIR")
    p.add_argument("--out", required=True, metavar="PREDICTIONS.json")
    p.add_argument("--method", default="findme", choices=METHODS)
    p.add_argument("--max", type=int, default=10, metavar="N", help="hypotheses per view (10)")
    p.add_argument("--motion-method", default="findme", metavar="NAME[,NAME...]",
                   help="pair motion estimator(s): " + ", ".join(MOTION_METHODS) + " (default "
                        "findme; features = the matches alone, the default before layouts); "
                        "with several, the first goes to --out and each other one to "
                        "OUT.<name>.json, from the same features and hypotheses")
    add_gravity_args(p)
    p.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="worker processes")
    p.add_argument("--room-spots", default="ids", choices=("ids", "auto"),
                   help="rooms: which photos share a spot: 'ids' (the spot token _p<N>_ of "
                        "the view ids, as a capture app marks a new spot) or 'auto' (from "
                        "rotation-only feature matches)")
    p.set_defaults(func=cmd_eval)


def add_gravity_args(p) -> None:
    """The flags of ``GravityInput`` (``--no-gravity``, ``--gravity-noise``,
    ``--gravity-sigma``, ``--gravity-refine``), shared by the tools that read views."""
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
             GravityInput.from_args(args), args.jobs, args.room_spots)
    return 0
