"""Plain photos in the mapper: a session's photos whose gravity came from their own lines
(no phone sensors) agree on it spot by spot before the plan, as ``findme plan`` does
(``plan/shared_gravity``).

Each such photo's gravity estimate comes over the bus with its hypotheses (``Camera``:
gravity, covariance, the alternatives its lines support nearly as well,
``convert.msg_gravity_estimate``). The rotation between two photos of a spot comes from
their feature matches (``spot.camera_rotation``, cached per pair in the session's relation
cache, like the matches themselves); the spot's photos vote (``shared_gravity.agree``); each
photo then takes its spot's gravity, or is left out with the reason
(``shared_gravity.verdicts``). A photo whose own estimate is its spot's (within
``agree_deg``) stays as it is; one whose estimate was wrong takes the spot's gravity, and
under it a boundary the USER chose is lifted
again as it is (they chose it on the image); one chosen automatically was found under the
wrong gravity, so the photo is hypothesized again under its spot's and the best boundary
taken, as ``findme plan`` does: the mapper keeps a frame without gravity as a JPEG at the
working size for this (about 60 kB; at most ``max_photos`` per session). The result is
cached per gravity. A photo whose gravity changed since the last plan loses its cached
turns and motions (they were computed under the old one); its matches stay.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

import schemas
from findme_core.errors import FindmeError
from findme_core.motion import features
from findme_core.plan import session as plan_session
from findme_core.plan import shared_gravity, spot
from findme_core.single import layout
from findme_core.single.scene import Scene
from findme_io.convert import msg_gravity_estimate, msg_hypotheses, msg_provenance
from findme_io.frame_photo import best_again
from findme_io.imageio import decode_photo


@dataclass
class Plain:
    """What the mapper keeps of a frame without gravity: its photo at the working size (JPEG,
    to be hypothesized again under its spot's gravity; ``scale`` of the full size), the
    spot's gravity at the last plan, and (gravity, ``session.Photo``) analysed under it."""

    jpeg: bytes
    scale: float
    gravity_used: tuple | None = None
    relifted: tuple = ()


def estimate_of(ph):
    """The gravity estimate photo ``ph`` (the mapper's ``_Photo``) brings, or None when its
    gravity was given."""
    hs = ph.hset
    return msg_gravity_estimate(hs.camera) if hs is not None and hs.HasField("camera") else None


def gravity_of(hset) -> tuple[str, float]:
    """(``Provenance.gravity_kind``, ``Provenance.gravity_sigma`` radians) of the gravity a
    hypothesis set's camera was built with (the frame's refined by the image: "sensor"; the
    image's own: "image"); ("exact", 0) when the set says nothing of it."""
    prov = msg_provenance(hset.camera) if hset is not None and hset.HasField("camera") else None
    return ("exact", 0.0) if prov is None else (prov.gravity_kind, prov.gravity_sigma)


def agreed(st, order: list, params: plan_session.SessionParams,
           shared: shared_gravity.SharedGravityParams = shared_gravity.SharedGravityParams()
           ) -> list:
    """The analysed photos (``session.Photo``) of session ``st``'s photos ``order``, plain
    photos under their spot's gravity or left out (module doc); as they are when every
    gravity was given."""
    photos = [st.photos[n].photo for n in order]
    ests = [estimate_of(st.photos[n]) for n in order]
    if all(e is None for e in ests):
        return photos
    cams = [p.camera for p in photos]
    rot = {}
    for i in range(len(order)):
        for j in range(i + 1, min(len(order), i + 1 + shared.window)):
            key = ("rotation", order[i], order[j])
            if key not in st.pairs:
                mk = ("match", order[i], order[j])
                if mk not in st.pairs:
                    st.pairs[mk] = features.match(photos[i].features, photos[j].features,
                                                  params.features)
                r = spot.camera_rotation(st.pairs[mk], cams[i], cams[j], shared.spot)
                st.pairs[key] = None if r is None else r[0]
            if st.pairs[key] is not None:
                rot[(i, j)] = st.pairs[key]
    sg = shared_gravity.agree(cams, ests, [p.features for p in photos], shared, rotations=rot)
    out = []
    for n, p, e, v, status, sigma in zip(order, photos, ests,
                                         shared_gravity.verdicts(ests, sg), sg.status,
                                         sg.sigmas):
        ph = st.photos[n]
        if status == "agreed" and not isinstance(v, str):
            v = None     # its own gravity is its spot's (within ``agree_deg``): as it is
        used = None if v is None or isinstance(v, str) else tuple(np.round(v, 12))
        if ph.plain is None and used is not None:
            # hypotheses claiming a gravity from the lines of a frame that gave gravity (a
            # sender's inconsistency): nothing kept to redo it with, as it is
            v, used = None, None
        if ph.plain is not None and ph.plain.gravity_used != used:
            for k in [k for k in st.pairs if k[0] in ("turn", "motion") and n in k[1:]]:
                del st.pairs[k]
            ph.plain.gravity_used = used
        if v is None:
            out.append(p if e is None else replace(p, gravity="image",
                                                   gravity_sigma=float(sigma)))
        elif isinstance(v, str):
            out.append(plan_session.Photo(p.camera, p.height, None, None, p.features, v,
                                          gravity="image", heading=p.heading))
        else:
            out.append(replace(_relifted(ph, p, v, params), gravity_sigma=float(sigma)))
    return out


def _relifted(ph, p: plan_session.Photo, g, params: plan_session.SessionParams
              ) -> plan_session.Photo:
    """``p`` (analysed under its own gravity) under its spot's gravity ``g``: a boundary the
    user chose is lifted again as it is; one chosen automatically was found under the wrong
    gravity, so the photo (kept at the working size) is hypothesized again under ``g`` and
    its best boundary taken, as ``findme plan`` does. Cached per gravity."""
    key = tuple(np.round(g, 12))
    if ph.plain.relifted and ph.plain.relifted[0] == key:
        return ph.plain.relifted[1]
    cam = p.camera.with_gravity(g)
    hyps = msg_hypotheses(ph.hset)
    if ph.selection is not None and 1 <= ph.selection.rank <= len(hyps):
        hyp, why = hyps[ph.selection.rank - 1], None
        if ph.selection.by != schemas.SELECTED_BY_USER:
            hyp, why = _best_again(ph, cam, p.height, params)
    else:
        hyp, why = None, p.reason
    out = plan_session.Photo(cam, p.height, None, None, p.features, why, gravity="image",
                             heading=p.heading)
    if hyp is not None:
        try:
            out = replace(out, layout=layout.from_hypothesis(cam, p.height, hyp.polyline,
                                                             hyp.kinds, 1),
                          scene=Scene(cam, p.height, hyp.polyline, hyp.kinds))
        except FindmeError as e:
            out = replace(out, reason=str(e).splitlines()[0][:200])
    ph.plain.relifted = (key, out)
    return out


def _best_again(ph, cam, height: float, params: plan_session.SessionParams):
    """(the best hypothesis of photo ``ph`` under ``cam`` in its full-size pixels, or None
    and the reason)."""
    try:
        image = decode_photo(ph.plain.jpeg, "its working-size copy").image
    except FindmeError as e:
        return None, str(e).splitlines()[0][:200]
    return best_again(image, ph.plain.scale, cam, height, params.method)
