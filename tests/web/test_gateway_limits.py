"""The gateway against hostile or careless clients (issue 11): one client's idle sockets do not
lock out another, idle pages and slow headers are closed, a DNS-rebinding Origin is refused
(allowed origins are configurable), and deeply nested JSON, a 5,000-digit number or a bug
while handling a message answer the page with an error and keep its socket.

The gateway runs in-process on an in-process bus; clients are aiohttp WebSockets and raw
sockets. A second client has its own address (127.0.0.2: all of 127/8 is loopback). Every
wait is on a message, a close or a reply."""

from __future__ import annotations

import asyncio
import json
import socket
import sys
from pathlib import Path

import aiohttp
import pytest

from services.runtime import bus
from services.web import page_session
from services.web.gateway import Gateway
from services.web.page_guard import (ClientPages, OriginPolicy, client_of, normalize_origin,
                                     served_names)

pytestmark = pytest.mark.timeout(120)


@pytest.fixture
def gateway(request):
    """Gateway(**kw) on an in-process bus, started; kw by indirect parametrisation."""
    zs = bus.open_session()
    gw = Gateway(zs, "127.0.0.1", 0, **getattr(request, "param", {}))
    url = gw.start()
    yield gw, url
    gw.stop()
    zs.close()


def ws_url(url):
    return url.replace("http", "ws", 1) + "ws"


async def error_about(ws, key, timeout=10):
    """The next error message on the page about ``key`` (relative to the session)."""
    while True:
        m = await ws.receive_json(timeout=timeout)
        if m["type"] == "error" and m["key"] == key:
            return m


async def alive(ws):
    await ws.send_str('{"type": "ping"}')
    while (await ws.receive_json(timeout=10))["type"] != "pong":
        pass


# ------------------------------------------------------------------------------ pure parts
def test_origin_policy():
    p = OriginPolicy(["https://findme.example.org", "http://LAB.example:8080/"])
    assert p.allows(None, "x", "http")                       # no Origin: not a browser page
    assert p.allows("https://findme.example.org", "127.0.0.1:8080", "http")  # behind a proxy
    assert p.allows("http://lab.example:8080", "lab.example:8080", "http")
    assert p.allows("http://127.0.0.1:8080", "127.0.0.1:8080", "http")     # loaded from here
    assert p.allows("http://[::1]:8080", "[::1]:8080", "http")
    assert p.allows("https://localhost", "localhost:443", "https")
    # DNS rebinding: Origin and Host name the same attacker domain
    assert not p.allows("http://evil.example:8080", "evil.example:8080", "http")
    assert not p.allows("http://6.6.6.6:8080", "127.0.0.1:8080", "http")    # another server
    assert not p.allows("https://127.0.0.1:8080", "127.0.0.1:8080", "http")  # other scheme
    for bad in ("null", "file://", "http://a.example/path", "http://u@127.0.0.1:8080", ""):
        assert not p.allows(bad, "127.0.0.1:8080", "http"), bad
    # a name the server is reached by (its certificate's, its own host name)
    own = OriginPolicy(own_names=["findme.lan"])
    assert own.allows("https://findme.lan:8443", "findme.lan:8443", "https")
    assert not own.allows("https://findme.lan:8443", "evil.example:8443", "https")
    assert not own.allows("https://evil.example:8443", "evil.example:8443", "https")
    assert normalize_origin("HTTPS://Findme.Example.org:443") == "https://findme.example.org"
    with pytest.raises(Exception, match="not scheme://host"):
        OriginPolicy(["findme.example.org"])


def test_served_names_include_the_certificate_names(tmp_path):
    pytest.importorskip("cryptography", reason="cryptography makes the certificate")
    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tools"))
    from make_certs import make_certs
    make_certs(tmp_path, ("findme.lan", "192.168.1.20"))
    names = served_names(str(tmp_path / "gateway.pem"))
    assert {"findme.lan", "gateway"} <= names and socket.gethostname().lower() in names
    assert "localhost" not in names and "192.168.1.20" not in names   # addresses need no name


def test_client_address_and_page_counts():
    assert client_of("10.0.0.9", "1.2.3.4") == "10.0.0.9"          # untrusted peer: its own
    assert client_of("10.0.0.9", "6.6.6.6, 1.2.3.4", {"10.0.0.9"}) == "1.2.3.4"
    assert client_of("10.0.0.9", "1.2.3.4, 10.0.0.8", {"10.0.0.9", "10.0.0.8"}) == "1.2.3.4"
    assert client_of(None, None) == "unknown"
    c = ClientPages(2)
    assert c.acquire("a") and c.acquire("a") and not c.acquire("a") and c.acquire("b")
    c.release("a")
    assert c.acquire("a") and not c.acquire("a")


# ------------------------------------------------------------------------------ live gateway
def test_idle_sockets_of_one_client_do_not_lock_out_another(gateway):
    """150 WebSockets from one address: the first ``max_per_client`` are pages, the rest are
    told why and closed (1013); a client at another address is served; closing a page frees
    a place for its own client."""
    gw, url = gateway
    limit = gw.clients.limit

    async def run():
        async with aiohttp.ClientSession(connector=aiohttp.TCPConnector(limit=0)) as one, \
                aiohttp.ClientSession(connector=aiohttp.TCPConnector(
                    local_addr=("127.0.0.2", 0))) as two:
            socks = await asyncio.gather(*(one.ws_connect(ws_url(url)) for _ in range(150)))
            first = await asyncio.gather(*(ws.receive_json(timeout=30) for ws in socks))
            pages = [ws for ws, m in zip(socks, first) if m["type"] == "hello"]
            refused = [(ws, m) for ws, m in zip(socks, first) if m["type"] == "error"]
            assert len(pages) == limit and len(refused) == 150 - limit
            assert all(m["code"] == "OVERLOADED" and "pages open" in m["message"]
                       for _, m in refused)
            for ws, _ in refused:
                assert (await ws.receive(timeout=10)).type == aiohttp.WSMsgType.CLOSE
                assert ws.close_code == aiohttp.WSCloseCode.TRY_AGAIN_LATER
            async with two.ws_connect(ws_url(url)) as other:   # the second client
                hello = await other.receive_json(timeout=30)
                assert hello["type"] == "hello", hello
                await alive(other)
            await pages[0].close()
            # the server frees the place once its side of the page has ended, just after the
            # close handshake: ask again until served (each try waits on the server's answer)
            for _ in range(100):
                again = await one.ws_connect(ws_url(url))
                first = await again.receive_json(timeout=30)
                if first["type"] == "hello":
                    break
                assert first["code"] == "OVERLOADED", first
                await again.close()
            assert first["type"] == "hello", first
            for ws in [*pages, again]:
                await ws.close()
        return gw.handler.stats["pages_open"]

    assert asyncio.run(run()) in range(0, limit + 1)


@pytest.mark.parametrize("gateway", [{"idle_timeout": 0.5}], indirect=True)
def test_an_idle_page_is_closed_with_the_reason(gateway):
    gw, url = gateway

    async def run():
        async with aiohttp.ClientSession() as http:
            ws = await http.ws_connect(ws_url(url), autoping=True)
            assert (await ws.receive_json(timeout=10))["type"] == "hello"
            while (m := await ws.receive(timeout=30)).type == aiohttp.WSMsgType.TEXT:
                pass   # whatever the bus sends the page meanwhile
            assert m.type == aiohttp.WSMsgType.CLOSE
            assert (m.data, m.extra) == (aiohttp.WSCloseCode.GOING_AWAY, "idle for 0.5 s")

    asyncio.run(run())


@pytest.mark.parametrize("gateway", [{"header_timeout": 0.5}], indirect=True)
def test_slow_headers_time_out_but_open_pages_stay(gateway):
    """Slowloris: a connection that never finishes its request headers is closed by the
    server; a WebSocket opened before it is still served afterwards."""
    gw, url = gateway
    host, port = url.split("//")[1].rstrip("/").split(":")

    async def run():
        async with aiohttp.ClientSession() as http, http.ws_connect(ws_url(url)) as ws:
            assert (await ws.receive_json(timeout=10))["type"] == "hello"

            def slowloris():
                with socket.create_connection((host, int(port)), timeout=30) as s:
                    s.sendall(b"GET / HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Slow: 1")
                    return s.recv(1024)      # b"": the server closed it
            assert await asyncio.to_thread(slowloris) == b""
            await alive(ws)

    asyncio.run(run())


@pytest.mark.parametrize("gateway", [{"allowed_origins": ["https://findme.example.org"]}], indirect=True)
def test_dns_rebinding_origin_refused_allowed_origins_configurable(gateway):
    gw, url = gateway
    port = url.rstrip("/").rsplit(":", 1)[1]

    async def status(origin, host):
        async with aiohttp.ClientSession() as http:
            try:
                async with http.ws_connect(ws_url(url), headers={
                        "Origin": origin, "Host": host}) as ws:
                    return (await ws.receive_json(timeout=10))["type"]
            except aiohttp.WSServerHandshakeError as e:
                return e.status

    async def run():
        return [await status(o, h) for o, h in [
            (f"http://evil.example:{port}", f"evil.example:{port}"),   # DNS rebinding
            ("http://evil.example", f"127.0.0.1:{port}"),
            ("null", f"127.0.0.1:{port}"),
            ("https://findme.example.org", "findme.example.org"),       # configured
            (f"http://127.0.0.1:{port}", f"127.0.0.1:{port}"),         # this server
            (f"http://localhost:{port}", f"localhost:{port}")]]

    assert asyncio.run(run()) == [403, 403, 403, "hello", "hello", "hello"]


def test_nested_and_huge_json_answered_on_the_page(gateway, monkeypatch):
    """Each answered by an error message on the page, whose socket stays open: deep nesting,
    a 5,000-digit integer, NaN, the same in an upload's header, and a bug in the gateway
    itself (INTERNAL)."""
    gw, url = gateway
    deep = "[" * 30_000 + "]" * 30_000     # under the text size limit; RecursionError before
    huge = '{"type": "select", "index": ' + "7" * 5000 + ', "rank": 1}'
    nan = '{"type": "select", "index": 0, "rank": NaN}'

    def header_upload(text):
        h = text.encode()
        return len(h).to_bytes(4, "big") + h + b"\xff\xd8\xff"

    async def run():
        async with aiohttp.ClientSession() as http, http.ws_connect(ws_url(url)) as ws:
            assert (await ws.receive_json(timeout=10))["type"] == "hello"
            got = []
            for text in (deep, huge, nan):
                await ws.send_str(text)
                got.append(await error_about(ws, "gateway"))
                await alive(ws)
            await ws.send_bytes(header_upload("{" + '"a":{' * 50 + "}" * 51))
            assert (await ws.receive_json(timeout=10))["type"] == "refused"
            got.append(await error_about(ws, "frame/0"))
            boom = iter([ZeroDivisionError("a bug")])
            real = page_session.parse_command
            monkeypatch.setattr(page_session, "parse_command",
                                lambda t: (_ for _ in ()).throw(next(boom)) if "boom" in t else real(t))
            await ws.send_str('{"type": "boom"}')
            got.append(await error_about(ws, "gateway"))
            await alive(ws)
            return got

    got = asyncio.run(run())
    assert [g["code"] for g in got] == ["MALFORMED", "TOO_LARGE", "MALFORMED", "MALFORMED",
                                        "INTERNAL"]
    assert "nested more than" in got[0]["message"] and "5000 characters" in got[1]["message"]
    assert "NaN" in got[2]["message"] and "upload header" in got[3]["message"]
    assert "ZeroDivisionError" in got[4]["message"]


def test_a_compressed_upload_is_bounded_after_decompression(gateway):
    """permessage-deflate: 40 MB of zeros travel as ~40 kB; the server stops inflating at its
    upload limit and closes the socket with 1009 (message too big)."""
    gw, url = gateway

    async def run():
        async with aiohttp.ClientSession() as http, \
                http.ws_connect(ws_url(url), compress=15) as ws:
            assert ws.compress and (await ws.receive_json(timeout=10))["type"] == "hello"
            await ws.send_bytes(bytes(40 << 20))
            while (m := await ws.receive(timeout=30)).type == aiohttp.WSMsgType.TEXT:
                pass
            return m.type, ws.close_code

    assert asyncio.run(run()) == (aiohttp.WSMsgType.CLOSE, aiohttp.WSCloseCode.MESSAGE_TOO_BIG)
