"""The room sets of a findme-eval dataset (rooms/<id>.json: ordered view ids): their ids
(``room_ids``), each room's photos analysed from their inputs only (``room_photos``), its
spots from the ids or the photos (``room_spots``), its plan as the scorer reads it
(``room_prediction``), one room in a worker (``room_job``) and every room
(``predict_rooms``).
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

from findme_core.errors import FindmeError, OutlineRefused
from findme_core.plan import session

from findme_io.imageio import read_image
from findme_io.session_photos import final_gravity, session_photos

from .views import view_camera

_SPOT = re.compile(r"_p(\d+)_")


def room_photos(room_dir: str, view_dir: str, rid: str, gravity=True) -> tuple[list, list]:
    """(view ids, analysed photos) of one findme-eval room set: only its ordered view ids
    and their camera inputs are read; each view's gravity as ``gravity`` (a
    ``views.GravityInput``, or True/False) gives it; photos whose gravity came from their own
    lines agree on it spot by spot (``session_photos``)."""
    with open(os.path.join(room_dir, rid + ".json")) as f:
        views = json.load(f)["views"]
    images, inputs = [], []
    for v in views:
        with open(os.path.join(view_dir, v + ".json")) as f:
            meta = json.load(f)
        img = read_image(os.path.join(view_dir, meta["image"]))
        cam, prov = view_camera(meta, img, gravity)
        images.append(img)
        inputs.append(final_gravity(img, cam, prov, float(meta["camera_height_m"]), True))
    return views, session_photos(images, inputs)[0]


def room_spots(views, spots_mode: str):
    """Spot labels from the ids' ``_p<N>_`` token ('ids'), or None ('auto': from the photos)."""
    if spots_mode != "ids":
        return None
    return [(_SPOT.search(v).group(1) if _SPOT.search(v) else v) for v in views]


def room_ids(index: dict) -> list[str]:
    """The dataset's room set ids (every subset's ``rooms``), sorted."""
    return sorted({r for ss in index["subsets"].values() for r in ss.get("rooms", [])})


def room_prediction(views, photos, spots_mode: str,
                    params: session.SessionParams | None = None) -> dict:
    """The scorer's room entry (polygon, poses of the placed photos) plus the plan's JSON
    (``params``: the session's, default ``SessionParams()``). A refused outline
    (``OutlineRefused``) gives the poses alone, with ``refused``: the reason (the scorer
    counts the room's outline missing and scores the poses)."""
    try:
        d = session.plan(photos, room_spots(views, spots_mode),
                         params or session.SessionParams())[0].to_dict(views)
    except OutlineRefused as e:
        d = {**e.plan.to_dict(views, outline=False), "refused": str(e)}
    d["poses"] = {k: p for k, p in d["poses"].items() if p is not None}
    return d


def room_job(args) -> tuple[str, dict | None, str | None]:
    """Plan of one findme-eval room set (``room_photos``); spots from the ids' ``_p<N>_``
    token ('ids') or from the photos ('auto')."""
    room_dir, view_dir, rid, spots_mode, *gravity = args
    cv2.setNumThreads(1)
    try:
        views, photos = room_photos(room_dir, view_dir, rid, *gravity)
        pred = room_prediction(views, photos, spots_mode)
        return rid, pred, pred.get("refused")
    except (FindmeError, OSError, KeyError, ValueError) as e:
        return rid, None, str(e)


def predict_rooms(dataset, index, view_dir, spots: str, jobs: int, gravity=True,
                  refused: dict | None = None) -> dict:
    """Plans of the dataset's room sets (rooms/<id>.json), in each room's frame; each view's
    gravity as ``gravity`` gives it (withheld: from the photos, agreed spot by spot). A room
    whose plan fails has no entry (the scorer counts it a failure), one whose outline is
    refused has its photos' poses alone; either reason goes into ``refused`` (room id -> the
    message), when given."""
    room_dir = os.path.join(dataset, index.get("rooms_dir", "rooms"))
    rooms = room_ids(index)
    out = {}
    jobs_ = [(room_dir, view_dir, r, spots, gravity) for r in rooms]
    with ProcessPoolExecutor(max(1, jobs), mp_context=mp.get_context("spawn")) as ex:
        for rid, pred, err in tqdm(ex.map(room_job, jobs_), total=len(jobs_), desc="rooms",
                                   unit="room", file=sys.stderr):
            if err:
                print(f"  {rid}: {err}", file=sys.stderr)
                if refused is not None:
                    refused[rid] = err
            if pred is not None:
                out[rid] = pred
    return out
