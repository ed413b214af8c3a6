"""``findme eval``: run over a dataset in the findme-eval layout and write predictions in
the format ``shared/eval/score.py`` reads.

Only inputs are used: the image, ``intrinsics``, ``gravity_cam``, ``camera_height_m`` and the
query pixels (``px`` of ``floor_points`` / ``wall_points`` / ``nonfloor_points``); of a pair
only its two view ids (``a``, ``b``): the motion comes from the two views' images and inputs
(rank-1 hypothesis of each chosen, the next ranks as candidate layouts). The result is the same on a copy of the dataset with its ground
truth removed.

A view's ``gravity_cam`` (exact: from the panorama, the depth's floor plane) is taken as it
is, with a 1-sigma of ``--gravity-sigma`` degrees (default
``provenance.INPUT_GRAVITY_SIGMA_DEG``) for the 3D sigmas. ``--gravity-refine`` does what the
services do with a phone's gravity: combine it with the photo's vanishing directions near it
(``gravity_fusion``). ``--gravity-noise DEG`` simulates a phone's sensor error: every view's
gravity is tilted by a random N(0, DEG) in pitch and in roll, seeded by the view's id.
``--no-gravity`` withholds every view's ``gravity_cam``: gravity then comes from the image
(vanishing directions) or is assumed level, as for a photo without sensors. Pairs
take the gravity their views end with, as the services do. Each view's prediction says which
gravity it used (``gravity_cam``), where it came from (``gravity_source``: input,
input+image, image or level), its 1-sigma (``gravity_sigma_deg``) and the 1-sigma of every 3D
point (``<kind>_sigma_m``, metres), so the estimate can be scored against the dataset's
gravity and the sigmas against the errors (``tools/gravity_report.py``).
"""

from __future__ import annotations

import json
import math
import os
import sys
import zlib
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass

import multiprocessing as mp

import cv2
import numpy as np
from tqdm import tqdm

from findme_core.geometry.camera import Camera
from findme_core.errors import FindmeError, InputError
from findme_core.geometry.manhattan import gravity_of, pitch_roll_deg
from findme_core.geometry.provenance import INPUT_GRAVITY_SIGMA_DEG, Provenance
from findme_core.single.methods import METHODS
from findme_core.motion.methods import METHODS as MOTION_METHODS
from findme_core.single.scene import Scene, boundary_sigma_px
from .options import gravity_sigma

from findme_io.camera_source import hypothesize_photo, with_gravity
from findme_io.imageio import read_image
from findme_core.motion.pair import motion_photos, photo_of

POINT_KINDS = ("floor_points", "wall_points", "nonfloor_points")
#: order of the per-point sigma parts written as ``<kind>_sigma_parts_m``
SIGMA_PARTS = ("boundary", "height", "pixel", "gravity")


def register(sub) -> None:
    p = sub.add_parser("eval", help="predictions for a findme-eval dataset",
                       description=__doc__)
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


def view_inputs(meta: dict) -> tuple[Camera, float, dict]:
    """Camera, camera height and query pixels of a view; nothing else is read."""
    k = meta["intrinsics"]
    cam = Camera(k["fx"], k["fy"], k["cx"], k["cy"], k["width"], k["height"],
                 meta.get("gravity_cam"))
    queries = {kind: [q["px"] for q in meta.get(kind) or []] for kind in POINT_KINDS}
    return cam, float(meta.get("camera_height_m") or 1.0), queries


@dataclass(frozen=True)
class GravityInput:
    """How a view's ``gravity_cam`` reaches the estimator (see the module doc).

    Attributes:
        given: False withholds it (``--no-gravity``).
        sigma_deg: its declared 1-sigma per axis, degrees (None:
            ``INPUT_GRAVITY_SIGMA_DEG``; 0: exact).
        noise_deg: a simulated sensor's error: N(0, noise) degrees on pitch and on roll,
            seeded by the view id.
        refine: combined with the photo's vanishing directions (``gravity_fusion``), as the
            services do; else taken as it is.
    """

    given: bool = True
    sigma_deg: float | None = None
    noise_deg: float = 0.0
    refine: bool = False

    def __post_init__(self) -> None:
        for name in ("sigma_deg", "noise_deg"):
            v = getattr(self, name)
            if v is not None and not (math.isfinite(v) and 0.0 <= v <= 20.0):
                raise InputError(f"gravity {name.replace('_deg', '')} must be 0-20 degrees, "
                                 f"got {v!r}")

    @classmethod
    def from_args(cls, a) -> "GravityInput":
        """From the flags of ``add_gravity_args``."""
        return cls(not a.no_gravity, a.gravity_sigma, a.gravity_noise, a.gravity_refine)

    def describe(self) -> str:
        """How the gravity was given, for the predictions file."""
        if not self.given:
            return "withheld: from the image, else level"
        sigma = INPUT_GRAVITY_SIGMA_DEG if self.sigma_deg is None else self.sigma_deg
        return ("given" + (f" with simulated sensor noise N(0, {self.noise_deg:g} deg) per axis"
                           if self.noise_deg else "")
                + f", declared 1-sigma {sigma:g} deg"
                + (", combined with the image's vanishing directions" if self.refine else ""))

    def of(self, meta: dict):
        """(gravity (3,) or None, declared 1-sigma in radians or None) of a view."""
        g = meta.get("gravity_cam") if self.given else None
        if g is None:
            return None, None
        if self.noise_deg > 0:
            rng = np.random.default_rng(zlib.crc32(str(meta.get("id", "")).encode()))
            pitch, roll = pitch_roll_deg(np.asarray(g, float) / np.linalg.norm(g))
            g = gravity_of(*(np.array([pitch, roll]) + rng.normal(0.0, self.noise_deg, 2)))
        return g, None if self.sigma_deg is None else math.radians(self.sigma_deg)


def _gravity_input(gravity) -> GravityInput:
    return gravity if isinstance(gravity, GravityInput) else GravityInput(given=bool(gravity))


def view_camera(meta: dict, image, gravity: GravityInput | bool = True
                ) -> tuple[Camera, Provenance]:
    """A view's camera from its intrinsics, and its gravity as ``gravity`` gives it
    (``GravityInput``; True: as it is, False: withheld) through
    ``camera_source.with_gravity``: the given one (combined with the image's vanishing
    directions when refined), or the image's estimate alone when withheld or absent."""
    cam, _, _ = view_inputs(meta)
    gi = _gravity_input(gravity)
    g, sigma = gi.of(meta)
    return with_gravity(cam, image, g, sigma, estimate=g is None or gi.refine)


def predict_view(args) -> tuple[str, dict | None, str | None]:
    """Prediction for one view: ranked polylines and the 3D of each query pixel."""
    view_dir, vid, method, max_n, *rest = args
    gravity = rest[0] if rest else True
    cv2.setNumThreads(1)
    try:
        with open(os.path.join(view_dir, vid + ".json")) as f:
            meta = json.load(f)
        _, h, queries = view_inputs(meta)
        image = read_image(os.path.join(view_dir, meta["image"]))
        cam, prov = view_camera(meta, image, gravity)
        hs, cam, prov = hypothesize_photo(image, cam, prov, method, max_n, camera_height=h)
        pred = {"hypotheses": [h_.polyline.round(3).tolist() for h_ in hs.hypotheses],
                "gravity_cam": [round(float(x), 6) for x in cam.gravity],
                "gravity_source": prov.gravity,
                "gravity_sigma_deg": round(math.degrees(prov.gravity_sigma), 4)}
        if hs.hypotheses and any(queries.values()):
            top = hs.hypotheses[0]
            try:
                scene = Scene(cam, h, top.polyline, top.kinds, gravity_cov=prov.gravity_cov,
                              boundary_sigma_px=boundary_sigma_px(cam.width, cam.height))
            except FindmeError:  # e.g. a level-camera polyline crossing a tilted horizon:
                scene = None     # its points have no answer, its hypotheses still count
            for kind, px in queries.items():
                if px:
                    located = [None] * len(px) if scene is None else scene.locate(px)
                    pred[kind] = [None if p is None or p.xyz is None else p.xyz.round(5).tolist()
                                  for p in located]
                    pred[kind + "_sigma_m"] = [None if p is None or p.xyz is None
                                               else round(p.sigma_m, 5) for p in located]
                    pred[kind + "_sigma_parts_m"] = [
                        None if p is None or p.xyz is None else
                        [round(p.sigma_parts[k], 5) for k in SIGMA_PARTS] for p in located]
        return vid, pred, None
    except FindmeError as e:
        return vid, None, str(e)


def pair_inputs(pair_dir, view_dir, pid: str, gravity: GravityInput | bool = True
                ) -> tuple[dict, list]:
    """A dataset pair's record and, for its photos A and B, (image, camera, camera height);
    of each view only its inputs are read (``view_inputs``), its camera with the gravity the
    view's own prediction ends with (``view_camera``, then ``hypothesize_photo``)."""
    with open(os.path.join(pair_dir, pid + ".json")) as f:
        pair = json.load(f)
    photos = []
    for which in ("a", "b"):
        with open(os.path.join(view_dir, pair[which] + ".json")) as f:
            meta = json.load(f)
        _, h, _ = view_inputs(meta)
        image = read_image(os.path.join(view_dir, meta["image"]))
        cam, prov = view_camera(meta, image, gravity)
        if prov.estimate is not None:   # the gravity the view's own prediction ends with
            cam = hypothesize_photo(image, cam, prov, max_n=1, camera_height=h)[1]
        photos.append((image, cam, h))
    return pair, photos


def predict_pair(args) -> tuple[str, dict, dict]:
    """Motion of one pair by each method: ({method: {x_m, z_m, yaw_deg, ...}}, {method: error})."""
    pair_dir, view_dir, pid, hyp_method, methods, *rest = args
    gravity = rest[0] if rest else True
    cv2.setNumThreads(1)
    preds, errs = {}, {}
    try:
        _, photos = pair_inputs(pair_dir, view_dir, pid, gravity)
        pa, pb = [photo_of(image, cam, h, 1, hyp_method, which)
                  for (image, cam, h), which in zip(photos, "AB")]
        for method, r in motion_photos(pa, pb, methods).items():
            if isinstance(r, FindmeError):
                errs[method] = str(r)
                continue
            m = r.motion
            preds[method] = {**_motion_numbers(m), "inliers": m.n_inliers, "matches": r.matches,
                             "alternatives": [_motion_numbers(a) for a in m.alternatives]}
            if m.layout is not None:
                preds[method]["layout_samples"] = m.layout.samples
    except (FindmeError, OSError, KeyError, ValueError) as e:   # a broken pair, not a crash
        errs = {method: str(e) for method in methods}
    return pid, preds, errs


def _motion_numbers(m) -> dict:
    return {"x_m": round(m.x, 6), "z_m": round(m.z, 6), "yaw_deg": round(math.degrees(m.yaw), 6),
            "sigma_x_m": round(m.sigma_x, 6), "sigma_z_m": round(m.sigma_z, 6),
            "sigma_yaw_deg": round(math.degrees(m.sigma_yaw), 6)}


def _motion_methods(text: str) -> list[str]:
    methods = [m.strip() for m in text.split(",") if m.strip()]
    bad = [m for m in methods if m not in MOTION_METHODS]
    if not methods or bad or len(set(methods)) != len(methods):
        raise InputError(f"--motion-method must be distinct names among "
                         f"{', '.join(MOTION_METHODS)}, got {text!r}")
    return methods


def cmd_eval(args) -> int:
    motion_methods = _motion_methods(args.motion_method)
    idx_path = os.path.join(args.dataset, "index.json")
    try:
        with open(idx_path) as f:
            index = json.load(f)
    except OSError:
        raise InputError(f"{args.dataset}: no index.json (not a findme-eval dataset)") from None
    view_dir = os.path.join(args.dataset, index.get("views_dir", "views"))
    views = sorted({v for ss in index["subsets"].values() for v in ss.get("views", [])})
    gravity = GravityInput.from_args(args)
    preds = {"views": {}, "pairs": {}, "method": args.method, "gravity": gravity.describe()}
    failures = []
    jobs = [(view_dir, v, args.method, args.max, gravity) for v in views]
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
    pair_dir = os.path.join(args.dataset, index.get("pairs_dir", "pairs"))
    pairs = sorted({p for ss in index["subsets"].values() for p in ss.get("pairs", [])})
    by_method = {m: {} for m in motion_methods}
    pair_failures = {m: [] for m in motion_methods}
    jobs = [(pair_dir, view_dir, p, args.method, motion_methods, gravity) for p in pairs]
    bar = tqdm(total=len(jobs), desc=f"pairs ({','.join(motion_methods)})", unit="pair",
               file=sys.stderr)

    def collect(pid, pred, err):
        for m in motion_methods:
            if m in pred:
                by_method[m][pid] = pred[m]
            else:
                pair_failures[m].append((pid, err.get(m, "no estimate")))
        bar.update()

    if args.jobs > 1 and len(jobs) > 1:
        with ProcessPoolExecutor(args.jobs, mp_context=mp.get_context("spawn")) as ex:
            for res in ex.map(predict_pair, jobs, chunksize=2):
                collect(*res)
    else:
        for job in jobs:
            collect(*predict_pair(job))
    bar.close()
    preds["rooms"] = predict_rooms(args.dataset, index, view_dir, args.room_spots, args.jobs)
    stem, ext = os.path.splitext(args.out)
    for i, m in enumerate(motion_methods):
        out = args.out if i == 0 else f"{stem}.{m}{ext or '.json'}"
        with open(out, "w") as f:
            json.dump({**preds, "pairs": by_method[m], "motion_method": m}, f)
        print(f"wrote {out}: {len(preds['views'])} views"
              + (f", {len(failures)} failed" if failures else "")
              + (f"; {len(by_method[m])} of {len(pairs)} pairs ({m})" if pairs else ""))
    for vid, err in failures[:10]:
        print(f"  {vid}: {err}", file=sys.stderr)
    for m in motion_methods:
        for pid, err in pair_failures[m][:10]:
            print(f"  {pid} ({m}): {err}", file=sys.stderr)
    return 0


def _collect(preds, failures, vid, pred, err):
    if err:
        failures.append((vid, err))
    else:
        preds["views"][vid] = pred


def predict_rooms(dataset, index, view_dir, spots: str, jobs: int) -> dict:
    """Plans of the dataset's room sets (rooms/<id>.json), in each room's frame."""
    from findme.plan_cli import room_job   # rooms live in plan_cli (one hunk here)
    room_dir = os.path.join(dataset, index.get("rooms_dir", "rooms"))
    rooms = sorted({r for ss in index["subsets"].values() for r in ss.get("rooms", [])})
    out = {}
    jobs_ = [(room_dir, view_dir, r, spots) for r in rooms]
    with ProcessPoolExecutor(max(1, jobs), mp_context=mp.get_context("spawn")) as ex:
        for rid, pred, err in tqdm(ex.map(room_job, jobs_), total=len(jobs_), desc="rooms",
                                   unit="room", file=sys.stderr):
            if err:
                print(f"  {rid}: {err}", file=sys.stderr)
            else:
                out[rid] = pred
    return out
