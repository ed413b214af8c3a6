"""Who may open a page on the gateway: the WebSocket's Origin, the client's address, and how
many pages one client may hold open.

Origin (what stops another web site, and DNS rebinding, from driving the gateway from a
victim's browser): a browser always sends the Origin of the page that opens a WebSocket. It
is allowed when it is in the configured allow-list (``--allow-origin``, e.g. the public
``https://findme.example.org`` behind a reverse proxy), or when the page was loaded from this
very server under a name it serves: an IP literal, ``localhost``, this machine's own names
or the DNS names of its certificate (``served_names``), and the Origin equals the address
the browser connected to (the Host header). Any other DNS name is refused: in a
DNS-rebinding attack Origin and Host both name the attacker's domain (``evil.example``,
re-resolved to this server), so comparing them alone proves nothing.
No Origin at all is a native client or a script, not a browser page: allowed.

Client address: the TCP peer, or, when the peer is a trusted reverse proxy, the nearest
untrusted address in its ``X-Forwarded-For`` (so one proxy is not one client).

Pure: no server, no bus.
"""

from __future__ import annotations

import ipaddress
import socket
import ssl
from collections import Counter
from urllib.parse import urlsplit

from findme_core.errors import InputError

_DEFAULT_PORT = {"http": 80, "https": 443}


def normalize_origin(origin: str) -> str | None:
    """``scheme://host[:port]``, lower-case, default port dropped, IPv6 in brackets; None
    when it is not an http(s) origin (``null``, ``file://``, garbage)."""
    try:
        u = urlsplit(str(origin).strip())
        port = u.port
    except ValueError:
        return None
    if u.scheme not in _DEFAULT_PORT or not u.hostname or u.path not in ("", "/") \
            or u.query or u.fragment or u.username is not None:
        return None
    host = f"[{u.hostname}]" if ":" in u.hostname else u.hostname
    keep = port is not None and port != _DEFAULT_PORT[u.scheme]
    return f"{u.scheme}://{host}" + (f":{port}" if keep else "")


def _is_address(host: str) -> bool:
    """An IP literal or localhost: no DNS name an attacker could re-point."""
    if host == "localhost":
        return True
    try:
        ipaddress.ip_address(host.strip("[]"))
    except ValueError:
        return False
    return True


def served_names(cert: str | None = None) -> set[str]:
    """The DNS names this server is reached by: its host name, fully qualified name and
    ``<name>.local`` (mDNS), and the DNS subjectAltNames of its HTTPS certificate ``cert``
    (a PEM file), all lower-case."""
    host = socket.gethostname().lower()
    names = {host, socket.getfqdn().lower(), f"{host.split('.')[0]}.local"}
    if cert:
        # the standard library's own decoder (ssl has no public one for a file)
        decoded = ssl._ssl._test_decode_cert(cert)
        names |= {v.lower() for k, v in decoded.get("subjectAltName", ()) if k == "DNS"}
    return {n for n in names if n and n != "localhost"}


class OriginPolicy:
    """Which browser pages may open a WebSocket (see the module docstring)."""

    def __init__(self, allowed=(), own_names=()):
        self.own = {n.lower() for n in own_names}
        self.allowed = set()
        for o in allowed:
            n = normalize_origin(o)
            if n is None:
                raise InputError(f"allowed origin {o!r} is not scheme://host[:port] "
                                 "(e.g. https://findme.example.org)")
            self.allowed.add(n)

    def allows(self, origin: str | None, host_header: str | None, scheme: str) -> bool:
        if origin is None:
            return True            # not a browser page
        o = normalize_origin(origin)
        if o is None:
            return False
        if o in self.allowed:
            return True
        host = urlsplit(o).hostname or ""
        return ((_is_address(host) or host in self.own) and host_header is not None
                and o == normalize_origin(f"{scheme}://{host_header}"))


def client_of(remote: str | None, forwarded_for: str | None, trusted=frozenset()) -> str:
    """The client's address: ``remote``, or behind a trusted proxy the nearest address in
    ``X-Forwarded-For`` that is not itself a trusted proxy."""
    if remote in trusted and forwarded_for:
        for hop in reversed([h.strip() for h in forwarded_for.split(",")]):
            if hop and hop not in trusted:
                return hop
    return remote or "unknown"


class ClientPages:
    """Open pages per client address, at most ``limit`` each."""

    def __init__(self, limit: int):
        self.limit = limit
        self.open: Counter = Counter()

    def acquire(self, client: str) -> bool:
        if self.open[client] >= self.limit:
            return False
        self.open[client] += 1
        return True

    def release(self, client: str) -> None:
        self.open[client] -= 1
        if self.open[client] <= 0:
            del self.open[client]
