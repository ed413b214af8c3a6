"""Where two numeric environments first part: every ``findme_core`` function's return value
traced while one view, pair, room or golden frame runs, under each environment, and the two
traces compared call by call. The first call whose discrete content (shapes, integers,
booleans, text, list lengths) differs, or whose floats differ by more than ``--rtol``, is the
innermost function that made (or returned) the diverging decision; read it, and the lines
between its callees' returns.

    python tools/kernel_trace.py view zr_r01_p0_v3            # Haswell vs SkylakeX
    python tools/kernel_trace.py pair ID | room ID | golden synth-box-user
    python tools/kernel_trace.py view ID --env OPENBLAS_CORETYPE=Haswell \\
        --env "NPY_DISABLE_CPU_FEATURES=AVX512F AVX512CD AVX512_SKX AVX512_CLX AVX512_CNL X86_V4"

Each ``--env`` is one run's environment (``NAME=VALUE``, several joined by ``;``); the default
compares ``OPENBLAS_CORETYPE=Haswell`` with ``SkylakeX``. A development tool: it runs the code
under ``sys.setprofile`` (slow: a view takes about ten times as long).
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import os
import pickle
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(os.environ.get("FINDME_EVAL_DIR", ROOT.parent / "shared" / "data" / "findme-eval"))
MAX_ELEMS = 200_000
CLOCKS = {"timing_ms"}   # fields that hold times, not answers


def _summary(v, depth=0):
    """A picklable picture of a value: floats kept as floats, the rest as discrete content."""
    import numpy as np
    if depth > 4:
        return ("deep", type(v).__name__)
    if isinstance(v, np.ndarray):
        if v.dtype.kind in "fc":
            if v.size > MAX_ELEMS:
                return ("bigf", v.shape, float(np.nansum(np.abs(v))))
            return ("f", v.shape, v.copy())
        if v.size > MAX_ELEMS:
            return ("bigd", v.shape, v.dtype.str, hashlib.sha1(v.tobytes()).hexdigest())
        return ("d", v.shape, v.dtype.str, v.tobytes())
    if isinstance(v, (bool, np.bool_)):
        return ("d", bool(v))
    if isinstance(v, (float, np.floating)):
        return ("f", (), np.array(float(v)))
    if isinstance(v, (int, np.integer, str, bytes, type(None))):
        return ("d", v if not isinstance(v, np.integer) else int(v))
    if isinstance(v, (list, tuple)):
        return ("seq", len(v), [_summary(x, depth + 1) for x in list(v)[:500]])
    if isinstance(v, dict):
        return ("map", sorted(map(str, v)), [_summary(v[k], depth + 1) for k in list(v)[:200]])
    if dataclasses.is_dataclass(v) and not isinstance(v, type):
        return ("obj", type(v).__name__,
                [_summary(getattr(v, f.name), depth + 1) if f.name not in CLOCKS else
                 ("d", "clock") for f in dataclasses.fields(v)])
    return ("type", type(v).__name__)


def _diff(a, b, path=""):
    """(discrete difference or None, largest relative float difference)."""
    import numpy as np
    if a[0] != b[0]:
        return f"{path}: {a[0]} vs {b[0]}", 0.0
    k = a[0]
    if k == "f":
        if a[1] != b[1]:
            return f"{path}: shape {a[1]} vs {b[1]}", 0.0
        x, y = a[2], b[2]
        fin = np.isfinite(x) & np.isfinite(y)
        if not np.array_equal(fin, np.isfinite(y)) or not np.array_equal(np.isfinite(x), fin):
            return f"{path}: finite pattern differs", 0.0
        if not fin.any():
            return None, 0.0
        d = np.abs(x[fin] - y[fin]) / np.maximum(1.0, np.abs(x[fin]))
        return None, float(d.max())
    if k in ("seq", "map", "obj"):
        if a[1] != b[1]:
            return f"{path}: {a[1] if k != 'seq' else 'length ' + str(a[1])} vs " \
                   f"{b[1] if k != 'seq' else b[1]}", 0.0
        worst = 0.0
        for i, (x, y) in enumerate(zip(a[2], b[2])):
            d, r = _diff(x, y, f"{path}[{i}]")
            if d:
                return d, worst
            worst = max(worst, r)
        return None, worst
    if k == "bigf":
        return (None if a[1] == b[1] else f"{path}: shape"), \
            abs(a[2] - b[2]) / max(1.0, abs(a[2]))
    return (None if a == b else f"{path}: {str(a)[:120]} vs {str(b)[:120]}"), 0.0


def _target(kind: str, ident: str):
    sys.path.insert(0, str(ROOT))
    if kind == "view":
        from findme.evaluation.views import predict_view
        return lambda: predict_view((str(DATA / "views"), ident, "findme", 10, True))
    if kind == "pair":
        from findme.evaluation.pairs import predict_pair
        return lambda: predict_pair((str(DATA / "pairs"), str(DATA / "views"), ident, "findme",
                                     ["findme"], True))
    if kind == "room":
        from findme.evaluation.rooms import room_job
        return lambda: room_job((str(DATA / "rooms"), str(DATA / "views"), ident, "ids"))
    if kind == "golden":
        import schemas
        from services.pipeline.hypotheses import HypothesesHandler
        from services.recording.mcap_reader import read_recording
        from services.runtime import bus
        recs = [r for r in read_recording(ROOT / "recordings" / "golden" / f"{ident}.mcap")
                if bus.parse_key(r.key).kind == "frame"]
        h = HypothesesHandler()

        def run():
            out = []
            for r in recs:
                try:
                    out += [o.msg for o in h.on_message(r.key, schemas.decode(
                        schemas.Frame, r.payload, check=False))]
                except Exception as e:  # noqa: BLE001 - a corrupt golden frame
                    out.append(repr(e))
            return out
        return run
    raise SystemExit(f"unknown target kind {kind!r}")


def record(kind: str, ident: str, out: str) -> None:
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    run = _target(kind, ident)
    core = str(ROOT / "findme_core") + os.sep
    trace = []

    def prof(frame, event, arg):
        if (event == "return" and frame.f_code.co_filename.startswith(core)
                and "timing" not in frame.f_code.co_qualname):
            c = frame.f_code
            name = f"{Path(c.co_filename).stem}.{c.co_qualname}:{frame.f_lineno}"
            try:
                trace.append((name, _summary(arg)))
            except Exception as e:  # noqa: BLE001 - a value we cannot picture
                trace.append((name, ("type", repr(e))))

    sys.setprofile(prof)
    try:
        run()
    finally:
        sys.setprofile(None)
    with open(out, "wb") as f:
        pickle.dump(trace, f)


def compare(ta, tb, rtol: float, show: int) -> int:
    found = 0
    worst = 0.0
    for i, ((na, sa), (nb, sb)) in enumerate(zip(ta, tb)):
        if na != nb:
            print(f"call {i}: control flow parts: {na} vs {nb}")
            return 1
        d, r = _diff(sa, sb)
        if d or r > rtol:
            print(f"call {i}: {na}: " + (d or f"floats differ by {r:.3g} (relative)"))
            found += 1
            if found >= show:
                return 1
        worst = max(worst, r)
    if len(ta) != len(tb):
        print(f"traces end apart: {len(ta)} vs {len(tb)} calls")
        return 1
    if found:
        return 1
    print(f"{len(ta)} calls, the same within {rtol:g} (largest relative float difference "
          f"{worst:.3g})")
    return 0


def _env(text: str) -> dict:
    out = {}
    for part in text.split(";"):
        if part.strip():
            k, _, v = part.partition("=")
            out[k.strip()] = v
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("kind", choices=("view", "pair", "room", "golden", "_record"))
    ap.add_argument("ident")
    ap.add_argument("--env", action="append", default=None, metavar="NAME=VALUE[;...]")
    ap.add_argument("--rtol", type=float, default=1e-6,
                    help="float difference (relative to max(1, |x|)) reported (1e-6)")
    ap.add_argument("--show", type=int, default=5, help="differing calls shown (5)")
    ap.add_argument("--out", help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.kind == "_record":
        k, _, ident = a.ident.partition(":")
        record(k, ident, a.out)
        return 0
    envs = a.env or ["OPENBLAS_CORETYPE=Haswell", "OPENBLAS_CORETYPE=SkylakeX"]
    if len(envs) != 2:
        raise SystemExit("give two --env (or none)")
    traces = []
    with tempfile.TemporaryDirectory() as tmp:
        for j, e in enumerate(envs):
            out = os.path.join(tmp, f"{j}.pkl")
            env = {**os.environ, "PYTHONPATH": str(ROOT), **_env(e)}
            subprocess.run([sys.executable, __file__, "_record", f"{a.kind}:{a.ident}",
                            "--out", out], env=env, check=True)
            with open(out, "rb") as f:
                traces.append(pickle.load(f))
    print(f"{a.kind} {a.ident}: {envs[0]!r} vs {envs[1]!r}")
    return compare(*traces, a.rtol, a.show)


if __name__ == "__main__":
    sys.exit(main())
