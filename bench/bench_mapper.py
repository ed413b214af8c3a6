"""Mapper cost: CPU per photo of a growing mapping session, with and without its pair cache.

    python bench/bench_mapper.py [--spots 3] [--step 45] [--json OUT.json]

A rendered 6 x 5 m room (the project's synth: exact ground-wall boundaries as hypotheses, the
rendered JPEGs as frames), photos turning right at each spot every ``--step`` degrees. Each
photo's frame, hypotheses and selection go through ``MapperHandler.on_message`` directly (no
bus). Measured, photo by photo, in one run on one core (CPU time, ``time.thread_time``):

* **mapper**: the handler as it runs: features once per photo, the new photo's pairs related
  once (cached), placement + outline + joint refinement over every photo so far;
* **baseline: no cache**: ``session.plan`` of the same analysed photos from scratch (every
  pair related again), what a mapper that recomputes everything would pay per photo.

Reported: CPU per photo (median, p10/p90) and at the last photo, for both; the final plan's
wall lengths against the truth.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench.common import fmt, pin_one_core, stats  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--spots", type=int, default=3)
    ap.add_argument("--step", type=int, default=45, help="degrees between photos at a spot")
    ap.add_argument("--json", metavar="OUT.json")
    a = ap.parse_args(argv)
    print(pin_one_core())
    from findme_core.plan import session as plan_session
    from findme_core.synth.room import Room
    from services.pipeline.mapper import MapperHandler
    from tests.plan_room import rendered_session

    spots = [(-1.5, -1.2), (1.4, 1.0), (-1.2, 1.3), (1.5, -1.4)][: a.spots]
    room = rendered_session(Room.rectangle(6.0, 5.0), spots, yaws=range(0, 360, a.step))
    m = MapperHandler(max_photos=len(room.frames))
    mapper_ms, base_ms = [], []
    msgs = list(room.messages())
    for n in range(len(room.frames)):
        t0 = time.thread_time()
        outs = [o for k, msg in msgs[3 * n: 3 * n + 3] for o in m.on_message(k, msg)]
        mapper_ms.append(1e3 * (time.thread_time() - t0))
        st = m.sessions[room.frames[0].session]
        photos = [st.photos[i].photo for i in range(n + 1)]
        t0 = time.thread_time()
        try:
            plan_session.plan(photos)
        except Exception:  # noqa: BLE001 - the baseline's outcome does not matter, its cost does
            pass
        base_ms.append(1e3 * (time.thread_time() - t0))
        print(f"photo {n + 1:2d}: mapper {mapper_ms[-1]:8.1f} ms   no cache {base_ms[-1]:8.1f} ms"
              f"   plan: {outs[-1].msg.reason or f'{len(outs[-1].msg.walls)} walls'}", flush=True)
    final = outs[-1].msg
    got = sorted(w.length_m for w in final.walls)
    print(fmt("mapper, per photo", stats(mapper_ms)))
    print(fmt("baseline: no cache, per photo", stats(base_ms)))
    print(f"last photo ({len(room.frames)}): mapper {mapper_ms[-1]:.0f} ms, no cache "
          f"{base_ms[-1]:.0f} ms; walls {np.round(got, 3).tolist()} (truth "
          f"{np.round(room.wall_lengths(), 3).tolist()})")
    if a.json:
        Path(a.json).write_text(json.dumps({"mapper_ms": mapper_ms, "no_cache_ms": base_ms,
                                            "walls_m": got, "truth_m": room.wall_lengths()}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
