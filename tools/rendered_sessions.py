"""Confident wrong poses in mapping sessions the project renders: rooms whose every answer is
known, photos turning at each spot with and without overlap, through the mapper's handler.

    python tools/rendered_sessions.py [--json OUT.json]
        [--heading-sigma DEG [--heading-in exif] [--heading-bias DEG]]

Rooms: 5 x 4, 7 x 3 and 8 x 6 m rectangles, an L (6 x 5 m less 2.5 x 2), a trapezoid; two or
three spots each; turns in steps of 50, 55 or 60 deg (overlapping views), 65 or 70 deg (a
hair of overlap) and 0, 50, 180, 230 deg (two halves that share nothing: the turn splits).
Each photo is a rendered JPEG whose hypothesis is its exact ground-wall boundary, given to
``MapperHandler.on_message`` (no bus) as a phone's session would come. Per session: photos
placed, the plan refused (and why), photos whose true pose lies outside 3 sigma of the
stated one in x, z or yaw (``confident_wrong``: with 0.02 m and 0.01 rad of slack for the
render), and the plan's area against the room's. ``--heading-sigma DEG``: each Frame carries
the phone's heading as the page sends it, the truth read off by a seeded N(0, DEG), declared
at DEG; with ``--heading-in exif`` each photo file carries it instead, as a camera app's
compass bearing (GPSImgDirection), taken at the files' 1-sigma
(``frame_photo.EXIF_HEADING_SIGMA_RAD``) whatever DEG is; ``--heading-bias DEG`` adds DEG to
every reading at the second spot (a compass near steel). A tool, not the product: it reads
the rendered truth.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import schemas  # noqa: E402
from findme_core.plan import polygon  # noqa: E402
from findme_core.synth.room import Room  # noqa: E402
from tests.plan_room import confident_wrong, rendered_session  # noqa: E402

ROOMS = {"5x4": Room.rectangle(5.0, 4.0), "L": Room.l_shape(6.0, 5.0, 2.5, 2.0),
         "7x3": Room.rectangle(7.0, 3.0), "8x6": Room.rectangle(8.0, 6.0),
         "trapezoid": Room([(-2.5, -2.0), (2.5, -2.0), (1.2, 2.2), (-2.5, 2.0)])}
LAYOUTS = [("5x4", [(-0.8, -0.5), (1.0, 0.6)]), ("L", [(-1.5, -1.0), (1.2, -1.4), (-1.6, 1.6)]),
           ("L", [(-1.5, -1.0), (1.2, -1.4)]), ("7x3", [(-2.0, 0.0), (2.0, 0.3)]),
           ("trapezoid", [(-1.0, -0.5), (0.8, -0.8)]), ("8x6", [(-2.0, -1.0), (2.0, 1.5)]),
           ("8x6", [(-2.5, -1.5), (0.5, 0.0), (2.5, 1.5)])]
TURNS = [tuple(range(0, 360, s))[: 360 // s] for s in (50, 55, 60, 65, 70)] + [(0, 50, 180, 230)]


def photo_sessions(turns=(50, 60)):
    """Each layout turning in steps of each of ``turns`` degrees, as a user's photos: (room,
    spots, step, the ``RenderedSession``, its JPEGs decoded (BGR)), for the tools that put
    the rendered photos through real hypotheses."""
    import cv2
    import numpy as np
    for room, spots in LAYOUTS:
        for step in turns:
            s = rendered_session(ROOMS[room], spots, yaws=range(0, 360, step))
            yield room, spots, step, s, [cv2.imdecode(np.frombuffer(d, np.uint8),
                                                      cv2.IMREAD_COLOR) for d in s.jpegs]


def run(room: str, spots, yaws, heading_sigma_deg=None, heading_in="frame",
        heading_bias_deg=0.0) -> dict:
    from services.pipeline.mapper import MapperHandler
    s = rendered_session(ROOMS[room], spots, yaws=yaws, heading_sigma_deg=heading_sigma_deg,
                         seed=len(spots) * 1000 + len(yaws), heading_in=heading_in,
                         heading_bias_deg=heading_bias_deg)
    last = s.plans(MapperHandler())[-1]
    placed = [q for q in last.poses if q.status == schemas.PLAN_PHOTO_STATUS_PLACED]
    wrong = [q.index for q in placed if q.index and confident_wrong(
        (q.x_m, q.z_m, q.yaw_rad), (q.sigma_x_m, q.sigma_z_m, q.sigma_yaw_rad), s.poses[q.index])]
    area = abs(polygon.area(s.polygon))
    return {"room": room, "spots": spots, "yaws": list(yaws), "photos": len(s.poses),
            "placed": len(placed), "refused": last.reason or None,
            "confident_wrong": wrong, "area_m2": round(last.area_m2, 2),
            "true_area_m2": round(area, 2)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", metavar="OUT.json")
    ap.add_argument("--heading-sigma", type=float, metavar="DEG",
                    help="each frame carries the phone's heading: the truth plus a seeded "
                         "N(0, DEG) error, declared at DEG (default: no heading)")
    ap.add_argument("--heading-in", choices=("frame", "exif"), default="frame",
                    help="where the heading goes: the Frame (the page's sensor, default) or "
                         "the photo file's EXIF (a compass bearing, taken at the files' sigma)")
    ap.add_argument("--heading-bias", type=float, default=0.0, metavar="DEG",
                    help="every heading at the second spot reads DEG more (a compass near "
                         "steel), on top of the N(0, --heading-sigma) error")
    a = ap.parse_args(argv)
    out = []
    for room, spots in LAYOUTS:
        for yaws in TURNS:
            r = run(room, spots, yaws, a.heading_sigma, a.heading_in, a.heading_bias)
            out.append(r)
            step = "skip" if len(yaws) == 4 else f"{yaws[1]:>4d}"
            print(f"{room:9s} {len(spots)} spots, turn {step}: placed {r['placed']:2d}/"
                  f"{r['photos']:2d}, confident wrong {len(r['confident_wrong']):2d}, area "
                  f"{r['area_m2']:5.1f} / {r['true_area_m2']:5.1f} m2"
                  + (f", refused: {r['refused'][:70]}" if r["refused"] else ""), flush=True)
    n = sum(r["placed"] for r in out)
    bad = sum(len(r["confident_wrong"]) for r in out)
    refused = sum(bool(r["refused"]) for r in out)
    print(f"{len(out)} sessions: {refused} refused; {n} photos placed, {bad} of them "
          "confidently wrong (photo 0, the frame's origin, is exact by definition)")
    if a.json:
        with open(a.json, "w") as f:
            json.dump(out, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
