"""Per-pair diagnosis of the two-photo motion on the dev pairs: what each estimator answered,
its error against the truth, and why it failed.

    python tools/motion_pairs.py ../shared/data/findme-eval [--subsets zind-pairs-level,...]
        [--methods findme,features,paper] [--jobs 2] [--out diag.json] [--pred PRED.json]

Per pair: keypoints and matches, the matches that are right under the true motion (epipolar
residual < ``thr_px`` at the true yaw and baseline direction, in front of both cameras), each
photo's true floor fraction and whether its rank-1 hypothesis sees floor (any WALL or OPEN
segment), and per method the error (m, deg), success (yaw <= 5 deg and translation <= 25 %
of the baseline, as score.py), or the refusal's reason. The failure cause is a short tag:

    ok                    success
    refused:<why>         no answer (``few-kp`` fewer than 8 matches, ``no-view``, ``scale``
                          no metric scale, ``walls`` walls only along one direction, other)
    wrong-yaw / wrong-t   answered, off in yaw (> 5 deg) / in translation only
  suffixed with the evidence the pair lacks: ``noflA``/``noflB`` (the photo's rank-1
  hypothesis sees no floor), ``<k>ok`` (correct matches, when fewer than 10).

``--why`` adds, for ``findme``, what its registration weighed (``Registration.trace``): the
yaw candidate nearest the true yaw (degrees), how many scored candidates are right (within
the success bounds) and the rank of the best of them, and for the candidates at the right
yaw (within 5 deg) the best baseline direction (degrees off) and the length ratios (to the
true baseline) of those within 10 deg of it. The failure's reason then reads: ``no-yaw``
(no candidate yaw within 5 deg), ``no-dir`` (right yaw, no direction within 10 deg),
``scale`` (right yaw and direction, no right length), ``outscored`` (a right candidate lost
the score: its rank), ``refine`` (the best candidate was right, the answer is not).

The summary line also counts the answers within 2 of their own 1-sigmas (translation: the
rms of the x and z sigmas; an honest sigma has ~95 % there).

``--pred`` writes score.py predictions (pairs only) of the first method; the others go to
PRED.<method>.json. Reads only the photos' inputs, as ``findme eval``; the truth is used only
to diagnose.
"""

from __future__ import annotations

import argparse
import json
import math
import multiprocessing as mp
import sys
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from findme.cli.evaluate import add_gravity_args  # noqa: E402
from findme.evaluation.pairs import pair_inputs  # noqa: E402
from findme.evaluation.views import GravityInput  # noqa: E402
from findme_core.errors import FindmeError  # noqa: E402
from findme_core.geometry.planar import _epipolar_terms, bearings  # noqa: E402
from findme_core.motion.methods import MotionParams  # noqa: E402
from findme_core.motion.pair import motion_photos, photo_of  # noqa: E402
from findme_core.single.search import SegKind  # noqa: E402

SUBSETS = ("zind-pairs-level", "zind-pairs-tilted", "tum-cabinet-pairs", "kitti06-pairs")


def _sees_floor(photo) -> bool:
    lay = photo.layouts[0] if photo.layouts else None
    return lay is not None and bool(np.any((lay.kind == SegKind.WALL) | (lay.kind == SegKind.OPEN)))


def _refusal_tag(msg: str) -> str:
    m = msg.lower()
    if "feature matches between" in m:
        return "few-kp"
    if "no common view" in m:
        return "no-view"
    if "distance between the photos" in m:
        return "scale"
    if "along the wall" in m:
        return "walls"
    return "other"


def _why(reg, g, base):
    """What the ``findme`` registration weighed against the truth (see the module doc)."""
    if reg is None or reg.trace is None:
        return {"reason": "no-candidates"}
    yaws, cy, ct, total = reg.trace
    ty, tx, tz = math.radians(g["yaw_deg"]), g["x_m"], g["z_m"]
    wrap = lambda a: np.abs(np.angle(np.exp(1j * np.asarray(a))))  # noqa: E731
    dyaw = wrap(cy - ty)
    right = (dyaw <= math.radians(5)) & (np.hypot(ct[:, 0] - tx, ct[:, 2] - tz) <= 0.25 * base)
    out = {"yaw_cand_deg": float(np.degrees(wrap(np.array(yaws) - ty).min())),
           "candidates": int(len(cy)), "right": int(right.sum())}
    if right.any():
        out["right_rank"] = int((total > total[right].max()).sum())
    at = dyaw <= math.radians(5)
    if at.any():
        ang = np.degrees(wrap(np.arctan2(ct[at, 0], ct[at, 2]) - math.atan2(tx, tz)))
        out["dir_deg"] = float(ang.min())
        out["ratios"] = sorted(round(float(r), 2) for r in
                               np.hypot(ct[at, 0], ct[at, 2])[ang < 10] / base)[:5]
    out["reason"] = ("refine" if right.any() and out["right_rank"] == 0 else
                     f"outscored({out['right_rank']})" if right.any() else
                     "no-yaw" if out["yaw_cand_deg"] > 5 else
                     "no-dir" if out.get("dir_deg", 180) > 10 else "scale")
    return out


def _traced(methods):
    """Run ``motion_photos`` keeping the ``findme`` Registration (its ``trace``)."""
    from findme_core.motion import methods as motion
    seen = []
    real = motion.Registration

    class Traced(real):
        def __init__(self, *a, **k):
            super().__init__(*a, **k)
            seen.append(self)
    motion.Registration = Traced
    return seen, lambda: setattr(motion, "Registration", real)


def diagnose(job):
    split, pid, methods, params, why, gravity = job
    import cv2
    cv2.setNumThreads(1)
    pair, photos = pair_inputs(split / "pairs", split / "views", pid, gravity)
    g = pair["motion"]
    base = math.hypot(g["x_m"], g["z_m"])
    out = {"pair": pid, "baseline_m": base, "truth": g}
    try:
        pa, pb = (photo_of(i, c, h, 1, "findme", w, max_layouts=params.max_layouts,
                           gravity_sigma=pv.unsensed_sigma,
                           gravity_alternatives=pv.unsensed_alternatives)
                  for (i, c, h, pv), w in zip(photos, "AB"))
    except FindmeError as e:
        return {**out, "error": str(e)}
    seen, restore = _traced(methods) if why else ([], lambda: None)
    try:
        res = motion_photos(pa, pb, methods, params=params)
    finally:
        restore()
    from findme_core.motion import features
    m = features.match(pa.features, pb.features)
    a, b = bearings(pa.camera, m.ua), bearings(pb.camera, m.ub)
    t = np.array([g["x_m"], pair.get("out_of_plane", {}).get("dy_m", 0.0), g["z_m"]])
    ok = 0
    if len(m):
        pix = 1.0 / math.sqrt(pa.camera.fx * pb.camera.fx)
        r, front, _, far = _epipolar_terms(a, b, math.radians(g["yaw_deg"]),
                                           t / max(np.linalg.norm(t), 1e-9), pix)
        ok = int(((r < params.thr_px) & (front | far)).sum())
    views = [json.loads((split / "views" / f"{pair[w]}.json").read_text()) for w in "ab"]
    out.update(kp=[len(pa.features), len(pb.features)], matches=len(m), correct=ok,
               floor_frac=[v.get("floor_fraction") for v in views],
               sees_floor=[_sees_floor(pa), _sees_floor(pb)],
               orient=[None if p.orientation is None else round(p.orientation.support, 2)
                       for p in (pa, pb)])
    for meth, r in res.items():
        if isinstance(r, Exception):
            out[meth] = {"refused": str(r), "cause": "refused:" + _refusal_tag(str(r))}
            continue
        mo = r.motion
        et = math.hypot(mo.x - g["x_m"], mo.z - g["z_m"])
        ey = abs((math.degrees(mo.yaw) - g["yaw_deg"] + 180) % 360 - 180)
        succ = ey <= 5 and et <= 0.25 * base
        alt_ok = any(abs((math.degrees(x.yaw) - g["yaw_deg"] + 180) % 360 - 180) <= 5
                     and math.hypot(x.x - g["x_m"], x.z - g["z_m"]) <= 0.25 * base
                     for x in mo.alternatives)
        out[meth] = {"x_m": mo.x, "z_m": mo.z, "yaw_deg": math.degrees(mo.yaw), "err_t": et,
                     "err_yaw": ey, "success": succ, "inliers": mo.n_inliers,
                     "sigma_t": math.hypot(mo.sigma_x, mo.sigma_z),
                     "sigma_yaw": math.degrees(mo.sigma_yaw),
                     "alternatives": len(mo.alternatives), "alt_ok": alt_ok,
                     "cause": "ok" if succ else ("wrong-yaw" if ey > 5 else "wrong-t")}
    if why and "findme" in out:
        out["findme"]["why"] = _why(seen[0] if seen else None, g, base)
    lack = "".join(f" nofl{w}" for w, s in zip("AB", out["sees_floor"]) if not s)
    lack += f" {ok}ok" if ok < 10 else ""
    for meth in methods:
        if out[meth]["cause"] != "ok":
            out[meth]["cause"] += lack
    return out


def _within(ans, err, sigma) -> str:
    """How many answers lie within 2 of their own 1-sigmas (an honest sigma: ~95 %; the
    translation's sigma is the rms of its x and z sigmas, so ~98 % there)."""
    k = sum(d[err] <= 2.0 * d[sigma] for d in ans)
    return f"{k}/{len(ans)}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("split", type=Path)
    ap.add_argument("--subsets", default=",".join(SUBSETS))
    ap.add_argument("--methods", default="findme,features,paper")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", type=Path)
    ap.add_argument("--pred", type=Path)
    ap.add_argument("--quiet", action="store_true", help="summary lines only")
    ap.add_argument("--why", action="store_true",
                    help="what findme's registration weighed against the truth (module doc)")
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                    help="a MotionParams field (e.g. orientation_weight=20); repeatable")
    add_gravity_args(ap)
    a = ap.parse_args(argv)
    gravity = GravityInput.from_args(a)
    index = json.loads((a.split / "index.json").read_text())
    methods = tuple(a.methods.split(","))
    params = replace(MotionParams(), **{k: type(getattr(MotionParams(), k))(v) for k, v in
                                        (kv.split("=", 1) for kv in a.set)})
    rows = {}
    for subset in a.subsets.split(","):
        pids = index["subsets"][subset]["pairs"]
        jobs = [(a.split, p, methods, params, a.why, gravity) for p in pids]
        with ProcessPoolExecutor(a.jobs, mp_context=mp.get_context("spawn")) as ex:
            res = list(ex.map(diagnose, jobs))
        rows[subset] = res
        if not a.quiet:
            print(f"== {subset}")
            print(f"{'pair':26s} {'base':>5s} {'kp':>10s} {'mt':>4s} {'ok':>3s} {'fl':>4s}  "
                  + "  ".join(f"{m:>30s}" for m in methods))
        for r in res:
            if "error" in r:
                print(f"{r['pair']:26s} error {r['error']}")
                continue
            cells = []
            for m in methods:
                d = r[m]
                cells.append(f"{d['cause'][:30]:>30s}" if "refused" in d else
                             f"{d['err_t']:5.2f}m {d['err_yaw']:5.1f}d {d['cause'][:17]:>17s}")
            fl = "".join("F" if s else "-" for s in r["sees_floor"])
            w = r.get("findme", {}).get("why")
            if w is not None and r["findme"]["cause"] != "ok":
                cells.append(f"{w['reason']:>13s} yaw~{w.get('yaw_cand_deg', float('nan')):4.1f} "
                             f"dir~{w.get('dir_deg', float('nan')):5.1f} "
                             f"len/true {w.get('ratios', [])}")
            if not a.quiet:
                print(f"{r['pair']:26s} {r['baseline_m']:5.2f} {r['kp'][0]:4d}/{r['kp'][1]:<5d} "
                      f"{r['matches']:4d} {r['correct']:3d} {fl:>4s}  " + "  ".join(cells))
        for m in methods:
            ans = [r[m] for r in res if m in r and "refused" not in r[m]]
            et = [d["err_t"] for d in ans]
            ey = [d["err_yaw"] for d in ans]
            succ = sum(d["success"] for d in ans)
            print(f"  {subset:20s} {m:9s} answered {len(ans)}/{len(res)}  "
                  f"t med {np.median(et) if et else float('nan'):.3f} m  "
                  f"yaw med {np.median(ey) if ey else float('nan'):.2f} deg  "
                  f"success {succ}/{len(res)} = {succ / max(len(res), 1):.2f}  "
                  f"within 2 sigma: t {_within(ans, 'err_t', 'sigma_t')} "
                  f"yaw {_within(ans, 'err_yaw', 'sigma_yaw')}")
    if a.out:
        a.out.write_text(json.dumps(rows, indent=1, default=float))
    if a.pred:
        for i, m in enumerate(methods):
            pairs = {r["pair"]: {k: r[m][k] for k in ("x_m", "z_m", "yaw_deg")}
                     for res in rows.values() for r in res if m in r and "refused" not in r[m]}
            path = a.pred if i == 0 else a.pred.with_suffix(f".{m}.json")
            path.write_text(json.dumps({"pairs": pairs, "motion_method": m}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
