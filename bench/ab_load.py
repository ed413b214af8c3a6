"""Is a change faster in the deployment? ``bench_load.py`` runs of two code trees (or two
environments) alternated in pairs, in both orders, with the paired differences.

    python bench/ab_load.py --base REV [--pairs 4] [--scenario peak] [--env-b K=V ...]
    python bench/ab_load.py --env-b MALLOC_TRIM_THRESHOLD_=268435456   # same code, B's env
    (``--keep DIR`` keeps each run's ``bench_load --json`` as DIR/A0.json, B0.json, ...: the
    per-process breakdown of every run)

A is the code at ``--base`` (a temporary git worktree; default: this tree), B this tree.
Each run is the whole ``bench_load.py --scenario S`` of its tree, started in that tree and
with ``PYTHONPATH`` set to it so that the services ``findme up`` would start import it too,
and B's runs with ``--env-b`` added to their environment. Pairs alternate AB, BA, AB, ...: this
machine's speed drifts over minutes (the same code gave 9.5-14.4 posed/s in one morning),
so only differences within a pair, and their signs over several pairs, say anything.

Prints per run: posed/s, the share of the compute bound measured in that run, photos posed
per CPU second, photo -> pose p50 and p99, unaccounted; then per figure B - A per pair,
their mean, median and standard error, and how many pairs B won. Run on a quiet machine:
nothing else of yours.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(HERE))
from bench.common import EVAL_DIR  # noqa: E402
from bench.load_rig import cpu_seconds  # noqa: E402

FIGURES = ("posed_per_s", "share_of_bound", "posed_per_cpu_s", "pose_p50_s", "pose_p99_s")


def figures(result: dict) -> dict:
    """The comparable figures of one ``bench_load --json`` result (its first run)."""
    r = result["runs"][0]
    cpu_s = cpu_seconds(r)
    bound = result.get("bound")
    return {"posed_per_s": r["posed_per_s"],
            "share_of_bound": r["posed_per_s"] / bound["photos_per_s"] if bound else None,
            "posed_per_cpu_s": r["delivered"] / max(cpu_s, 1e-9),
            "pose_p50_s": r["p50_ms"] / 1e3, "pose_p99_s": r["p99_ms"] / 1e3,
            "unaccounted": r["unaccounted"]}


def one_run(tree: Path, scenario: str, env: dict, out: Path) -> dict:
    """One ``bench_load`` run of ``tree``; its figures."""
    # both trees read the same photos: a worktree elsewhere would not find ../shared and
    # fall back to rendered ones, which cost twice as much
    e = {**os.environ, "FINDME_EVAL_DIR": str(EVAL_DIR), **env, "PYTHONPATH": str(tree)}
    # run IN the tree: the services are started as ``python -m findme.cli``, which puts the
    # working directory first on the import path, before PYTHONPATH (run from B's tree,
    # A's runs served B's code: two A/Bs of 2026-11-29 compared B with itself)
    r = subprocess.run([sys.executable, str(tree / "bench" / "bench_load.py"), "--scenario",
                        scenario, "--json", str(out)], env=e, check=True, text=True,
                       cwd=str(tree), stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
    first = r.stdout.splitlines()[0] if r.stdout else ""
    return {**figures(json.loads(out.read_text())), "photos": first.split(",")[0]}


def paired(a: list[dict], b: list[dict]) -> list[str]:
    """Lines: per figure, B - A of each pair, mean, median, standard error, B's wins."""
    out = []
    for k in FIGURES:
        d = [y[k] - x[k] for x, y in zip(a, b) if x[k] is not None and y[k] is not None]
        if not d:
            continue
        se = statistics.stdev(d) / len(d) ** 0.5 if len(d) > 1 else float("nan")
        out.append(f"{k:16s} B - A per pair: {' '.join(f'{v:+.3f}' for v in d)}   mean "
                   f"{statistics.fmean(d):+.3f} (standard error {se:.3f}), median "
                   f"{statistics.median(d):+.3f}; B higher in {sum(v > 0 for v in d)} of {len(d)}")
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--base", help="A: this git revision (default: this tree, for --env-b)")
    ap.add_argument("--pairs", type=int, default=4)
    ap.add_argument("--scenario", default="peak", choices=("peak", "steady", "gateway"))
    ap.add_argument("--env-b", nargs="*", default=[], metavar="K=V",
                    help="environment variables of B's runs only")
    ap.add_argument("--keep", metavar="DIR", type=Path,
                    help="keep each run's bench_load --json here (A0.json, B0.json, ...)")
    a = ap.parse_args(argv)
    env_b = dict(kv.split("=", 1) for kv in a.env_b)
    if not a.base and not env_b:
        ap.error("nothing to compare: give --base REV, --env-b K=V, or both")
    if a.keep:
        a.keep.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="ab-load-") as tmp:
        base = HERE
        if a.base:
            base = Path(tmp) / "base"
            subprocess.run(["git", "-C", str(HERE), "worktree", "add", "--detach", str(base),
                            a.base], check=True, capture_output=True)
        try:
            runs: dict = {"A": [], "B": []}
            for i in range(a.pairs):
                order = ("A", "B") if i % 2 == 0 else ("B", "A")
                for side in order:
                    tree, env = (base, {}) if side == "A" else (HERE, env_b)
                    out = (a.keep or Path(tmp)) / f"{side}{i}.json"
                    f = one_run(tree, a.scenario, env, out)
                    runs[side].append(f)
                    share = ("-" if f["share_of_bound"] is None
                             else f"{100 * f['share_of_bound']:.0f} %")
                    print(f"pair {i + 1} {side}: posed {f['posed_per_s']:.1f}/s, {share} of "
                          f"the bound, {f['posed_per_cpu_s']:.2f} posed per CPU s, "
                          f"photo -> pose p50 / p99 {f['pose_p50_s']:.1f} / "
                          f"{f['pose_p99_s']:.1f} s, {f['unaccounted']} unaccounted", flush=True)
        finally:
            if a.base:
                subprocess.run(["git", "-C", str(HERE), "worktree", "remove", "--force",
                                str(base)], check=False, capture_output=True)
    pools = {f["photos"] for side in runs.values() for f in side}
    if len(pools) > 1:
        print(f"NOT COMPARABLE: the runs sent different photos ({'; '.join(sorted(pools))})")
    print(f"A: {a.base or 'this tree'}; B: this tree; photos: {'; '.join(sorted(pools))}"
          + (f" with {' '.join(a.env_b)}" if env_b else ""))
    print("\n".join(paired(runs["A"], runs["B"])))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
