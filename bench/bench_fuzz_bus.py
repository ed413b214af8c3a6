"""Fuzz the bus: malformed messages on every key every service subscribes to or answers, into
a router and every service as separate processes (issue 11).

    python bench/bench_fuzz_bus.py [--messages 100000] [--seed 1] [--json OUT.json]

Services: every one the registry has (hypotheses, selection --auto, measurement, odometry,
mapper, recorder, viewer writing .rrd files, gateway with one page open on a WebSocket), each
``findme serve`` in its own process, clients of a ``findme router``; capture publishes a
warm-up session first (and ends, as it does). The keys come from the handlers themselves
(``inputs``, ``queries``, ``cache_keys``) plus every service's status queryable and the
page's session.

Messages (``--messages`` is the number of MALFORMED ones, each refused by decoding, the
schema checks or the key authority exactly as a service does it, checked here before
sending): random bytes, truncated and bit-flipped protobufs, valid messages of the wrong
type, absurd values (NaN, infinities, huge sizes and counts, empty ids, out-of-range enums,
index 2^32-1 against a key that says otherwise), key/payload mismatches (another photo,
another kind, a foreign session in the payload) and keys whose session is not valid
(too long, "..", spaces, non-ASCII; keys like "-1" or "007" for a photo number). A mutation
that happens to be a VALID message is sent too, counted apart ("valid-shaped"), and what
each service did with it is reported.

Expected: every typed subscriber of a put's key answers it with exactly one Error
(``findme/<session>/error``, or ``findme/@errors`` when the key names no valid session);
every measure query gets one error reply and one Error; cache and status queries are
answered with what the service has (garbage payloads are ignored there); raw subscribers
(recorder, viewer) and the page do not answer: they record, skip, or drop. Counted: errors
received vs expected per service, queries completed, crashes (a process gone before the
end or not exiting 0 on SIGTERM), hangs (a service that does not drain its queue), INTERNAL
errors and tracebacks in the logs, RSS before/after per service, liveliness tokens lost
during the run (a link Zenoh closed). Then the example pair sent through the same processes
(``findme send``) must print what ``findme run`` prints (timings aside).

Sending is paced: at most ``--window`` expected errors outstanding (a hostile client, not a
flood). ``--window 0`` floods: a consumer that stays behind for more than 5 s then has its
link closed by Zenoh (``transport/link/tx/queue/congestion_control/block/wait_before_close``),
and what was queued on it is lost: reported as missing errors and lost liveliness tokens.
"""

from __future__ import annotations

import argparse
import asyncio
import faulthandler
import json
import os
import random
import re
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections import Counter, defaultdict
from importlib import resources
from pathlib import Path

import zenoh

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
import schemas  # noqa: E402
from bench.fuzz_messages import KIND_TYPE, SESSIONS, mutate, templates, verdict  # noqa: E402
from findme_core.errors import FindmeError  # noqa: E402
from services.runtime.bus import BusConfig, SERVICES, open_session, wait_alive  # noqa: E402
from services.registry import make_handler, service_names  # noqa: E402

EXAMPLES = resources.files("findme") / "examples"


# ------------------------------------------------------------------------------ processes
class Proc:
    def __init__(self, name, args, tmp, stdout=False):
        self.name = name
        self.err = open(tmp / f"{name}.stderr", "w")
        self.p = subprocess.Popen([sys.executable, "-m", "findme.cli", *map(str, args)],
                                  stdout=subprocess.PIPE if stdout else subprocess.DEVNULL,
                                  stderr=self.err, text=True,
                                  env=dict(os.environ, OPENCV_NUM_THREADS="1"))

    def rss_mb(self, field="VmRSS"):
        try:
            for line in Path(f"/proc/{self.p.pid}/status").read_text().splitlines():
                if line.startswith(field + ":"):
                    return int(line.split()[1]) / 1024
        except FileNotFoundError:
            return float("nan")
        return float("nan")

    def log(self):
        return Path(self.err.name).read_text(errors="replace")


def wait_line(proc, pattern, timeout=60):
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        if re.search(pattern, proc.log()):
            return
        if proc.p.poll() is not None:
            break
        time.sleep(0.05)   # a log file, not a pipe: polled (a benchmark, not a test)
    raise RuntimeError(f"{proc.name}: no {pattern!r}: {proc.log()[-2000:]}")


# ------------------------------------------------------------------------------ the run
class Tally:
    """Every Error and every output seen on the bus, by key and service."""

    def __init__(self, expected: Counter):
        self.cv = threading.Condition()
        self.expected = expected          # (key, service name) -> errors expected (shared)
        self.matched = 0                  # errors received that were expected
        self.errors = Counter()           # (key, service name) -> count
        self.codes = Counter()
        self.error_total = 0
        self.internal = []

    def on_error(self, sample):
        try:
            e = schemas.decode(schemas.Error, sample.payload.to_bytes())
        except FindmeError:
            return
        with self.cv:
            ks = (e.key, e.service.split("/")[0])
            self.errors[ks] += 1
            self.matched += self.errors[ks] <= self.expected.get(ks, 0)
            self.codes[schemas.ErrorCode.Name(e.code)] += 1
            self.error_total += 1
            if e.code == schemas.ErrorCode.ERROR_CODE_INTERNAL and len(self.internal) < 20:
                self.internal.append(f"{e.service}: {e.key[:80]}: {e.message[:200]}")
            self.cv.notify_all()


def page_thread(url, stats, stop):
    """One page open on the gateway for the whole run: its session id, messages received,
    and a ping answered at the end."""
    import aiohttp

    async def run():
        async with aiohttp.ClientSession() as http, \
                http.ws_connect(url.replace("http", "ws", 1) + "ws") as ws:
            hello = await ws.receive_json(timeout=30)
            stats["sid"] = hello["session"]
            stats["ready"].set()
            while not stop.is_set():
                try:
                    m = await ws.receive(timeout=0.5)
                except asyncio.TimeoutError:
                    continue
                if m.type != aiohttp.WSMsgType.TEXT:
                    stats["closed"] = True
                    return
                stats["received"][json.loads(m.data)["type"]] += 1
            await ws.send_str('{"type": "ping"}')
            while (await ws.receive_json(timeout=30))["type"] != "pong":
                pass
            stats["pong"] = True

    try:
        asyncio.run(run())
    except Exception as e:  # noqa: BLE001 - reported
        stats["failure"] = repr(e)
        stats["ready"].set()


RESULT_LINES = ("motion ", "measure ", "distance ", "photo ")


def session_lines(*argv):
    """The result lines ``findme ARGV`` prints (motion, measurement, distance, each photo's
    hypotheses count, selection and scene; timings and file names left out, and pose lines,
    which a disturbed bus may leave out when the motion fails)."""
    out = subprocess.run([sys.executable, "-m", "findme.cli", *argv], capture_output=True,
                         text=True, timeout=600, check=True).stdout
    return [re.sub(r" in \d+ ms", "", ln) for ln in out.splitlines()
            if ln.startswith(RESULT_LINES) and "file:" not in ln and ": at x " not in ln]


def statuses(client) -> dict:
    """ServiceStatus of every live service instance (one status query to all; every
    instance replies on the query's own key, so no consolidation)."""
    out = {}
    for q in client.get(f"{SERVICES}/*/*/status", timeout=10,
                        consolidation=zenoh.ConsolidationMode.NONE):
        if q.ok is not None:
            s = schemas.decode(schemas.ServiceStatus, q.ok.payload.to_bytes())
            out[f"{s.service}/{s.instance}"] = s
    return out


def depths(client) -> dict:
    """Queue depth of every live service instance."""
    return {k: s.queue_depth for k, s in statuses(client).items()}


def drain_all(client, patience=60.0):
    """(statuses, hung services): polls every service's status until each has an empty queue
    and no new input twice in a row; one whose queue does not move for ``patience`` seconds
    is hung."""
    last, moved, quiet = {}, {}, Counter()
    while True:
        st = statuses(client)
        now = time.monotonic()
        for n, s in st.items():
            sig = (s.frames_in, s.queue_depth, s.results_out, s.errors)
            if sig != last.get(n):
                last[n], moved[n], quiet[n] = sig, now, 0
            elif s.queue_depth == 0:
                quiet[n] += 1
        hung = [n for n, s in st.items() if s.queue_depth and now - moved[n] > patience]
        if all(quiet[n] >= 2 or n in hung for n in st):
            return st, hung
        time.sleep(0.5)   # polling status counters (a benchmark, not a test)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--messages", type=int, default=100_000, help="malformed messages to send")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--json", help="write the results here")
    ap.add_argument("--keep", action="store_true", help="keep the temporary folder (logs)")
    ap.add_argument("--window", type=int, default=4000,
                    help="at most this many expected errors outstanding while sending "
                         "(0 = flood: send as fast as the bus takes it)")
    a = ap.parse_args(argv)
    faulthandler.register(signal.SIGUSR1)   # kill -USR1 <pid>: where is it?
    rng = random.Random(a.seed)
    tmp = Path(tempfile.mkdtemp(prefix="findme-fuzz-"))
    print(f"logs and recordings in {tmp}", flush=True)
    expected_run = session_lines("run", "--no-record")

    # every key of every service, from the handlers themselves
    class Args:
        method, max, latest, auto, interactive, out = "findme", 10, None, True, False, str(tmp)
    inputs, queries, caches = defaultdict(list), defaultdict(list), defaultdict(list)
    for name in service_names():
        h = make_handler(name, Args)
        for inp in h.inputs:
            kind = inp.key.split("/")[2]
            (inputs[kind] if inp.type is not None else inputs["*raw*"]).append(name)
        for q in h.queries:
            queries[q.key.split("/")[2]].append(name)
        for ck in h.cache_keys:
            caches[ck].append(name)
        h.close()
    typed = {k: v for k, v in inputs.items() if k != "*raw*"}
    print(f"typed inputs {dict(typed)}; raw: {inputs['*raw*']}; queries {dict(queries)}; "
          f"caches {dict(caches)}", flush=True)

    port = __import__("tests.services.conftest", fromlist=["free_port"]).free_port()
    ep = f"tcp/127.0.0.1:{port}"
    procs, closers = {}, []
    try:
        return fuzz(a, rng, tmp, ep, procs, closers, typed, queries, caches, expected_run)
    finally:   # whatever happened: no process of ours left running
        for close in reversed(closers):
            try:
                close()
            except zenoh.ZError as e:   # already closed on the normal path
                print(f"cleanup: {e}", file=sys.stderr)
        for p in reversed(list(procs.values())):
            if p.p.poll() is None:
                p.p.kill()
                p.p.wait(10)
        if not a.keep:
            import shutil
            shutil.rmtree(tmp, ignore_errors=True)


def fuzz(a, rng, tmp, ep, procs, closers, typed, queries, caches, expected_run):
    """Start everything, fuzz, drain, run a correct session, stop, report (see main)."""
    procs["router"] = Proc("router", ["router", "--listen", ep], tmp)
    wait_line(procs["router"], "listening on")
    warm = "warm-1"
    photos = [str(EXAMPLES / "room_a.jpg"), str(EXAMPLES / "room_b.jpg")]
    for name in [n for n in service_names() if n != "capture"]:   # every service there is
        flags = {"selection": ["--auto"], "recorder": ["--out", tmp / "rec"],
                 "viewer": ["--out", tmp / "rrd"],
                 "gateway": ["--http", "127.0.0.1:0"]}.get(name, [])
        procs[name] = Proc(name, ["serve", name, "--connect", ep, "--instance", name, *flags],
                           tmp, stdout=name == "gateway")
    client = open_session(BusConfig(mode="client", connect=(ep,)))
    closers.append(client.close)
    for name in procs:
        if name != "router":
            wait_alive(client, name, 120)
    # the warm-up session: capture publishes the example pair and ends once it has its results
    cap = Proc("capture", ["serve", "capture", "--connect", ep, "--session", warm, *photos], tmp)
    if cap.p.wait(300) != 0:
        raise RuntimeError(f"the warm-up capture failed: {cap.log()[-2000:]}")
    url = procs["gateway"].p.stdout.readline().split("serving ", 1)[1].split()[0]
    expected = Counter()        # (key, service) -> errors expected
    tally = Tally(expected)
    blips = Counter()   # liveliness tokens that went away during the run (a link closed)
    lsub = client.liveliness().declare_subscriber(
        f"{SERVICES}/**", lambda smp: smp.kind == zenoh.SampleKind.DELETE and
        blips.update([str(smp.key_expr).split("/")[-2]]))
    subs = [lsub, client.declare_subscriber("findme/*/error", tally.on_error),
            client.declare_subscriber("findme/@errors", tally.on_error)]
    closers.append(lambda: [s.undeclare() for s in subs])   # else exit waits on their threads
    drain_all(client)      # the warm-up's last results (the mapper's plan) before measuring
    page = {"received": Counter(), "ready": threading.Event(), "closed": False, "pong": False}
    stop_page = threading.Event()
    pt = threading.Thread(target=page_thread, args=(url, page, stop_page), daemon=True)
    pt.start()
    page["ready"].wait(60)
    sessions = SESSIONS + [page["sid"]]
    before = {n: p.rss_mb() for n, p in procs.items()}
    st0 = statuses(client)

    # ---------------------------------------------------------------- fuzz
    what = {}                   # (key, service) -> "mutation kind" of the last message there
    sent = Counter()            # category -> messages
    by_kind = Counter()
    valid_shaped = defaultdict(list)   # kind -> keys
    valid_keys = set()
    gets = {"sent": 0, "done": 0, "ok": 0, "err": 0}
    gcv = threading.Condition()

    def on_reply(reply):
        with gcv:
            gets["ok" if reply.ok is not None else "err"] += 1

    def on_done():
        with gcv:
            gets["done"] += 1
            gcv.notify_all()

    def get(key, payload):
        with gcv:   # at most 64 queries in flight
            gcv.wait_for(lambda: gets["sent"] - gets["done"] < 64, 600)
            gets["sent"] += 1
        client.get(key, zenoh.handlers.Callback(on_reply, on_done), payload=payload, timeout=30)

    put_kinds = sorted(set(KIND_TYPE) - {"measure"})
    weights = {k: (20 if k in typed else 3) for k in put_kinds}
    weights["measure"] = 10
    kinds, w = zip(*weights.items())
    cache_keys = [k for k in caches]
    status_keys = [f"{SERVICES}/{n}/{n}/status" for n in procs if n != "router"]
    malformed, i, t0, total_expected, slack, stalls = 0, 0, time.perf_counter(), 0, 0, []
    while malformed < a.messages:
        i += 1
        r = rng.random()
        if r < 0.02:   # a cache or status query with garbage: answered with what it has
            k = rng.choice(cache_keys).replace("*", rng.choice(sessions), 1).replace("*", str(i))
            get(rng.choice([k, rng.choice(status_keys)]), rng.randbytes(rng.randrange(64)))
            sent["cache/status query"] += 1
            continue
        kind = rng.choices(kinds, w)[0]
        session = rng.choice(sessions)
        good = templates(session, i)[kind]
        cat, key, payload = mutate(rng, kind, session, i, good)
        key_kind = key.split("/")[2] if key.count("/") >= 2 else kind
        v = verdict(key_kind, key, payload) if key_kind in KIND_TYPE else "refused"
        try:
            zenoh.KeyExpr(key)
        except zenoh.ZError:
            sent["key zenoh refuses (not sent)"] += 1
            continue
        if v == "valid":
            valid_shaped[key_kind].append(key)
            valid_keys.add(key)
            sent[f"valid-shaped ({cat})"] += 1
        else:
            malformed += 1
            sent[cat] += 1
            by_kind[key_kind] += 1
            answer = queries.get(key_kind, []) if kind == "measure" else typed.get(key_kind, [])
            if len(key.split("/")) != (5 if key_kind == "motion" else 3 if key_kind in
                                       ("trajectory", "error", "measure") else 4):
                answer = []   # no subscription matches a key of another shape
            with tally.cv:
                for svc in answer:
                    ks = (key, svc)
                    expected[ks] += 1
                    what[ks] = f"{cat} {key_kind}"
                    # an error already here beyond what was expected (e.g. about a valid-shaped
                    # message on the same key) now counts as this one's
                    tally.matched += tally.errors[ks] >= expected[ks]
                total_expected += len(answer)
                if a.window and not tally.cv.wait_for(   # paced: `window` errors outstanding
                        lambda: total_expected - tally.matched - slack < a.window, 10):
                    slack = total_expected - tally.matched   # lost or late: stop waiting on them
                    stalls.append(f"message {i}: {slack} errors outstanding for 10 s")
        if kind == "measure":
            get(key, payload)
        else:
            client.put(key, payload, congestion_control=zenoh.CongestionControl.BLOCK)
        if a.window and i % 250 == 0:   # and every queue at most half full (the viewer, ...)
            t_wait = time.monotonic()
            while max(depths(client).values(), default=0) > 128:
                if time.monotonic() - t_wait > 120:
                    stalls.append(f"message {i}: a queue stayed over 128 for 120 s")
                    break
                time.sleep(0.05)   # polling queue depths (a benchmark, not a test)
        if i % 20000 == 0:
            print(f"  {i} sent ({malformed} malformed), {tally.error_total} errors back, "
                  f"{time.perf_counter() - t0:.0f} s", flush=True)
    send_s = time.perf_counter() - t0

    # ---------------------------------------------------------------- drain
    def settled():
        with tally.cv:
            return tally.matched

    last, last_t = -1, time.monotonic()
    while True:
        got = settled()
        with gcv:
            qdone = gets["done"] == gets["sent"]
        if got >= total_expected and qdone:
            break
        if got != last:
            last, last_t = got, time.monotonic()
        elif time.monotonic() - last_t > 60:
            print(f"  no progress for 60 s: {got} of {total_expected} errors, queries "
                  f"{gets['done']} of {gets['sent']} done", flush=True)
            break      # whatever is missing is reported
        with tally.cv:
            tally.cv.wait(1.0)
    errors_s = time.perf_counter() - t0 - send_s
    st1, hangs = drain_all(client)
    drain_s = time.perf_counter() - t0 - send_s
    after_fuzz = {n: p.rss_mb() for n, p in procs.items()}

    blips_fuzz = dict(blips)   # (findme send's own token leaves when it ends)
    # ---------------------------------------------------------------- a correct session
    got_lines = session_lines("send", "--connect", ep, "--session", "after-1")
    same = bool(expected_run) and got_lines == expected_run
    after = {n: p.rss_mb() for n, p in procs.items()}
    peak = {n: p.rss_mb("VmHWM") for n, p in procs.items()}
    stop_page.set()
    pt.join(60)
    alive_at_end = {n: p.p.poll() is None for n, p in procs.items()}
    for close in reversed(closers):
        close()
    closers.clear()
    for p in reversed(list(procs.values())):
        if p.p.poll() is None:
            p.p.send_signal(signal.SIGTERM)
    codes = {}
    for p in procs.values():
        try:
            codes[p.name] = p.p.wait(60)
        except subprocess.TimeoutExpired:
            p.p.kill()
            codes[p.name] = "hung on SIGTERM"
    tracebacks = {n: p.log().count("Traceback") for n, p in procs.items()}

    # ---------------------------------------------------------------- report
    per_service = {}
    for (key, svc), n in expected.items():
        d = per_service.setdefault(svc, Counter())
        d["expected"] += n
        d["received"] += min(tally.errors[(key, svc)], n)
    for (key, svc), n in tally.errors.items():
        extra_n = n - expected.get((key, svc), 0)
        if extra_n > 0:
            tag = "for valid-shaped" if key in valid_keys else "other (cascades)"
            per_service.setdefault(svc, Counter())[tag] += extra_n
    crashes = [n for n, alive in alive_at_end.items() if not alive] + \
        [n for n, c in codes.items() if c != 0]
    # the viewer stops cleanly (exit 0) after its recording limit, for its supervisor to
    # start it afresh (Rerun never frees a recording stream): reported, not a crash
    restarts = [n for n in crashes if codes.get(n) == 0
                and "starts a fresh viewer" in procs[n].log()]
    crashes = [n for n in crashes if n not in restarts]
    print()
    print(f"sent: {i} messages in {send_s:.0f} s (then {errors_s:.0f} s until the last error, "
          f"{drain_s:.0f} s until every queue was empty): {malformed} "
          f"malformed, {sum(v for k, v in sent.items() if k.startswith('valid'))} valid-shaped, "
          f"{sent['cache/status query']} cache/status queries")
    print("by mutation: " + ", ".join(f"{k} {v}" for k, v in sorted(sent.items())))
    print("malformed by key kind: " + ", ".join(f"{k} {v}" for k, v in sorted(by_kind.items())))
    print()
    print(f"{'service':12s} {'errors expected':>15s} {'received':>9s} {'missing':>8s} "
          f"{'extra (valid-shaped, cascades)':>31s} {'in':>8s} {'RSS before':>11s} "
          f"{'after fuzz':>11s} {'after':>7s} {'peak':>7s} {'tracebacks':>10s} exit")
    for n, p in procs.items():
        d = per_service.get(n, Counter())
        s0, s1 = st0.get(f"{n}/{n}"), st1.get(f"{n}/{n}")
        fin = s1.frames_in - s0.frames_in if s0 is not None and s1 is not None else 0
        print(f"{n:12s} {d['expected']:15d} {d['received']:9d} {d['expected'] - d['received']:8d} "
              f"{d['for valid-shaped']:>15d}, {d['other (cascades)']:<14d} {fin:8d} "
              f"{before[n]:8.0f} MB {after_fuzz[n]:8.0f} MB {after[n]:4.0f} MB {peak[n]:4.0f} MB "
              f"{tracebacks[n]:10d} {codes[n]}")
    print()
    print(f"measure queries and cache/status queries: {gets['sent']} sent, {gets['done']} "
          f"completed, {gets['err']} error replies, {gets['ok']} data replies")
    print("error codes received: " + ", ".join(f"{k.removeprefix('ERROR_CODE_')} {v}"
                                               for k, v in tally.codes.most_common()))
    if tally.internal:
        print("INTERNAL errors (bugs):")
        for line in tally.internal:
            print("   ", line)
    missing = Counter()
    examples = defaultdict(list)
    for ks, n in expected.items():
        short = n - min(tally.errors[ks], n)
        if short:
            missing[(ks[1], what[ks])] += short
            if len(examples[ks[1]]) < 5:
                examples[ks[1]].append(f"{ks[0][:90]} ({what[ks]})")
    if missing:
        print("missing errors by service and mutation: " + ", ".join(
            f"{svc} {w}: {n}" for (svc, w), n in missing.most_common(20)))
        for svc, ex in examples.items():
            print(f"   e.g. {svc}: " + "; ".join(ex))
    vs = {k: len(v) for k, v in valid_shaped.items()}
    print(f"valid-shaped messages by kind: {vs} (answered per service above as 'extra')")
    print(f"page {page.get('sid')}: received {dict(page['received'])}, socket closed "
          f"{page['closed']}, pong at the end {page['pong']}, failure {page.get('failure')}")
    print(f"pacing stalls: {len(stalls)} {stalls[:5]}")
    if restarts:
        print(f"stopped for their supervisor to restart them (recording limit): {restarts}")
    print(f"crashes {len(crashes)} {crashes}; hangs {len(hangs)} {hangs}; liveliness "
          f"tokens lost during the run (a link closed): {blips_fuzz or 0}")
    print(f"two-photo session afterwards prints what findme run prints: {same}")
    for ln in got_lines:
        print("   bus:", ln)
    if not same:
        for ln in expected_run:
            print("   run:", ln)
    res = {"messages": i, "malformed": malformed, "sent": dict(sent), "send_s": send_s,
           "drain_s": drain_s, "per_service": {k: dict(v) for k, v in per_service.items()},
           "rss_mb": {"before": before, "after_fuzz": after_fuzz, "after": after, "peak": peak},
           "queries": gets, "codes": dict(tally.codes), "internal": tally.internal,
           "crashes": crashes, "planned_restarts": restarts, "hangs": hangs, "stalls": stalls, "liveliness_lost": blips_fuzz, "exit": codes, "tracebacks": tracebacks,
           "same_as_findme_run": same,
           "missing": {f"{svc} {w}": n for (svc, w), n in missing.items()}, "bus_lines": got_lines, "run_lines": expected_run,
           "page": {k: (dict(v) if isinstance(v, Counter) else v) for k, v in page.items()
                    if k != "ready"}}
    if a.json:
        Path(a.json).write_text(json.dumps(res, indent=1, default=str))
    ok = not crashes and not hangs and same and all(
        d["expected"] == d["received"] for d in per_service.values())
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
