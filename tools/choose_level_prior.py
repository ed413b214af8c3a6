"""Choose the 1-sigma of "level assumed" (``vanishing.GravityParams.level_sigma_deg``) leave one
room out: when a photo shows nothing that tells gravity, its tilt is only known to be a hand-held
photo's, so the prior's width is how hand-held photos of rooms are tilted.

    python tools/choose_level_prior.py ../shared/data/findme-eval

Every dev view's true gravity (all subsets but KITTI, a car's camera) as pitch and roll about
level; per axis the 1-sigma is the RMS about level of the views of the other groups (ZInD room,
TUM block of 6 frames), and each group's views are normalised by it: within 1 / 2 / 3 sigma is
how often "level, +- that" holds a photo's truth when its lines tell nothing. The shipped value
is the RMS over all views. Printed beside it: the 10 deg used before. Reads the dataset's
ground truth: a tool, not the product.
"""

from __future__ import annotations

import argparse
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
sys.path.insert(0, os.path.dirname(__file__))
from sigma_coverage import group_of  # noqa: E402
from findme_core.geometry.manhattan import pitch_roll_deg  # noqa: E402
from findme_core.single.gravity_alternatives import down  # noqa: E402
from findme_core.single.vanishing import GravityParams  # noqa: E402


def tilts(dataset: str) -> tuple[np.ndarray, np.ndarray]:
    """((V, 2) true pitch and roll in degrees, > 0 pitch looking down; (V,) group ids)."""
    idx = json.load(open(os.path.join(dataset, "index.json")))
    vids = sorted({v for n, ss in idx["subsets"].items() for v in ss.get("views", [])
                   if not n.startswith("kitti")})
    out = []
    for vid in vids:
        meta = json.load(open(os.path.join(dataset, "views", vid + ".json")))
        out.append(pitch_roll_deg(down(np.asarray(meta["gravity_cam"], float))))
    return np.array(out), np.array([group_of(v) for v in vids])


def coverage(z: np.ndarray) -> str:
    return " / ".join(f"{np.mean(z <= k):.2f}" for k in (1, 2, 3))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dataset")
    a = ap.parse_args(argv)
    t, groups = tilts(a.dataset)
    held = []
    for g in sorted(set(groups)):
        s = np.sqrt(np.mean(t[groups != g] ** 2, axis=0))
        held.append(np.abs(t[groups == g]) / s)
        print(f"without {g:8s} pitch {s[0]:5.1f} roll {s[1]:4.1f} deg   ({np.sum(groups == g)} "
              "views left out)")
    z = np.vstack(held)
    s_all = np.sqrt(np.mean(t ** 2, axis=0))
    print(f"all {len(t)} views: pitch {s_all[0]:.1f}, roll {s_all[1]:.1f} deg (shipped: "
          f"{GravityParams.level_sigma_deg})")
    print(f"leave-one-room-out, within 1 / 2 / 3 sigma: pitch {coverage(z[:, 0])}, "
          f"roll {coverage(z[:, 1])}")
    z10 = np.abs(t) / 10.0
    print(f"at 10 deg (before):          within 1 / 2 / 3 sigma: pitch {coverage(z10[:, 0])}, "
          f"roll {coverage(z10[:, 1])}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
