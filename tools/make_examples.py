"""Render the bundled example photos (findme/examples/) from a synthetic room.

    python tools/make_examples.py

Two phone-like photos (tilted, slightly rolled) of a 4.6 x 5.8 m room with a cabinet, the
second taken after stepping forward-right and turning. Each photo has a sidecar JSON with
what a phone would send (intrinsics, gravity, camera height) and the exact ground truth
(the planar motion between the two, a few floor points), so the demo can show its error.
Deterministic: the same files every run.
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np

from findme_core.synth.render import Box, Pose, Room, planar_motion, render

OUT = Path(__file__).resolve().parents[1] / "findme" / "examples"


def main():
    OUT.mkdir(parents=True, exist_ok=True)
    room = Room.rectangle(4.6, 5.8, floor_style="wood",
                          boxes=(Box(0.6, 1.3, 0.8, 0.5, 0.75, yaw_deg=10.0),))
    poses = {"room_a": Pose(-0.4, -1.6, 1.42, yaw_deg=12.0, pitch_deg=28.0, roll_deg=-3.0),
             "room_b": Pose(0.1, -1.1, 1.42, yaw_deg=-6.0, pitch_deg=26.0, roll_deg=2.0)}
    views = {}
    for name, pose in poses.items():
        v = render(room, pose, 640, 480, hfov_deg=66.0, seed=7)
        views[name] = v
        cv2.imwrite(str(OUT / f"{name}.jpg"), v.image, [cv2.IMWRITE_JPEG_QUALITY, 92])
        c = v.camera
        floor = np.argwhere(v.labels == 0)
        pick = floor[np.linspace(0, len(floor) - 1, 4).astype(int)]
        meta = {
            "image": f"{name}.jpg",
            "intrinsics": {"fx": c.fx, "fy": c.fy, "cx": c.cx, "cy": c.cy,
                           "width": c.width, "height": c.height},
            "gravity_cam": [round(float(x), 6) for x in c.gravity],
            "camera_height_m": v.camera_height,
            "ground_truth": {
                "floor_points": [{"px": [int(u), int(r)],
                                  "xyz_m": [round(float(x), 4) for x in v.points_cam[r, u]]}
                                 for r, u in pick],
            },
            "note": "rendered by tools/make_examples.py (synthetic room; free to redistribute)",
        }
        (OUT / f"{name}.json").write_text(json.dumps(meta, indent=1) + "\n")
    x, z, yaw = planar_motion(poses["room_a"], poses["room_b"])
    (OUT / "pair.json").write_text(json.dumps(
        {"a": "room_a", "b": "room_b",
         "motion": {"x_m": round(x, 4), "z_m": round(z, 4), "yaw_deg": round(yaw, 3)}},
        indent=1) + "\n")
    print(f"wrote {OUT}: room_a.jpg, room_b.jpg (+ .json), pair.json; motion {x:.3f} {z:.3f} {yaw:.2f}")


if __name__ == "__main__":
    main()
