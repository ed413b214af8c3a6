"""Fit the hypothesis ranking weights (findme_core.single.ranking.RankWeights) on a labelled split.

    python tools/fit_ranker.py ../shared/data/findme-eval [--out weights.json] [--show]

For every view with a label map: run the generator with the search weights, keep every
re-ranked candidate's features and its floor pixel error (scored like shared/eval/score.py),
then fit the re-ranking weights w to minimise the expected top-1 error under the model's
softmax over each view's candidates (sum_c softmax(w . f / T)_c error_c), with an L2 pull
towards the starting weights. The search's own costs (ranking.SEARCH_WEIGHTS) are not
fitted: the candidate pool stays fixed, so there is no feedback loop. By default every fit
(in sample, and each held-out fold) is ``shipped_procedure``, the one behind
ranking.RANK_WEIGHTS: the smooth fit from the search's weights, then ``far`` from its grid.

Held-out accuracy is reported by leave-one-group-out cross-validation (ZInD: one room per
group; TUM: blocks of 6 frames), so the figures are not in-sample. Only the dev split is
ever used for fitting; the weights are hyper-parameters and carry no image data.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import sys
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")   # before numpy: the fit's sums in one order every run

import cv2  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
from findme_core.geometry import ties  # noqa: E402
from findme_core.single import hypotheses as H  # noqa: E402
from findme_core.single.ranking import FEATURES  # noqa: E402
from findme.evaluation.views import view_inputs  # noqa: E402

SUBSETS = ("zind-level", "zind-level-lowfloor", "zind-tilted", "zind-pairs-level",
           "zind-pairs-tilted", "tum-cabinet", "zind-rooms")


def group_of(vid: str) -> str:
    m = re.match(r"z\w+?_r(\d+)_", vid)
    if m:
        return "room" + m.group(1)
    m = re.match(r"tum_cab_(\d+)", vid)
    return f"tum{int(m.group(1)) // 6}" if m else vid


def pixel_errors(polys, labels):
    valid = (labels != 255) & ~((labels >= 100) & (labels < 200))
    gt = labels == 0
    H_, W_ = labels.shape
    n = valid.sum()
    rows = np.arange(H_, dtype=float)[:, None]
    out = []
    for poly in polys:
        a = np.asarray(poly, float)
        vp = np.interp(np.arange(W_, dtype=float), a[:, 0], a[:, 1])
        pred = rows >= vp[None, :] - 1e-6
        out.append(float(((pred != gt) & valid).sum()) / n)
    return np.array(out)


def candidates(job):
    view_dir, vid, w = job
    cv2.setNumThreads(1)
    meta = json.load(open(os.path.join(view_dir, vid + ".json")))
    cam, _, _ = view_inputs(meta)
    image = cv2.imread(os.path.join(view_dir, meta["image"]))
    labels = cv2.imread(os.path.join(view_dir, meta["labels"]), cv2.IMREAD_UNCHANGED)
    params = replace(H.HypothesisParams(), snap=False)
    dbg: dict = {}
    H.generate(image, cam, 10, params, debug=dbg)
    ranked = dbg.get("ranked") or []
    if not ranked:
        return vid, np.zeros((0, len(FEATURES))), np.zeros(0)
    # rounded to 1e-6: a view's scores move by ~1e-10 with the process's memory layout, and
    # the sharp softmax fit amplified that into weights (and held-out figures) that differed
    # from run to run (zind-rooms held out 2.56 / 4.17 / 4.22 % in three runs of one code)
    feats = np.round(np.array([r[3] for r in ranked]), 6)
    errs = pixel_errors(dbg["polylines"], labels)
    return vid, feats, errs


def exp(x: np.ndarray) -> np.ndarray:
    """e**x of float64 ``x`` by IEEE arithmetic alone (+, -, *, /, rint, ldexp: the same bits
    on every CPU, where numpy's own exp has an AVX-512 version that differs in the last bit):
    x = k ln 2 + r, |r| <= ln 2 / 2, e**r by its Taylor series to r**17 / 17! (relative error
    below 1e-15 where e**x is a normal number), times 2**k. Below -745 it is 0."""
    x = np.asarray(x, float)
    under = x < -745.0
    x = np.where(under, 0.0, x)
    k = np.rint(x / _LN2_HI)
    r = (x - k * _LN2_HI) - k * _LN2_LO
    term, total = np.ones_like(r), np.ones_like(r)
    for n in range(1, 18):
        term = term * r / n
        total = total + term
    return np.where(under, 0.0, np.ldexp(total, k.astype(int)))


#: ln 2 split so that k * _LN2_HI is exact for |k| < 2**11 (Cody and Waite's reduction)
_LN2_HI, _LN2_LO = 0.693145751953125, 1.42860682030941723212e-06


def fit(data, w0, free, temp=0.01, l2=0.02, iters=800, lr=0.05, cap=0.15):
    """Minimise mean expected top-1 error, sum_c softmax(w . f / temp)_c e_c, by Adam
    (weights not in ``free`` stay at w0); features are standardised for the optimiser."""
    F_all = np.concatenate([f for f, e in data if len(e)])
    mu, sd = F_all.mean(0), F_all.std(0) + 1e-9
    sd[~free] = 1.0
    mu[~free] = 0.0
    z0 = w0 * sd                      # weights in standardised units
    z = z0.copy()
    m = np.zeros_like(z)
    v = np.zeros_like(z)
    # errors above `cap` count as `cap`: hopeless views (no candidate near the truth) must not
    # dominate the fit
    fs = [((f - mu) / sd, np.minimum(e, cap)) for f, e in data if len(e) > 1]
    b1 = b2 = 1.0      # 0.9 ** it and 0.999 ** it by products: no libm pow
    for _ in range(iters):
        b1, b2 = b1 * 0.9, b2 * 0.999
        g = np.zeros_like(z)
        for f, e in fs:
            # products without BLAS (``ties``): the fit is chaotic (a softmax at temp 0.01
            # over 800 Adam steps), and BLAS kernels differ in the last bits between CPUs:
            # Haswell and SkylakeX kernels gave far -16 and -32 and rooms IoU 0.95 and 0.84
            # (2026-12-01) from the same candidates
            s = ties.matvec(f, z) / temp
            p = exp(s - s.max())
            p /= p.sum()
            g += ties.dot(f, (p * (e - ties.dot(p, e)))[:, None], axis=0) / temp
        g = g / len(fs) + l2 * (z - z0)
        g[~free] = 0
        m = 0.9 * m + 0.1 * g
        v = 0.999 * v + 0.001 * g * g
        z = z - lr * (m / (1 - b1)) / (np.sqrt(v / (1 - b2)) + 1e-8)
    return z / sd


def top1(data, w):
    return np.array([e[ties.argmax(ties.matvec(f, w))] if len(e) else 1.0 for f, e in data])


def grid_choice(data, w0, name, values, cap=0.15):
    """Weight ``name`` set to the value among ``values`` with the least mean top-1 error
    (errors capped at ``cap``), the other weights at w0. For a weight whose effect is a
    large jump (a prior that only acts on implausible candidates), where the smooth
    softmax objective of ``fit`` is flat."""
    i = FEATURES.index(name)
    best, best_err = None, np.inf
    for x in values:
        w = w0.copy()
        w[i] = x
        err = np.mean(np.minimum(top1(data, w), cap))
        if err < best_err - 1e-12:
            best, best_err = w, err
    return best


#: ``far``'s grid (``ranking.RANK_WEIGHTS``: chosen after the smooth fit, the others fixed).
FAR_GRID = (0.0, -4.0, -8.0, -12.0, -16.0, -24.0, -32.0)


def shipped_procedure(train, free):
    """The procedure behind ``ranking.RANK_WEIGHTS``, from scratch on ``train``: the smooth
    fit from the search's own weights (``fit``, pulled towards them), then ``far`` chosen
    from ``FAR_GRID`` with the other weights fixed (``grid_choice``: ``far`` acts only on
    implausible candidates, where the smooth fit is flat). A fold of the leave-one-group-out
    runs exactly this on the other groups."""
    from findme_core.single.ranking import SEARCH_WEIGHTS
    w = fit(train, SEARCH_WEIGHTS.vector(), free)
    return grid_choice(train, w, "far", FAR_GRID) if free[FEATURES.index("far")] else w


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dataset")
    ap.add_argument("--out")
    ap.add_argument("--show", action="store_true", help="print every view's held-out error")
    ap.add_argument("--free", metavar="NAME[,NAME...]",
                    help="fit only these weights (default: all but support), e.g. far")
    ap.add_argument("--loro-out", metavar="FOLDS.json",
                    help="write each leave-one-group-out fold's weights ({group: {name: w}}), "
                         "each by the shipped weights' own procedure (shipped_procedure: "
                         "the smooth fit from ranking.SEARCH_WEIGHTS, then far from its grid) "
                         "on the other groups: tools/loro_eval.py runs the pipeline on each "
                         "group with its fold's")
    ap.add_argument("--refit-out", metavar="FOLDS.json",
                    help="write the shipped procedure refitted on every group, as folds for "
                         "tools/loro_eval.py ({group: {name: w}}, every group the same): the "
                         "in-sample counterpart of --loro-out, whose gap to it is the held-out "
                         "loss and whose gap to the shipped weights is theirs")
    ap.add_argument("--grid", metavar="NAME=V1,V2,...",
                    help="instead of fitting, choose one weight from these values (e.g. "
                         "far=0,-4,-8,-12,-16,-24), each held-out fold choosing on its own")
    a = ap.parse_args(argv)
    index = json.load(open(os.path.join(a.dataset, "index.json")))
    view_dir = os.path.join(a.dataset, index.get("views_dir", "views"))
    subset_of = {}
    for s in SUBSETS:
        for vid in index["subsets"][s]["views"]:
            subset_of.setdefault(vid, s)
    vids = sorted(subset_of)
    from findme_core.single.ranking import RANK_WEIGHTS
    w = RANK_WEIGHTS.vector()
    names = set(a.free.split(",")) if a.free else set(FEATURES) - {"support"}
    unknown = names - set(FEATURES)
    if unknown:
        ap.error(f"unknown weight(s) {', '.join(sorted(unknown))}; choose among {', '.join(FEATURES)}")
    free = np.array([f in names for f in FEATURES])
    # the shipped weights' procedure; --free: a smooth fit of some weights from the current
    shipped = not (a.free or a.grid)
    fitter = fit if a.free else (lambda train, w0, free: shipped_procedure(train, free))
    if a.grid:
        name, _, vals = a.grid.partition("=")
        if name not in FEATURES or not vals:
            ap.error(f"--grid wants NAME=V1,V2,... with NAME among {', '.join(FEATURES)}")
        values = [float(x) for x in vals.split(",")]

        def fitter(train, w0, free):   # the grid replaces the smooth fit
            return grid_choice(train, w0, name, values)
    with ProcessPoolExecutor(os.cpu_count()) as ex:
        res = list(ex.map(candidates, [(view_dir, v, w) for v in vids], chunksize=4))
    data = {vid: (f, e) for vid, f, e in res}
    oracle = {vid: (e.min() if len(e) else 1.0) for vid, (f, e) in data.items()}
    groups = sorted({group_of(v) for v in vids})
    held, fold_w = {}, {}
    for g in groups:
        train = [data[v] for v in vids if group_of(v) != g]
        wg = fold_w[g] = fitter(train, w, free)
        if a.grid:
            print(f"  fold {g}: {name} = {wg[FEATURES.index(name)]:g}")
        for v in vids:
            if group_of(v) == g:
                held[v] = top1([data[v]], wg)[0]
    w_new = fitter([data[v] for v in vids], w, free)
    if a.loro_out:   # the held-out fits above when they were the shipped procedure
        folds = {g: dict(zip(FEATURES, (fold_w[g] if shipped else shipped_procedure(
            [data[v] for v in vids if group_of(v) != g], free)).tolist())) for g in groups}
        json.dump(folds, open(a.loro_out, "w"), indent=1)
        print("  folds (shipped_procedure, leave one group out), far per fold:",
              ", ".join(f"{g} {folds[g]['far']:g}" for g in groups))
    if a.refit_out:
        w_all = w_new if shipped else shipped_procedure([data[v] for v in vids], free)
        json.dump({g: dict(zip(FEATURES, w_all.tolist())) for g in groups},
                  open(a.refit_out, "w"), indent=1)
    print("top-1 median pixel error per subset "
          "(current weights | held-out fit | in-sample fit | best candidate)")
    for s in SUBSETS:
        vs = [v for v in vids if subset_of[v] == s]
        cur = np.median(top1([data[v] for v in vs], w))
        ho = np.median([held[v] for v in vs])
        ins = np.median(top1([data[v] for v in vs], w_new))
        orc = np.median([oracle[v] for v in vs])
        print(f"  {s:22s} {100 * cur:6.2f}% | {100 * ho:6.2f}% | {100 * ins:6.2f}% | {100 * orc:6.2f}%")
    print("  weights:", json.dumps(dict(zip(FEATURES, np.round(w_new, 5).tolist()))))
    w = w_new
    if a.show:
        for s in SUBSETS:
            vs = [v for v in vids if subset_of[v] == s]
            print(s, "held-out errors:", " ".join(f"{v}:{100 * held[v]:.1f}" for v in vs))
    if a.out:
        json.dump(dict(zip(FEATURES, w.tolist())), open(a.out, "w"), indent=1)


if __name__ == "__main__":
    main()
