"""``findme hypotheses`` and ``findme locate``: single-image mode from the command line."""

from __future__ import annotations

import json
import sys
import time

import cv2
import numpy as np

from findme_core.errors import HypothesisError, InputError
from findme_core.methods import METHODS, hypothesize
from findme_core.overlay import draw_hypotheses
from findme_core.scene import Scene, distances
from findme_core.search import SegKind

from findme_io.imageio import read_image
from .options import add_camera_args, camera_from, camera_height, floats

KIND_NAMES = {int(k): k.name.lower() for k in SegKind}


def register(sub) -> None:
    p = sub.add_parser("hypotheses", help="ground-wall boundary hypotheses of one photo",
                       description="Ranked ground-wall boundary hypotheses of one photo.")
    p.add_argument("image")
    add_camera_args(p)
    p.add_argument("--max", type=int, default=10, metavar="N", help="at most N hypotheses (10)")
    p.add_argument("--method", default="findme", choices=METHODS,
                   help="findme (default) or paper (the paper's method, for comparison)")
    p.add_argument("--overlay", metavar="OUT.png", help="write the numbered selection image")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=cmd_hypotheses)

    q = sub.add_parser("locate", help="3D position of tapped pixels of one photo",
                       description="3D position (camera frame, metres) of pixels on the floor "
                                   "or a wall, under a chosen boundary hypothesis.")
    q.add_argument("image")
    add_camera_args(q)
    q.add_argument("--camera-height", type=float, metavar="M",
                   help="camera height above the floor in metres (default: 1, results up to scale)")
    q.add_argument("--hypothesis", type=int, default=1, metavar="RANK",
                   help="which hypothesis (1 = best ranked)")
    q.add_argument("--max", type=int, default=10, metavar="N", help=argparse_suppress())
    q.add_argument("--method", default="findme", choices=METHODS)
    pts = q.add_mutually_exclusive_group(required=True)
    pts.add_argument("--point", action="append", metavar="U,V",
                     help="a pixel; repeat for more (negative values: --point=-4,2)")
    pts.add_argument("--points", metavar="FILE.json",
                     help='pixels as JSON: [[u, v], ...] or {"points": [[u, v], ...]}')
    q.add_argument("--json", action="store_true", help="print one JSON object")
    q.set_defaults(func=cmd_locate)


def argparse_suppress():
    import argparse
    return argparse.SUPPRESS


def _load(args):
    image = read_image(args.image)
    H, W = image.shape[:2]
    cam = camera_from(W, H, args.hfov, args.intrinsics, getattr(args, "gravity", None))
    return image, cam


def hypotheses_json(hs) -> dict:
    """The JSON contract of ``findme hypotheses --json`` (best first, rank from 1)."""
    return {
        "width": hs.width, "height": hs.height,
        "hypotheses": [{"rank": i + 1, "score": round(float(h.score), 6),
                        "support": round(float(h.support), 4),
                        "polyline": [[round(float(u), 3), round(float(v), 3)] for u, v in h.polyline],
                        "segments": [KIND_NAMES[int(k)] for k in h.kinds]}
                       for i, h in enumerate(hs.hypotheses)],
        "reason": hs.reason,
        "timing_ms": {k: round(v, 3) for k, v in hs.timing_ms.items()},
    }


def cmd_hypotheses(args) -> int:
    image, cam = _load(args)
    t0 = time.perf_counter()
    hs = hypothesize(image, cam, args.method, args.max, clock=time.perf_counter)
    out = hypotheses_json(hs)
    out["timing_ms"]["total"] = round(1e3 * (time.perf_counter() - t0), 3)
    if args.overlay:
        img = draw_hypotheses(image, [h.polyline for h in hs.hypotheses])
        if not cv2.imwrite(args.overlay, img):
            raise InputError(f"cannot write the overlay image {args.overlay!r}")
    if args.json:
        print(json.dumps(out))
        return 0
    if not hs.hypotheses:
        print(f"no hypotheses: {hs.reason}")
        return 0
    print(f"{len(hs.hypotheses)} hypotheses for {args.image} ({hs.width}x{hs.height}), best first:")
    for h in out["hypotheses"]:
        corners = " ".join(f"({u:.0f},{v:.0f})" for u, v in h["polyline"])
        print(f"  {h['rank']:2d}  score {h['score']:7.3f}  edge support {h['support']:.2f}  {corners}")
    print(f"  ({out['timing_ms']['total']:.0f} ms)")
    if args.overlay:
        print(f"selection image: {args.overlay}")
    return 0


def read_points(args) -> list[tuple[float, float]]:
    if args.point:
        return [floats(p, 2, "--point") for p in args.point]
    try:
        with open(args.points) as f:
            data = json.load(f)
    except OSError as e:
        raise InputError(f"cannot read {args.points}: {e.strerror}") from None
    except json.JSONDecodeError as e:
        raise InputError(f"{args.points} is not valid JSON: {e.msg} at line {e.lineno}") from None
    pts = data.get("points") if isinstance(data, dict) else data
    if not isinstance(pts, list) or not pts:
        raise InputError(f'{args.points}: expected [[u, v], ...] or {{"points": [[u, v], ...]}}')
    out = []
    for i, p in enumerate(pts):
        if (not isinstance(p, (list, tuple)) or len(p) != 2
                or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in p)):
            raise InputError(f"{args.points}: point {i} is {p!r}, expected [u, v] numbers")
        out.append((float(p[0]), float(p[1])))
    return out


def locate_json(scene: Scene, pixels, rank: int, polyline, metric: bool) -> dict:
    located = scene.locate(pixels)
    dist = distances(located, scene.height, scene.height_sigma)
    r = lambda x: None if x is None else round(float(x), 6)  # noqa: E731
    return {
        "points": [{"pixel": [r(p.pixel[0]), r(p.pixel[1])], "surface": p.surface,
                    "xyz_m": None if p.xyz is None else [r(x) for x in p.xyz],
                    "sigma_m": r(p.sigma_m), "error": p.error} for p in located],
        "distances_m": [r(d) for d, _, _ in dist],
        "distance_sigma_m": [r(s) for _, s, _ in dist],
        "camera_height_m": scene.height, "metric": metric,
        "hypothesis": {"rank": rank, "polyline": np.round(polyline, 3).tolist()},
    }


def cmd_locate(args) -> int:
    pixels = read_points(args)
    image, cam = _load(args)
    h, metric = camera_height(args.camera_height)
    hs = hypothesize(image, cam, args.method, max(args.max, args.hypothesis))
    if args.hypothesis < 1 or args.hypothesis > len(hs.hypotheses):
        raise HypothesisError(
            f"hypothesis {args.hypothesis} does not exist: this photo has "
            f"{len(hs.hypotheses)} hypotheses" + (f" ({hs.reason})" if hs.reason else ""))
    hyp = hs.hypotheses[args.hypothesis - 1]
    scene = Scene(cam, h, hyp.polyline, hyp.kinds)
    out = locate_json(scene, pixels, args.hypothesis, hyp.polyline, metric)
    if args.json:
        print(json.dumps(out))
        return 0
    unit = "m" if metric else "camera heights"
    for i, p in enumerate(out["points"]):
        if p["error"]:
            print(f"  {i + 1}. ({p['pixel'][0]:g}, {p['pixel'][1]:g})  no answer: {p['error']}")
        else:
            x, y, z = p["xyz_m"]
            print(f"  {i + 1}. ({p['pixel'][0]:g}, {p['pixel'][1]:g})  {p['surface']:5s} "
                  f"x {x:+.3f} y {y:+.3f} z {z:+.3f} {unit}  (± {p['sigma_m']:.3f})")
    for i, (d, s) in enumerate(zip(out["distances_m"], out["distance_sigma_m"])):
        if d is not None:
            print(f"  distance {i + 1}-{i + 2}: {d:.3f} {unit} (± {s:.3f})")
    if not metric:
        print("  (no --camera-height given: distances are in units of the camera height)",
              file=sys.stderr)
    return 0
