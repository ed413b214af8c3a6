"""``findme status``: which services are alive on a bus, with their counters."""

from __future__ import annotations

import json
import time

import zenoh

import schemas
from services.runtime import bus

from .bus_options import add_bus_args, open_bus


STATUS_HELP = """\
Which services are alive on the bus, each instance with how long it has been up
and its counters: messages in, results out, errors (by code), dropped, waiting.
Without a router it says so in one line (exit status 2) within --wait seconds.

Example:  findme status --connect tcp/127.0.0.1:7447"""


def register(sub) -> None:
    st = sub.add_parser("status", help="which services are alive, with their counters",
                        description=STATUS_HELP)
    add_bus_args(st)
    st.add_argument("--json", action="store_true", help="print a JSON list, one object per "
                    "service instance")
    st.add_argument("--wait", type=float, default=2.0, metavar="S",
                    help="how long to wait for the router (default 2 s)")
    st.set_defaults(func=cmd_status)


#: how long ``service_statuses`` waits for the liveliness history when nothing answered
HISTORY_WAIT_S = 1.0


def alive_services(session: zenoh.Session, timeout: float = 3.0) -> set[str]:
    """Names of the services whose liveliness tokens are on the bus now."""
    return {str(r.ok.key_expr).split("/")[-2] for r in
            session.liveliness().get(f"{bus.SERVICES}/**", timeout=timeout) if r.ok}


def service_statuses(session: zenoh.Session, timeout: float = 3.0, peers=None) -> list:
    """ServiceStatus of every live service instance.

    Every instance answers one status query sent to all of them (target ALL, no
    consolidation); an instance whose liveliness token is up but which does not answer (hung)
    is listed with its name alone. The tokens come from a liveliness subscriber with history
    (``peers``, a ``runtime.peers.Peers`` a long-lived caller keeps; else one made here):
    liveliness queries repeated on one long-lived session sometimes come back empty."""
    from services.runtime.peers import Peers
    own = peers is None
    peers = Peers(session, "*", seed_timeout=timeout) if own else peers
    try:
        found = {}
        for k, payload in bus.get_all(session, f"{bus.SERVICES}/*/*/status", timeout):
            try:
                st = schemas.decode(schemas.ServiceStatus, payload)
            except Exception:  # noqa: BLE001 - a foreign reply on our key: not a service
                continue
            found[(st.service, st.instance)] = st
        if own and not found:
            # the seed query of a subscriber just declared can come back empty at once (see
            # ``runtime.peers``; 1 run in 11 of test_deploy's status as a device): its
            # history still comes, so wait for it before saying that nothing is alive
            peers.wait_for(bool, min(timeout, HISTORY_WAIT_S))
        for name, inst in peers.all():
            found.setdefault((name, inst), schemas.ServiceStatus(service=name, instance=inst))
    finally:
        if own:
            peers.close()
    return [found[k] for k in sorted(found)]


def cmd_status(args) -> int:
    session = open_bus(args, connect_timeout_s=args.wait)
    try:
        st = service_statuses(session)
    finally:
        session.close()
    if args.json:
        from google.protobuf.json_format import MessageToDict
        print(json.dumps([MessageToDict(s, preserving_proto_field_name=True) for s in st]))
        return 0
    if not st:
        print("no Find Me services are alive on this bus")
        return 0
    now = time.time_ns()
    print(f"{'service':12s} {'instance':10s} {'up':>8s} {'in':>7s} {'out':>7s} {'errors':>7s} "
          f"{'dropped':>8s} {'queue':>6s}")
    for s in st:
        if not s.started_ns:    # alive (its token), but its status did not come back
            print(f"{s.service:12s} {s.instance:10s} {'alive':>8s}  no counters (this client may "
                  "not read them, or the service does not answer)")
            continue
        up = f"{(now - s.started_ns) / 1e9:.0f} s"
        print(f"{s.service:12s} {s.instance:10s} {up:>8s} {s.frames_in:7d} {s.results_out:7d} "
              f"{s.errors:7d} {s.dropped:8d} {s.queue_depth:6d}")
        detail = delivery_detail(s)
        if detail:
            print(f"{'':23s} {detail}")
    return 0


#: status counters that say where inputs went (``runtime.inbox``), in this order
DELIVERY = ("overloaded", "expired", "shed", "superseded", "too_large", "deferred", "unreported",
            "duplicates", "recovered", "handed_over")


def delivery_detail(s) -> str:
    """One line: errors by code and where dropped/recovered inputs went (non-zero only)."""
    c = dict(s.counters)
    errs = [f"{k.removeprefix('error_').replace('_', ' ')} {v}" for k, v in sorted(c.items())
            if k.startswith("error_") and v]
    other = [f"{k.replace('_', ' ')} {c[k]}" for k in DELIVERY if c.get(k)]
    return "; ".join(x for x in (("errors: " + ", ".join(errs)) if errs else "",
                                 ", ".join(other)) if x)
