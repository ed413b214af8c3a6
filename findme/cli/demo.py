"""``findme demo``: the single-image pipeline on the bundled example photo.

Ranks the boundary hypotheses of a rendered room (a cabinet on a wood floor, taken by a
tilted phone), writes the numbered selection image, then measures under the best-ranked
hypothesis: the example's ground-truth floor points (their error is printed), the distance
between two of them, and a point on a wall.
"""

from __future__ import annotations

import json
import math
import time
from importlib import resources
from pathlib import Path

import cv2
import numpy as np

from findme_core.geometry.camera import Camera
from findme_core.single.methods import hypothesize
from findme_io.overlay import draw_hypotheses
from findme_core.geometry.provenance import INPUT_GRAVITY_SIGMA_DEG, tilt_cov
from findme_core.single.scene import Scene, boundary_sigma_px, distances

from findme_io.imageio import read_image

DEMO_HELP = """\
The single-photo steps on the bundled example photo (a rendered room with a
cabinet, taken by a tilted phone): its floor-wall boundary hypotheses, best
first; the numbered selection image (DIR/selection.png); then, under the best
hypothesis, the 3D position of the example's known floor points next to their
true values, the distance between two of them and a point on a wall."""


def register(sub) -> None:
    p = sub.add_parser("demo", help="the single-photo steps on the bundled example photo",
                       description=DEMO_HELP)
    p.add_argument("--out", default="findme-demo", metavar="DIR",
                   help="folder for the numbered selection image (default findme-demo)")
    p.set_defaults(func=cmd_demo)


def example(name: str = "room_a") -> tuple[np.ndarray, Camera, float, dict]:
    """(image, camera, camera height, metadata) of a bundled example photo."""
    base = resources.files("findme") / "examples"
    meta = json.loads((base / f"{name}.json").read_text())
    k = meta["intrinsics"]
    cam = Camera(k["fx"], k["fy"], k["cx"], k["cy"], k["width"], k["height"], meta["gravity_cam"])
    with resources.as_file(base / meta["image"]) as path:
        image = read_image(path)
    return image, cam, float(meta["camera_height_m"]), meta


def cmd_demo(args) -> int:
    image, cam, h, meta = example("room_a")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    hs = hypothesize(image, cam, "findme", 5)
    ms = 1e3 * (time.perf_counter() - t0)
    print(f"example photo: room_a.jpg ({cam.width}x{cam.height}, pitch {cam.pitch_deg:.0f} deg, "
          f"roll {cam.roll_deg:.0f} deg, camera {h:.2f} m above the floor)")
    print(f"{len(hs.hypotheses)} boundary hypotheses in {ms:.0f} ms, best first:")
    for i, hyp in enumerate(hs.hypotheses):
        steps = int((hyp.kinds == 1).sum())
        print(f"  {i + 1}. score {hyp.score:6.2f}, {len(hyp.polyline) - 1} segments"
              + (f", {steps} occluding steps" if steps else ""))
    sel = out / "selection.png"
    cv2.imwrite(str(sel), draw_hypotheses(image, [x.polyline for x in hs.hypotheses], selected=0))
    print(f"selection image (hypotheses numbered, 1 drawn thick): {sel}")
    best = hs.hypotheses[0]
    # the sigmas a user is shown: the calibrated boundary error and the given gravity's
    scene = Scene(cam, h, best.polyline, best.kinds,
                  boundary_sigma_px=boundary_sigma_px(cam.width, cam.height),
                  gravity_cov=tilt_cov(math.radians(INPUT_GRAVITY_SIGMA_DEG)))
    truth = meta["ground_truth"]["floor_points"]
    pts = scene.locate([q["px"] for q in truth])
    print("measured under hypothesis 1 (camera frame: x right, y down, z forward; metres):")
    for q, p in zip(truth, pts):
        if p.xyz is None:
            print(f"  pixel {tuple(q['px'])}: {p.error}")
            continue
        err = np.linalg.norm(p.xyz - np.array(q["xyz_m"]))
        print(f"  pixel {tuple(q['px'])}: {p.surface} at ({p.xyz[0]:+.3f}, {p.xyz[1]:+.3f}, "
              f"{p.xyz[2]:+.3f}) ± {p.sigma_m:.3f}; true ({q['xyz_m'][0]:+.3f}, "
              f"{q['xyz_m'][1]:+.3f}, {q['xyz_m'][2]:+.3f}), off by {100 * err:.1f} cm")
    d, s, _ = distances(pts[:2], h, scene.height_sigma)[0]
    dt = np.linalg.norm(np.subtract(truth[0]["xyz_m"], truth[1]["xyz_m"]))
    print(f"  distance point 1 - point 2: {d:.3f} m ± {s:.3f} (true {dt:.3f} m)")
    wall = scene.locate([(60, 60)])[0]
    if wall.xyz is not None:
        print(f"  pixel (60, 60): {wall.surface}, {np.linalg.norm(wall.xyz):.2f} m from the camera "
              f"± {wall.sigma_m:.2f}")
    return 0
