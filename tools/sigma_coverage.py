"""Do the stated 1-sigmas hold? Coverage of every sigma a ``findme eval`` run states, per
quantity, in sample and leave-one-room-out.

    python tools/sigma_coverage.py DATASET_DIR PREDICTIONS.json [--json OUT.json] [--markdown]
        [--widened]

For each quantity the normalised error z = |error| / sigma of every answered item, and the
share within 1, 2 and 3 sigma (a Gaussian: 0.68 / 0.95 / 0.997; the goal: 0.60-0.80 within 1,
>= 0.97 within 3):

* floor / wall / non-floor points: the 3D distance to the truth over ``<kind>_sigma_m``;
* distances between two points of one photo (``distances``): |d - d_true| / sigma;
* gravity from the image (sources image / level / input+image): the pitch and roll errors,
  each over the per-axis 1-sigma (``gravity_sigma_deg``), on the views whose gravity the
  dataset measured (``gravity_measured``: not KITTI's nominal one);
* pair motion: x, z, yaw errors over ``sigma_x_m`` / ``sigma_z_m`` / ``sigma_yaw_deg``;
* rooms: wall lengths (walls seen and not seen apart; matched to the truth as the shared
  ``coverage.py`` does), photo poses on the plan (x, z over ``sigma_xz_m``, yaw), corners
  (x and z of the vertex nearest each scored true corner, as the shared scorer's corner
  error, over ``corner_sigma_m``).

Leave-one-room-out (``--loro``, the default): each sigma is scaled by one factor fitted on the
OTHER rooms (ZInD: one room per group; TUM: blocks of 6 frames; KITTI: one group) by the rule
the product's sigma constants are fitted by (``fit_factor`` / ``rule_key``: the coverage
within 1 and 3 sigma nearest the goal, 0.60-0.80 and >= 0.97, and among factors equally near
it, nearest a Gaussian's 0.68 and 0.99; ``calibrate_sigma``, ``calibrate_plan``), and the
left-out room is scored with it: the coverage a room never used for fitting gets. "in" is the
coverage as stated (in sample: the constants were fitted on these rooms).

The rule's history. Until 2026-11-30 the constants put 68 % within 1 sigma; that shrinks a
sigma until the wrong answers' tail lies beyond 3. Until 2026-12-02 (morning) this tool's
factor still did, and gave a left-out room shrunk sigmas no constant of the product has (ZInD
level pairs' yaw, gravity withheld: 0.83 / 1.00 / 1.00 in sample, 0.50 / 0.50 / 0.56 left
out). Until 2026-12-02 (afternoon) the rule was the coverage nearest a Gaussian's 0.68 and
0.99 alone: a 1-sigma share above 0.68 cost as much as one below it, so with a tail of wrong
answers it still traded the tail for the 1-sigma row (the boundary's 1-sigma: 13.2 px, 0.72
/ 0.87 within 1 / 3, against the shipped 34 px's 0.83 / 0.93). The goal allows 0.80 within 1,
and what it asks at 3 sigma is what a user relies on; the goal first gives 36.5 px. Left out, over
the three gravity modes, 21 rows gain 0.01-0.07 within 3 sigma and none loses (ZInD wall
points, the dataset's gravity, 0.76 / 0.84 -> 0.79 / 0.88 within 1 / 3); within 1 sigma TUM's
cabinet faces go to 0.82-0.85, over the goal's 0.80. Reads the dataset's ground truth:
a tool, not the product.

``--widened`` asks what one constant could do if the 3-sigma goal came first: each room
scored with the factor that puts at least 97 % of the OTHER rooms' items within 3 sigma (and
at least 68 % within 1), with how much wider that makes the sigma (the median factor of the
folds over the stated sigma's). Measured 2026-11-29 on the dev split (dataset's gravity):
within 3 sigma then reaches 0.94-0.97 for the point and distance rows, but within 1 sigma
becomes 0.89-0.96 (goal <= 0.80), and for ZInD wall points and every TUM row the sigmas
4.9-8.5x wider (wall points 7.1x, TUM non-floor points 8.5x). The
errors are two populations (right boundary: centimetres; wrong boundary: metres), which no
one Gaussian sigma describes: the goal needs the wrong boundaries told apart, not a constant.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
from collections import defaultdict

import numpy as np

POINT_KINDS = ("floor_points", "wall_points", "nonfloor_points")


def group_of(item_id: str) -> str:
    """The leave-one-out group of a view, pair or room id: its ZInD room, its TUM block of
    6 frames (a pair by its first frame), KITTI as one group."""
    m = re.search(r"_r(\d+)", item_id)
    if m and item_id.startswith("z"):
        return "room" + m.group(1)
    m = re.match(r"tum_cab_(\d+)", item_id)
    if m:
        return f"tum{int(m.group(1)) // 6}"
    if item_id.startswith("kitti"):
        return "kitti"
    return item_id


def gravity_measured(meta: dict) -> bool:
    """Whether a view's ``gravity_cam`` is a measurement the estimate can be scored against.
    The dataset marks the ones that are not: KITTI's is the nominal mounting ("gravity_note":
    "APPROXIMATION: camera assumed level ..."; its true per-frame pitch and roll are not in
    the files), so an estimate 2 deg off it may be right."""
    return not str(meta.get("gravity_note", "")).startswith("APPROXIMATION")


def wrap_deg(d):
    return (d + 180.0) % 360.0 - 180.0


def pitch_roll(g):
    g = np.asarray(g, float) / np.linalg.norm(g)
    return math.degrees(math.asin(float(np.clip(g[2], -1, 1)))), math.degrees(math.atan2(g[0], g[1]))


def _subsets(idx: dict) -> dict:
    """{view or pair id: the first subset of the dataset's index that lists it}."""
    subset_of = {}
    for name, ss in idx["subsets"].items():
        for v in ss.get("views", []):
            subset_of.setdefault(v, name)
        for p in ss.get("pairs", []):
            subset_of[p] = name
    return subset_of


def views(dataset: str, preds: dict):
    """(view id, its truth, its prediction, its family: tum, kitti or zind) of every predicted
    view the dataset has, by id."""
    idx = json.load(open(os.path.join(dataset, "index.json")))
    vdir = os.path.join(dataset, idx.get("views_dir", "views"))
    subset_of = _subsets(idx)
    for vid, p in sorted(preds.get("views", {}).items()):
        meta_path = os.path.join(vdir, vid + ".json")
        if not os.path.exists(meta_path):
            continue
        s = subset_of.get(vid, vid)
        yield (vid, json.load(open(meta_path)), p,
               "tum" if s.startswith("tum") else ("kitti" if s.startswith("kitti") else "zind"))


def point_errors(meta: dict, pred: dict, kind: str):
    """(index, |error| metres, stated sigma metres) of every answered point of ``kind``
    (floor_points, ...) of one view with a positive finite sigma."""
    xs, sigmas = pred.get(kind) or [], pred.get(kind + "_sigma_m") or []
    for i, (q, x, s) in enumerate(zip(meta.get(kind) or [], xs, sigmas)):
        if x is None or s is None or not math.isfinite(s) or s <= 0:
            continue
        yield i, float(np.linalg.norm(np.subtract(x, q["xyz_m"]))), s


def point_quantity(kind: str, query: dict, family: str) -> str:
    """The row a query point's coverage is counted in: its kind and family; TUM's non-floor
    points split by their surface, vertical (a cabinet's front: the product's wall model)
    or not (a cabinet's top: neither floor nor wall, which the product has no model for)."""
    name = kind.replace("_", " ")
    if kind == "nonfloor_points" and "vertical_surface" in query:
        name += ", vertical" if query["vertical_surface"] else ", not vertical"
    return f"{name} ({family})"


def collect(dataset: str, preds: dict) -> dict:
    """{quantity: [(group, |error|, stated sigma), ...]} of every stated sigma the
    predictions carry."""
    idx = json.load(open(os.path.join(dataset, "index.json")))
    out: dict = defaultdict(list)
    subset_of = _subsets(idx)
    for vid, meta, p, family in views(dataset, preds):
        g = group_of(vid)
        for k in POINT_KINDS:
            for i, err, s in point_errors(meta, p, k):
                out[point_quantity(k, meta[k][i], family)].append((g, err, s))
        for d in p.get("distances") or []:
            i, j, ki, kj = d["a"], d["b"], d["kind_a"], d["kind_b"]
            pa, pb = (meta.get(ki) or [])[i], (meta.get(kj) or [])[j]
            if d.get("d_m") is None or not d.get("sigma_m"):
                continue
            true = float(np.linalg.norm(np.subtract(pa["xyz_m"], pb["xyz_m"])))
            out[f"distances ({family})"].append((g, abs(d["d_m"] - true), d["sigma_m"]))
        src = p.get("gravity_source")
        s = p.get("gravity_sigma_deg")
        if (src in ("image", "level", "input+image") and s and meta.get("gravity_cam")
                and gravity_measured(meta)):
            pp, rp = pitch_roll(p["gravity_cam"])
            pt, rt = pitch_roll(meta["gravity_cam"])
            out[f"gravity pitch ({src})"].append((g, abs(pp - pt), s))
            out[f"gravity roll ({src})"].append((g, abs(wrap_deg(rp - rt)), s))
    pdir = os.path.join(dataset, idx.get("pairs_dir", "pairs"))
    for pid, p in sorted(preds.get("pairs", {}).items()):
        path = os.path.join(pdir, pid + ".json")
        if not os.path.exists(path) or p.get("x_m") is None:
            continue
        m = json.load(open(path))
        t, sub = m["motion"], m.get("subset", subset_of.get(pid, "?"))
        g = group_of(pid)
        for ax, e, s in (("x", p["x_m"] - t["x_m"], p.get("sigma_x_m")),
                         ("z", p["z_m"] - t["z_m"], p.get("sigma_z_m")),
                         ("yaw", wrap_deg(p["yaw_deg"] - t["yaw_deg"]), p.get("sigma_yaw_deg"))):
            if s and math.isfinite(s) and s > 0:
                out[f"motion {ax} ({sub})"].append((g, abs(e), s))
    rdir = os.path.join(dataset, idx.get("rooms_dir", "rooms"))
    for rid, r in sorted((preds.get("rooms") or {}).items()):
        path = os.path.join(rdir, rid + ".json")
        if not os.path.exists(path) or not r:
            continue
        room = json.load(open(path))
        g = group_of(rid)
        for kind, e, s in _wall_errors(room, r):
            out[kind].append((g, e, s))
        for e, s in _corner_errors(room, r):
            out["plan corner x, z"].append((g, e, s))
        truth = {v: room["poses_planar"][i] if isinstance(room["poses_planar"], list)
                 else room["poses_planar"][v] for i, v in enumerate(room["views"])}
        for v, pose in (r.get("poses") or {}).items():
            t = truth.get(v)
            if pose is None or t is None or v == room["views"][0]:
                continue
            sxz, sy = pose.get("sigma_xz_m"), pose.get("sigma_yaw_deg")
            if sxz:
                out["plan pose x, z"].append((g, abs(pose["x_m"] - t["x_m"]), sxz))
                out["plan pose x, z"].append((g, abs(pose["z_m"] - t["z_m"]), sxz))
            if sy:
                out["plan pose yaw"].append((g, abs(wrap_deg(pose["yaw_deg"] - t["yaw_deg"])), sy))
    return out


def _corner_errors(room: dict, pr: dict):
    """(|error|, sigma) along x and along z of the predicted vertex nearest each scored true
    corner (as the shared scorer's corner error), where that vertex has a 1-sigma (a corner
    of a wall nobody saw has none: inferred)."""
    poly = np.asarray(pr.get("floor_polygon_m") or [], float).reshape(-1, 2)
    sig = pr.get("corner_sigma_m") or []
    if len(poly) == 0 or len(sig) != len(poly):
        return
    truth = np.asarray(room["floor_polygon_m"], float)
    scored = room.get("corners_scored") or [True] * len(truth)
    for c in truth[np.asarray(scored, bool)]:
        j = int(np.argmin(np.linalg.norm(poly - c[None], axis=1)))
        if sig[j] is not None:
            for ax in (0, 1):
                yield abs(float(poly[j, ax] - c[ax])), float(sig[j][ax])


def _wall_errors(room: dict, pr: dict):
    """(kind, |length error|, sigma) of every predicted wall with a sigma matched to a true wall (direction within
    20 deg, overlapping, mean offset <= 0.3 m; the nearest), as shared/eval/coverage.py."""
    truth = [w for w in room.get("walls", []) if w.get("scored", True)]
    for w in pr.get("walls", []):
        s = w.get("sigma_m")
        if s is None or not math.isfinite(s) or s <= 0:
            continue
        a, b = np.asarray(w["a"], float), np.asarray(w["b"], float)
        e = b - a
        Lp = float(np.linalg.norm(e))
        if Lp < 1e-6:
            continue
        nrm = np.array([-e[1], e[0]]) / Lp
        best = None
        for t in truth:
            ta, tb = np.asarray(t["a"], float), np.asarray(t["b"], float)
            d = tb - ta
            L = float(np.linalg.norm(d))
            u = d / L
            if math.degrees(math.acos(min(1.0, abs(float(u @ e)) / Lp))) > 20:
                continue
            tp, tq = sorted((float((a - ta) @ u), float((b - ta) @ u)))
            if min(tq, L) - max(tp, 0.0) <= 0:
                continue
            samples = ta[None] + np.linspace(0, 1, 11)[:, None] * d[None]
            off = float(np.mean(np.abs((samples - a) @ nrm)))
            if off <= 0.3 and (best is None or off < best[0]):
                best = (off, L)
        if best is not None:
            kind = "wall length (seen)" if w.get("seen", True) else "wall length (not seen)"
            yield kind, abs(Lp - best[1]), s


def coverage(z: np.ndarray) -> tuple[float, float, float]:
    return tuple(float(np.mean(z <= k)) for k in (1.0, 2.0, 3.0))


def _left_out(items: list, factor) -> tuple[np.ndarray, list[float]]:
    """z = |error| / sigma of every item, its sigma scaled by ``factor(z of the other
    groups' items)`` (1 when they are fewer than 5); and each group's factor."""
    groups = np.array([i[0] for i in items])
    z = np.array([i[1] / i[2] for i in items], float)
    out, factors = np.empty_like(z), []
    for g in np.unique(groups):
        held = groups == g
        train = z[~held]
        c = factor(train) if len(train) >= 5 else 1.0
        out[held] = z[held] / max(c, 1e-9)
        factors.append(c)
    return out, factors


def widened(items: list) -> tuple[np.ndarray, float]:
    """z of every item under the factor fitted on the other groups so that >= 97 % of
    their items lie within 3 sigma and >= 68 % within 1 (``--widened``), and the median
    factor of the folds."""
    z, factors = _left_out(items, lambda t: max(float(np.quantile(t, 0.68)),
                                                float(np.quantile(t, 0.97)) / 3.0))
    return z, float(np.median(factors))


def loro(items: list) -> np.ndarray:
    """z of every item with its sigma scaled by the factor fitted on the other groups by the
    rule the product's constants are fitted by (``fit_factor``: coverage nearest the goal,
    then a Gaussian's): what a constant fitted without the item's room gives it."""
    return _left_out(items, lambda t: fit_factor(lambda k: t / k, SCALES)[1])[0]


#: the scale grid of ``fit_model`` and a Gaussian's coverage within 1 and 3 sigma (the
#: tie-break of ``rule_key``)
SCALES = np.exp(np.linspace(np.log(0.3), np.log(30.0), 93))
TARGET = (0.68, 0.99)
#: the goal every stated sigma is held to: within 1 sigma in this band, within 3 at least this
GOAL = ((0.60, 0.80), 0.97)


#: a floor term must improve the fit's loss by this much to be kept (fewer parameters)
FLOOR_GAIN = 0.005


def target_loss(z: np.ndarray) -> float:
    """How far the coverage of the normalised errors ``z`` within 1 and 3 sigma is from
    ``TARGET`` (squares; more than ``TARGET[1]`` within 3 costs nothing)."""
    c1, c3 = float(np.mean(z <= 1)), float(np.mean(z <= 3))
    return (c1 - TARGET[0]) ** 2 + (min(c3, TARGET[1]) - TARGET[1]) ** 2


def goal_gap(c1: float, c3: float) -> float:
    """How far the shares ``c1`` within 1 sigma and ``c3`` within 3 are from ``GOAL``
    (squares of the shortfalls; 0 anywhere inside it)."""
    (lo, hi), least3 = GOAL
    return max(lo - c1, c1 - hi, 0.0) ** 2 + max(least3 - c3, 0.0) ** 2


def goal_loss(z: np.ndarray) -> float:
    """``goal_gap`` of the normalised errors ``z``' coverage within 1 and 3 sigma."""
    return goal_gap(float(np.mean(z <= 1)), float(np.mean(z <= 3)))


def rule_key(z: np.ndarray) -> tuple[float, float]:
    """The rule every sigma constant is chosen by, as a key to compare (smaller is better):
    ``goal_loss`` first, then, among values equally far from the goal (inside it, mostly),
    ``target_loss``, the one nearest a Gaussian."""
    return goal_loss(z), target_loss(z)


def improves(new: tuple[float, float], old: tuple[float, float], by: float = 1e-12) -> bool:
    """Whether ``rule_key`` ``new`` beats ``old`` by more than ``by``: in the goal's loss, or
    at the same goal loss (to 1e-12) in the Gaussian's."""
    if abs(new[0] - old[0]) > 1e-12:
        return new[0] < old[0] - by
    return new[1] < old[1] - by


def fit_factor(z_of, grid) -> tuple[tuple[float, float], float]:
    """(key, k): the k of ``grid`` (ascending) whose ``z_of(k)`` has the least ``rule_key``;
    ties: the smaller k."""
    best, arg = (np.inf, np.inf), float(grid[0])
    for k in grid:
        key = rule_key(z_of(float(k)))
        if improves(key, best):
            best, arg = key, float(k)
    return best, arg


def fit_model(err: np.ndarray, sig: np.ndarray) -> tuple[float, float]:
    """(k, f): the sigma model hypot(k * stated, f) of least ``rule_key`` (a grid over k;
    f from the errors' quantiles). f = 0 unless a floor improves the key by ``FLOOR_GAIN``.
    Ties: the smaller k, then the smaller f."""
    def best_k(f):
        return fit_factor(lambda k: err / np.hypot(k * sig, f), SCALES)
    best, k0 = best_k(0.0)
    arg, gain = (k0, 0.0), FLOOR_GAIN
    for f in np.unique(np.quantile(err, [0.1, 0.25, 0.4, 0.55, 0.7])):
        key, k = best_k(float(f))
        if f > 0 and improves(key, best, gain):
            best, arg, gain = key, (k, float(f)), 1e-12
    return arg


def leave_group_out(groups: np.ndarray, fit, score) -> tuple[dict, np.ndarray]:
    """Leave one group out: for each group (sorted), ``params = fit(others)`` on the mask of
    the other groups' items, then ``score(params, held)``, an array (..., n held) over its
    own items. Returns ({group: params}, the scores of every item, (..., N) in item order)."""
    folds, out = {}, None
    for g in np.unique(groups):
        held = groups == g
        folds[str(g)] = params = fit(~held)
        s = np.asarray(score(params, held), float)
        if out is None:
            out = np.empty(s.shape[:-1] + (len(groups),))
        out[..., held] = s
    return folds, out


def loro_model(items: list) -> tuple[np.ndarray, dict]:
    """z of every item under the (k, f) model fitted on the other groups; and the (k, f)
    of each group's fold."""
    groups = np.array([i[0] for i in items])
    err = np.array([i[1] for i in items], float)
    sig = np.array([i[2] for i in items], float)
    folds, out = leave_group_out(
        groups, lambda m: fit_model(err[m], sig[m]) if m.sum() >= 5 else (1.0, 0.0),
        lambda kf, held: err[held] / np.hypot(kf[0] * sig[held], kf[1]))
    return out, folds


def table(res: dict, markdown: bool = False) -> str:
    rows = []
    head = ("| quantity | n | groups | in sample: within 1 / 2 / 3 sigma | leave-one-room-out: "
            "within 1 / 2 / 3 sigma | goal |")
    if markdown:
        rows += [head, "|---|---|---|---|---|---|"]
    for k in sorted(res):
        r = res[k]
        ok = (0.60 <= r["loro"][0] <= 0.80 and r["loro"][2] >= 0.97) if r["n"] >= 10 else None
        mark = "–" if ok is None else ("met" if ok else "short")
        cells = (k, str(r["n"]), str(r["groups"]), " / ".join(f"{c:.2f}" for c in r["in"]),
                 " / ".join(f"{c:.2f}" for c in r["loro"]), mark)
        rows.append("| " + " | ".join(cells) + " |" if markdown else
                    f"{cells[0]:34s} {cells[1]:>5s} {cells[2]:>3s}  in {cells[3]}   loro "
                    f"{cells[4]}   {mark}")
    return "\n".join(rows)


def report(dataset: str, preds: dict) -> dict:
    """{quantity: coverage figures} of the predictions' items (``collect``, ``summarise``)."""
    return summarise(collect(dataset, preds))


def summarise(collected: dict) -> dict:
    """{quantity: coverage figures} of ``collect``'s {quantity: items}."""
    res = {}
    for k, items in collected.items():
        z = np.array([i[1] / i[2] for i in items], float)
        err = np.array([i[1] for i in items], float)
        sig = np.array([i[2] for i in items], float)
        model = fit_model(err, sig)
        zl, folds = loro_model(items)
        res[k] = {"n": len(z), "groups": len({i[0] for i in items}), "in": coverage(z),
                  "loro": coverage(loro(items)), "model": model,
                  "model_in": coverage(err / np.hypot(model[0] * sig, model[1])),
                  "model_loro": coverage(zl), "folds": folds}
    return res


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dataset")
    ap.add_argument("predictions")
    ap.add_argument("--json", metavar="OUT.json")
    ap.add_argument("--markdown", action="store_true")
    ap.add_argument("--widened", action="store_true",
                    help="also: a constant chosen for >= 97 %% within 3 sigma, left out")
    a = ap.parse_args(argv)
    collected = collect(a.dataset, json.load(open(a.predictions)))
    res = summarise(collected)
    print(table(res, a.markdown))
    if a.widened:
        print("\na constant chosen for >= 97 % within 3 sigma on the other rooms, left out:")
        for k, items in sorted(collected.items()):
            if len(items) >= 10:
                z, f = widened(items)
                c = coverage(z)
                print(f"{k:34s} {len(z):5d}  within 1 / 2 / 3 sigma {c[0]:.2f} / {c[1]:.2f} / "
                      f"{c[2]:.2f}   sigma x {f:.2f}")
    if a.json:
        json.dump(res, open(a.json, "w"), indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
