"""``findme plan`` (a room's floor plan from a session of photos) and ``findme locate-in``
(where a new photo was taken on a plan).

Photos are given in capture order: stand at a spot, turn right taking photos tilted down to
see the floor, move to the next spot. Each photo's camera comes from its sidecar
``PHOTO.json`` when there is one (the findme-eval view format: ``intrinsics``,
``gravity_cam``, ``camera_height_m``), else from ``--hfov`` / ``--gravity`` /
``--camera-height`` and the photo's EXIF; its gravity is refined by the photo's own lines
(``--gravity-sigma 0``: exact), or estimated from them when none is given. The plan's frame
is the level frame of the first photo (x right, z forward, metres); degrees only here, at
the edge.
"""

from __future__ import annotations

import json
import math
import os

import numpy as np

from findme_core.errors import FindmeError, InputError, OutlineRefused
from findme_core.geometry.camera import Camera
from findme_core.plan import relocalise, session
from findme_core.plan.floorplan import Plan

from findme_io.camera_source import with_gravity
from findme_io.frame_photo import exif_heading
from findme_io.imageio import read_photo
from findme_io.plan_svg import plan_svg
from findme_io.session_photos import final_gravity, session_photos
from .options import add_camera_args, camera_height, photo_camera_from

PLAN_HELP = """\
The room's floor plan from a session of photos, in the order they were taken:
stand at a spot, turn round taking photos tilted down so that they show the
floor, move to the next spot. It prints the walls with their lengths and 1-sigma
(walls not seen marked), openings, the floor area, the corners with the 1-sigma
of their x and z (a corner of a wall not seen is inferred) and where each photo
was taken (x to the right, z forward of the first photo, yaw in degrees). A
photo's camera comes from PHOTO.json beside it when there is one (intrinsics,
gravity_cam, camera_height_m), else from the options and its EXIF. An outline
the photos contradict is not drawn: when they saw past one of its walls, where
each photo was taken is still printed, with its 1-sigma, and the exit status is
1; when it leaves a camera outside, nothing is (exit status 2, as for an error).

Example:  findme plan spot1_*.jpg spot2_*.jpg --camera-height 1.45 \\
              --svg plan.svg"""

LOCATE_IN_HELP = """\
Where a new photo was taken on a floor plan made by findme plan --json: its
position and heading in the plan, and the other places a symmetric room allows
almost as well (a rectangular room looks alike turned half round). Several
photos taken standing at one place (turning round) are found together; --photos
with the plan's own photos adds their feature matches.

Example:  findme plan a.jpg b.jpg c.jpg --json > plan.json
          findme locate-in plan.json new.jpg --photos a.jpg b.jpg c.jpg"""


def register(sub) -> None:
    p = sub.add_parser("plan", help="a room's floor plan from a session of photos",
                       description=PLAN_HELP)
    p.add_argument("photos", nargs="+", metavar="PHOTO", help="the photos, in capture order")
    add_camera_args(p)
    p.add_argument("--camera-height", type=float, metavar="M",
                   help="camera height above the floor in metres (default: PHOTO.json's, "
                        "else unknown: lengths in camera heights)")
    p.add_argument("--spots", metavar="N,N,...",
                   help="spot label of each photo (photos with one label were taken standing "
                        "at one place); default: found from the photos")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--svg", metavar="OUT.svg", help="also draw the plan")
    p.add_argument("--feet", action="store_true", help="wall lengths in feet in the drawing")
    p.set_defaults(func=cmd_plan)
    q = sub.add_parser("locate-in", help="where a new photo was taken on a floor plan",
                       description=LOCATE_IN_HELP)
    q.add_argument("plan", metavar="PLAN.json", help="a plan from findme plan --json")
    q.add_argument("photo", nargs="+", metavar="PHOTO",
                   help="one photo, or several taken at one place")
    add_camera_args(q)
    q.add_argument("--camera-height", type=float, metavar="M",
                   help="camera height above the floor in metres, as the plan was made with "
                        "(default: PHOTO.json's, else unknown: camera heights)")
    q.add_argument("--photos", nargs="+", metavar="SESSION_PHOTO",
                   help="the photos the plan was made from, as given to findme plan: the new "
                        "photo's feature matches and motions with them count too (the plan's "
                        "walls alone leave a rectangular room's quarter turns open)")
    q.add_argument("--json", action="store_true", help="print one JSON object")
    q.set_defaults(func=cmd_locate_in)


def photo_inputs(path: str, args) -> tuple:
    """(image, ``session_photos.PhotoGravity``, heading) of one photo: the sidecar's inputs,
    else the flags, then the photo's EXIF; its gravity as ``findme hypotheses`` takes it (a
    given one refined by the photo's lines unless ``--gravity-sigma 0``, else estimated from
    them: then ``estimate`` is that ``GravityEstimate``, else None); its heading from the
    file's EXIF compass bearing (``frame_photo.exif_heading``; None without one)."""
    photo = read_photo(path)
    img = photo.image
    sigma = None if args.gravity_sigma is None else math.radians(args.gravity_sigma)
    side = os.path.splitext(path)[0] + ".json"
    if os.path.exists(side):
        try:
            with open(side) as f:
                meta = json.load(f)
            k = meta["intrinsics"]
            cam = Camera(k["fx"], k["fy"], k["cx"], k["cy"], img.shape[1], img.shape[0])
            height = meta.get("camera_height_m")
            cam, prov = with_gravity(cam, img, meta.get("gravity_cam"), sigma)
        except (OSError, KeyError, TypeError, ValueError) as e:
            raise InputError(f"{side}: not a camera sidecar ({e})") from None
    else:
        height = None
        cam, prov = photo_camera_from(photo, args.hfov, args.intrinsics, args.gravity,
                                      gravity_sigma_deg=args.gravity_sigma)
    if args.camera_height is None and height:
        h, metric = float(height), True
    else:
        h, metric = camera_height(args.camera_height)
    return img, final_gravity(img, cam, prov, h, metric), exif_heading(photo.exif)


def cmd_plan(args) -> int:
    spots = None
    if args.spots:
        spots = [s.strip() for s in args.spots.split(",")]
        if len(spots) != len(args.photos):
            raise InputError(f"--spots has {len(spots)} labels for {len(args.photos)} photos")
    images, inputs, headings = zip(*(photo_inputs(path, args) for path in args.photos))
    metric = all(g.metric for g in inputs)
    photos, _ = session_photos(images, inputs, headings)
    names = [os.path.basename(p) for p in args.photos]
    try:
        plan, _, timing = session.plan(photos, spots)
    except OutlineRefused as e:   # where the photos were taken stands; the outline does not
        return _refused_outline(e, names, metric, args)
    out = plan.to_dict(names)
    out["metric"] = metric
    out["timing_ms"] = {k: round(v, 1) for k, v in timing.items()}
    if args.svg:
        with open(args.svg, "w") as f:
            f.write(plan_svg(plan, names, feet=args.feet))
    if args.json:
        print(json.dumps(out))
        return 0
    unit = "m" if metric else "camera heights"
    print(f"floor plan: {len(plan.walls)} walls, area {plan.area_m2:.2f} "
          f"{'m²' if metric else 'h² (h: the camera height)'}"
          + ("" if plan.closed else f"; missing walls (not seen): {plan.missing}"))
    for k, w in enumerate(plan.walls):
        print(f"  wall {k}: {w.length_m:.2f} "
              + (f"± {w.sigma_m:.2f} {unit}" if w.seen else f"{unit} (not seen: inferred, not "
                                                            "measured)")
              + "".join(f", opening {a:.2f}-{b:.2f}" for a, b in w.apertures))
    for k, (v, s) in enumerate(zip(out["floor_polygon_m"], out["corner_sigma_m"])):
        print(f"  corner {k}: x {v[0]:+.2f} z {v[1]:+.2f} "
              + (f"± {s[0]:.2f} / {s[1]:.2f} {unit}" if s is not None else
                 f"{unit} (a wall not seen: inferred, not measured)"))
    _print_poses(out, unit)
    return 0


def _print_poses(out: dict, unit: str) -> None:
    """Each photo's pose (x, z in ``unit``), with its 1-sigma when it has one."""
    for name, p in out["poses"].items():
        print(f"  {name}: " + ("not placed: " + out["notes"].get(name, "") if p is None else
                              f"x {p['x_m']:+.2f} z {p['z_m']:+.2f} yaw {p['yaw_deg']:+.1f} deg"
                              + (f" (1-sigma {p['sigma_xz_m']:.2f} {unit} and "
                                 f"{p['sigma_yaw_deg']:.1f} deg)" if "sigma_xz_m" in p else "")))


def _refused_outline(e: OutlineRefused, names, metric: bool, args) -> int:
    """``findme plan`` whose outline's walls its photos saw past (``OutlineRefused``): the
    reason, and where each photo was taken with its 1-sigma (a plan without walls, which
    ``locate-in --photos`` takes; ``--svg`` draws the photos alone). Exit status 1: no
    floor plan."""
    out = {**e.plan.to_dict(names, outline=False), "reason": str(e), "metric": metric}
    if args.svg:
        with open(args.svg, "w") as f:
            f.write(plan_svg(Plan.from_dict(out), names, feet=args.feet,
                             title="no outline: " + str(e).split(":")[0]))
    if args.json:
        print(json.dumps(out))
    else:
        print(f"no floor plan: {e}")
        unit = "m" if metric else "camera heights"
        print(f"where the photos were taken (x, z in {unit}; the outline is not drawn):")
        _print_poses(out, unit)
    return 1


def cmd_locate_in(args) -> int:
    try:
        with open(args.plan) as f:
            d = json.load(f)
        plan, plan_names = Plan.from_dict(d), list(d.get("poses", {}))
    except (OSError, KeyError, TypeError, ValueError) as e:
        raise InputError(f"{args.plan}: not a plan from findme plan --json ({e})") from None
    if not plan.walls and not args.photos:   # an outline refused: its photos' places only
        raise InputError(f"{args.plan} has no walls ({d.get('reason') or 'no outline'}); "
                         "find a photo on it with --photos and the plan's photos")
    photos = _photos(args.photo, args)
    if all(p.layout is None for p in photos):
        raise FindmeError("no photo shows a usable floor boundary: "
                          + "; ".join(f"{n}: {p.reason}" for n, p in zip(args.photo, photos)))
    if args.photos:
        cands, scores = _find_with_photos(plan, plan_names, args, photos)
        agreeing = [None] * len(scores)
    else:
        cands, scores, agreeing = _find_by_walls(plan, photos)
    names = [os.path.basename(p) for p in args.photo]
    first = int(np.flatnonzero(np.isfinite(cands[0, :, 0]))[0])   # the first photo placed
    poses = [{"photo": names[first], **_pose(c[first]), "score": round(float(s), 2),
              **({"agreeing": a} if a is not None else {})}
             for c, s, a in zip(cands, scores, agreeing)]
    best = poses[0]
    amb = (poses[1]["score"] / best["score"] if len(poses) > 1 and best["score"] > 0 else 0.0)
    found, why = relocalise.verdict(scores, bool(args.photos), turn=len(photos) > 1)
    if found:     # a stated pose carries its 1-sigma (``relocalise.FOUND_SIGMA``)
        best = {**best, "sigma_xz_m": relocalise.FOUND_SIGMA[0],
                "sigma_yaw_deg": relocalise.FOUND_SIGMA[1]}
    out = {"pose": best, "alternatives": poses[1:], "ambiguity": round(amb, 3),
           "found": found, **({"reason": why} if why else {})}
    if len(photos) > 1:
        out["photos"] = {n: _pose(c) if np.isfinite(c[0]) else None
                         for n, c in zip(names, cands[0])}
    if args.json:
        print(json.dumps(out))
        return 0
    if found:
        print(f"you are at {_where(best, len(photos) > 1, relocalise.FOUND_SIGMA)}")
    else:
        print(f"cannot tell where you are: {why}. {len(poses)} place(s) fit, best first:")
        for k, q in enumerate(poses):
            print(f"  {k + 1}. {_where(q, len(photos) > 1)}, score {q['score']:.1f}"
                  + (f" ({q['agreeing']} wall samples agree)" if "agreeing" in q else ""))
    lost = [n for n, c in zip(names, cands[0]) if not np.isfinite(c[0])]
    if lost:
        print(f"  not placed (no view shared with the other photos): {', '.join(lost)}")
    return 0


def _where(q: dict, many: bool, sigma=None) -> str:
    """A found pose as the user reads it (``many``: which photo of a turn it is; ``sigma``:
    (metres on x and z, degrees) of a stated pose)."""
    sx, sy = ("", "") if sigma is None else (f" ± {sigma[0]:.2f} m", f" ± {sigma[1]:.1f}")
    return (f"x {q['x_m']:+.2f}{sx}, z {q['z_m']:+.2f}{sx}, facing {q['yaw_deg']:+.1f}{sy} deg"
            + (f" in {q['photo']}" if many else ""))


def _photos(paths, args) -> list:
    """``session.Photo`` of photos taken together (``session_photos``)."""
    images, inputs, headings = zip(*(photo_inputs(p, args) for p in paths))
    return session_photos(images, inputs, headings)[0]


def _pose(c) -> dict:
    return {"x_m": round(float(c[0]), 3), "z_m": round(float(c[1]), 3),
            "yaw_deg": round(math.degrees(float(c[2])), 2)}


def _find_by_walls(plan: Plan, photos):
    """(poses (C, K, 3), scores (C,), agreeing samples (C,)) of K photos taken at one place
    on the plan's walls alone (``relocalise.locate_turn``); NaN rows for the photos the turn
    does not link."""
    block, rel = session.turn(photos) if len(photos) > 1 else (np.zeros(1, int), np.zeros(1))
    cands, found = relocalise.locate_turn(plan, [p.layout for p in photos], block, rel)
    return cands, np.array([p.score for p in found]), [p.agreeing for p in found]


def _find_with_photos(plan: Plan, plan_names: list, args, photos):
    """(poses (C, K, 3), scores (C,)) of K photos taken at one place on ``plan`` with the
    plan's photos (``--photos``, in the plan's order: its pose keys are their file names):
    ``session.find``."""
    names = [os.path.basename(p) for p in args.photos]
    if names != plan_names:
        raise InputError(f"--photos {names} are not the plan's photos {plan_names} (the same "
                         "files in the same order as given to findme plan)")
    plan_photos = _photos(args.photos, args)
    return session.find(plan_photos, plan.poses, photos)
