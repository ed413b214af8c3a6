"""``findme motion``: the planar motion between two photos (two-image mode, paper step 5).

Pipeline (``findme_core.motion.pair``, shared with ``findme eval``, the odometry service and the
benchmark): hypotheses of each photo (the chosen rank becomes the photo's scene, the next ranks
candidate layouts), its room orientation from its lines, ORB features and matches, then
``findme_core.motion.methods.estimate`` registers the two photos' layouts with the matches and gives
(x, z, yaw) of photo B in photo A's level frame, with its evidence and, where the evidence
allows several, the alternatives. Degrees only here, at the edge.
"""

from __future__ import annotations

import json
import math
import sys
import time

from findme_core.geometry.manhattan import pitch_roll_deg
from findme_core.motion import gravity_spread
from findme_core.motion.methods import METHODS
from findme_core.motion.pair import PairResult, motion_photos, photo_of
from findme_core.single.methods import METHODS as HYPOTHESIS_METHODS

from findme_io.camera_source import camera_json, hypothesize_photo
from findme_io.motion_msg import motion_gravity_text, set_motion_gravity
from schemas import Motion
from findme_io.imageio import read_photo
from .options import add_camera_args, camera_height, finite_float, photo_camera_from


def _estimate_json(m) -> dict:
    """One motion's numbers and evidence (also each alternative's)."""
    r6 = lambda v: round(float(v), 6)  # noqa: E731
    out = {"x_m": r6(m.x), "z_m": r6(m.z), "yaw_deg": r6(math.degrees(m.yaw)),
           "sigma_x_m": r6(m.sigma_x), "sigma_z_m": r6(m.sigma_z),
           "sigma_yaw_deg": r6(math.degrees(m.sigma_yaw)), "dy_m": r6(m.dy),
           "inliers": m.n_inliers, "scale_points": m.n_scale}
    if math.isfinite(m.score):
        out["score"] = round(float(m.score), 3)
    if m.layout is not None:
        lay = m.layout
        out["layout"] = {"hypotheses": [lay.rank_a, lay.rank_b], "samples": lay.samples,
                         "violations": lay.violations,
                         "rms_m": None if not math.isfinite(lay.rms_m) else r6(lay.rms_m),
                         "walls": [list(w) for w in lay.walls],
                         "corners": [list(c) for c in lay.corners]}
    if m.appearance[1]:
        out["appearance"] = {"correlation": r6(m.appearance[0]), "samples": m.appearance[1]}
    return out


def motion_json(r: PairResult, metric: bool) -> dict:
    """The JSON contract of ``findme motion --json``: the motion, its evidence (inliers;
    ``layout``: which hypotheses' walls were registered, how many boundary samples agree,
    which walls (A's index, B's index) and corners matched, the rms residual; ``appearance``:
    the correlation of the photos' normalised images over the samples each sees of the
    other's floor and walls) and the
    ``alternatives`` the evidence allows too (a symmetric room; another distance along the
    way, when a photo's depths may be wrong), best first;
    ``gravity``, when a photo's gravity came from its lines: whether the two photos agreed
    on it through their matches (``motion.pair_gravity``); ``gravity_tilts``, then too: the
    motion estimated again with each such photo's gravity tilted by its 1-sigma
    (``motion.gravity_spread``; ``another``: a different motion, which the sigmas cover;
    ``ruled_out``: a different motion fewer of the matches agree with, which they do not;
    ``motion`` null: none found)."""
    m = r.motion
    out = _estimate_json(m)
    out.update({"matches": r.matches, "keypoints": list(r.keypoints), "method": m.method,
                "metric": metric, "alternatives": [_estimate_json(a) for a in m.alternatives],
                "timing_ms": {k: round(v, 3) for k, v in r.timing_ms.items()}})
    g = r.gravity
    if g is not None:
        out["gravity"] = {"status": g.status, "angle_deg": (round(math.degrees(g.angle), 3)
                                                            if math.isfinite(g.angle) else None),
                          "sigma_a_deg": round(math.degrees(g.sigma_a), 3),
                          "sigma_b_deg": round(math.degrees(g.sigma_b), 3), "reason": g.reason}
    if r.gravity_spread is not None:
        out["gravity_tilts"] = [
            {"photo": "AB"[t.photo], "axis": gravity_spread.AXES[t.axis],
             "tilt_deg": round(math.degrees(t.angle), 3), "another": t.another,
             "ruled_out": t.ruled_out,
             "motion": None if t.motion is None else _estimate_json(t.motion)}
            for t in r.gravity_spread.tilts]
    return out


def _gravity_text(pg, provs) -> str:
    """The motion line's clauses on the gravities it rests on (as ``findme run`` says them)."""
    msg = Motion()
    set_motion_gravity(msg, pg)
    return motion_gravity_text(msg, "photo A", "photo B",
                               *((p.gravity, p.gravity_sigma) for p in provs))


def _agreed(pg, which: str) -> dict:
    """Photo ``which``'s gravity as the motion used it, once the photos agreed on it."""
    pitch, roll = pitch_roll_deg(pg.gravity_a if which == "A" else pg.gravity_b)
    return {"pitch_deg": pitch, "roll_deg": roll,
            "sigma_deg": math.degrees(pg.sigma_a if which == "A" else pg.sigma_b),
            "source": "image"}


MOTION_HELP = """\
Where photo B was taken relative to photo A, on the floor: x (to the right) and
z (forward) of photo A's level view, and the turn (yaw, > 0: B turned right),
each with its 1-sigma. It registers the two photos' floor-wall boundaries with
their feature matches; when the evidence allows other motions too (a symmetric
room; another distance along the way, when a photo's depths may be wrong), they
are listed and the 1-sigma covers them; so are the motions the photos give when
a gravity found in their lines (none given) is tilted by its 1-sigma. Without
--camera-height lengths are in camera heights.

Example:  findme motion a.jpg b.jpg --camera-height 1.45"""


def register(sub) -> None:
    p = sub.add_parser("motion", help="how the camera moved between two photos",
                       description=MOTION_HELP)
    p.add_argument("image_a", metavar="PHOTO_A", help="the first photo")
    p.add_argument("image_b", metavar="PHOTO_B", help="the second photo, of the same room")
    add_camera_args(p, gravity_flags=("--gravity-a", "--gravity-b"))
    p.add_argument("--camera-height", type=finite_float, metavar="M",
                   help="camera height above the floor in metres, both photos (default: 1, "
                        "results up to scale)")
    p.add_argument("--hypothesis-a", type=int, default=1, metavar="RANK",
                   help="chosen boundary hypothesis of photo A (1 = best ranked)")
    p.add_argument("--hypothesis-b", type=int, default=1, metavar="RANK",
                   help="chosen boundary hypothesis of photo B (1 = best ranked)")
    p.add_argument("--method", default="findme", choices=METHODS,
                   help="motion estimator: findme (default: the photos' layouts and their "
                        "feature matches), features (the matches alone), lifted, or paper "
                        "(eqs. 5-8)")
    p.add_argument("--hypothesis-method", default="findme", choices=HYPOTHESIS_METHODS,
                   help="boundary hypothesis method of both photos: findme (default) or paper")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=cmd_motion)


def cmd_motion(args) -> int:
    h, metric = camera_height(args.camera_height)
    images, cams, sources, own = [], [], [], []
    for which, path, grav, flag in (("A", args.image_a, args.gravity_a, "--gravity-a"),
                                    ("B", args.image_b, args.gravity_b, "--gravity-b")):
        photo = read_photo(path)   # lens: flags, else EXIF; gravity: flag, else the image
        cam, prov = photo_camera_from(photo, args.hfov, args.intrinsics, grav, flag,
                                      getattr(args, "gravity_sigma", None))
        if prov.estimate is not None:
            # a gravity from the image is refined with the photo's best boundary, as the
            # hypotheses service and ``findme eval`` refine it: the same motion as theirs
            _, cam, prov = hypothesize_photo(photo.image, cam, prov, args.hypothesis_method,
                                             1, camera_height=h if metric else None)
        images.append(photo.image)
        cams.append(cam)
        sources.append(camera_json(cam, prov))
        own.append(prov)
    clock = time.perf_counter
    photos = [photo_of(img, cam, h, rank, args.hypothesis_method, which, clock=clock,
                       gravity_sigma=prov.unsensed_sigma,
                       gravity_alternatives=prov.unsensed_alternatives)
              for img, cam, rank, which, prov in zip(
                  images, cams, (args.hypothesis_a, args.hypothesis_b), "AB", own)]
    hyp_ms = sum(p.timing_ms.pop("hypotheses") for p in photos)
    res = motion_photos(*photos, (args.method,), clock=clock)[args.method]
    if isinstance(res, Exception):
        raise res
    out = motion_json(res, metric)
    out["timing_ms"]["hypotheses"] = round(hyp_ms, 3)
    out["photos"] = [{"camera": s["camera"], "gravity": s["gravity"]} for s in sources]
    if args.json:
        print(json.dumps(out))
        return 0
    unit = "m" if metric else "camera heights"
    print(f"photo B relative to photo A ({out['method']}): x {out['x_m']:+.3f} ± "
          f"{out['sigma_x_m']:.3f} {unit} (right), z {out['z_m']:+.3f} ± {out['sigma_z_m']:.3f} "
          f"{unit} (forward), yaw {out['yaw_deg']:+.2f} ± {out['sigma_yaw_deg']:.2f} deg "
          "(> 0: turned right)" + _gravity_text(res.gravity, own))
    print(f"  {out['inliers']} of {out['matches']} matches agree, {out['scale_points']} 3D points "
          f"fix the scale; {sum(out['timing_ms'].values()):.0f} ms")
    if "layout" in out:
        lay = out["layout"]
        print(f"  layouts (hypotheses {lay['hypotheses'][0]} and {lay['hypotheses'][1]}): "
              f"{lay['samples']} boundary samples on each other's walls, {len(lay['walls'])} "
              f"wall pairs, {len(lay['corners'])} corners")
    if "appearance" in out:
        app = out["appearance"]
        print(f"  appearance: the photos correlate {app['correlation']:+.3f} over "
              f"{app['samples']} samples each sees of the other's floor and walls")
    for k, alt in enumerate(out["alternatives"], 2):
        print(f"  candidate {k} (the evidence allows it too): x {alt['x_m']:+.3f}, "
              f"z {alt['z_m']:+.3f} {unit} ({math.hypot(alt['x_m'], alt['z_m']):.3f} {unit} "
              f"apart), yaw {alt['yaw_deg']:+.2f} deg")
    for t in out.get("gravity_tilts", ()):
        if t["another"] or t["ruled_out"]:
            mo = t["motion"]
            why = ("the 1-sigma covers it" if t["another"] else
                   f"the matches rule it out ({mo['inliers']} agree with it, {out['inliers']} "
                   "with the answer)")
            print(f"  photo {t['photo']}'s gravity tilted {t['tilt_deg']:+.1f} deg ({t['axis']}, "
                  f"its 1-sigma) gives another motion: x {mo['x_m']:+.3f}, z {mo['z_m']:+.3f} "
                  f"{unit}, yaw {mo['yaw_deg']:+.2f} deg; {why}")
    for which, s in zip("AB", sources):
        g = s["gravity"]
        if res.gravity is not None and res.gravity.status == "agreed":
            g = {**g, **_agreed(res.gravity, which)}
        note = {"input": "given", "image": f"from the photo's lines, ± {g['sigma_deg']:.1f} deg",
                "input+image": f"given, refined by the photo's lines, ± {g['sigma_deg']:.1f} deg",
                "level": "NOT KNOWN: level assumed"}[g["source"]]
        print(f"  photo {which}: camera {s['camera']['hfov_deg']:.1f} deg ({s['camera']['source']}), "
              f"pitch {g['pitch_deg']:+.1f} roll {g['roll_deg']:+.1f} deg ({note})", file=sys.stderr)
    if not metric:
        print("  (no --camera-height given: distances are in units of the camera height)",
              file=sys.stderr)
    return 0
