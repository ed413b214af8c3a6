"""Does a status call see every live service, every time?

    python bench/bench_liveliness.py [--n 60]

A router and three services (selection, measurement, store), each its own process; one
long-lived client session asks, in a row:

* ``liveliness().get("findme/@services/**")`` n times back to back right after
  ``bus.wait_alive`` for each service (a liveliness subscriber declared and undeclared per
  service, as a client waiting for the services does), then n times back to back later,
  n times 0.25 s apart, and once on each of 15 fresh sessions: what ``findme status`` and
  sharding used before;
* ``findme.cli.status.service_statuses`` n times back to back, also right after
  ``bus.wait_alive`` (now: every instance answers a status query sent to all, plus a
  liveliness subscriber with history).

Prints how many calls saw all three services, and how many saw none.
"""

from __future__ import annotations

import argparse
import os
import sys
import threading

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
from bench.bench_load import Deployment  # noqa: E402
from findme.cli.status import service_statuses  # noqa: E402
from services.runtime import bus  # noqa: E402


def count(tokens) -> int:
    return len({t for t in tokens if t.startswith(bus.SERVICES)})


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=60)
    args = ap.parse_args()
    import tempfile
    with tempfile.TemporaryDirectory() as out:
        dep = Deployment(0, out, services=("selection", "measurement", "store"))
        try:
            c, pace = dep.client, threading.Event()

            def live(session):
                return count(str(r.ok.key_expr) for r in
                             session.liveliness().get(f"{bus.SERVICES}/**", timeout=3) if r.ok)
            names = ("selection", "measurement", "store")

            def after_wait(ask):
                for name in names:
                    bus.wait_alive(c, name)
                return [ask() for _ in range(args.n)]
            rows = {"liveliness get, right after wait_alive": after_wait(lambda: live(c)),
                    "liveliness get, back to back": [live(c) for _ in range(args.n)]}
            spaced = []
            for _ in range(args.n):
                spaced.append(live(c))
                pace.wait(0.25)
            rows["liveliness get, 0.25 s apart"] = spaced
            fresh = []
            for _ in range(15):
                s = bus.open_session(bus.BusConfig(mode="client", connect=(dep.ep,)))
                fresh.append(live(s))
                s.close()
            rows["liveliness get, fresh session each"] = fresh
            rows["service_statuses, right after wait_alive"] = after_wait(
                lambda: len(service_statuses(c)))
        finally:
            dep.close()
    for name, seen in rows.items():
        print(f"{name:42s} all 3: {sum(x == 3 for x in seen):3d} / {len(seen)}   "
              f"none: {sum(x == 0 for x in seen):3d}")


if __name__ == "__main__":
    main()
