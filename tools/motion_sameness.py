"""Proof that a speed change left the two-photo motion unchanged: the ``findme`` motion of
every 640x480 dev pair (``bench/bench_motion.py``'s ``pairs()``, prepared as there: the
photos' own hypotheses and lines, ``pair.prepare``, ``pair.motion_photos``) dumped by one
code tree and compared with another's dump.

    python tools/motion_sameness.py dump OUT.json [--code DIR]   # DIR: another checkout
    python tools/motion_sameness.py compare A.json B.json [--tol 1e-9]

Per pair: x, z, dy (m), yaw (rad), the 1-sigmas, score, inlier count and mask, n_scale, the
layout agreement's sample/violation counts and every alternative's (x, z, yaw), or the
refusal's message; also the match and keypoint counts. ``compare`` prints the largest
difference of each field over the pairs and exits 1 when any exceeds ``--tol`` or any
discrete field (counts, masks, messages, which pairs answered) differs.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import sys
from pathlib import Path


def _motion(m) -> dict:
    return {"x": m.x, "z": m.z, "yaw": m.yaw, "dy": m.dy, "sigma_x": m.sigma_x,
            "sigma_z": m.sigma_z, "sigma_yaw": m.sigma_yaw, "score": m.score,
            "n_inliers": m.n_inliers, "inliers": "".join("1" if v else "0" for v in m.inliers),
            "n_scale": m.n_scale,
            "layout": None if m.layout is None else [m.layout.samples, m.layout.violations,
                                                     list(map(list, m.layout.walls)),
                                                     list(map(list, m.layout.corners))],
            "alternatives": [[a.x, a.z, a.yaw, a.score] for a in m.alternatives]}


def dump(out: str, code: str | None) -> None:
    here = Path(__file__).resolve().parents[1]
    root = Path(code).resolve() if code else here
    os.environ.setdefault("FINDME_EVAL_DIR", str(here.parent / "shared" / "data" / "findme-eval"))
    sys.path.insert(0, str(root))
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    from bench.bench_motion import pairs
    from findme_core.errors import FindmeError
    from findme_core.motion.features import FeatureParams
    from findme_core.single.methods import hypothesize
    from findme_core.motion.methods import MotionParams
    from findme_core.motion.pair import motion_photos, prepare
    import findme_core
    print(f"code: {Path(findme_core.__file__).parent}", file=sys.stderr)
    params, fp, res = MotionParams(), FeatureParams(), {}
    for pid, ia, ib, ca, cb, ha, hb in pairs():
        hsa, hsb = (hypothesize(i, c, "findme", params.max_layouts) for i, c in ((ia, ca), (ib, cb)))
        pa = prepare(ia, ca, ha, hsa.hypotheses, 1, hsa.lines.ends, params.max_layouts, fp)
        pb = prepare(ib, cb, hb, hsb.hypotheses, 1, hsb.lines.ends, params.max_layouts, fp)
        r = motion_photos(pa, pb, ("findme",), fp, params)["findme"]
        res[pid] = ({"error": str(r)} if isinstance(r, FindmeError) else
                    {"matches": r.matches, "keypoints": list(r.keypoints), **_motion(r.motion)})
    Path(out).write_text(json.dumps(res, indent=0))
    print(f"{len(res)} pairs -> {out}", file=sys.stderr)


def _flat(v, path=""):
    """{field path: scalar} of a nested record (lists indexed)."""
    if isinstance(v, dict):
        return {k2: x for k, w in v.items() for k2, x in _flat(w, f"{path}/{k}").items()}
    if isinstance(v, list):
        return {k2: x for i, w in enumerate(v) for k2, x in _flat(w, f"{path}[{i}]").items()}
    return {path: v}


def compare(fa: str, fb: str, tol: float) -> int:
    A, B = json.loads(Path(fa).read_text()), json.loads(Path(fb).read_text())
    worst, discrete = {}, []
    if A.keys() != B.keys():
        discrete.append(f"pairs: {sorted(A.keys() ^ B.keys())}")
    for pid in sorted(A.keys() & B.keys()):
        fa_, fb_ = _flat(A[pid]), _flat(B[pid])
        for k in fa_.keys() | fb_.keys():
            x, y = fa_.get(k), fb_.get(k)
            if isinstance(x, float) and isinstance(y, float):
                d = 0.0 if (math.isnan(x) and math.isnan(y)) else abs(x - y)
                field = re.sub(r"\[\d+\]", "[]", k)
                worst[field] = max(worst.get(field, (0.0, "")), (d, pid))
            elif x != y:
                discrete.append(f"{pid}{k}: {x!r} vs {y!r}"[:200])
    answered = sum("error" not in v for v in A.values())
    print(f"{len(A)} pairs ({answered} answered, {len(A) - answered} refused in {fa})")
    for k, (d, where) in sorted(worst.items()):
        print(f"  max |diff| {k:28s} {d:.3e}   ({where})")
    for p in discrete:
        print(f"  DIFFERS: {p}")
    bad = discrete or any(d > tol for d, _ in worst.values())
    print("SAME" + (" (bit-identical)" if not worst or max(d for d, _ in worst.values()) == 0
                    else f" within {tol:g}") if not bad else "DIFFERENT")
    return 1 if bad else 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    d = sub.add_parser("dump")
    d.add_argument("out")
    d.add_argument("--code", help="the checkout whose code runs (default: this one)")
    c = sub.add_parser("compare")
    c.add_argument("a")
    c.add_argument("b")
    c.add_argument("--tol", type=float, default=1e-9)
    a = ap.parse_args(argv)
    if a.cmd == "dump":
        dump(a.out, a.code)
        return 0
    return compare(a.a, a.b, a.tol)


if __name__ == "__main__":
    sys.exit(main())
