"""How the boundary hypotheses do on the photos the project renders, where the exact boundary
is known: the rooms and turns of ``tools/rendered_sessions.py``, each photo through
``methods.hypothesize`` with its true gravity and camera height.

    python tools/rendered_ranker.py [--turns 50,60] [--max 5] [--json OUT.json]

Per photo: the mean |row error| of the top-1 and of the best of the first ``--max``
hypotheses against ``View.ground_truth_boundary_polyline`` (rows clipped to the image,
every 4th column), as a share of the image height; then the medians, p90s and the photos
over 5 % (a wrong boundary: a poster's lower edge, "no floor visible" over a wood floor).
A synthetic check beside the real dev split, not a replacement for it: the rendered rooms'
textures are few. A tool, not the product: it reads the rendered truth.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

#: a photo whose top-1 is off by more than this share of the height has a wrong boundary
BAD = 0.05


def row_error(polyline, truth, width: int, height: int) -> float:
    """Mean |row difference| of two (M, 2) polylines over every 4th column, rows clipped to
    the image, as a share of ``height``."""
    xs = np.arange(0.0, width, 4.0)
    p, t = np.asarray(polyline, float), np.asarray(truth, float)
    rp = np.clip(np.interp(xs, p[:, 0], p[:, 1]), 0.0, height)
    rt = np.clip(np.interp(xs, t[:, 0], t[:, 1]), 0.0, height)
    return float(np.mean(np.abs(rp - rt)) / height)


def photo_errors(view, image, max_n: int) -> tuple[float, float]:
    """(top-1, best of ``max_n``) row error of one rendered view's hypotheses (1.0 when it
    has none)."""
    from findme_core.single.methods import hypothesize
    from tests.plan_room import H
    hs = hypothesize(image, view.camera, "findme", max_n, camera_height=H)
    t = view.ground_truth_boundary_polyline()
    t = t[np.isfinite(t[:, 1])]
    W, Hh = view.camera.width, view.camera.height
    errs = [row_error(h.polyline, t, W, Hh) for h in hs.hypotheses]
    return (errs[0], min(errs)) if errs else (1.0, 1.0)


def run(turns=(50, 60), max_n: int = 5) -> list[dict]:
    from tools.rendered_sessions import photo_sessions
    out = []
    for room, spots, step, s, images in photo_sessions(turns):
        for n, (v, img) in enumerate(zip(s.views, images)):
            top, best = photo_errors(v, img, max_n)
            out.append({"room": room, "spots": len(spots), "turn": step, "photo": n,
                        "top1": round(top, 4), "best": round(best, 4)})
    return out


def summary(rows: list[dict], max_n: int) -> str:
    top = np.array([r["top1"] for r in rows])
    best = np.array([r["best"] for r in rows])
    lines = [f"{len(rows)} photos: top-1 median {100 * np.median(top):.1f} %, p90 "
             f"{100 * np.percentile(top, 90):.1f} %, over {100 * BAD:.0f} %: "
             f"{int(np.sum(top > BAD))}; best of {max_n}: median {100 * np.median(best):.1f} %, "
             f"p90 {100 * np.percentile(best, 90):.1f} %, over {100 * BAD:.0f} %: "
             f"{int(np.sum(best > BAD))}"]
    lines += [f"  {r['room']} {r['spots']} spots, turn {r['turn']}, photo {r['photo']}: top-1 "
              f"{100 * r['top1']:.1f} %, best {100 * r['best']:.1f} %"
              for r in rows if r["top1"] > BAD]
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--turns", default="50,60", help="turn steps in degrees, comma-separated")
    ap.add_argument("--max", type=int, default=5, help="hypotheses kept per photo")
    ap.add_argument("--json", metavar="OUT.json")
    a = ap.parse_args(argv)
    rows = run(tuple(int(t) for t in a.turns.split(",")), a.max)
    print(summary(rows, a.max))
    if a.json:
        Path(a.json).write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
