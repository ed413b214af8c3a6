"""One view of a findme-eval dataset: its inputs (``view_inputs``: only the image, camera,
camera height and query pixels are read), its gravity as ``GravityInput`` gives it
(``view_camera``) and its prediction (``predict_view``: ranked polylines and the 3D of each
query pixel with its 1-sigma). See ``findme.evaluation`` for the whole contract.
"""

from __future__ import annotations

import json
import math
import os
import zlib
from dataclasses import dataclass

import cv2
import numpy as np

from findme_core.geometry.camera import Camera
from findme_core.errors import FindmeError, InputError
from findme_core.geometry.manhattan import gravity_of, pitch_roll_deg
from findme_core.geometry.provenance import INPUT_GRAVITY_SIGMA_DEG, Provenance
from findme_core.motion.photo_lines import photo_lines
from findme_core.single.scene import Scene, boundary_sigma_px, distances

from findme_io.camera_source import hypothesize_photo, with_gravity
from findme_io.imageio import read_image

POINT_KINDS = ("floor_points", "wall_points", "nonfloor_points")
#: order of the per-point sigma parts written as ``<kind>_sigma_parts_m``
SIGMA_PARTS = ("boundary", "height", "pixel", "gravity", "surface")
#: the surface a user tapping a dataset's query point would say it is on (``--declared-surface``;
#: TUM's non-floor points: ``declared_surfaces``)
DECLARED = {"floor_points": "floor", "wall_points": "wall"}
#: 1-sigma of a dataset view's camera height: its truth was computed with that very height
DATASET_HEIGHT_SIGMA_M = 0.0


def view_inputs(meta: dict) -> tuple[Camera, float, dict]:
    """Camera, camera height and query pixels of a view; nothing else is read."""
    k = meta["intrinsics"]
    cam = Camera(k["fx"], k["fy"], k["cx"], k["cy"], k["width"], k["height"],
                 meta.get("gravity_cam"))
    queries = {kind: [q["px"] for q in meta.get(kind) or []] for kind in POINT_KINDS}
    return cam, float(meta.get("camera_height_m") or 1.0), queries


@dataclass(frozen=True)
class GravityInput:
    """How a view's ``gravity_cam`` reaches the estimator (see ``findme.evaluation``).

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
        """From the flags of ``findme.cli.evaluate.add_gravity_args``."""
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


def declared_surfaces(meta: dict) -> dict:
    """{kind: [surface said or None per query point]}: what a user tapping each would say it
    is on (``--declared-surface``): a floor point "floor", a wall point "wall", a TUM
    non-floor point "wall" where its surface is vertical (a cabinet's front), "top" where it
    is not (the cabinet's top) and nothing where the dataset does not say."""
    out = {}
    for kind in POINT_KINDS:
        qs = meta.get(kind) or []
        if kind == "nonfloor_points":
            out[kind] = [{True: "wall", False: "top"}.get(q.get("vertical_surface")) for q in qs]
        else:
            out[kind] = [DECLARED.get(kind)] * len(qs)
    return out


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
    height_sigma = rest[1] if len(rest) > 1 else DATASET_HEIGHT_SIGMA_M
    declared = rest[2] if len(rest) > 2 else False
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
                              boundary_sigma_px=boundary_sigma_px(cam.width, cam.height),
                              height_sigma=height_sigma, lines=photo_lines(hs, image))
            except FindmeError:  # e.g. a level-camera polyline crossing a tilted horizon:
                scene = None     # its points have no answer, its hypotheses still count
            located_by = {}
            said_by = declared_surfaces(meta) if declared else {}
            for kind, px in queries.items():
                if px:
                    said = said_by.get(kind)
                    located = [None] * len(px) if scene is None else scene.locate(px, said)
                    located_by[kind] = located
                    pred[kind] = [None if p is None or p.xyz is None else p.xyz.round(5).tolist()
                                  for p in located]
                    pred[kind + "_sigma_m"] = [None if p is None or p.xyz is None
                                               else round(p.sigma_m, 5) for p in located]
                    pred[kind + "_sigma_parts_m"] = [
                        None if p is None or p.xyz is None else
                        [round(p.sigma_parts[k], 5) for k in SIGMA_PARTS] for p in located]
                    pred[kind + "_surface"] = [None if p is None else p.surface for p in located]
                    if said is not None:   # notes come only with a said surface
                        pred[kind + "_note"] = [None if p is None else p.note for p in located]
            if scene is not None:
                pred["distances"] = _distances(located_by, scene)
        return vid, pred, None
    except FindmeError as e:
        return vid, None, str(e)


def _distances(located_by: dict, scene) -> list:
    """Distances a user would measure between two points of the photo, with their 1-sigma
    (``uncertainty.distances``): consecutive query points of one kind (0-1, 2-3, ...) and the
    i-th floor point to the i-th wall point, each once both ends have an answer."""
    pairs = [(k, i, k, i + 1) for k, pts in located_by.items() for i in range(0, len(pts) - 1, 2)]
    fl, wl = located_by.get("floor_points", []), located_by.get("wall_points", [])
    pairs += [("floor_points", i, "wall_points", i) for i in range(min(len(fl), len(wl), 10))]
    out = []
    for ka, i, kb, j in pairs:
        a, b = located_by[ka][i], located_by[kb][j]
        if a is None or b is None or a.xyz is None or b.xyz is None:
            continue
        d, sigma, _ = distances([a, b], scene.height, scene.height_sigma)[0]
        out.append({"kind_a": ka, "a": i, "kind_b": kb, "b": j, "d_m": round(d, 5),
                    "sigma_m": round(sigma, 5)})
    return out
