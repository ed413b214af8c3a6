"""One pair of a findme-eval dataset: its two photos' inputs (``pair_inputs``: of each view
only its inputs, its gravity as the view's own prediction ends with it) and the motion of
photo B in photo A's level frame by each method asked (``predict_pair``).
"""

from __future__ import annotations

import json
import math
import os

import cv2

from findme_core.errors import FindmeError
from findme_core.motion.pair import motion_photos, photo_of

from findme_io.camera_source import hypothesize_photo
from findme_io.imageio import read_image

from .views import GravityInput, view_camera, view_inputs


def pair_inputs(pair_dir, view_dir, pid: str, gravity: GravityInput | bool = True
                ) -> tuple[dict, list]:
    """A dataset pair's record and, for its photos A and B, (image, camera, camera height,
    provenance: its ``unsensed_sigma`` and ``unsensed_alternatives``); of each
    view only its inputs are read (``view_inputs``), its camera with the gravity the view's
    own prediction ends with (``view_camera``, then ``hypothesize_photo``)."""
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
            _, cam, prov = hypothesize_photo(image, cam, prov, max_n=1, camera_height=h)
        photos.append((image, cam, h, prov))
    return pair, photos


def predict_pair(args) -> tuple[str, dict, dict]:
    """Motion of one pair by each method: ({method: {x_m, z_m, yaw_deg, ...}}, {method: error})."""
    pair_dir, view_dir, pid, hyp_method, methods, *rest = args
    gravity = rest[0] if rest else True
    cv2.setNumThreads(1)
    preds, errs = {}, {}
    try:
        _, photos = pair_inputs(pair_dir, view_dir, pid, gravity)
        pa, pb = [photo_of(image, cam, h, 1, hyp_method, which,
                           gravity_sigma=prov.unsensed_sigma,
                           gravity_alternatives=prov.unsensed_alternatives)
                  for (image, cam, h, prov), which in zip(photos, "AB")]
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
