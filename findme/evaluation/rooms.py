"""The room sets of a findme-eval dataset (rooms/<id>.json: ordered view ids): each room's
photos analysed from their inputs only (``room_photos``), its spots from the ids or the
photos (``room_spots``), its plan as the scorer reads it (``room_prediction``), one room in
a worker (``room_job``) and every room (``predict_rooms``).
"""

from __future__ import annotations

import json
import multiprocessing as mp
import os
import re
import sys
from concurrent.futures import ProcessPoolExecutor

import cv2
from tqdm import tqdm

from findme_core.plan import session
from findme_core.geometry.camera import Camera
from findme_core.errors import FindmeError

from findme_io.imageio import read_image

_SPOT = re.compile(r"_p(\d+)_")


def room_photos(room_dir: str, view_dir: str, rid: str) -> tuple[list, list]:
    """(view ids, analysed photos) of one findme-eval room set: only its ordered view ids
    and their camera inputs are read."""
    with open(os.path.join(room_dir, rid + ".json")) as f:
        views = json.load(f)["views"]
    photos = []
    for v in views:
        with open(os.path.join(view_dir, v + ".json")) as f:
            meta = json.load(f)
        k = meta["intrinsics"]
        cam = Camera(k["fx"], k["fy"], k["cx"], k["cy"], k["width"], k["height"],
                     meta.get("gravity_cam"))
        photos.append(session.analyse(read_image(os.path.join(view_dir, meta["image"])),
                                      cam, float(meta["camera_height_m"])))
    return views, photos


def room_spots(views, spots_mode: str):
    """Spot labels from the ids' ``_p<N>_`` token ('ids'), or None ('auto': from the photos)."""
    if spots_mode != "ids":
        return None
    return [(_SPOT.search(v).group(1) if _SPOT.search(v) else v) for v in views]


def room_prediction(views, photos, spots_mode: str) -> dict:
    """The scorer's room entry (polygon, poses of the placed photos) plus the plan's JSON."""
    plan, _, _ = session.plan(photos, room_spots(views, spots_mode))
    d = plan.to_dict(views)
    d["poses"] = {k: p for k, p in d["poses"].items() if p is not None}
    return d


def room_job(args) -> tuple[str, dict | None, str | None]:
    """Plan of one findme-eval room set (``room_photos``); spots from the ids' ``_p<N>_``
    token ('ids') or from the photos ('auto')."""
    room_dir, view_dir, rid, spots_mode = args
    cv2.setNumThreads(1)
    try:
        views, photos = room_photos(room_dir, view_dir, rid)
        return rid, room_prediction(views, photos, spots_mode), None
    except (FindmeError, OSError, KeyError, ValueError) as e:
        return rid, None, str(e)


def predict_rooms(dataset, index, view_dir, spots: str, jobs: int) -> dict:
    """Plans of the dataset's room sets (rooms/<id>.json), in each room's frame."""
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
