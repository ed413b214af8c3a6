"""What the two-photo motion says about two photos that share nothing: each dataset pair's
photo A with photo B of a pair from ANOTHER room (the same subset, view kind and gravity),
through the documented two-photo path (``findme.evaluation.pairs.predict_pair``, as
``findme eval``: each photo's own hypotheses, ``motion_photos``), beside the dataset's own
pairs.

    python tools/unrelated_pairs.py ../shared/data/findme-eval [--no-gravity] [--json OUT]

Every answer is one of: refused (a ``MotionError`` with its reason), wide (the stated yaw
1-sigma > ``--wide-deg``, 10: the answer says it does not know the heading) or tight. For the
dataset's pairs, a tight answer is right when its yaw error is within 3 sigma. Two photos of
different rooms have no motion: a tight answer there is a confident wrong one. Reads the
dataset's ground truth (which room a pair is in, its motion): a tool, not the product.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import sys
import tempfile
from collections import Counter

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
from findme.evaluation.pairs import predict_pair  # noqa: E402
from findme.evaluation.views import GravityInput  # noqa: E402

SUBSETS = ("zind-pairs-level", "zind-pairs-tilted")


def room_of(pair_id: str) -> str:
    """The room of a findme-eval ZInD pair id (``zpl_r06_p10_p11_t0`` -> ``r06``)."""
    m = re.match(r"z\w\w_(r\d+)_", pair_id)
    if m is None:
        raise ValueError(f"not a ZInD pair id: {pair_id!r}")
    return m[1]


def pairings(pair_ids: list[str]) -> list[tuple[str, str]]:
    """(pair giving photo A, pair of another room giving photo B) for every pair: the
    k-th pair with the (7 k)-th of the other rooms' pairs, in the given order (the same
    pairings on every machine). Pairs of a room with no other room are left out."""
    out = []
    for k, p in enumerate(pair_ids):
        others = [q for q in pair_ids if room_of(q) != room_of(p)]
        if others:
            out.append((p, others[(7 * k) % len(others)]))
    return out


def verdict(pred: dict | None, truth: dict | None, wide_deg: float) -> str:
    """refused / wide / tight (unrelated photos), or refused / wide / right / wrong (a
    dataset pair: a tight yaw within 3 sigma of the truth is right)."""
    if pred is None:
        return "refused"
    if pred["sigma_yaw_deg"] > wide_deg:
        return "wide"
    if truth is None:
        return "tight"
    err = abs((pred["yaw_deg"] - truth["yaw_deg"] + 180.0) % 360.0 - 180.0)
    return "right" if err <= 3.0 * pred["sigma_yaw_deg"] else "wrong"


def motion_of(pair_dir: str, view_dir: str, pid: str, gravity: GravityInput):
    """({yaw_deg, sigma_yaw_deg, inliers, matches}, None) or (None, the refusal), as
    ``findme eval`` predicts a pair (``findme.evaluation.pairs.predict_pair``)."""
    _, preds, errs = predict_pair((pair_dir, view_dir, pid, "findme", ("findme",), gravity))
    p = preds.get("findme")
    if p is None:
        return None, errs.get("findme")
    return {k: p[k] for k in ("yaw_deg", "sigma_yaw_deg", "inliers", "matches")}, None


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("dataset")
    ap.add_argument("--no-gravity", action="store_true", help="withhold the views' gravity")
    ap.add_argument("--wide-deg", type=float, default=10.0)
    ap.add_argument("--json", help="every answer, one record per pair")
    a = ap.parse_args(argv)
    with open(os.path.join(a.dataset, "index.json")) as f:
        idx = json.load(f)
    pdir = os.path.join(a.dataset, idx.get("pairs_dir", "pairs"))
    vdir = os.path.join(a.dataset, idx.get("views_dir", "views"))
    gravity = GravityInput(given=not a.no_gravity)
    records = []
    with tempfile.TemporaryDirectory() as tmp:
        for sub in SUBSETS:
            pids = list(idx["subsets"][sub]["pairs"])
            jobs = [(pdir, p, None) for p in pids]
            for p, q in pairings(pids):
                with open(os.path.join(pdir, p + ".json")) as f:
                    va = json.load(f)["a"]
                with open(os.path.join(pdir, q + ".json")) as f:
                    vb = json.load(f)["b"]
                nid = f"{p}__{q}"
                with open(os.path.join(tmp, nid + ".json"), "w") as f:
                    json.dump({"a": va, "b": vb}, f)
                jobs.append((tmp, nid, q))
            for n, (d, pid, other) in enumerate(jobs):
                print(f"\r{sub}: {n + 1}/{len(jobs)}", end="", file=sys.stderr, flush=True)
                pred, why = motion_of(d, vdir, pid, gravity)
                truth = None
                if other is None:
                    with open(os.path.join(d, pid + ".json")) as f:
                        truth = json.load(f)["motion"]
                records.append({"subset": sub, "pair": pid, "unrelated": other is not None,
                                "answer": pred, "refused": why,
                                "verdict": verdict(pred, truth, a.wide_deg)})
            print(file=sys.stderr)
    if a.json:
        with open(a.json, "w") as f:
            json.dump(records, f, indent=1)
    for sub in SUBSETS:
        for unrelated in (False, True):
            c = Counter(r["verdict"] for r in records
                        if r["subset"] == sub and r["unrelated"] == unrelated)
            n = sum(c.values())
            what = "photos of two rooms" if unrelated else "the dataset's pairs"
            print(f"{sub:18s} {what:20s} n={n:3d}  " + "  ".join(
                f"{k} {c[k]}" for k in ("refused", "wide", "right", "wrong", "tight") if c[k]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
