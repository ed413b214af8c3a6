"""The load benchmark's rig: the deployment as processes, phones (plain Zenoh puts or
WebSocket pages through the gateway), the ledger of every frame, and where each process's
CPU, bytes, decodes, queue time and memory go (``breakdown``).

Used by ``bench_load.py``; no timing of its own beyond what it is asked to sample.
"""

from __future__ import annotations

import asyncio
import json
import os
import signal
import socket
import struct
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

#: what ``findme up`` starts besides the router, the hypotheses workers and odometry
UP_SERVICES = ("store", "selection", "measurement", "mapper", "recorder")
CLK_TCK = os.sysconf("SC_CLK_TCK")


# ---------------------------------------------------------------------------------- photos
def photos(k: int, size: tuple[int, int], quality: int = 90, noise: float = 0.0):
    """Photos walking forward then back over k/2 places, never the same place twice in a
    row (each photo overlaps the next; identical photos have no motion): [(jpeg, camera,
    camera height)]. A size above 1024 px is rendered at a quarter and upscaled (cubic)
    with ``noise`` grey levels of sensor noise (1-sigma), as a phone's 12 MP photo."""
    room = Room.rectangle(5.0, 6.0, floor_style="wood")
    half = k // 2
    W, H = size
    big = max(W, H) > 1024
    rw, rh = (W // 4, H // 4) if big else (W, H)
    rng = np.random.default_rng(0)
    out = []
    for i in list(range(half)) + list(range(half - 2, 0, -1)):
        v = render(room, Pose(-0.3 + 0.04 * i, -1.8 + 0.08 * i, 1.4, yaw_deg=10 - 2 * i,
                              pitch_deg=27), rw, rh, hfov_deg=70, seed=5)
        img, cam = v.image, v.camera
        if big:
            img = cv2.resize(img, (W, H), interpolation=cv2.INTER_CUBIC)
            cam = cam.scaled(W / rw)
        if noise:
            img = np.clip(img + rng.normal(0, noise, img.shape), 0, 255).astype(np.uint8)
        jpeg = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, quality])[1].tobytes()
        out.append((jpeg, cam, v.camera_height))
    return out


def tum_walk(size: tuple[int, int] | None = None, quality: int = 92, noise: float = 0.0):
    """The TUM RGB-D cabinet frames of the dev split (``../shared/data/findme-eval``, CC BY
    4.0), in capture order then back (a hand-held camera walking round a cabinet, 12-20 cm
    between frames), as [(jpeg, camera with the dataset's gravity, camera height)]; None
    without the data. With ``size`` larger than 640x480 each frame is upscaled (cubic, the
    camera scaled to match: pixel centres kept) with ``noise`` grey levels of sensor noise
    and encoded at ``quality``, as a phone's 12 MP photo; else the dataset's own JPEG bytes."""
    from bench.common import EVAL_DIR
    from findme.evaluation.views import view_inputs
    idx = EVAL_DIR / "index.json"
    if not idx.exists():
        return None
    views = sorted(json.loads(idx.read_text())["subsets"]["tum-cabinet"]["views"])
    rng = np.random.default_rng(0)
    out = []
    for v in views + views[-2:0:-1]:
        meta = json.loads((EVAL_DIR / "views" / f"{v}.json").read_text())
        cam, h, _ = view_inputs(meta)
        data = (EVAL_DIR / "views" / meta["image"]).read_bytes()
        if size is not None and tuple(size) != (cam.width, cam.height):
            img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
            img = cv2.resize(img, size, interpolation=cv2.INTER_CUBIC)
            if noise:
                img = np.clip(img + rng.normal(0, noise, img.shape), 0, 255).astype(np.uint8)
            s = size[0] / cam.width
            cam = cam.scaled(s)
            data = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, quality])[1].tobytes()
        out.append((data, cam, h))
    return out


# ---------------------------------------------------------------------------------- processes
def proc_stats(pid: int) -> tuple[float, float, float, float]:
    """(RSS MB, CPU seconds: user + system, private (anonymous) MB, shared-memory MB) of a
    process. Zenoh's shared-memory pools (16 MB a sending process) are mapped by every
    process that receives from it: the same pages count in each one's RSS."""
    mem = {}
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith(("VmRSS:", "RssAnon:", "RssShmem:")):
                mem[line.split(":")[0]] = int(line.split()[1]) / 1024
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (mem.get("VmRSS", 0.0), (int(fields[11]) + int(fields[12])) / CLK_TCK,
            mem.get("RssAnon", 0.0), mem.get("RssShmem", 0.0))


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Deployment:
    """Router + services as processes (``findme up``'s set by default: store, ``workers``
    hypotheses, selection, measurement, ``odometry`` odometry, mapper, recorder); with
    ``gateway`` the phone page's gateway instead of selection (as ``findme up --gateway``).
    A client session for the phones and the results."""

    def __init__(self, workers: int, out_dir: str, extra=(), odometry: int = 1,
                 services=UP_SERVICES, gateway: bool = False, env: dict | None = None):
        self.ep = f"tcp/127.0.0.1:{_free_port()}"
        self.procs: dict[str, subprocess.Popen] = {}
        self.env = {**os.environ, **(env or {})}
        self.logs = tempfile.mkdtemp(prefix="bench-load-logs-")
        self._spawn("router", "router", "--listen", self.ep)
        self._wait_log("router", "listening on")
        self.client = bus.open_session(bus.BusConfig(mode="client", connect=(self.ep,)))
        services = tuple(s for s in services if not (gateway and s == "selection"))
        names = ([("hypotheses", f"h{i}") for i in range(workers)] +
                 [("odometry", f"o{i}") for i in range(odometry) if workers] +
                 [(n, n) for n in services])
        self.http = None
        if gateway:
            self.http = f"127.0.0.1:{_free_port()}"
            names.append(("gateway", "gateway"))
        for name, inst in names:
            args = ["serve", name, "--connect", self.ep, "--instance", inst, "--quiet", *extra]
            args += {"selection": ["--auto"], "recorder": ["--out", out_dir],
                     "gateway": ["--http", self.http or ""]}.get(name, [])
            self._spawn(inst, *args)
        self._wait_alive(names)

    def _spawn(self, tag, *args):
        log = open(os.path.join(self.logs, f"{tag}.log"), "w")  # noqa: SIM115 - closed at exit
        self.procs[tag] = subprocess.Popen([sys.executable, "-m", "findme.cli", *args],
                                           stdout=subprocess.DEVNULL, stderr=log, env=self.env)

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
        """instance -> every counter of its status report (frames_in, results_out, ...)."""
        out = {}
        for _, payload in bus.get_all(self.client, f"{bus.SERVICES}/*/*/status", 10):
            st = schemas.decode(schemas.ServiceStatus, payload)
            out[st.instance] = {"in": st.frames_in, "out": st.results_out, "errors": st.errors,
                                "dropped": st.dropped, **dict(st.counters)}
        return out

    def snapshot(self) -> dict:
        """Processes' (RSS, CPU) and services' counters, now."""
        return {"t": time.monotonic(), "proc": self.stats(), "status": self.statuses()}

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


class Sampler:
    """RSS of every process every ``every`` s, on a thread of its own, until ``stop``."""

    def __init__(self, dep: Deployment, every: float = 10.0, say=None):
        self.dep, self.every, self.say = dep, every, say
        self.samples: list[tuple[float, dict]] = []
        self.private: list[dict] = []
        self._stop = threading.Event()
        self.t0 = time.monotonic()
        self._take()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _take(self):
        rss = {k: round(v[0]) for k, v in self.dep.stats().items()}
        self.private.append({k: round(v[2]) for k, v in self.dep.stats().items()})
        self.samples.append((round(time.monotonic() - self.t0, 1), rss))
        if self.say:
            self.say(f"  {self.samples[-1][0]:6.0f} s  RSS MB {rss}")

    def _run(self):
        while not self._stop.wait(self.every):
            self._take()

    def stop(self) -> list:
        self._stop.set()
        self._thread.join()
        self._take()
        return self.samples

    def at(self, t: float) -> dict:
        """The sample nearest after ``t`` s (the first minute's end: flat after it?)."""
        return next((s for tt, s in self.samples if tt >= t), self.samples[-1][1])


# ---------------------------------------------------------------------------------- ledger
#: the pipeline's stages in order: a photo's error is told by the earliest that gave one
STAGES = ("gateway", "hypotheses", "selection", "measurement", "odometry", "mapper",
          "recorder", "store")


class Ledger:
    """What happened to every frame sent: pose, failed motion, errors; latencies photo ->
    hypotheses and photo -> pose."""

    def __init__(self, client):
        self.cv = threading.Condition()
        self.sent: dict[tuple[str, int], float] = {}
        self.hyp: dict[tuple[str, int], float] = {}
        self.pose: dict[tuple[str, int], float] = {}
        self.failed: set[tuple[str, int]] = set()
        self.errors: dict[tuple[str, int], list[tuple[int, str]]] = {}   # (code, service)
        self.dup_poses = 0
        self.plans: dict[str, list[int]] = {}   # session -> [plans, photos placed in the last]
        self.subs = [client.declare_subscriber("findme/*/pose/*", self._pose),
                     client.declare_subscriber("findme/*/hypotheses/*", self._hyp),
                     client.declare_subscriber("findme/*/plan", self._plan),
                     client.declare_subscriber("findme/*/motion/*/*", self._motion),
                     client.declare_subscriber("findme/*/error", self._error)]

    def sending(self, session: str, n: int) -> None:
        with self.cv:
            self.sent[(session, n)] = time.perf_counter()

    def _hyp(self, sample):
        t = time.perf_counter()
        k = bus.parse_key(str(sample.key_expr))
        with self.cv:
            self.hyp.setdefault((k.session, k.index()), t)

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
            self.errors.setdefault(ident, []).append((e.code, e.service.split("/")[0] or "?"))
            self.cv.notify_all()

    @staticmethod
    def _cause(errs: list[tuple[int, str]]) -> tuple[int, str]:
        """The error that ended a photo: the earliest stage's (hypotheses refusing a frame is
        why odometry later reports it as a gap), else the first that came."""
        return min(errs, key=lambda ce: STAGES.index(ce[1]) if ce[1] in STAGES else len(STAGES))

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
            hlat = [1e3 * (self.hyp[f] - t) for f, t in sent.items() if f in self.hyp]
            failed = [f for f in sent if f not in self.pose and f in self.failed]
            errs: dict[str, int] = {}
            by_service: dict[str, int] = {}
            for f in sent:
                if f not in self.pose and f not in self.failed and f in self.errors:
                    code, svc = self._cause(self.errors[f])
                    name = schemas.ErrorCode.Name(code).removeprefix("ERROR_CODE_")
                    errs[name] = errs.get(name, 0) + 1
                    by_service[svc] = by_service.get(svc, 0) + 1
            done = len(lat) + len(failed) + sum(errs.values())
            plans = {"sessions": len(self.plans),
                     "plans": sum(v[0] for v in self.plans.values()),
                     "placed_in_last_median": float(np.median([v[1] for v in
                                                              self.plans.values()]))
                     if self.plans else None}
            pct = (lambda a, q: float(np.percentile(a, q)) if a else None)
            return {"offered": len(sent), "delivered": len(lat), "failed": len(failed),
                    "hypotheses": len(hlat), "mapper": plans,
                    "errors": errs, "error_services": by_service,
                    "unaccounted": len(sent) - done, "dup_poses": self.dup_poses,
                    "p50_ms": pct(lat, 50), "p99_ms": pct(lat, 99), "max_ms": pct(lat, 100),
                    "hyp_p50_ms": pct(hlat, 50), "hyp_p99_ms": pct(hlat, 99)}

    def close(self):
        for s in self.subs:
            s.undeclare()


# ---------------------------------------------------------------------------------- phones
def drive(client, ledger, pool, phones: int, seconds: float, fps: float = 2.0,
          session_s: float | None = None, tag: str = "p", on_tick=None):
    """Each phone sends a frame every 1/fps s (phases spread over the period) for
    ``seconds``, a plain BLOCK put of a ``findme.v1.Frame``; with ``session_s`` a phone
    starts a new session that often."""
    period, t0 = 1.0 / fps, time.perf_counter()
    n_per = int(round(seconds * fps))
    pace = threading.Event()
    for step in range(n_per):
        for p in range(phones):
            due = t0 + step * period + p * period / phones
            delay = due - time.perf_counter()
            if delay > 0:
                pace.wait(delay)
            epoch = int(step * period // session_s) if session_s else 0
            session = f"{tag}{p:02d}e{epoch}"
            n = step - (int(round(epoch * session_s / period)) if session_s else 0)
            jpeg, cam, h = pool[(n + p) % len(pool)]
            f = make_frame(session, n, jpeg, intrinsics=(cam.fx, cam.fy, cam.cx, cam.cy,
                                                         cam.width, cam.height),
                           gravity=cam.gravity, camera_height_m=h)
            ledger.sending(session, n)
            bus.put(client, bus.key(session, "frame", n), schemas.encode(f))
        if on_tick:
            on_tick(time.perf_counter() - t0)


class drive_pages:
    """Each phone is a page: a WebSocket to the gateway (``/ws``) uploading one photo every
    1/fps s as the page does (``[u32][JSON header][JPEG]``: the photo's intrinsics, gravity
    from the phone's sensors, camera height); the gateway selects rank 1 for it. The pages
    run on an event loop of their own thread and stay open (their results come through
    them) until ``close``; ``counts``: uploads, frames acknowledged, refused."""

    def __init__(self, http: str, ledger, pool, phones: int, seconds: float, fps: float):
        self.http, self.ledger, self.pool = http, ledger, pool
        self.phones, self.n, self.fps = phones, int(round(seconds * fps)), fps
        self.counts = {"uploads": 0, "frames": 0, "refused": 0}
        self.sent = threading.Event()
        self.loop = asyncio.new_event_loop()
        self.thread = threading.Thread(target=self.loop.run_until_complete, args=(self._main(),),
                                       daemon=True)
        self.thread.start()

    async def _main(self):
        self.stop = asyncio.Event()
        t0 = time.perf_counter() + 0.5
        await asyncio.gather(*(self._page(p, t0) for p in range(self.phones)))

    async def _page(self, p: int, t0: float):
        import aiohttp
        async with aiohttp.ClientSession() as hs, hs.ws_connect(
                f"http://{self.http}/ws", max_msg_size=0, origin=f"http://{self.http}") as ws:
            sid = (await ws.receive_json())["session"]

            async def reader():
                async for m in ws:
                    if m.type == aiohttp.WSMsgType.TEXT:
                        kind = json.loads(m.data).get("type")
                        if kind in ("frame", "refused"):
                            self.counts["frames" if kind == "frame" else "refused"] += 1
            task = asyncio.create_task(reader())
            period = 1.0 / self.fps
            for n in range(self.n):
                due = t0 + n * period + p * period / self.phones
                await asyncio.sleep(max(0.0, due - time.perf_counter()))
                jpeg, cam, h = self.pool[(n + p) % len(self.pool)]
                head = json.dumps({
                    "type": "frame", "id": f"u{n}",
                    "lens": {"kind": "intrinsics", "fx": cam.fx, "fy": cam.fy, "cx": cam.cx,
                             "cy": cam.cy, "width": cam.width, "height": cam.height},
                    "gravity": [float(x) for x in cam.gravity], "gravity_sigma_deg": 1.5,
                    "camera_height_m": h, "capture_time_ms": time.time() * 1e3}).encode()
                self.ledger.sending(sid, n)
                self.counts["uploads"] += 1
                await ws.send_bytes(struct.pack(">I", len(head)) + head + jpeg)
            if self.counts["uploads"] >= self.phones * self.n:
                self.sent.set()
            await self.stop.wait()
            task.cancel()

    def wait_sent(self) -> None:
        while not self.sent.wait(0.5):
            if not self.thread.is_alive():
                raise RuntimeError("the pages stopped before sending every photo")

    def close(self) -> None:
        self.loop.call_soon_threadsafe(self.stop.set)
        self.thread.join(10)


# ---------------------------------------------------------------------------------- breakdown
def _instance_of(tag: str) -> str:
    return tag   # the bench names every instance after its process tag


def breakdown(start: dict, end: dict, photos: int) -> list[dict]:
    """Per process, per photo offered: CPU ms (utime + stime), messages and kB in / out,
    image decodes and their ms, protobuf decode / encode ms, handling CPU ms (worker
    threads) and the rest (Zenoh's threads, callbacks, the GIL's churn), mean and max wait
    in the queue, mean handling time per message, RSS MB at start and end."""
    rows = []
    n = max(photos, 1)
    for tag in sorted(end["proc"]):
        if tag not in start["proc"]:
            continue
        (rss0, cpu0, anon0, shm0), (rss1, cpu1, anon1, shm1) = start["proc"][tag], end["proc"][tag]
        a = start["status"].get(_instance_of(tag), {})
        b = end["status"].get(_instance_of(tag), {})
        d = {k: b.get(k, 0) - a.get(k, 0) for k in b}
        cpu_ms = 1e3 * (cpu1 - cpu0) / n
        row = {"process": tag, "cpu_ms": cpu_ms, "rss0": rss0, "rss1": rss1,
               "anon1": anon1, "shm1": shm1}
        if b:
            waits, handled = max(d.get("waits", 0), 1), max(d.get("handled", 0), 1)
            row.update({
                "msgs_in": d.get("in", 0) / n, "kb_in": d.get("in_bytes", 0) / n / 1e3,
                "msgs_out": d.get("out", 0) / n, "kb_out": d.get("out_bytes", 0) / n / 1e3,
                "decodes": d.get("image_decodes", 0) / n,
                "decode_ms": d.get("image_decode_us", 0) / n / 1e3,
                "decoded_mpx": d.get("image_decoded_kpx", 0) / n / 1e3,
                "probes": d.get("image_probes", 0) / n,
                "pb_ms": (d.get("pb_decode_us", 0) + d.get("pb_encode_us", 0)) / n / 1e3,
                "handle_cpu_ms": d.get("handle_cpu_us", 0) / n / 1e3,
                "tick_cpu_ms": d.get("tick_cpu_us", 0) / n / 1e3,
                "other_cpu_ms": cpu_ms - (d.get("handle_cpu_us", 0) + d.get("tick_cpu_us", 0))
                / n / 1e3,
                "fetches": d.get("fetches", 0) / n, "fetch_ms": d.get("fetch_us", 0) / n / 1e3,
                "busy_s": (d.get("handle_us", 0) + d.get("tick_us", 0)) / 1e6,
                "wait_mean_ms": d.get("wait_us", 0) / waits / 1e3,
                "wait_max_ms": b.get("wait_max_us", 0) / 1e3,
                "handle_mean_ms": d.get("handle_us", 0) / handled / 1e3,
                "errors": d.get("errors", 0), "dropped": d.get("dropped", 0)})
        rows.append(row)
    total = {"process": "ALL", "cpu_ms": sum(r["cpu_ms"] for r in rows),
             "rss0": sum(r["rss0"] for r in rows), "rss1": sum(r["rss1"] for r in rows)}
    for k in ("decodes", "decode_ms", "kb_in", "kb_out", "handle_cpu_ms", "tick_cpu_ms",
              "other_cpu_ms", "pb_ms"):
        total[k] = sum(r.get(k, 0.0) for r in rows)
    return rows + [total]


def cpu_seconds(run: dict) -> float:
    """CPU seconds all the deployment's processes used in a ``bench_load`` run (its
    breakdown's ALL row, per photo offered, times the photos offered)."""
    every = next(b for b in run["breakdown"] if b["process"] == "ALL")
    return every["cpu_ms"] * run["offered"] / 1e3


#: the processes on the way from a photo to its pose besides the hypotheses and odometry
#: instances (h0, h1, o0, ...); the store, recorder, mapper and router take in every photo
#: offered, posed or refused
PATH_SERVICES = ("selection", "measurement")


def posed_split(run: dict) -> dict:
    """CPU ms per photo posed in a ``bench_load`` run, by where it went: ``path`` the
    handlers on the way to a pose (hypotheses, selection, measurement, odometry: what the
    compute bound measures), ``intake`` those processes' CPU outside their handlers
    (Zenoh's threads, callbacks, refusals), ``off_path`` all of the store's, recorder's,
    mapper's and router's; ``offered_per_posed`` photos offered per photo posed."""
    k = run["offered"] / max(run["delivered"], 1)
    out = {"path": 0.0, "intake": 0.0, "off_path": 0.0, "offered_per_posed": k}
    for b in run["breakdown"]:
        tag = b["process"]
        if tag == "ALL":
            continue
        on_path = tag in PATH_SERVICES or (tag[:1] in ("h", "o") and tag[1:].isdigit())
        if on_path and "handle_cpu_ms" in b:
            out["path"] += k * (b["handle_cpu_ms"] + b["tick_cpu_ms"])
            out["intake"] += k * b["other_cpu_ms"]
        else:
            out["off_path"] += k * b["cpu_ms"]
    out["all"] = out["path"] + out["intake"] + out["off_path"]
    return out


def breakdown_table(rows: list[dict]) -> str:
    head = ("| process | CPU ms/photo | handler CPU | tick CPU | other CPU | msgs in / out | "
            "kB in / out | decodes (ms, Mpx) | probes | protobuf ms | bus queries (wall ms) | "
            "queue wait mean / max ms | handling ms/msg | worker busy s | RSS MB start -> end |")
    lines = [head, "|" + "---|" * 15]
    f1 = (lambda r, k, fmt="{:.1f}": fmt.format(r[k]) if k in r else "-")
    for r in rows:
        lines.append(
            f"| {r['process']} | {r['cpu_ms']:.1f} | {f1(r, 'handle_cpu_ms')} | "
            f"{f1(r, 'tick_cpu_ms')} | {f1(r, 'other_cpu_ms')} | "
            + (f"{r['msgs_in']:.1f} / {r['msgs_out']:.1f} | {r['kb_in']:.0f} / {r['kb_out']:.0f} | "
               f"{r['decodes']:.2f} ({r['decode_ms']:.1f}, {r['decoded_mpx']:.2f}) | "
               f"{r['probes']:.2f} | {r['pb_ms']:.2f} | {r['fetches']:.2f} ({r['fetch_ms']:.0f}) | "
               f"{r['wait_mean_ms']:.0f} / {r['wait_max_ms']:.0f} | {r['handle_mean_ms']:.1f} | "
               f"{r['busy_s']:.0f} | "
               if "msgs_in" in r else
               (f"- | {r['kb_in']:.0f} / {r['kb_out']:.0f} | {r['decodes']:.2f} ({r['decode_ms']:.1f}) "
                f"| - | {r['pb_ms']:.2f} | - | - | - | - | " if r["process"] == "ALL" else
                "- | - | - | - | - | - | - | - | - | "))
            + f"{r['rss0']:.0f} -> {r['rss1']:.0f}"
            + (f" ({r['anon1']:.0f} + {r['shm1']:.0f}) |" if "anon1" in r else " |"))
    return "\n".join(lines)
