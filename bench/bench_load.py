"""Load on the bus: N phones into the deployment ``findme up`` starts, each service its own
process, with where every process's CPU, bytes, decodes, queue time and memory go.

The issue-25 scenarios, one command each (the machine's other load shows in the CPU per
photo only through contention; say when a run was contended):

    python bench/bench_load.py --scenario steady    # 20 phones x 1 fps, 600 s, 640x480
    python bench/bench_load.py --scenario peak      # 20 phones x 2 fps, 60 s: vs the compute bound
    python bench/bench_load.py --scenario gateway   # 5 pages x 0.5 fps, 4032x3024 JPEGs, 60 s
    (``--seconds S`` shortens any of them; ``--json OUT.json`` keeps everything)

The matrix of earlier stops, and its variants:

    python bench/bench_load.py [--phones 1 5 20] [--fps 2] [--workers 2] [--odometry 1]
                               [--size 640x480] [--mapper on|off|both] [--seconds 30]
    python bench/bench_load.py --soak 600 --phones 5 --workers 2     # memory over 10 minutes
    python bench/bench_load.py --fairness      # a small photo right after four 12 MB ones

Deployment (loopback, ``load_rig.Deployment``): ``findme router``, ``findme serve`` store,
hypotheses (``--workers``, default 2), selection --auto, measurement, odometry
(``--odometry``, default 1), mapper (``--mapper off`` leaves it out), recorder; with
``--scenario gateway`` the gateway instead of selection (``findme up --gateway``). Each
phone is a session; it sends a photo of a walk (``--pool``: the dev split's TUM RGB-D cabinet
frames in order and back, 640x480, the dataset's camera and gravity, as a hand-held phone
takes them; ``rendered``: a slow walk through a rendered room with a wood floor, whose
texture makes every stage several times dearer; ``--size``, default 640x480: larger photos
are upscaled, with sensor noise) every 1/fps s as a plain BLOCK
put of a ``findme.v1.Frame`` from a client session, as a phone app of someone else's making
would (the gateway scenario: as our page does, over its WebSocket).

Per run: offered frames; hypotheses delivered; delivered (a pose came); failed (a Motion
came with its error: odometry answered, no pose); errors by code and by the service that
sent them (frames with no pose but an Error naming their frame, hypotheses or selection);
unaccounted = offered - the above (goal 0); duplicate poses; latency photo -> hypotheses
and photo -> pose (send to arrival, p50 / p99); then the breakdown per process and per
photo offered (``load_rig.breakdown``): CPU (utime + stime from /proc), the part the
worker threads spent handling and the rest (Zenoh's threads, the callbacks), messages and
bytes in and out, image decodes (ms, megapixels) and header probes, protobuf decode and
encode, queue wait (mean, max) and handling time per message, RSS at start and end (and
every ``--sample`` s). A run ends when every frame is accounted for, or 30 s after the last
photo if some never are.

The compute bound (``--scenario peak``, or ``--bound``): the same photos through the
pipeline's handlers in this process, one after another, as ``bench_pipeline.py`` drives
them (hypotheses, selection, measurement, odometry, encode, recording: thread CPU per
photo); photos/s the machine's cores could pose = cores x 1000 / mean ms. Measured just
before the deployment starts and again just after it stops, in the same run; the ratio is
against the mean of the two, and both are printed (this machine's speed drifts: the bound
took 94-129 ms a photo across one morning's runs, and 1-8 % apart before and after one run).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
import schemas  # noqa: E402
from findme_core.synth.render import Pose, Room, render  # noqa: E402
from bench.load_rig import (UP_SERVICES, Deployment, Ledger, Sampler, breakdown,  # noqa: E402
                            breakdown_table, cpu_seconds, drive, drive_pages, photos,
                            posed_split,
                            tum_walk)
from findme_io.convert import make_frame  # noqa: E402
from services.runtime import bus  # noqa: E402

SCENARIOS = {
    # name: phones, fps, seconds, size, gateway, session_s, goals
    "steady": dict(phones=20, fps=1.0, seconds=600.0, size="640x480", gateway=False,
                   session_s=120.0, goal=">= 99 % posed, p99 photo -> pose <= 1 s, "
                   "0 unaccounted, RSS flat after the first minute"),
    "peak": dict(phones=20, fps=2.0, seconds=60.0, size="640x480", gateway=False,
                 session_s=None, goal="0 unaccounted, posed/s >= 80 % of the compute bound"),
    "gateway": dict(phones=5, fps=0.5, seconds=60.0, size="4032x3024", gateway=True,
                    session_s=None, goal="all posed, p99 photo -> pose <= 2 s"),
}


def compute_bound(pool, repeat: int = 2) -> dict:
    """CPU ms per photo of the pool as one session through the pipeline's handlers
    (``bench_pipeline.run_session``), the cheapest of ``repeat`` runs; photos/s on this
    machine's cores."""
    import cv2

    from bench.bench_pipeline import run_session
    # one OpenCV thread, as the services run (findme's one_thread_per_process): thread CPU
    # time then counts all the work (with OpenCV's pool it misses its workers' share)
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    runs = []
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(repeat):
            per, poses = run_session(f"bound{r}", pool, Path(tmp))
            runs.append([sum(p.values()) for p in per])
    cv2.setNumThreads(threads)
    ms = min(runs, key=sum)
    cores = os.cpu_count() or 1
    return {"ms_per_photo_mean": float(np.mean(ms)), "ms_per_photo_median": float(np.median(ms)),
            "ms_per_photo_p90": float(np.percentile(ms, 90)), "cores": cores,
            "photos_per_s": cores * 1e3 / float(np.mean(ms))}


def bracketed(before: dict, after: dict) -> dict:
    """The compute bound of a run measured just ``before`` and just ``after`` it
    (``compute_bound``): the mean of the two means (ms CPU per photo), with both kept."""
    ms = (before["ms_per_photo_mean"] + after["ms_per_photo_mean"]) / 2
    return {**before, "ms_per_photo_mean": ms, "photos_per_s": before["cores"] * 1e3 / ms,
            "before": before, "after": after}


def run(workers, phones, seconds, pool, fps=2.0, extra=(), odometry=1, mapper=True,
        gateway=False, session_s=None, sample_s=10.0, say=print, tag=None):
    services = UP_SERVICES if mapper else tuple(s for s in UP_SERVICES if s != "mapper")
    with tempfile.TemporaryDirectory(prefix="bench-load-rec-") as out:
        dep = Deployment(workers, out, extra, odometry, services, gateway=gateway)
        try:
            ledger = Ledger(dep.client)
            start = dep.snapshot()
            sampler = Sampler(dep, sample_s, say)
            t0 = time.perf_counter()
            pages = None
            if gateway:
                pages = drive_pages(dep.http, ledger, pool, phones, seconds, fps)
                pages.wait_sent()
            else:
                drive(dep.client, ledger, pool, phones, seconds, fps, session_s,
                      tag or f"w{workers}n{phones}-")
            sent_s = time.perf_counter() - t0
            ledger.wait(30)
            done_s = time.perf_counter() - t0
            end = dep.snapshot()
            rss = sampler.stop()
            if pages:
                pages.close()
            summ = ledger.summary()
            res = {"workers": workers, "odometry": odometry, "phones": phones, "fps": fps,
                   "seconds": seconds, "with_mapper": mapper, "gateway": gateway, **summ,
                   "sent_s": round(sent_s, 1), "done_s": round(done_s, 1),
                   "posed_per_s": summ["delivered"] / max(done_s, 1e-9),
                   "breakdown": breakdown(start, end, summ["offered"]),
                   "rss_mb": {k: (round(start["proc"][k][0]), round(end["proc"][k][0]))
                              for k in end["proc"] if k in start["proc"]},
                   "rss_mb_at_60s": sampler.at(60.0), "rss_mb_over_time": rss,
                   "private_mb": {k: (round(start["proc"][k][2]), round(end["proc"][k][2]))
                                  for k in end["proc"] if k in start["proc"]},
                   "private_mb_at_60s": next((p for (t, _), p in zip(rss, sampler.private)
                                              if t >= 60.0), sampler.private[-1]),
                   "status": end["status"], "pages": pages.counts if pages else None}
            ledger.close()
        finally:
            res_close = dep.close()
        res.update(res_close)
        res["recordings"] = len([p for p in os.listdir(out) if p.endswith(".mcap")])
    return res


def fairness(pool, repeats: int = 3) -> dict:
    """Phone B's one small photo alone, then right after phone A's four ~12 MB photos:
    B's latency photo -> hypotheses and photo -> pose (1 hypotheses worker)."""
    big = big_jpeg()
    out = {"big_mb": round(len(big) / 1e6, 1), "alone": [], "after_big": []}
    with tempfile.TemporaryDirectory(prefix="bench-fair-rec-") as rec:
        dep = Deployment(1, rec, services=("store", "selection", "measurement", "recorder"))
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


def big_jpeg(target_mb: float = 12.0) -> bytes:
    """A 4000x3000 photo of about ``target_mb`` MB (a render, upscaled, with sensor noise)."""
    import cv2
    from findme_core.synth.render import Pose, Room, render
    v = render(Room.rectangle(5.0, 6.0, floor_style="wood"), Pose(0.0, -1.5, 1.45, yaw_deg=5,
                                                                  pitch_deg=25), 640, 480, seed=3)
    img = cv2.resize(v.image, (4000, 3000), interpolation=cv2.INTER_CUBIC).astype(np.int16)
    noisy = np.clip(img + np.random.default_rng(0).integers(-40, 40, img.shape), 0, 255)
    for q in (100, 99, 98, 97, 96, 95, 90, 85):
        data = cv2.imencode(".jpg", noisy.astype(np.uint8), [cv2.IMWRITE_JPEG_QUALITY, q])[1].tobytes()
        if len(data) <= target_mb * 1.05e6:
            return data
    return data


def soak(workers, phones, seconds, pool, session_s, every=30.0, odometry=1, fps=2.0,
         mapper=False):
    r = run(workers, phones, seconds, pool, fps, ("--idle", "60", "--latch", "120"), odometry,
            mapper, session_s=session_s, sample_s=every, tag="soak")
    return r


def table(rows) -> str:
    lines = ["| hyp. workers / odometry | mapper | phones x fps | offered | hypotheses | posed | "
             "failed | errors (by service) | unaccounted | dup | photo -> hypotheses p50 / p99 ms | "
             "photo -> pose p50 / p99 / max ms | posed/s | plans (placed in the last) |",
             "|" + "---|" * 14]
    for r in rows:
        errs = ", ".join(f"{k} {v}" for k, v in sorted(r["errors"].items())) or "0"
        by = ", ".join(f"{k} {v}" for k, v in sorted(r.get("error_services", {}).items()))
        lat = (f"{r['p50_ms']:.0f} / {r['p99_ms']:.0f} / {r['max_ms']:.0f}"
               if r["p50_ms"] is not None else "-")
        hl = (f"{r['hyp_p50_ms']:.0f} / {r['hyp_p99_ms']:.0f}"
              if r.get("hyp_p50_ms") is not None else "-")
        mp = r.get("mapper") or {}
        plans = (f"{mp['plans']} ({mp['placed_in_last_median']:.0f})" if mp.get("plans")
                 else "-")
        lines.append(f"| {r['workers']} / {r['odometry']} | "
                     f"{'yes' if r.get('with_mapper') else 'no'} | {r['phones']} x {r['fps']:g}"
                     f"{' (gateway)' if r.get('gateway') else ''} | {r['offered']} | "
                     f"{r['hypotheses']} | {r['delivered']} | {r['failed']} | {errs}"
                     f"{f' ({by})' if by else ''} | {r['unaccounted']} | {r['dup_poses']} | "
                     f"{hl} | {lat} | {r['posed_per_s']:.1f} | {plans} |")
    return "\n".join(lines)


def rss_table(r) -> str:
    lines = ["| process | RSS MB start | at 60 s | end | end - at 60 s | private (anonymous) MB "
             "start / at 60 s / end |", "|---|---|---|---|---|---|"]
    at60, p60 = r["rss_mb_at_60s"], r.get("private_mb_at_60s", {})
    for k, (a, b) in sorted(r["rss_mb"].items()):
        m = at60.get(k, a)
        pa, pb = r.get("private_mb", {}).get(k, (0, 0))
        lines.append(f"| {k} | {a} | {m} | {b} | {b - m:+d} | {pa} / {p60.get(k, pa)} / {pb} |")
    return "\n".join(lines)


def report(r, bound=None) -> str:
    out = [table([r]), "", "Per process, per photo offered:", breakdown_table(r["breakdown"]),
           "", rss_table(r)]
    cpu_s = cpu_seconds(r)
    out += ["", f"the deployment used {cpu_s:.0f} CPU s in {r['done_s']:.0f} s "
                f"({cpu_s / max(r['done_s'], 1e-9):.2f} of {os.cpu_count()} cores: the rest went "
                f"to other work on the machine); posed {r['delivered'] / max(cpu_s, 1e-9):.2f} "
                "photos per CPU second"]
    if bound:
        out[-1] += (f" (the bound: {1e3 / bound['ms_per_photo_mean']:.2f}, "
                    f"{100 * r['delivered'] / max(cpu_s, 1e-9) * bound['ms_per_photo_mean'] / 1e3:.0f} %"
                    " of it)")
        split, b_ms = posed_split(r), bound["ms_per_photo_mean"]
        out += [f"CPU per photo posed: {split['all']:.0f} ms against the bound's {b_ms:.0f}: "
                f"the handlers on its way {split['path']:.0f} ms ({split['path'] - b_ms:+.0f}), "
                f"their processes' intake {split['intake']:.0f} ms, the store, recorder, "
                f"mapper and router {split['off_path']:.0f} ms; "
                f"{split['offered_per_posed']:.1f} photos offered a photo posed"]
        share = r["posed_per_s"] / bound["photos_per_s"]
        sides = ""
        if "after" in bound:
            b, a = bound["before"], bound["after"]
            shares = sorted(r["posed_per_s"] / x["photos_per_s"] for x in (b, a))
            sides = (f", the mean of {b['ms_per_photo_mean']:.1f} before and "
                     f"{a['ms_per_photo_mean']:.1f} after the run (medians "
                     f"{b['ms_per_photo_median']:.1f} / {a['ms_per_photo_median']:.1f})")
        out += ["", f"compute bound (pipeline handlers in one process, same photos, same run): "
                    f"{bound['ms_per_photo_mean']:.1f} ms CPU per photo mean{sides} "
                    f"-> {bound['photos_per_s']:.1f} photos/s on {bound['cores']} cores; "
                    f"posed {r['posed_per_s']:.1f}/s = {100 * share:.0f} % of it"
                    + (f" ({100 * shares[0]:.0f}-{100 * shares[1]:.0f} % against either side)"
                       if sides else "")]
    return "\n".join(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenario", choices=sorted(SCENARIOS),
                    help="one of the issue-25 scenarios (the options below override it)")
    ap.add_argument("--phones", type=int, nargs="+")
    ap.add_argument("--fps", type=float, help="photos per second per phone (default 2)")
    ap.add_argument("--workers", type=int, nargs="+", default=[2],
                    help="hypotheses workers (default 2, as findme up)")
    ap.add_argument("--seconds", type=float)
    ap.add_argument("--odometry", type=int, default=2,
                    help="odometry instances (default 2, as findme up)")
    ap.add_argument("--size", help="photo size WxH (default 640x480)")
    ap.add_argument("--pool", choices=("tum", "rendered"), default="tum",
                    help="the photos: the dev split's TUM cabinet walk (default; rendered "
                         "without the data) or a rendered walk through a room with a wood floor")
    ap.add_argument("--soak", type=float, metavar="S", help="one long run of S seconds")
    ap.add_argument("--session-s", type=float,
                    help="a phone starts a new session this often (default: one session)")
    ap.add_argument("--fairness", action="store_true",
                    help="one small photo alone vs right after another phone's four 12 MB ones")
    ap.add_argument("--mapper", choices=("off", "on", "both"), default="on",
                    help="the mapper service (default on, as findme up; both: each run "
                         "without, then with it)")
    ap.add_argument("--bound", action="store_true",
                    help="also measure the compute bound (default with --scenario peak)")
    ap.add_argument("--sample", type=float, default=10.0, metavar="S",
                    help="RSS of every process every S seconds (default 10)")
    ap.add_argument("--json", metavar="OUT")
    args = ap.parse_args()
    sc = SCENARIOS.get(args.scenario or "", {})
    phones = args.phones or ([sc["phones"]] if sc else [1, 5, 20])
    fps = args.fps or sc.get("fps", 2.0)
    seconds = args.seconds or sc.get("seconds", 30.0)
    size = args.size or sc.get("size", "640x480")
    session_s = args.session_s or sc.get("session_s")
    gateway = sc.get("gateway", False)
    w, h = map(int, size.lower().split("x"))
    big = max(w, h) > 1024
    pool = tum_walk((w, h), quality=95, noise=4.0 if big else 0.0) if args.pool == "tum" else None
    if pool is None:
        args.pool = "rendered"
        pool = photos(24 if not big else 12, (w, h), noise=2.0 if big else 0.0)
    print(f"{len(pool)} photos ({args.pool}) {w}x{h}, {np.mean([len(p[0]) for p in pool]) / 1e3:.1f} kB each; "
          f"{os.cpu_count()} cores; load average {os.getloadavg()[0]:.1f} before", flush=True)
    if sc:
        print(f"scenario {args.scenario}: {phones[0]} phones x {fps:g} fps for {seconds:g} s"
              f"{' through the gateway' if gateway else ''}; goal: {sc['goal']}", flush=True)
    out: dict = {"scenario": args.scenario, "size": size, "load_before": os.getloadavg()}
    bound = None
    if args.bound or args.scenario == "peak":
        bound = out["bound"] = compute_bound(pool)
        print(f"compute bound: {bound['ms_per_photo_mean']:.1f} ms CPU per photo (mean) -> "
              f"{bound['photos_per_s']:.1f} photos/s", flush=True)
    if args.fairness:
        out["fairness"] = fairness(pool)
        print(json.dumps(out["fairness"], indent=1))
    elif args.soak:
        res = soak(args.workers[0], phones[0], args.soak, pool, args.session_s or 60.0,
                   odometry=args.odometry, fps=fps, mapper=args.mapper == "on")
        out["soak"] = res
        print(report(res))
    else:
        rows = []
        for workers in args.workers:
            for n in phones:
                for mapper in {"off": [False], "on": [True], "both": [False, True]}[args.mapper]:
                    r = run(workers, n, seconds, pool, fps, odometry=args.odometry,
                            mapper=mapper, gateway=gateway, session_s=session_s,
                            sample_s=args.sample)
                    rows.append(r)
                    if bound is None:
                        print(report(r), flush=True)
        if bound is not None:   # the machine's speed after the runs, then their reports
            after = out["bound_after"] = compute_bound(pool)
            print(f"compute bound after the runs: {after['ms_per_photo_mean']:.1f} ms CPU per "
                  f"photo (mean)", flush=True)
            bound = out["bound"] = bracketed(bound, after)
            for r in rows:
                print(report(r, bound), flush=True)
        out["runs"] = rows
        if len(rows) > 1:
            print(table(rows))
    out["load_after"] = os.getloadavg()
    print(f"load average {out['load_before'][0]:.1f} before, {out['load_after'][0]:.1f} after "
          "(> 2: other work shared the cores)")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=1, default=str)


if __name__ == "__main__":
    main()
