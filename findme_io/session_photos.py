"""A session's photos as the floor plan takes them (``findme plan``, ``locate-in``, and
``findme eval``'s rooms): each photo's camera with the gravity its hypotheses end with, then
the photos whose gravity came from their own lines agree on it spot by spot
(``plan/shared_gravity``) before their layouts are made.
"""

from __future__ import annotations

from dataclasses import replace
from typing import NamedTuple

from findme_core.geometry.camera import Camera
from findme_core.plan import shared_gravity

from findme_io.camera_source import hypothesize_photo


class PhotoGravity(NamedTuple):
    """One photo's inputs to the plan with the gravity its hypotheses end with."""

    camera: Camera
    height: float          # camera height, metres (1.0 and ``metric`` False: camera heights)
    metric: bool
    estimate: object       # ``GravityEstimate`` when gravity came from the photo alone, else None
    kind: str              # ``Provenance.gravity_kind``: exact, sensor or image
    sigma: float = 0.0     # ``Provenance.gravity_sigma``: its tilt's 1-sigma per axis, radians


def final_gravity(img, cam, prov, height: float, metric: bool) -> PhotoGravity:
    """One photo with the gravity its hypotheses end with (``camera_source.hypothesize_photo``:
    an estimate from the photo's lines is refined with its best boundary); ``estimate`` is
    the ``GravityEstimate`` when gravity came from the photo alone (sources image or level),
    else None (given, or refined from a given one)."""
    est = None
    if prov.estimate is not None:
        _, cam, prov = hypothesize_photo(img, cam, prov, max_n=1,
                                         camera_height=height if metric else None)
        if prov.gravity in ("image", "level"):
            est = prov.estimate
    return PhotoGravity(cam, height, metric, est, prov.gravity_kind, prov.gravity_sigma)


def session_photos(images, inputs: list[PhotoGravity], headings=None) -> tuple[list, dict]:
    """``session.Photo`` of each photo from its ``final_gravity`` (its gravity's kind with
    it) and its heading (``headings``: one per photo, ``session.Photo.heading``, e.g. the
    file's ``frame_photo.exif_heading``; None: none); {index: why} of the photos left out
    because their gravity could not be told (``shared_gravity``)."""
    photos, sg = shared_gravity.analyse_plain(
        images, [i.camera for i in inputs], [i.height for i in inputs],
        [i.estimate for i in inputs], kinds=[i.kind for i in inputs],
        sigmas=[i.sigma for i in inputs])
    if headings is not None:
        photos = [replace(p, heading=h) for p, h in zip(photos, headings, strict=True)]
    return photos, ({} if sg is None else {i: p.reason for i, p in enumerate(photos)
                                             if p.layout is None and p.reason
                                             and p.reason.startswith("gravity unknown")})
