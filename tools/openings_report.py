"""Doors and openings the plan says, against the truth: real rooms and closed rendered ones.

    python tools/openings_report.py [DATASET_DIR] [--no-gravity] [--rendered]

For each plan two answers from the same photos, layouts and poses: "now" the shipped rule
(``apertures.stretches``: one vote per photo, floor seen beyond the wall against its base
seen standing) and "fans only" the rule before it (any photo's floor fan past the wall opens
it). DATASET_DIR (findme-eval): every room set planned as ``findme eval`` plans it
(``room_photos``, the dataset's gravity, or from the photos with ``--no-gravity``); each
said stretch is on a true door or opening where it lies within 0.1 m of one of the dataset's
apertures; "found" is the share of the dataset's door and opening length said (closed doors
show no floor beyond, so it cannot reach 1). ``--rendered``: the closed rooms of
``tools/rendered_sessions.py`` (two turns each) rendered and analysed as ``findme plan``
analyses photos (real hypotheses, the true gravity): every opening said is wrong.

A tool, not the product: it reads the truth.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from findme_core.errors import FindmeError  # noqa: E402
from findme_core.plan import apertures, session, walls  # noqa: E402

TOL_M = 0.1


def openings(plan, layouts) -> dict:
    """{"now": [(a, b) (2,) ends of each said stretch], "fans only": [...]} of one plan."""
    fans, who = apertures.session_fans(layouts, plan.poses)
    ev = walls.evidence(layouts, plan.poses)
    out = {"now": [], "fans only": []}
    for w in plan.walls:
        if not w.seen:
            continue
        a, b = np.asarray(w.a, float), np.asarray(w.b, float)
        u = (b - a) / max(float(np.linalg.norm(b - a)), 1e-12)
        before = apertures.stretches(a, b, fans, who)   # no base: any fan past the wall
        for name, st in (("now", w.apertures), ("fans only", before)):
            out[name] += [(a + lo * u, a + hi * u) for lo, hi in st]
    return out


def _near(pts, segs) -> np.ndarray:
    hit = np.zeros(len(pts), bool)
    for a, b in segs:
        ab = b - a
        t = np.clip(((pts - a) @ ab) / max(float(ab @ ab), 1e-12), 0.0, 1.0)
        hit |= np.linalg.norm(pts - (a + t[:, None] * ab), axis=1) <= TOL_M
    return hit


def score(said, truth) -> tuple[float, float, float, float]:
    """(metres said, of them on a true aperture, true metres, of them said)."""
    def along(segs, other):
        tot = ok = 0.0
        for a, b in segs:
            n = max(int(np.linalg.norm(b - a) / 0.02), 1)
            pts = a + ((np.arange(n) + 0.5) / n)[:, None] * (b - a)
            tot += float(np.linalg.norm(b - a))
            ok += float(np.linalg.norm(b - a)) * float(_near(pts, other).mean())
        return tot, ok
    return (*along(said, truth), *along(truth, said))


def stretches_of(walls_, kinds=None) -> list:
    """[(a, b) ends] of the apertures of walls as the plan JSON and the dataset write them
    ({"a", "b", "apertures": [{"kind", "from_m", "to_m"}]}), of ``kinds`` (default all)."""
    out = []
    for w in walls_:
        a, b = np.array(w["a"], float), np.array(w["b"], float)
        u = (b - a) / max(float(np.linalg.norm(b - a)), 1e-12)
        out += [(a + ap["from_m"] * u, a + ap["to_m"] * u) for ap in w.get("apertures", ())
                if kinds is None or ap["kind"] in kinds]
    return out


def truth_of(dataset: str, rid: str) -> list:
    """The dataset's doors and openings of room ``rid`` (windows show no floor beyond)."""
    with open(os.path.join(dataset, "rooms", rid + ".json")) as f:
        return stretches_of(json.load(f)["walls"], ("door", "opening"))


def prediction_rows(dataset: str, preds: dict) -> list:
    """(room, (said, on a true one, true, found) metres) of ``findme eval``'s room entries."""
    return [(rid, score(stretches_of(r.get("walls", ())), truth_of(dataset, rid)))
            for rid, r in sorted(preds.get("rooms", {}).items())]


def dataset_rows(dataset: str, gravity: bool) -> list:
    from findme.evaluation.rooms import room_photos, room_spots
    rooms = sorted(f[:-5] for f in os.listdir(os.path.join(dataset, "rooms")))
    rows = []
    for rid in rooms:
        truth = truth_of(dataset, rid)
        views, photos = room_photos(os.path.join(dataset, "rooms"),
                                    os.path.join(dataset, "views"), rid, gravity)
        try:
            plan = session.plan(photos, room_spots(views, "ids"))[0]
        except FindmeError as e:
            print(f"  {rid}: no plan ({str(e)[:70]})", flush=True)
            continue
        said = openings(plan, [p.layout for p in photos])
        rows.append((rid, {k: score(v, truth) for k, v in said.items()}))
        print(_line(rid, rows[-1][1]), flush=True)
    return rows


def rendered_rows() -> list:
    from findme_io.camera_source import with_gravity
    from findme_io.session_photos import final_gravity, session_photos
    from tests.plan_room import H
    from tools.rendered_sessions import photo_sessions
    rows = []
    for room, spots, step, s, images in photo_sessions():
        inputs = []
        for v, img in zip(s.views, images):
            cam, prov = with_gravity(v.camera, img, v.camera.gravity)
            inputs.append(final_gravity(img, cam, prov, H, True))
        photos = session_photos(images, inputs)[0]
        name = f"{room} {len(spots)} spots, turn {step}"
        try:
            plan = session.plan(photos, None)[0]
        except FindmeError as e:
            print(f"  {name}: no plan ({str(e)[:70]})", flush=True)
            continue
        said = openings(plan, [p.layout for p in photos])
        rows.append((name, {k: score(v, []) for k, v in said.items()}))
        print(_line(name, rows[-1][1]), flush=True)
    return rows


def _line(name, r) -> str:
    return f"  {name:24s} " + "; ".join(
        f"{k}: said {s[0]:.2f} m, on a true one {s[1]:.2f} m, found {s[3]:.2f} of {s[2]:.2f} m"
        for k, s in r.items())


def _total(title, rows) -> None:
    for k in ("fans only", "now"):
        s = np.sum([r[k] for _, r in rows], axis=0) if rows else np.zeros(4)
        print(f"{title}, {k:9s}: said {s[0]:.2f} m, on a true door or opening {s[1]:.2f} m "
              f"({s[1] / max(s[0], 1e-9):.2f}), wrong {s[0] - s[1]:.2f} m; of "
              f"{s[2]:.2f} m of true doors and openings {s[3]:.2f} m said")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("dataset", nargs="?")
    ap.add_argument("--no-gravity", action="store_true")
    ap.add_argument("--rendered", action="store_true")
    a = ap.parse_args(argv)
    if a.dataset:
        _total("real rooms", dataset_rows(a.dataset, not a.no_gravity))
    if a.rendered:
        _total("closed rendered rooms", rendered_rows())
    return 0


if __name__ == "__main__":
    sys.exit(main())
