"""``findme hypotheses`` and ``findme locate``: single-image mode from the command line."""

from __future__ import annotations

import json
import math
import sys
import time

import cv2
import numpy as np

from findme_core.errors import HypothesisError, InputError
from findme_core.motion.photo_lines import photo_lines
from findme_core.single.methods import METHODS
from findme_io.camera_source import hypothesize_photo
from findme_io.overlay import draw_hypotheses
from findme_core.single.room_view import judge
from findme_core.single.scene import Scene, boundary_sigma_px, distances
from findme_core.single.search import SegKind

from findme_io.camera_source import camera_json
from findme_io.imageio import read_photo
from .options import (add_camera_args, camera_height, finite_float, photo_camera_from,
                      said_points, surfaces)

#: Extensions the selection image can be written as (what OpenCV encodes).
OVERLAY_EXT = (".png", ".jpg", ".jpeg", ".webp", ".bmp", ".tif", ".tiff")

KIND_NAMES = {int(k): k.name.lower() for k in SegKind}


HYPOTHESES_HELP = """\
The photo's floor-wall boundary hypotheses, best first: each a line across the
photo with the floor below it, made of segments where a wall or an object stands
on the floor, occluding steps, floor running past the top of the photo, and
columns with no floor in view. The camera comes from --hfov / --intrinsics, else
the photo's EXIF focal length, else a typical phone; gravity from --gravity
(refined by the photo's lines), else from the photo's lines, else level (and
then it says so). A photo that does not look like a room (no floor-wall
boundary, taken from above, an object filling the view) is said to be one, with
the reason.

Example:  findme hypotheses room.jpg --overlay numbered.png"""

LOCATE_HELP = """\
The 3D position of pixels of one photo (camera frame: x right, y down, z
forward) on the floor or a wall, under a boundary hypothesis (the best one
unless --hypothesis says), with the 1-sigma of each and the distances between
consecutive points. Without --camera-height lengths are in camera heights.

Example:  findme locate room.jpg --camera-height 1.45 --point 320,400 \\
              --point 500,410"""


def register(sub) -> None:
    p = sub.add_parser("hypotheses", help="a photo's floor-wall boundary hypotheses, best first",
                       description=HYPOTHESES_HELP)
    p.add_argument("image", metavar="PHOTO", help="the photo (JPEG, PNG, WebP, HEIC, ...)")
    add_camera_args(p)
    p.add_argument("--max", type=int, default=10, metavar="N", help="at most N hypotheses (10)")
    p.add_argument("--method", default="findme", choices=METHODS,
                   help="findme (default) or paper (the paper's method, for comparison)")
    p.add_argument("--overlay", metavar="OUT.png",
                   help="write the photo with the hypotheses drawn and numbered (best on top)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=cmd_hypotheses)

    q = sub.add_parser("locate", help="3D position of pixels of a photo, and their distances",
                       description=LOCATE_HELP)
    q.add_argument("image", metavar="PHOTO", help="the photo")
    add_camera_args(q)
    q.add_argument("--camera-height", type=finite_float, metavar="M",
                   help="camera height above the floor in metres (default: unknown; lengths "
                        "are then in camera heights)")
    q.add_argument("--hypothesis", type=int, default=1, metavar="RANK",
                   help="which hypothesis (1 = best ranked)")
    q.add_argument("--max", type=int, default=10, metavar="N",
                   help="hypotheses to make before picking --hypothesis (default 10)")
    q.add_argument("--method", default="findme", choices=METHODS,
                   help="hypothesis method: findme (default) or paper")
    pts = q.add_mutually_exclusive_group(required=True)
    pts.add_argument("--point", action="append", metavar="U,V[,floor|wall|top]",
                     help="a pixel (column, row from the top-left pixel's centre); repeat for "
                          "more (a negative value: --point=-4,2); with floor, wall or top: the "
                          "surface you tapped, whatever the boundary says (floor: on the "
                          "floor; wall: no answer where the boundary puts the floor; top: on "
                          "the top of something standing on the floor line below it, a table "
                          "or a counter, found by its front edge)")
    pts.add_argument("--points", metavar="FILE.json",
                     help='pixels as JSON: [[u, v], ...] or {"points": [[u, v], ...]}; '
                          'a pixel may name its surface: [u, v, "floor"]')
    q.add_argument("--json", action="store_true", help="print one JSON object")
    q.set_defaults(func=cmd_locate)


def _load(args):
    """(image, Camera, Provenance) of the photo: flags, else EXIF and the image, else defaults."""
    photo = read_photo(args.image)
    cam, prov = photo_camera_from(photo, args.hfov, args.intrinsics, getattr(args, "gravity", None),
                                  gravity_sigma_deg=getattr(args, "gravity_sigma", None))
    return photo.image, cam, prov


def _check_overlay(path: str | None) -> None:
    if path and not path.lower().endswith(OVERLAY_EXT):
        raise InputError(f"cannot write the overlay image {path!r}: its name must end in one of "
                         + ", ".join(OVERLAY_EXT))


def hypotheses_json(hs, camera=None, provenance=None, view=None) -> dict:
    """The JSON contract of ``findme hypotheses --json`` (best first, rank from 1), with the
    camera and gravity used and where they came from when given, and whether the photo
    looks like a room view (``view``: ``room_view.judge``) when given."""
    out = camera_json(camera, provenance) if camera is not None else {}
    if view is not None:
        out["room_view"] = {"ok": view.ok, "reason": view.reason}
    return {**out,
        "width": hs.width, "height": hs.height,
        "hypotheses": [{"rank": i + 1, "score": round(float(h.score), 6),
                        "support": round(float(h.support), 4),
                        "flat": round(float(h.flat), 4),
                        "smooth": round(float(h.smooth), 4),
                        "polyline": [[round(float(u), 3), round(float(v), 3)] for u, v in h.polyline],
                        "segments": [KIND_NAMES[int(k)] for k in h.kinds]}
                       for i, h in enumerate(hs.hypotheses)],
        "reason": hs.reason,
        "timing_ms": {k: round(v, 3) for k, v in hs.timing_ms.items()},
    }


def cmd_hypotheses(args) -> int:
    _check_overlay(args.overlay)
    t0 = time.perf_counter()
    image, cam, prov = _load(args)
    t1 = time.perf_counter()
    hs, cam, prov = hypothesize_photo(image, cam, prov, args.method, args.max,
                                      clock=time.perf_counter,
                                      camera_height=getattr(args, "camera_height", None))
    view = judge(hs, cam, getattr(args, "camera_height", None))
    out = hypotheses_json(hs, cam, prov, view)
    out["timing_ms"]["decode_and_camera"] = round(1e3 * (t1 - t0), 3)
    out["timing_ms"]["total"] = round(1e3 * (time.perf_counter() - t0), 3)
    if args.overlay:
        img = draw_hypotheses(image, [h.polyline for h in hs.hypotheses])
        try:
            ok = cv2.imwrite(args.overlay, img)
        except cv2.error:
            ok = False
        if not ok:
            raise InputError(f"cannot write the overlay image {args.overlay!r}")
    if args.json:
        print(json.dumps(out))
        return 0
    if not hs.hypotheses:
        print(f"no hypotheses: {hs.reason}")
        return 0
    _say_sources(out)
    if not view.ok:
        print(f"not a room view: {view.reason}")
    print(f"{len(hs.hypotheses)} hypotheses for {args.image} ({hs.width}x{hs.height}), best first"
          + (" (guesses: this photo does not look like a room):" if not view.ok else ":"))
    for h in out["hypotheses"]:
        corners = " ".join(f"({u:.0f},{v:.0f})" for u, v in h["polyline"])
        said = (f"  the same colour above and below along {100 * h['flat']:.0f} % of it"
                if h["flat"] else "")
        said += (f"  smooth below (a counter top, a sill?) along {100 * h['smooth']:.0f} % of it"
                 if h["smooth"] else "")
        print(f"  {h['rank']:2d}  score {h['score']:7.3f}  edge support {h['support']:.2f}  "
              f"{corners}{said}")
    print(f"  ({out['timing_ms']['total']:.0f} ms)")
    if args.overlay:
        print(f"selection image: {args.overlay}")
    return 0


def _say_sources(out: dict) -> None:
    """One line on stderr saying where the camera and gravity came from (a warning when
    level was assumed)."""
    c, g = out["camera"], out["gravity"]
    text = {"input": "given", "exif": "from the photo's EXIF", "default": "assumed"}[c["source"]]
    gtext = {"input": "given", "image": f"from the photo's lines (± {g['sigma_deg']:.1f} deg)",
             "input+image": f"given, refined by the photo's lines (± {g['sigma_deg']:.1f} deg)",
             "level": f"NOT KNOWN: level assumed (± {g['sigma_deg']:.0f} deg), give --gravity"}
    print(f"  camera {c['hfov_deg']:.1f} deg wide ({text}); gravity pitch {g['pitch_deg']:+.1f} "
          f"roll {g['roll_deg']:+.1f} deg ({gtext[g['source']]})", file=sys.stderr)


def read_points(args) -> tuple[list[tuple[float, float]], list[str | None] | None]:
    """(pixels, the surface each was said to be on or None; None when none was)."""
    if args.point:
        return said_points(args.point, "--point")
    try:
        with open(args.points, "rb") as f:
            raw = f.read(1_000_001)
    except OSError as e:
        raise InputError(f"cannot read {args.points}: {e.strerror}") from None
    if len(raw) > 1_000_000:
        raise InputError(f"{args.points}: over 1 MB, not a points file")
    try:
        data = json.loads(raw.decode("utf-8"), parse_constant=_no_constant)
    except UnicodeDecodeError:
        raise InputError(f"{args.points} is not a text file (not UTF-8 JSON)") from None
    except json.JSONDecodeError as e:
        raise InputError(f"{args.points} is not valid JSON: {e.msg} at line {e.lineno}") from None
    except ValueError as e:
        raise InputError(f"{args.points}: {e}") from None
    pts = data.get("points") if isinstance(data, dict) else data
    if not isinstance(pts, list) or not pts:
        raise InputError(f'{args.points}: expected [[u, v], ...] or {{"points": [[u, v], ...]}}')
    out, said = [], []
    for i, p in enumerate(pts):
        if isinstance(p, (list, tuple)) and len(p) == 3:
            p, s = p[:2], p[2]
            said.append(s if isinstance(s, str) else repr(s))
        else:
            said.append(None)
        if (not isinstance(p, (list, tuple)) or len(p) != 2
                or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in p)):
            raise InputError(f"{args.points}: point {i} is {p!r}, expected [u, v] numbers")
        try:
            out.append((float(p[0]), float(p[1])))
        except OverflowError:   # a 400-digit integer
            raise InputError(f"{args.points}: point {i} is not a finite pixel") from None
        if not all(math.isfinite(x) for x in out[-1]):
            raise InputError(f"{args.points}: point {i} is {p!r}, not finite")
    return out, surfaces(said, args.points)


def _no_constant(name: str):
    raise ValueError(f"{name} is not a pixel coordinate (finite numbers only)")


def locate_json(scene: Scene, pixels, rank: int, polyline, metric: bool,
                provenance=None, surfaces=None) -> dict:
    located = scene.locate(pixels, surfaces)
    dist = distances(located, scene.height, scene.height_sigma)
    r = lambda x: None if x is None else round(float(x), 6)  # noqa: E731
    up = scene.camera.R_level_from_cam[1]   # level y (down) of a camera-frame point
    src = camera_json(scene.camera, provenance) if provenance is not None else {}
    return {**src,
        "points": [{"pixel": [r(p.pixel[0]), r(p.pixel[1])], "surface": p.surface,
                    "xyz_m": None if p.xyz is None else [r(x) for x in p.xyz],
                    "sigma_m": r(p.sigma_m), "error": p.error, "note": p.note,
                    # above the floor: a top's height, a wall point's on its wall
                    "height_m": None if p.xyz is None else r(scene.height - up @ p.xyz),
                    "said": None if surfaces is None else surfaces[i],
                    "sigma_parts_m": None if p.sigma_parts is None else
                    {k: r(v) for k, v in p.sigma_parts.items()}} for i, p in enumerate(located)],
        "distances_m": [r(d) for d, _, _ in dist],
        "distance_sigma_m": [r(s) for _, s, _ in dist],
        "camera_height_m": scene.height, "metric": metric,
        "hypothesis": {"rank": rank, "polyline": np.round(polyline, 3).tolist()},
    }


def cmd_locate(args) -> int:
    pixels, surfaces = read_points(args)
    h, metric = camera_height(args.camera_height)
    image, cam, prov = _load(args)
    hs, cam, prov = hypothesize_photo(image, cam, prov, args.method,
                                      max(args.max, args.hypothesis),
                                      camera_height=h if metric else None)
    if args.hypothesis < 1 or args.hypothesis > len(hs.hypotheses):
        raise HypothesisError(
            f"hypothesis {args.hypothesis} does not exist: this photo has "
            f"{len(hs.hypotheses)} hypotheses" + (f" ({hs.reason})" if hs.reason else ""))
    hyp = hs.hypotheses[args.hypothesis - 1]
    view = judge(hs, cam, h if metric else None)
    if not view.ok:
        print(f"findme locate: warning: not a room view: {view.reason}; the points below "
              "rest on a guessed boundary", file=sys.stderr)
    scene = Scene(cam, h, hyp.polyline, hyp.kinds, gravity_cov=prov.gravity_cov,
                  boundary_sigma_px=boundary_sigma_px(cam.width, cam.height),
                  lines=photo_lines(hs, image))
    out = locate_json(scene, pixels, args.hypothesis, hyp.polyline, metric, prov, surfaces)
    out["room_view"] = {"ok": view.ok, "reason": view.reason}
    if args.json:
        print(json.dumps(out))
        return 0
    _say_sources(out)
    unit = "m" if metric else "camera heights"
    for i, p in enumerate(out["points"]):
        if p["error"]:
            print(f"  {i + 1}. ({p['pixel'][0]:g}, {p['pixel'][1]:g})  no answer: {p['error']}")
        else:
            x, y, z = p["xyz_m"]
            print(f"  {i + 1}. ({p['pixel'][0]:g}, {p['pixel'][1]:g})  {p['surface']:5s}"
                  + (" (as you said) " if p["said"] else " ") +
                  f"x {x:+.3f} y {y:+.3f} z {z:+.3f} {unit}  (± {p['sigma_m']:.3f})"
                  + (f", {p['height_m']:.3f} {unit} above the floor" if p["surface"] == "top"
                     else "")
                  + (f"\n     note: {p['note']}" if p["note"] else ""))
    for i, (d, s) in enumerate(zip(out["distances_m"], out["distance_sigma_m"])):
        if d is not None:
            print(f"  distance {i + 1}-{i + 2}: {d:.3f} {unit} (± {s:.3f})")
    if not metric:
        print("  (no --camera-height given: distances are in units of the camera height)",
              file=sys.stderr)
    return 0
