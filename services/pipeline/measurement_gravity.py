"""A photo's scene under the gravity a motion agreed on (the measurement service).

The odometry's motions carry the gravity two photos agreed on through their matches when one
photo's own gravity came from its lines, unsure (``Motion.gravity``, status "agreed";
``motion.pair_gravity``). The measurement service keeps, per photo, the tightest such gravity
and builds the photo's scene again under it when its 1-sigma is below the photo's own:

* a boundary the USER chose is kept (they chose it on the image) and lifted again;
* one chosen automatically was found under the wrong gravity, so the photo (its frame,
  fetched from the bus and decoded at the working size) is hypothesized again under the
  agreed gravity and the best boundary taken, as the mapper and ``findme plan`` do. When the
  frame is gone or no boundary is found, the photo stays under its own gravity (whose wide
  sigma its answers carry) and the miss is counted.

A sensor's gravity is never replaced. Frames: gravity (3,) unit in the photo's camera
coordinates; sigmas radians; polylines in the photo's pixels.
"""

from __future__ import annotations

from dataclasses import replace
from typing import NamedTuple

import schemas
from findme_core.errors import HypothesisError
from findme_core.geometry.provenance import Provenance, tilt_cov
from findme_core.single.scene import Scene, boundary_sigma_px
from findme_core.single.segments import WORK_SIZE
from findme_io.frame_photo import best_again
from findme_io.imageio import decode_photo


class Held(NamedTuple):
    """One photo's scene as the service holds it: the Scene, the selected rank, whether it
    is metric, the gravity's provenance, and who chose the boundary (``Selection.by``; None
    when unknown: rebuilt from its Scene message)."""

    scene: Scene
    rank: int
    metric: bool
    prov: Provenance
    by: int | None


def scene_of(cam, prov: Provenance, height: float, height_sigma: float, polyline, kinds,
             lines=None) -> Scene:
    """The Scene of a photo: its camera and gravity covariance, camera height (metres) and
    its 1-sigma, boundary (M, 2) pixels and its (M - 1,) kinds, and the (L, 4) lines its
    hypotheses came with (pixels; None: not known), where a top's edge is looked for."""
    return Scene(cam, height, polyline, kinds, height_sigma=height_sigma,
                 gravity_cov=prov.gravity_cov,
                 boundary_sigma_px=boundary_sigma_px(cam.width, cam.height), lines=lines)


def under_agreed(agreed, cam, prov: Provenance):
    """(camera, provenance) of a photo under ``agreed`` ((3,) gravity, 1-sigma radians, or
    None), when the photo's own gravity came from its lines (or was assumed level) with a
    wider 1-sigma; else None (nothing to change)."""
    if agreed is None or prov.gravity not in ("image", "level"):
        return None
    g, sigma = agreed
    if not sigma < prov.gravity_sigma:
        return None
    return (replace(cam, gravity=g),
            replace(prov, gravity="image", gravity_cov=tilt_cov(sigma), estimate=None))


def boundary_under(frame, cam, height: float | None, by: int | None, polyline, kinds):
    """((M, 2) polyline, (M - 1,) kinds) of a photo under ``cam``'s (agreed) gravity: the
    user's as it is; an automatic choice found again in ``frame`` (its Frame message, or None
    when it is gone; ``height``: camera height in metres, None when not known), as the
    hypotheses service found it.

    Raises:
        FindmeError: there is none (the frame is gone or unreadable, or no boundary under
            that gravity), with the reason.
    """
    if by == schemas.SELECTED_BY_USER:
        return polyline, kinds
    if frame is None:
        raise HypothesisError("its frame is no longer on the bus")
    photo = decode_photo(frame.image.data, f"frame {frame.index}", reduce_to=WORK_SIZE)
    h, why = best_again(photo.image, photo.scale, cam, height)
    if h is None:
        raise HypothesisError(why)
    return h.polyline, h.kinds
