"""Load on the bus: N phones x 2 fps into a router and the services, each its own process.

    python bench/bench_load.py [--phones 1 5 20 40] [--workers 1 2] [--seconds 30]
                               [--json OUT.json]
    python bench/bench_load.py --soak 600 --phones 5 --workers 2     # memory over 10 minutes
    python bench/bench_load.py --phones 5 20 --workers 1 --mapper both  # the mapper's cost

Deployment (loopback): ``findme router``, ``findme serve`` store, hypotheses (1 or 2
workers), selection --auto, measurement, odometry, recorder. Each phone is a session; it
sends a small rendered photo (``--size``, default 160x120, a slow walk through one room so
successive photos overlap) every 0.5 s as a plain BLOCK put of a ``findme.v1.Frame`` from
a client session, as a phone app of someone else's making would.

Per run: offered frames; delivered (a pose came); failed (a Motion came with its error:
odometry answered, no pose); errors by code (frames with no pose but an Error naming their
frame, hypotheses or selection); unaccounted = offered - the above (goal 0); duplicate
poses; latency photo -> pose (send to arrival, p50/p99); RSS and CPU of each process at
start and end. A run ends when every frame is accounted for, or 30 s after the last photo
if some never are. The baseline is 1 phone, same run. ``--soak`` runs one deployment for
that many seconds (phones start a new session every ``--session-s``; services forget a
session idle for 60 s and the store holds small results for 120 s, so that the plateau
shows within minutes) and samples RSS. ``--mapper on`` adds the mapper service (floor
plans; ``both``: each run without, then with it): plans received per session and what the
last one covered (photos placed / photos the mapper may take, ``max_photos`` 32).
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time

import cv2
import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
import schemas  # noqa: E402
from findme_core.synth.render import Pose, Room, render  # noqa: E402
from findme_io.convert import make_frame  # noqa: E402
from services.runtime import bus  # noqa: E402

SERVICES = ("store", "selection", "measurement", "recorder")
CLK_TCK = os.sysconf("SC_CLK_TCK")


def photos(k: int, size: tuple[int, int]):
    """Photos walking forward then back over k/2 places, never the same place twice in a
    row (each photo overlaps the next; identical photos have no motion): (jpeg, camera, h)."""
    room = Room.rectangle(5.0, 6.0, floor_style="wood")
    half = k // 2
    out = []
    for i in list(range(half)) + list(range(half - 2, 0, -1)):
        v = render(room, Pose(-0.3 + 0.04 * i, -1.8 + 0.08 * i, 1.4, yaw_deg=10 - 2 * i,
                              pitch_deg=27), size[0], size[1], hfov_deg=70, seed=5)
        out.append((cv2.imencode(".jpg", v.image, [cv2.IMWRITE_JPEG_QUALITY, 90])[1].tobytes(),
                    v.camera, v.camera_height))
    return out


def proc_stats(pid: int) -> tuple[float, float]:
    """(RSS MB, CPU seconds) of a process."""
    with open(f"/proc/{pid}/status") as f:
        rss = next(int(line.split()[1]) for line in f if line.startswith("VmRSS:")) / 1024
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return rss, (int(fields[11]) + int(fields[12])) / CLK_TCK


class Deployment:
    """Router + services as processes; a client session for the phones and the results."""

    def __init__(self, workers: int, out_dir: str, extra=(), odometry: int = 1,
                 services=SERVICES):
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            self.ep = f"tcp/127.0.0.1:{s.getsockname()[1]}"
        self.procs: dict[str, subprocess.Popen] = {}
        self.logs = tempfile.mkdtemp(prefix="bench-load-logs-")
        self._spawn("router", "router", "--listen", self.ep)
        self._wait_log("router", "listening on")
        self.client = bus.open_session(bus.BusConfig(mode="client", connect=(self.ep,)))
        names = ([("hypotheses", f"h{i}") for i in range(workers)] +
                 [("odometry", f"o{i}") for i in range(odometry) if workers] +
                 [(n, n) for n in services])
        for name, inst in names:
            args = ["serve", name, "--connect", self.ep, "--instance", inst, *extra]
            args += {"selection": ["--auto"], "recorder": ["--out", out_dir]}.get(name, [])
            self._spawn(inst, *args)
        self._wait_alive(names)

    def _spawn(self, tag, *args):
        log = open(os.path.join(self.logs, f"{tag}.log"), "w")  # noqa: SIM115 - closed at exit
        self.procs[tag] = subprocess.Popen([sys.executable, "-m", "findme.cli", *args],
                                           stdout=subprocess.DEVNULL, stderr=log)

    def _wait_log(self, tag, text, timeout=60):
        path, t0 = os.path.join(self.logs, f"{tag}.log"), time.monotonic()
        pace = threading.Event()
        while text not in open(path).read():
            if time.monotonic() - t0 > timeout or self.procs[tag].poll() is not None:
                raise RuntimeError(f"{tag} did not log {text!r}: {open(path).read()[-2000:]}")
            pace.wait(0.05)

    def _wait_alive(self, names, timeout=120):
        import zenoh
        want = {f"{bus.SERVICES}/{n}/{i}" for n, i in names}
        seen, cv = set(), threading.Condition()

        def cb(s):
            with cv:
                if s.kind == zenoh.SampleKind.PUT:
                    seen.add(str(s.key_expr))
                cv.notify_all()
        sub = self.client.liveliness().declare_subscriber(f"{bus.SERVICES}/**", cb, history=True)
        with cv:
            ok = cv.wait_for(lambda: want <= seen, timeout)
        sub.undeclare()
        if not ok:
            raise RuntimeError(f"services not up: {sorted(want - seen)}")

    def stats(self) -> dict:
        return {tag: proc_stats(p.pid) for tag, p in self.procs.items() if p.poll() is None}

    def statuses(self) -> dict:
        out = {}
        for _, payload in bus.get_all(self.client, f"{bus.SERVICES}/*/*/status", 10):
            st = schemas.decode(schemas.ServiceStatus, payload)
            out[st.instance] = {"in": st.frames_in, "out": st.results_out, "errors": st.errors,
                                "dropped": st.dropped, **dict(st.counters)}
        return out

    def close(self):
        self.client.close()
        for p in self.procs.values():
            if p.poll() is None:
                p.send_signal(signal.SIGTERM)
        for p in self.procs.values():
            try:
                p.wait(30)
            except subprocess.TimeoutExpired:
                p.kill()
        closed = "Closing transport" in open(os.path.join(self.logs, "router.log")).read()
        return {"router_closed_a_transport": closed}


class Ledger:
    """What happened to every frame sent: pose, failed motion, errors; latencies."""

    def __init__(self, client):
        self.cv = threading.Condition()
        self.sent: dict[tuple[str, int], float] = {}
        self.pose: dict[tuple[str, int], float] = {}
        self.failed: set[tuple[str, int]] = set()
        self.errors: dict[tuple[str, int], int] = {}
        self.dup_poses = 0
        self.plans: dict[str, list[int]] = {}   # session -> [plans, photos placed in the last]
        self.subs = [client.declare_subscriber("findme/*/pose/*", self._pose),
                     client.declare_subscriber("findme/*/plan", self._plan),
                     client.declare_subscriber("findme/*/motion/*/*", self._motion),
                     client.declare_subscriber("findme/*/error", self._error)]

    def _pose(self, sample):
        t = time.perf_counter()
        k = bus.parse_key(str(sample.key_expr))
        with self.cv:
            ident = (k.session, k.index())
            if ident in self.pose:
                self.dup_poses += 1
            self.pose.setdefault(ident, t)
            self.cv.notify_all()

    def _plan(self, sample):
        p = schemas.decode(schemas.Plan, sample.payload.to_bytes())
        placed = sum(q.status == schemas.PLAN_PHOTO_STATUS_PLACED for q in p.poses)
        with self.cv:
            n = self.plans.setdefault(p.session, [0, 0])
            n[0] += 1
            n[1] = max(n[1], placed)

    def _motion(self, sample):
        m = schemas.decode(schemas.Motion, sample.payload.to_bytes())
        if m.error:
            with self.cv:
                self.failed.add((m.session, m.index_b))
                self.cv.notify_all()

    def _error(self, sample):
        e = schemas.decode(schemas.Error, sample.payload.to_bytes())
        try:
            k = bus.parse_key(e.key)
            ident = (k.session, k.index())
        except Exception:  # noqa: BLE001 - an error about no photo (a query): not a frame's
            return
        with self.cv:
            self.errors.setdefault(ident, e.code)
            self.cv.notify_all()

    def accounted(self) -> int:
        return sum(1 for f in self.sent if f in self.pose or f in self.failed or f in self.errors)

    def wait(self, timeout: float) -> None:
        """Until every frame sent is accounted for, or ``timeout`` s without progress."""
        with self.cv:
            last = -1
            while self.accounted() < len(self.sent):
                n = self.accounted()
                if n == last:
                    return
                last = n
                self.cv.wait_for(lambda: self.accounted() > n, timeout)

    def summary(self) -> dict:
        with self.cv:
            sent = dict(self.sent)
            lat = [1e3 * (self.pose[f] - t) for f, t in sent.items() if f in self.pose]
            failed = [f for f in sent if f not in self.pose and f in self.failed]
            errs: dict[str, int] = {}
            for f in sent:
                if f not in self.pose and f not in self.failed and f in self.errors:
                    name = schemas.ErrorCode.Name(self.errors[f]).removeprefix("ERROR_CODE_")
                    errs[name] = errs.get(name, 0) + 1
            done = len(lat) + len(failed) + sum(errs.values())
            plans = {"sessions": len(self.plans),
                     "plans": sum(v[0] for v in self.plans.values()),
                     "placed_in_last_median": float(np.median([v[1] for v in
                                                              self.plans.values()]))
                     if self.plans else None}
            return {"offered": len(sent), "delivered": len(lat), "failed": len(failed),
                    "mapper": plans,
                    "errors": errs, "unaccounted": len(sent) - done, "dup_poses": self.dup_poses,
                    "p50_ms": float(np.percentile(lat, 50)) if lat else None,
                    "p99_ms": float(np.percentile(lat, 99)) if lat else None}

    def close(self):
        for s in self.subs:
            s.undeclare()


def drive(client, ledger, pool, phones: int, seconds: float, session_s: float | None = None,
          tag: str = "p", on_tick=None):
    """Each phone sends a frame every 0.5 s (phases spread over the period) for ``seconds``;
    with ``session_s`` a phone starts a new session that often."""
    period, t0 = 0.5, time.perf_counter()
    n_per = int(seconds / period)
    pace = threading.Event()
    for step in range(n_per):
        for p in range(phones):
            due = t0 + step * period + p * period / phones
            delay = due - time.perf_counter()
            if delay > 0:
                pace.wait(delay)
            epoch = int(step * period // session_s) if session_s else 0
            session = f"{tag}{p:02d}e{epoch}"
            n = step - (int(epoch * session_s / period) if session_s else 0)
            jpeg, cam, h = pool[(n + p) % len(pool)]
            f = make_frame(session, n, jpeg, intrinsics=(cam.fx, cam.fy, cam.cx, cam.cy,
                                                         cam.width, cam.height),
                           gravity=cam.gravity, camera_height_m=h)
            with ledger.cv:
                ledger.sent[(session, n)] = time.perf_counter()
            bus.put(client, bus.key(session, "frame", n), schemas.encode(f))
        if on_tick:
            on_tick(time.perf_counter() - t0)


def run(workers, phones, seconds, pool, extra=(), odometry=1, mapper=False):
    with tempfile.TemporaryDirectory(prefix="bench-load-rec-") as out:
        dep = Deployment(workers, out, extra, odometry,
                         SERVICES + ("mapper",) if mapper else SERVICES)
        try:
            start = dep.stats()
            ledger = Ledger(dep.client)
            drive(dep.client, ledger, pool, phones, seconds, tag=f"w{workers}n{phones}-")
            ledger.wait(30)
            end = dep.stats()
            res = {"workers": workers, "odometry": odometry, "phones": phones,
                   "with_mapper": mapper, **ledger.summary(),
                   "rss_mb": {k: (round(start[k][0]), round(end[k][0])) for k in end},
                   "cpu_s": {k: round(end[k][1] - start[k][1], 1) for k in end},
                   "status": dep.statuses()}
            ledger.close()
        finally:
            res_close = dep.close()
        res.update(res_close)
        res["recordings"] = len([p for p in os.listdir(out) if p.endswith(".mcap")])
    return res


def soak(workers, phones, seconds, pool, session_s, every=30.0, odometry=1):
    samples = []
    with tempfile.TemporaryDirectory(prefix="bench-soak-rec-") as out:
        dep = Deployment(workers, out, ("--idle", "60", "--latch", "120"), odometry)
        try:
            ledger = Ledger(dep.client)
            samples.append((0.0, {k: round(v[0]) for k, v in dep.stats().items()}))
            nxt = [every]

            def tick(t):
                if t >= nxt[0]:
                    samples.append((round(t), {k: round(v[0]) for k, v in dep.stats().items()}))
                    print(f"  {t:5.0f} s  RSS MB {samples[-1][1]}", flush=True)
                    nxt[0] += every
            drive(dep.client, ledger, pool, phones, seconds, session_s, "soak", tick)
            ledger.wait(30)
            samples.append((round(seconds) + 1, {k: round(v[0]) for k, v in dep.stats().items()}))
            res = {"workers": workers, "phones": phones, "seconds": seconds,
                   **ledger.summary(), "rss_mb_over_time": samples, "status": dep.statuses()}
            ledger.close()
        finally:
            res.update(dep.close())
    return res


def big_jpeg(target_mb: float = 12.0) -> bytes:
    """A 4000x3000 photo of about ``target_mb`` MB (a render, upscaled, with sensor noise)."""
    v = render(Room.rectangle(5.0, 6.0, floor_style="wood"), Pose(0.0, -1.5, 1.45, yaw_deg=5,
                                                                  pitch_deg=25), 640, 480, seed=3)
    img = cv2.resize(v.image, (4000, 3000), interpolation=cv2.INTER_CUBIC).astype(np.int16)
    noisy = np.clip(img + np.random.default_rng(0).integers(-40, 40, img.shape), 0, 255)
    for q in (100, 99, 98, 97, 96, 95, 90, 85):
        data = cv2.imencode(".jpg", noisy.astype(np.uint8), [cv2.IMWRITE_JPEG_QUALITY, q])[1].tobytes()
        if len(data) <= target_mb * 1.05e6:
            return data
    return data


def fairness(pool, repeats: int = 3) -> dict:
    """Phone B's one small photo alone, then right after phone A's four ~12 MB photos:
    B's latency photo -> hypotheses and photo -> pose (1 hypotheses worker)."""
    big = big_jpeg()
    out = {"big_mb": round(len(big) / 1e6, 1), "alone": [], "after_big": []}
    with tempfile.TemporaryDirectory(prefix="bench-fair-rec-") as rec:
        dep = Deployment(1, rec)
        got, cv = {}, threading.Condition()

        def cb(sample):
            with cv:
                got[str(sample.key_expr)] = time.perf_counter()
                cv.notify_all()
        sub = dep.client.declare_subscriber("findme/*/**", cb)
        try:
            jpeg, cam, h = pool[0]
            intr = (cam.fx, cam.fy, cam.cx, cam.cy, cam.width, cam.height)
            for r in range(2 * repeats):
                contended = r % 2 == 1
                if contended:
                    for n in range(4):
                        f = make_frame(f"fa{r}", n, big, hfov_deg=70.0, gravity=cam.gravity,
                                       camera_height_m=h)
                        bus.put(dep.client, bus.key(f"fa{r}", "frame", n), schemas.encode(f))
                s = f"fb{r}"
                t0 = time.perf_counter()
                bus.put(dep.client, bus.key(s, "frame", 0), schemas.encode(
                    make_frame(s, 0, jpeg, intrinsics=intr, gravity=cam.gravity, camera_height_m=h)))
                keys = [f"findme/{s}/hypotheses/0", f"findme/{s}/pose/0"]
                with cv:
                    cv.wait_for(lambda: all(k in got for k in keys), 120)
                lat = [round(1e3 * (got[k] - t0)) if k in got else None for k in keys]
                out["after_big" if contended else "alone"].append(lat)
                if contended:   # A's photos are all answered before the next round
                    def answered(n, a=f"findme/fa{r}/"):
                        return a + f"pose/{n}" in got or any(
                            k.startswith(a + "motion/") and k.endswith(f"/{n}") for k in got)
                    with cv:
                        cv.wait_for(lambda: all(answered(n) for n in range(4)), 300)
        finally:
            sub.undeclare()
            out.update(dep.close())
    return out


def table(rows) -> str:
    lines = ["| hyp. workers | odometry | mapper | phones | offered | delivered | failed | "
             "errors | unaccounted | dup | p50 / p99 ms | plans (placed in the last) | "
             "RSS MB start -> end |", "|" + "---|" * 13]
    for r in rows:
        errs = ", ".join(f"{k} {v}" for k, v in sorted(r["errors"].items())) or "0"
        rss = ", ".join(f"{k} {a}->{b}" for k, (a, b) in sorted(r["rss_mb"].items()))
        lat = f"{r['p50_ms']:.0f} / {r['p99_ms']:.0f}" if r["p50_ms"] is not None else "-"
        mp = r.get("mapper") or {}
        plans = (f"{mp['plans']} ({mp['placed_in_last_median']:.0f})" if mp.get("plans")
                 else "-")
        lines.append(f"| {r['workers']} | {r['odometry']} | {'yes' if r.get('with_mapper') else 'no'} | "
                     f"{r['phones']} | {r['offered']} | {r['delivered']} | "
                     f"{r['failed']} | {errs} | {r['unaccounted']} | {r['dup_poses']} | {lat} | "
                     f"{plans} | {rss} |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--phones", type=int, nargs="+", default=[1, 5, 20, 40])
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--seconds", type=float, default=30.0)
    ap.add_argument("--odometry", type=int, default=1, help="odometry instances (default 1)")
    ap.add_argument("--size", default="160x120", help="photo size WxH (default 160x120)")
    ap.add_argument("--soak", type=float, metavar="S", help="one long run of S seconds")
    ap.add_argument("--session-s", type=float, default=60.0,
                    help="soak: a phone starts a new session this often (default 60 s)")
    ap.add_argument("--fairness", action="store_true",
                    help="one small photo alone vs right after another phone's four 12 MB ones")
    ap.add_argument("--mapper", choices=("off", "on", "both"), default="off",
                    help="add the mapper service (both: each run without, then with it)")
    ap.add_argument("--json", metavar="OUT")
    args = ap.parse_args()
    w, h = map(int, args.size.lower().split("x"))
    pool = photos(24, (w, h))
    print(f"{len(pool)} photos {w}x{h}, {np.mean([len(p[0]) for p in pool]) / 1e3:.1f} kB each; "
          f"{os.cpu_count()} cores", flush=True)
    if args.fairness:
        out = {"fairness": fairness(pool)}
        print(json.dumps(out, indent=1))
    elif args.soak:
        res = soak(args.workers[0], args.phones[0], args.soak, pool, args.session_s,
                   odometry=args.odometry)
        out = {"soak": res}
        print(json.dumps({k: v for k, v in res.items() if k != "status"}, indent=1))
    else:
        rows = []
        for workers in args.workers:
            for phones in args.phones:
                for mapper in {"off": [False], "on": [True], "both": [False, True]}[args.mapper]:
                    r = run(workers, phones, args.seconds, pool, odometry=args.odometry,
                            mapper=mapper)
                    rows.append(r)
                    print(table([r]).splitlines()[-1], flush=True)
        out = {"runs": rows}
        print(table(rows))
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
