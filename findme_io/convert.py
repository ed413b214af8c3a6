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
    """The clause a motion's line ends with when it rests on ``caveats`` (``gravity_caveat``
    texts, None skipped), else ""."""
    notes = [c for c in caveats if c]
    return ("; it rests on " + " and ".join(notes) + ", which its figures do not allow for"
            if notes else "")


def set_motion_gravity(msg, pg) -> None:
    """Fill ``msg.gravity`` (a ``schemas.Motion``, in place like ``set_motion_estimate``)
    with a ``motion.pair_gravity.PairGravity``; nothing for None (the sensors gave both)."""
    if pg is None:
        return
    g = msg.gravity
    g.status, g.reason = pg.status, pg.reason or ""
    if math.isfinite(pg.angle):
        g.angle_rad = float(pg.angle)
    for f, s in (("sigma_a_rad", pg.sigma_a), ("sigma_b_rad", pg.sigma_b)):
        if math.isfinite(s):              # absent: assumed level, no evidence
            setattr(g, f, float(s))
    if pg.status == "agreed":
        g.gravity_a.CopyFrom(schemas.vec3_to_msg(pg.gravity_a))
        g.gravity_b.CopyFrom(schemas.vec3_to_msg(pg.gravity_b))


def msg_agreed_gravities(msg) -> tuple:
    """Of a ``schemas.Motion`` whose photos agreed on gravity: ((which photo, (3,) unit
    gravity in its camera frame, 1-sigma radians), ...) for A and B where both are given;
    else ()."""
    g = msg.gravity if msg.HasField("gravity") else None
    if g is None or g.status != "agreed":
        return ()
    out = []
    for which, v, s in (("a", "gravity_a", "sigma_a_rad"), ("b", "gravity_b", "sigma_b_rad")):
        if g.HasField(v) and g.HasField(s):
            vec = schemas.msg_to_vec3(getattr(g, v))
            out.append((which, vec / np.linalg.norm(vec), float(getattr(g, s))))
    return tuple(out)


def motion_gravity_text(msg, photo_a: str, photo_b: str, own_a, own_b) -> str:
    """The clauses a successful motion's line ends with about the gravities it rests on:
    whether the photos agreed on gravity through their matches (``msg.gravity``), and the
    ``gravity_caveat`` of each photo's gravity as the motion used it. ``own_a`` / ``own_b``:
    (source, 1-sigma radians) of each photo's own gravity, or None when unknown."""
    g = msg.gravity if msg.HasField("gravity") else None
    own = [o or ("input", 0.0) for o in (own_a, own_b)]
    clause = ""
    if g is not None and g.status == "agreed":
        # the combined gravity came from the lines of both photos: no longer "assumed level"
        own = [("image" if src == "level" else src, getattr(g, f) if g.HasField(f) else s)
               for (src, s), f in zip(own, ("sigma_a_rad", "sigma_b_rad"))]
        if g.HasField("angle_rad") and math.degrees(g.angle_rad) > UNSURE_GRAVITY_DEG:
            clause = (f"; {photo_a} and {photo_b} agreed on gravity through their matches "
                      f"(their own were {math.degrees(g.angle_rad):.0f} deg apart)")
    elif g is not None and g.status == "disagree":
        clause = f"; {photo_a} and {photo_b} DISAGREE on which way is down ({g.reason})"
    return clause + rests_on(gravity_caveat(name, src, s)
                             for name, (src, s) in zip((photo_a, photo_b), own))


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
    pixels (``pair.photo_lines``), sent so that odometry need not detect them again."""
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


def set_motion_estimate(msg, mo, max_alternatives: int = schemas.MAX_ALTERNATIVES):
    """Fill a ``schemas.Motion`` (in place: a builder, like protobuf's own setters) with a
    ``findme_core.motion.model.PlanarMotion``: B's pose in A's level frame (metres,
    radians, as on the bus), its 1-sigmas, inliers and its evidence: score, the lifted
    points that fixed the scale, the layouts' agreement and the ``max_alternatives`` best
    alternatives (a symmetric room). ``matches`` is the caller's (the matching stage's)."""
    msg.x_m, msg.z_m, msg.yaw_rad = float(mo.x), float(mo.z), float(mo.yaw)
    msg.sigma_x_m, msg.sigma_z_m = float(mo.sigma_x), float(mo.sigma_z)
    msg.sigma_yaw_rad = float(mo.sigma_yaw)
    msg.inliers, msg.scale_points = mo.n_inliers, int(mo.n_scale)
    if math.isfinite(mo.score):
        msg.score = float(mo.score)
    corr, samples = mo.appearance
    if samples and math.isfinite(corr):
        msg.appearance, msg.appearance_samples = float(np.clip(corr, -1.0, 1.0)), int(samples)
    lay = mo.layout
    if lay is not None:
        out = msg.layout
        out.rank_a, out.rank_b = max(int(lay.rank_a), 1), max(int(lay.rank_b), 1)
        out.samples, out.violations = int(lay.samples), int(lay.violations)
        if math.isfinite(lay.rms_m):
            out.rms_m = float(lay.rms_m)
        for name in ("walls", "corners"):   # as many as the schema takes
            getattr(out, name).extend(schemas.IndexPair(a=int(a), b=int(b))
                                      for a, b in getattr(lay, name)[:schemas.MAX_LAYOUT_PAIRS])
    for a in mo.alternatives[:max_alternatives]:
        alt = msg.alternatives.add(x_m=float(a.x), z_m=float(a.z), yaw_rad=float(a.yaw),
                                   sigma_x_m=float(a.sigma_x), sigma_z_m=float(a.sigma_z),
                                   sigma_yaw_rad=float(a.sigma_yaw), inliers=a.n_inliers)
        if math.isfinite(a.score):
            alt.score = float(a.score)
    return msg


def motion_text(msg, unit: str = "m") -> str:
    """One line about a ``schemas.Motion`` for logs and consoles: the motion (degrees at
    this edge; lengths in ``unit``: "m", or "h" when the scenes are in camera heights), its
    evidence, the other distances along the same way the evidence allows (the same turn and
    direction of travel within 3 deg) and 'ambiguous' when it allows other motions."""
    if msg.error:
        return f"motion {msg.index_a} -> {msg.index_b}: no estimate: {msg.error}"
    why = [f"{msg.inliers}/{msg.matches} inliers"]
    nw = len(msg.layout.walls) if msg.HasField("layout") else 0
    if nw:
        why.append(f"{nw} wall{'s line' if nw > 1 else ' lines'} up")

    def alike(a: float, b: float) -> bool:
        return abs(math.remainder(a - b, 2.0 * math.pi)) < math.radians(3.0)
    way = math.atan2(msg.x_m, msg.z_m)
    along = [a for a in msg.alternatives
             if alike(a.yaw_rad, msg.yaw_rad) and alike(math.atan2(a.x_m, a.z_m), way)]
    if along:
        why.append("the distance may also be " + " or ".join(
            f"{math.hypot(a.x_m, a.z_m):.3f} {unit}" for a in along))
    na = len(msg.alternatives) - len(along)
    if na:
        why.append(f"ambiguous: {na} other motion{'s fit' if na > 1 else ' fits'} almost as well")
    return (f"motion {msg.index_a} -> {msg.index_b}: x {msg.x_m:+.3f} {unit}, "
            f"z {msg.z_m:+.3f} {unit}, yaw {math.degrees(msg.yaw_rad):+.2f} deg "
            f"({'; '.join(why)})")
