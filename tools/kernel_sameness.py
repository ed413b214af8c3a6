"""Same answers on every machine: ``findme eval`` of the dev split run in subprocesses under
two (or more) numeric environments (OpenBLAS kernels, numpy's SIMD dispatch), and the
prediction files compared beyond the tolerances of ``findme regress``.

    python tools/kernel_sameness.py                       # whole dev split, Haswell vs SkylakeX
    python tools/kernel_sameness.py --sample 40           # ~40 views, ~20 pairs, no room
    python tools/kernel_sameness.py --env OPENBLAS_CORETYPE=SkylakeX \\
        --env "NPY_DISABLE_CPU_FEATURES=AVX512F AVX512CD AVX512_SKX AVX512_CLX AVX512_CNL X86_V4"
    python tools/kernel_sameness.py --sample 60 --gravity refine   # gravity as the services
    python tools/kernel_sameness.py --compare A.json B.json   # two prediction files

Each ``--env`` is one run (``NAME=VALUE``, several joined by ``;``); the first run is the
reference the others are compared with. Counted, with the ids that differ:

* top-1: the best hypothesis of a view differs by more than ``--px`` (1 px) anywhere on the
  polyline (symmetric distance between the two polylines), or one run has none;
* any hypothesis: some hypothesis of the view differs so (or their number differs);
* top-1 / any hypothesis vertices: the same, vertex by vertex as ``findme regress`` compares
  polylines (a vertex's number or position beyond 1 px: a zero-length segment counts);
* points: a query pixel's 3D point moves more than 1 mm (or gets / loses an answer);
* motions: a pair's motion (x, z beyond 1 mm, yaw beyond 0.01 deg) or whether it has one;
* rooms: a room plan's walls (ends, lengths), poses (1 mm, 0.01 deg) or area (beyond
  1 mm x its perimeter) or its discrete content (closed, wall count, notes) differ.

Exit status 1 when any count is not 0. Writes nothing into the repository (``--keep DIR``
keeps the prediction files). ``--sample N`` builds a thinned copy of the dataset's index
(evenly spaced ids of every subset) in a temporary directory, linking the data.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(os.environ.get("FINDME_EVAL_DIR", ROOT.parent / "shared" / "data" / "findme-eval"))
ENVS = ("OPENBLAS_CORETYPE=Haswell", "OPENBLAS_CORETYPE=SkylakeX")
TOL_M = 1e-3
TOL_DEG = 0.01


# ----------------------------------------------------------------------------- polylines
def _samples(poly: np.ndarray, step: float = 0.5, cap: int = 4000) -> np.ndarray:
    """Points along a polyline every ``step`` px (at most ``cap`` per segment), vertices
    included."""
    out = [poly[:1]]
    for a, b in zip(poly[:-1], poly[1:]):
        n = int(min(cap, max(1, math.ceil(np.hypot(*(b - a)) / step))))
        t = np.arange(1, n + 1)[:, None] / n
        out.append(a + t * (b - a))
    return np.vstack(out)


def _to_polyline(p: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """(P,) distance of points ``p`` to the polyline's segments."""
    a, b = poly[:-1], poly[1:]
    ab = b - a
    L2 = np.maximum((ab * ab).sum(1), 1e-18)
    best = np.full(len(p), np.inf)
    for i in range(0, len(p), 2048):
        q = p[i:i + 2048, None, :]
        t = np.clip(((q - a) * ab).sum(2) / L2, 0.0, 1.0)
        d = np.hypot(*(q - (a + t[..., None] * ab)).transpose(2, 0, 1)).min(1)
        best[i:i + 2048] = d
    return best


def polyline_distance(pa, pb) -> float:
    """Symmetric largest distance (px) between two polylines (Hausdorff over their
    segments); 0 for two identical ones, inf when only one is given."""
    if pa is None or pb is None:
        return 0.0 if pa is None and pb is None else math.inf
    A, B = np.asarray(pa, float), np.asarray(pb, float)
    if len(A) < 2 or len(B) < 2:
        return 0.0 if np.array_equal(A, B) else math.inf
    return float(max(_to_polyline(_samples(A), B).max(), _to_polyline(_samples(B), A).max()))


# ------------------------------------------------------------------------------ compare
def _point_moved(a, b) -> bool:
    if (a is None) != (b is None):
        return True
    return a is not None and math.dist(a, b) > TOL_M


def vertices_differ(pa, pb, px: float) -> bool:
    """Vertex by vertex, as ``findme regress`` compares them: their number differs or a
    vertex moved more than ``px``."""
    if pa is None or pb is None:
        return (pa is None) != (pb is None)
    return len(pa) != len(pb) or any(math.dist(a, b) > px for a, b in zip(pa, pb))


def compare_views(A: dict, B: dict, px: float) -> dict[str, list[str]]:
    out = {"top-1": [], "any hypothesis": [], "top-1 vertices": [],
           "any hypothesis vertices": [], "points": []}
    for vid in sorted(A.keys() | B.keys()):
        a, b = A.get(vid), B.get(vid)
        if a is None or b is None:
            for k in out:
                out[k].append(f"{vid} (answered in one run only)")
            continue
        ha, hb = a.get("hypotheses", []), b.get("hypotheses", [])
        d = [polyline_distance(x, y) for x, y in zip(ha, hb)]
        top = polyline_distance(ha[0] if ha else None, hb[0] if hb else None)
        if top > px:
            out["top-1"].append(f"{vid} ({top:.1f} px)")
        if len(ha) != len(hb) or any(x > px for x in d):
            worst = max(d, default=0.0)
            first = next((i for i, x in enumerate(d) if x > px), None)
            out["any hypothesis"].append(
                f"{vid} (" + (f"{len(ha)} vs {len(hb)} hypotheses" if len(ha) != len(hb) else
                              f"rank {first + 1} first, up to {worst:.1f} px") + ")")
        if vertices_differ(ha[0] if ha else None, hb[0] if hb else None, px):
            out["top-1 vertices"].append(vid)
        if len(ha) != len(hb) or any(vertices_differ(x, y, px) for x, y in zip(ha, hb)):
            out["any hypothesis vertices"].append(vid)
        kinds = [k for k in a if k.endswith("_points") and not k.endswith("sigma_m")]
        moved = sum(_point_moved(x, y) for k in kinds
                    for x, y in zip(a.get(k) or [], b.get(k) or []))
        if moved or any(len(a.get(k) or []) != len(b.get(k) or []) for k in kinds):
            out["points"].append(f"{vid} ({moved} moved)")
    return out


def _motion_differs(a: dict, b: dict) -> str | None:
    dx = math.hypot(a["x_m"] - b["x_m"], a["z_m"] - b["z_m"])
    dy = abs((a["yaw_deg"] - b["yaw_deg"] + 180.0) % 360.0 - 180.0)
    if dx > TOL_M or dy > TOL_DEG:
        return f"{dx * 1e3:.1f} mm, {dy:.3f} deg"
    return None


def compare_pairs(A: dict, B: dict) -> list[str]:
    out = []
    for pid in sorted(A.keys() | B.keys()):
        a, b = A.get(pid), B.get(pid)
        if a is None or b is None:
            out.append(f"{pid} (a motion in one run only)")
            continue
        d = _motion_differs(a, b)
        if d:
            out.append(f"{pid} ({d})")
    return out


def _room_differs(a: dict, b: dict) -> str | None:
    for k in ("closed", "manhattan"):
        if a.get(k) != b.get(k):
            return f"{k} {a.get(k)} vs {b.get(k)}"
    wa, wb = a.get("walls", []), b.get("walls", [])
    if len(wa) != len(wb):
        return f"{len(wa)} vs {len(wb)} walls"
    for i, (x, y) in enumerate(zip(wa, wb)):
        if (math.dist(x["a"], y["a"]) > TOL_M or math.dist(x["b"], y["b"]) > TOL_M
                or abs(x["length_m"] - y["length_m"]) > TOL_M or x.get("seen") != y.get("seen")):
            return f"wall {i}"
    if len(a.get("missing_walls", [])) != len(b.get("missing_walls", [])):
        return "missing walls"
    perim = sum(w["length_m"] for w in wa) or 1.0
    if abs(a.get("area_m2", 0.0) - b.get("area_m2", 0.0)) > TOL_M * perim:
        return f"area {a.get('area_m2')} vs {b.get('area_m2')}"
    pa, pb = a.get("poses", {}), b.get("poses", {})
    if pa.keys() != pb.keys():
        return f"posed views {sorted(pa.keys() ^ pb.keys())}"
    for v in sorted(pa):
        if isinstance(pa[v], dict) and isinstance(pb[v], dict):
            d = _motion_differs(pa[v], pb[v])
            if d:
                return f"pose {v}: {d}"
        elif pa[v] != pb[v]:
            return f"pose {v}"
    if sorted(a.get("notes", {})) != sorted(b.get("notes", {})):
        return "notes"
    return None


def compare_rooms(A: dict, B: dict) -> list[str]:
    out = []
    for rid in sorted(A.keys() | B.keys()):
        a, b = A.get(rid), B.get(rid)
        d = "a plan in one run only" if a is None or b is None else _room_differs(a, b)
        if d:
            out.append(f"{rid} ({d})")
    return out


def compare(fa: Path, fb: Path, px: float = 1.0, show: int = 50) -> int:
    """Print the counts (and ids) of answers that differ; the number of differing answers."""
    A, B = json.loads(Path(fa).read_text()), json.loads(Path(fb).read_text())
    views = compare_views(A.get("views", {}), B.get("views", {}), px)
    rows = [(k, v, len(A.get("views", {}).keys() | B.get("views", {}).keys()), "views")
            for k, v in views.items()]
    rows.append(("motions", compare_pairs(A.get("pairs", {}), B.get("pairs", {})),
                 len(A.get("pairs", {}).keys() | B.get("pairs", {}).keys()), "pairs"))
    rows.append(("rooms", compare_rooms(A.get("rooms", {}), B.get("rooms", {})),
                 len(A.get("rooms", {}).keys() | B.get("rooms", {}).keys()), "rooms"))
    total = 0
    for name, ids, n, of in rows:
        print(f"  {name}: {len(ids)} of {n} {of} differ")
        for i in ids[:show]:
            print(f"    {i}")
        if len(ids) > show:
            print(f"    ... and {len(ids) - show} more")
        if name != "points":   # points follow the top-1 (counted there)
            total += len(ids)
    return total


# ------------------------------------------------------------------------------ running
def _thin(ids: list, k: int) -> list:
    ids = sorted(ids)
    if k >= len(ids):
        return ids
    return [ids[int(i * len(ids) / k)] for i in range(k)] if k > 0 else []


def sample_dataset(src: Path, dst: Path, n_views: int, n_rooms: int) -> Path:
    """A copy of ``src``'s index with about ``n_views`` views, ``n_views // 2`` pairs and
    ``n_rooms`` rooms (evenly spaced ids of every subset), its data linked."""
    index = json.loads((src / "index.json").read_text())
    all_views = {v for s in index["subsets"].values() if not s.get("rooms")
                 for v in s.get("views", [])}
    all_pairs = {p for s in index["subsets"].values() for p in s.get("pairs", [])}
    for s in index["subsets"].values():
        if s.get("rooms"):
            s["rooms"] = _thin(s["rooms"], n_rooms)
            s["views"] = []   # a room's views are its own; not sampled as single views
            continue
        s["views"] = _thin(s.get("views", []),
                           round(n_views * len(s.get("views", [])) / max(1, len(all_views))))
        s["pairs"] = _thin(s.get("pairs", []),
                           round(n_views / 2 * len(s.get("pairs", [])) / max(1, len(all_pairs))))
    dst.mkdir(parents=True, exist_ok=True)
    for d in ("views_dir", "pairs_dir", "rooms_dir"):
        name = index.get(d, d[:-4])
        if (src / name).exists() and not (dst / name).exists():
            (dst / name).symlink_to((src / name).resolve())
    (dst / "index.json").write_text(json.dumps(index))
    return dst


def _env(text: str) -> dict:
    out = {}
    for part in text.split(";"):
        if part.strip():
            k, _, v = part.partition("=")
            out[k.strip()] = v
    return out


def run_eval(dataset: Path, out: Path, env_text: str, jobs: int, extra=()) -> float:
    """``findme eval`` (with ``extra`` arguments) in a subprocess under ``env_text``; its CPU
    seconds."""
    env = {**os.environ, "PYTHONPATH": str(ROOT), **_env(env_text)}
    cmd = [sys.executable, "-m", "findme.cli", "eval", str(dataset), "--out", str(out),
           "--jobs", str(jobs), *extra]
    t0 = os.times()
    r = subprocess.run(cmd, env=env, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                       text=True)
    t1 = os.times()
    if r.returncode:
        raise SystemExit(f"findme eval under {env_text!r} failed:\n{r.stderr[-2000:]}")
    print(f"  {env_text}: {r.stdout.strip().splitlines()[-1]}", file=sys.stderr)
    return (t1.children_user + t1.children_system) - (t0.children_user + t0.children_system)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--dataset", type=Path, default=DATA)
    ap.add_argument("--sample", type=int, default=None, metavar="N",
                    help="about N views and N/2 pairs (default: the whole split)")
    ap.add_argument("--rooms", type=int, default=None, metavar="K",
                    help="rooms planned (default: all; 0 with --sample)")
    ap.add_argument("--env", action="append", default=None, metavar="NAME=VALUE[;...]")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--gravity", choices=("given", "refine", "none"), default="given",
                    help="the views' gravity as given (default), refined by the photo's lines "
                         "as the services refine a phone's (--gravity-refine), or withheld: "
                         "estimated from the photo (--no-gravity)")
    ap.add_argument("--px", type=float, default=1.0, help="polyline tolerance (1 px)")
    ap.add_argument("--keep", type=Path, help="keep the prediction files here")
    ap.add_argument("--compare", nargs=2, type=Path, metavar=("A.json", "B.json"))
    a = ap.parse_args(argv)
    if a.compare:
        print(f"{a.compare[0]} vs {a.compare[1]}:")
        return 1 if compare(*a.compare, a.px) else 0
    envs = a.env or list(ENVS)
    if len(envs) < 2:
        raise SystemExit("give at least two --env (or none)")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        dataset = a.dataset
        if a.sample is not None or a.rooms is not None:
            index = json.loads((a.dataset / "index.json").read_text())
            n_views = a.sample if a.sample is not None else len(
                {v for s in index["subsets"].values() if not s.get("rooms")
                 for v in s.get("views", [])})
            rooms = a.rooms if a.rooms is not None else (0 if a.sample is not None else 10**6)
            dataset = sample_dataset(a.dataset, tmp / "data", n_views, rooms)
        outdir = a.keep or tmp
        outdir.mkdir(parents=True, exist_ok=True)
        files = []
        for i, e in enumerate(envs):
            f = outdir / f"run{i}.json"
            t = time.monotonic()
            cpu = run_eval(dataset, f, e, a.jobs, {"given": (), "refine": ("--gravity-refine",),
                                                    "none": ("--no-gravity",)}[a.gravity])
            print(f"  run {i} ({e}): {time.monotonic() - t:.0f} s wall, {cpu:.0f} s CPU",
                  file=sys.stderr)
            files.append(f)
        differ = 0
        for i, f in enumerate(files[1:], 1):
            print(f"{envs[0]!r} vs {envs[i]!r}:")
            differ += compare(files[0], f, a.px)
    print("SAME" if not differ else f"DIFFER: {differ} answers")
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main())
