"""Converters between bus messages (``schemas``) and core objects (``findme_core``).

Angles: the bus carries radians (``yaw_rad``), the core works in radians; degrees appear only
in ``Frame.hfov_deg`` (a user-facing lens setting) and on the command line.
"""

from __future__ import annotations

import math
import time

import numpy as np

import schemas
from findme_core.errors import ImageError
from findme_core.geometry.camera import Camera
from findme_core.geometry.provenance import Provenance, tilt_cov
from findme_core.motion.pair_gravity import UNSURE_GRAVITY_DEG
from findme_core.single.hypotheses import Hypothesis, HypothesisSet
from findme_core.single.vanishing import GravityEstimate
from findme_core.single.scene import Located, distances

_FORMATS = {b"\xff\xd8\xff": "jpeg", b"\x89PNG": "png", b"RIFF": "webp"}


def image_format(data: bytes) -> str:
    for magic, fmt in _FORMATS.items():
        if data.startswith(magic):
            return fmt
    raise ImageError("image bytes are not JPEG, PNG or WebP")


def make_frame(session: str, index: int, image_bytes: bytes, *, intrinsics=None,
               hfov_deg: float | None = None, gravity=None, camera_height_m=None,
               camera_height_sigma_m=None, device: str = "", time_ns: int | None = None,
               gravity_sigma_rad: float | None = None, heading_rad: float | None = None,
               heading_sigma_rad: float | None = None, heading_ref: str = ""):
    """A Frame message; ``intrinsics`` is (fx, fy, cx, cy, width, height) or None;
    ``heading_rad`` / ``heading_sigma_rad`` / ``heading_ref``: the phone's heading, its
    1-sigma (radians) and what it is measured from (``Frame.heading_ref``)."""
    t = time.time_ns() if time_ns is None else int(time_ns)
    f = schemas.Frame(session=session, index=int(index), capture_time_ns=t, device=device)
    f.image.data = image_bytes
    f.image.format = image_format(image_bytes)
    f.image.frame_id = f"{session}/camera/{index}"
    f.image.timestamp.CopyFrom(schemas.ns_to_timestamp(t))
    if intrinsics is not None:
        fx, fy, cx, cy, w, h = intrinsics
        f.intrinsics.CopyFrom(schemas.Intrinsics(fx=fx, fy=fy, cx=cx, cy=cy, width=int(w),
                                                 height=int(h)))
    elif hfov_deg is not None:
        f.hfov_deg = float(hfov_deg)
    if gravity is not None:
        f.gravity.CopyFrom(schemas.vec3_to_msg(gravity))
        if gravity_sigma_rad is not None:
            f.gravity_sigma_rad = float(gravity_sigma_rad)
    if camera_height_m is not None:
        f.camera_height_m = float(camera_height_m)
    if camera_height_sigma_m is not None:
        f.camera_height_sigma_m = float(camera_height_sigma_m)
    if heading_rad is not None:
        f.heading_rad = float(heading_rad)
        if heading_sigma_rad is not None:
            f.heading_sigma_rad = float(heading_sigma_rad)
        f.heading_ref = heading_ref
    return f


def camera_msg(cam: Camera, prov: Provenance | None = None):
    """A Camera message; with the provenance: lens and gravity sources and gravity sigma."""
    m = schemas.Camera(
        intrinsics=schemas.Intrinsics(fx=cam.fx, fy=cam.fy, cx=cam.cx, cy=cam.cy,
                                      width=cam.width, height=cam.height),
        gravity=schemas.vec3_to_msg(cam.gravity))
    if prov is not None:
        m.lens_source, m.gravity_source = prov.camera, prov.gravity
        m.gravity_sigma_rad = prov.gravity_sigma
        m.gravity_cov_rad2.extend(float(x) for x in prov.gravity_cov.ravel())
        est = prov.estimate
        if prov.gravity == "image" and est is not None and est.alternatives:
            for g, r in est.alternatives[:schemas.MAX_GRAVITY_ALTERNATIVES]:
                if np.all(np.isfinite(g)) and math.isfinite(r) and r > 0:
                    m.gravity_alternatives.add(gravity=schemas.vec3_to_msg(g), ratio=float(r))
            if est.fit_cov is not None:
                m.gravity_fit_cov_rad2.extend(float(x) for x in np.ravel(est.fit_cov))
    return m


def msg_gravity_estimate(msg) -> GravityEstimate | None:
    """The gravity estimate a Camera message carries when its gravity came from the image
    ("image", with its alternatives and own fit covariance) or was assumed level; None when
    it was given (sensors, "input", "input+image") or not said."""
    if msg.gravity_source not in ("image", "level") or not msg.HasField("gravity"):
        return None
    prov = msg_provenance(msg)
    fit = (np.asarray(msg.gravity_fit_cov_rad2, float).reshape(2, 2)
           if len(msg.gravity_fit_cov_rad2) == 4 else None)
    alts = tuple((schemas.msg_to_vec3(a.gravity), float(a.ratio))
                 for a in msg.gravity_alternatives[:schemas.MAX_GRAVITY_ALTERNATIVES])
    return GravityEstimate(schemas.msg_to_vec3(msg.gravity), prov.gravity_cov,
                           msg.gravity_source, alternatives=alts, fit_cov=fit)


def msg_camera(msg) -> Camera:
    k = msg.intrinsics
    g = schemas.msg_to_vec3(msg.gravity) if msg.HasField("gravity") else None
    return Camera(k.fx, k.fy, k.cx, k.cy, k.width, k.height, g)


def msg_provenance(msg) -> Provenance | None:
    """The Provenance a Camera message carries, None when it says nothing (older senders)."""
    if not msg.gravity_source:
        return None
    cov = (np.asarray(msg.gravity_cov_rad2, float).reshape(2, 2) if len(msg.gravity_cov_rad2) == 4
           else tilt_cov(msg.gravity_sigma_rad))
    return Provenance(msg.lens_source or "input", msg.gravity_source, cov)




def gravity_caveat(photo: str, source: str, sigma_rad: float) -> str | None:
    """What a user must know about a photo's gravity (``source`` and its 1-sigma tilt in
    radians) when no sensor gave it: assumed level, or from the photo's lines with a 1-sigma
    over ``UNSURE_GRAVITY_DEG``; else None. ``photo`` names it ("photo 1", "photo B")."""
    sigma = math.degrees(sigma_rad)
    if source == "level":
        return f"{photo}'s gravity ASSUMED LEVEL (± {sigma:.0f} deg)"
    if source == "image" and sigma > UNSURE_GRAVITY_DEG:
        return f"{photo}'s gravity from its lines, unsure (± {sigma:.0f} deg)"
    return None


def rests_on(caveats) -> str:
    """The clause a motion's line ends with when it rests on ``caveats`` ((gravity source,
    ``gravity_caveat`` text or None) per photo, None skipped), else "". A gravity from a
    photo's lines is tilted by its 1-sigma in the motion (``motion.gravity_spread``); one
    assumed level is not."""
    said = [(src, c) for src, c in caveats if c]
    if not said:
        return ""
    level = any(src == "level" for src, _ in said)
    how = ("which its figures do not allow for" if level and len(said) == 1 else
           "which its figures allow for only as far as a tilt by that 1-sigma moves the motion"
           + (" (not at all where level is assumed)" if level else ""))
    return "; it rests on " + " and ".join(c for _, c in said) + ", " + how


def provenance_text(msg) -> str:
    """One line saying where a Camera message's lens and gravity came from."""
    k = msg.intrinsics
    hfov = math.degrees(2 * math.atan(k.width / (2 * k.fx))) if k.fx > 0 else float("nan")
    lens = {"input": "given", "exif": "from EXIF", "default": "assumed"}.get(msg.lens_source, "?")
    grav = {"input": "given", "input+image": "given, refined by the image",
            "image": "from the image", "level": "LEVEL ASSUMED"}.get(
        msg.gravity_source, "?")
    return (f"camera {hfov:.1f} deg ({lens}); gravity {grav} "
            f"(± {math.degrees(msg.gravity_sigma_rad):.1f} deg)")


def hypothesis_set_msg(session: str, index: int, hs: HypothesisSet, method: str,
                       camera: Camera | None = None, provenance: Provenance | None = None,
                       lines=None):
    """The bus message of a photo's hypotheses; ``lines``: (N, 4) the photo's lines in its
    pixels (``photo_lines.photo_lines``), sent so that odometry need not detect them again."""
    m = schemas.HypothesisSet(session=session, index=index, width=hs.width, height=hs.height,
                              reason=hs.reason or "", method=method,
                              timing_ms={k: float(v) for k, v in hs.timing_ms.items()})
    if camera is not None:
        m.camera.CopyFrom(camera_msg(camera, provenance))
    if not hs.hypotheses and not m.reason:
        m.reason = "no hypotheses"
    for i, h in enumerate(hs.hypotheses):
        m.hypotheses.add(rank=i + 1, score=float(h.score), support=float(np.clip(h.support, 0, 1)),
                         polyline=schemas.polyline_to_msg(h.polyline, h.kinds))
    if lines is not None:
        m.lines.extend(np.asarray(lines, float).ravel().tolist())
    return m


def msg_lines(msg) -> np.ndarray | None:
    """(N, 4) the lines [u1, v1, u2, v2] a HypothesisSet carries, photo pixels; None when it
    carries none (the reader detects them)."""
    return np.asarray(msg.lines, float).reshape(-1, 4) if len(msg.lines) else None


def msg_hypotheses(msg) -> list[Hypothesis]:
    out = []
    for h in msg.hypotheses:
        poly, kinds = schemas.msg_to_polyline(h.polyline)
        out.append(Hypothesis(poly, kinds, h.score, h.support))
    return out


def msg_room_view(msg, camera_height: float | None = None):
    """Whether the photo of a HypothesisSet message looks like a room view
    (``room_view.judge`` on what the message carries: its hypotheses, size and camera;
    ``camera_height`` metres, when known, only for the wording), or None when the message
    has no hypotheses (its ``reason`` says why) or no camera."""
    from findme_core.single.lines import Lines
    from findme_core.single.room_view import judge
    if not msg.hypotheses or not msg.HasField("camera"):
        return None
    hs = HypothesisSet(msg.width, msg.height, msg_hypotheses(msg),
                       Lines(np.zeros((0, 4)), np.zeros((0, 3)), np.zeros(0)),
                       np.zeros(0, int), msg.reason or None)
    return judge(hs, msg_camera(msg.camera), camera_height)


def measure_reply_msg(session: str, index: int, rank: int, metric: bool,
                      located: list[Located], height: float, height_sigma: float,
                      said: list[str | None] | None = None):
    """The MeasureReply of ``located`` (one per requested pixel, in order; ``said``: the
    surface the request said of each, or None) and the distances between consecutive
    points."""
    r = schemas.MeasureReply(session=session, index=index, rank=rank, metric=metric)
    for i, p in enumerate(located):
        mp = r.points.add(pixel=schemas.Pixel(u=float(p.pixel[0]), v=float(p.pixel[1])),
                          surface=schemas.surface_value(p.surface), error=p.error or "",
                          said=schemas.surface_value(said[i] if said else None),
                          note=p.note or "")
        if p.xyz is not None:
            mp.xyz.CopyFrom(schemas.vec3_to_msg(p.xyz))
            mp.sigma_m = float(p.sigma_m)
    for i, (d, s, err) in enumerate(distances(located, height, height_sigma)):
        dm = r.distances.add(a=i, b=i + 1, error=err or "")
        if d is not None:
            dm.distance_m, dm.sigma_m = float(d), float(s)
    return r
