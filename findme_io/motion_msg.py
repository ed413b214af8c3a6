"""Motion messages (``schemas.Motion``): filled from the core's ``PlanarMotion`` and
``PairGravity``, read back (the gravities two photos agreed on), and said in one line for
consoles and Rerun.

Lengths in metres (or camera heights where said), angles in radians on the bus and degrees
only in the text.
"""

from __future__ import annotations

import math

import numpy as np

import schemas
from findme_core.motion.alternatives import on_the_way
from findme_core.motion.pair_gravity import UNSURE_GRAVITY_DEG

from .convert import gravity_caveat, rests_on


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


def sigma_text(msg, unit: str = "m") -> str | None:
    """The 1-sigmas of a ``schemas.Motion`` or ``schemas.Pose`` (x, z in ``unit``, yaw in
    degrees) as "± 0.012 m, ± 0.015 m, ± 0.75 deg", or None when it states none."""
    if not all(msg.HasField(f) for f in ("sigma_x_m", "sigma_z_m", "sigma_yaw_rad")):
        return None
    return (f"± {msg.sigma_x_m:.3f} {unit}, ± {msg.sigma_z_m:.3f} {unit}, "
            f"± {math.degrees(msg.sigma_yaw_rad):.2f} deg")


def motion_text(msg, unit: str = "m") -> str:
    """One line about a ``schemas.Motion`` for logs and consoles: the motion (degrees at
    this edge; lengths in ``unit``: "m", or "h" when the scenes are in camera heights), its
    1-sigmas (``sigma_text``), its evidence, the other distances along the same way the
    evidence allows (the same turn and direction of travel, ``alternatives.on_the_way``) and
    'ambiguous' when it allows other motions."""
    if msg.error:
        return f"motion {msg.index_a} -> {msg.index_b}: no estimate: {msg.error}"
    sig = sigma_text(msg, unit)
    why = ([sig] if sig else []) + [f"{msg.inliers}/{msg.matches} inliers"]
    nw = len(msg.layout.walls) if msg.HasField("layout") else 0
    if nw:
        why.append(f"{nw} wall{'s line' if nw > 1 else ' lines'} up")
    alts = list(msg.alternatives)
    way = on_the_way(msg.yaw_rad, msg.x_m, msg.z_m, [a.yaw_rad for a in alts],
                     [a.x_m for a in alts], [a.z_m for a in alts])
    along = [a for a, w in zip(alts, way) if w]
    if along:
        why.append("the distance may also be " + " or ".join(
            f"{math.hypot(a.x_m, a.z_m):.3f} {unit}" for a in along))
    na = len(msg.alternatives) - len(along)
    if na:
        why.append(f"ambiguous: {na} other motion{'s fit' if na > 1 else ' fits'} almost as well")
    return (f"motion {msg.index_a} -> {msg.index_b}: x {msg.x_m:+.3f} {unit}, "
            f"z {msg.z_m:+.3f} {unit}, yaw {math.degrees(msg.yaw_rad):+.2f} deg "
            f"({'; '.join(why)})")


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
    return clause + rests_on((src, gravity_caveat(name, src, s))
                             for name, (src, s) in zip((photo_a, photo_b), own))
