"""The gateway: serves the phone client (a web page) and bridges each page to the bus.

    GET /            the page (findme/web/index.html), its scripts (``WEB_FILES``) and
                     /style.css; nothing else
    GET /ws          a WebSocket: ONE new session per connection (= per page load)

The browser never names a key. The gateway makes the session id (``web-<random>``) and a
``PageSession`` (page_session.py) builds every key itself, so a page can only act on its
own session:

    page -> gateway                         gateway -> bus
    binary  [u32 len][JSON header][image]   findme/<s>/frame/<n>      (n = 0, 1, ... per page)
    {"type": "select", index, rank, ...}    findme/<s>/selection/<n>  (by USER)
    {"type": "measure", id, index, pixels}  query findme/<s>/measure  -> {"type": "measure", ...}
                                            (the reply also on findme/<s>/measured/<n>, for the record)

    bus -> page: everything on findme/<s>/** except frames, as JSON: hypotheses, selection,
    scene, motion, pose, trajectory, plan and error (``Error.message`` verbatim).

When photo n's hypotheses arrive the gateway selects rank 1 for it (by AUTO: "the best one
preselected"); the user's tap on another publishes a new selection (by USER). So do not run
a ``selection --auto`` service beside a gateway (two selectors would race).

Limits, enforced whatever the page does: upload bytes (``MAX_UPLOAD_BYTES``, also the
WebSocket's frame limit: above it the socket is closed with 1009), open sessions
(``MAX_SESSIONS``) and open pages per client address (``MAX_PAGES_PER_CLIENT``; the next
one is told why and closed with 1013), a page that sends nothing for ``IDLE_TIMEOUT_S`` is
closed (1001, "idle"), request headers must be complete within ``HEADER_TIMEOUT_S``
(slowloris), and, in page_input.py and page_session.py, JSON nesting and number sizes
(checked before parsing), decoded pixels, photos per session, pixels per measure query,
text message size and measure queries in flight. Every refusal is an ``Error`` on the
session's ``error`` key (so it is recorded like any other) which reaches the page through
its subscription; so does a bug while handling a page's message (INTERNAL), and the socket
stays open. A WebSocket upgrade from a page of another origin is refused (403): see
page_guard.py for the allow-list and why comparing Origin with Host is not enough.

The pure parts (page_input.py: ``parse_upload``, ``build_frame``, ``parse_command``;
page_output.py: ``to_page``) need no bus and no server; ``Gateway`` runs them with aiohttp
on a thread of its own.
"""

from __future__ import annotations

import asyncio
import logging
import ssl
import threading
import uuid
from importlib import resources

import zenoh
from aiohttp import WSCloseCode, WSMsgType, web

import schemas
from findme_io.imageio import MAX_PIXELS
from findme_core.errors import BusError, InputError

from ..runtime import bus
from .page_guard import ClientPages, OriginPolicy, client_of, served_names
from .page_input import MAX_HEADER_BYTES, MAX_MEASURE_PIXELS, MAX_UPLOAD_BYTES
from .page_session import MAX_PHOTOS, PageSession
from ..runtime.handler import Handler
from ..runtime.service import Service

log = logging.getLogger("findme.services.gateway")

MAX_SESSIONS = 100             # open pages at once
MAX_PAGES_PER_CLIENT = 8       # open pages per client address (one client cannot take all)
IDLE_TIMEOUT_S = 900.0         # a page that sends nothing for this long is closed
#: A connection must complete its request headers this long after it opens (or after its
#: previous response): aiohttp's keepalive_timeout, which also closes a connection that
#: never completes a request (slow headers). A WebSocket, once open, is not affected.
HEADER_TIMEOUT_S = 15.0
WEB_FILES = {"/": ("index.html", "text/html"), "/app.js": ("app.js", "text/javascript"),
             "/style.css": ("style.css", "text/css")}
WEB_FILES["/plan.js"] = ("plan.js", "text/javascript")   # the floor plan drawing
#: the page's parts (ES modules app.js imports; findme/web/common.js says what each does)
WEB_FILES.update({f"/{name}.js": (f"{name}.js", "text/javascript")
                  for name in ("common", "settings", "capture", "results", "points", "motion")})


class GatewayHandler(Handler):
    """The gateway's part of the runtime: liveliness, status counters, and the cache that
    answers other services' queries for the frames and selections its pages published."""

    name = "gateway"
    cache_keys = ("findme/*/frame/*", "findme/*/selection/*")

    def __init__(self):
        self.stats = {"pages": 0, "pages_open": 0, "frames": 0, "selections": 0,
                      "measures": 0, "refused": 0}

    def counters(self):
        return dict(self.stats)


def make_gateway(args) -> GatewayHandler:
    """Registry factory: the handler alone (``findme serve gateway`` and ``findme app`` run
    the whole ``Gateway`` with its web server)."""
    return GatewayHandler()


class Gateway:
    """The page server and bridge on a Zenoh session (see the module docstring)."""

    def __init__(self, session: zenoh.Session, host: str = "127.0.0.1", port: int = 8080,
                 ssl_context: ssl.SSLContext | None = None, instance: str | None = None,
                 max_upload_bytes: int = MAX_UPLOAD_BYTES, allowed_origins=(),
                 own_names=None, trusted_proxies=(), max_per_client: int = MAX_PAGES_PER_CLIENT,
                 idle_timeout: float = IDLE_TIMEOUT_S, header_timeout: float = HEADER_TIMEOUT_S):
        self.session, self.host, self.port, self.ssl = session, host, port, ssl_context
        self.handler = GatewayHandler()
        self.service = Service(self.handler, session, instance=instance)
        self.max_upload = max_upload_bytes
        self.origins = OriginPolicy(allowed_origins,
                                    served_names() if own_names is None else own_names)
        self.trusted = frozenset(trusted_proxies)
        self.clients = ClientPages(max_per_client)
        self.idle_timeout, self.header_timeout = idle_timeout, header_timeout
        self.pages: dict[str, PageSession] = {}
        self.url = ""
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._ready = threading.Event()
        self._error: BaseException | None = None
        self._decode = None  # asyncio.Semaphore: decoding photos costs CPU, 2 at a time

    # -------------------------------------------------------------- lifecycle
    def start(self, timeout: float = 30.0) -> str:
        """Start the service and the web server; returns the page's URL once bound."""
        self.service.start()
        self._thread = threading.Thread(target=self._run, name="gateway-http", daemon=True)
        self._thread.start()
        if not self._ready.wait(timeout) or self._error:
            self.service.stop()
            raise BusError(f"the gateway's web server did not start on "
                               f"{self.host}:{self.port}: {self._error}") from self._error
        return self.url

    def stop(self, timeout: float = 10.0) -> None:
        loop = self._loop
        if loop and loop.is_running():
            fut = asyncio.run_coroutine_threadsafe(self._shutdown(), loop)
            try:
                fut.result(timeout)
            except Exception as e:  # noqa: BLE001 - stopping anyway
                log.warning("gateway shutdown: %s", e)
            loop.call_soon_threadsafe(loop.stop)
        if self._thread:
            self._thread.join(timeout)
        self.service.stop()

    def _run(self) -> None:
        loop = self._loop = asyncio.new_event_loop()
        asyncio.set_event_loop(loop)
        self._decode = asyncio.Semaphore(2)
        app = web.Application(client_max_size=64 * 1024)
        for path in WEB_FILES:
            app.router.add_get(path, self._static)
        app.router.add_get("/ws", self._ws)
        self._runner = web.AppRunner(app, access_log=None, handle_signals=False,
                                     keepalive_timeout=self.header_timeout)
        try:
            loop.run_until_complete(self._runner.setup())
            site = web.TCPSite(self._runner, self.host, self.port, ssl_context=self.ssl)
            loop.run_until_complete(site.start())
            host, port = self._runner.addresses[0][:2]
            scheme = "https" if self.ssl else "http"
            shown = f"[{host}]" if ":" in host else host
            self.url = f"{scheme}://{shown}:{port}/"
        except BaseException as e:  # noqa: BLE001 - reported by start()
            self._error = e
            self._ready.set()
            loop.close()
            return
        self._ready.set()
        log.info("gateway serving %s", self.url)
        try:
            loop.run_forever()
        finally:
            loop.close()

    async def _shutdown(self) -> None:
        for p in list(self.pages.values()):
            await p.ws.close(code=WSCloseCode.GOING_AWAY, message=b"server stopping")
        await self._runner.cleanup()

    # -------------------------------------------------------------- http
    async def _static(self, request: web.Request) -> web.Response:
        name, ctype = WEB_FILES[request.path]
        body = (resources.files("findme") / "web" / name).read_bytes()
        return web.Response(body=body, content_type=ctype, charset="utf-8", headers={
            "Cache-Control": "no-cache",
            "X-Content-Type-Options": "nosniff",
            "Referrer-Policy": "no-referrer",
            "Content-Security-Policy": "default-src 'self'; img-src 'self' blob: data:; "
                                       "media-src 'self' blob:; connect-src 'self'; "
                                       "object-src 'none'; base-uri 'none'; frame-ancestors 'none'",
        })

    async def _ws(self, request: web.Request) -> web.StreamResponse:
        origin = request.headers.get("Origin")
        if not self.origins.allows(origin, request.headers.get("Host"), request.scheme):
            log.warning("WebSocket from origin %r (Host %r) refused", origin, request.host)
            raise web.HTTPForbidden(text=f"WebSocket from origin {origin!r} refused: not an "
                                         "allowed origin of this server")
        client = client_of(request.remote, request.headers.get("X-Forwarded-For"), self.trusted)
        ws = web.WebSocketResponse(max_msg_size=self.max_upload + MAX_HEADER_BYTES + 4,
                                   heartbeat=30.0)
        await ws.prepare(request)
        busy = (f"the server has {MAX_SESSIONS} open sessions" if len(self.pages) >= MAX_SESSIONS
                else None if self.clients.acquire(client) else
                f"your address already has {self.clients.limit} pages open; close one")
        if busy:
            await ws.send_json({"type": "error", "code": "OVERLOADED", "key": "",
                                "message": f"{busy}; try again later"})
            await ws.close(code=WSCloseCode.TRY_AGAIN_LATER, message=busy.encode()[:120])
            return ws
        try:
            return await self._page(ws, request, client)
        finally:
            self.clients.release(client)

    async def _page(self, ws: web.WebSocketResponse, request: web.Request, client: str):
        """One page's session, from its hello to its socket's close."""
        page = PageSession(f"web-{uuid.uuid4().hex[:12]}", ws, self.session, self.service,
                           self.handler.stats, self.max_upload, self._decode)
        self.pages[page.sid] = page
        self.handler.stats["pages"] += 1
        self.handler.stats["pages_open"] = len(self.pages)
        loop = asyncio.get_running_loop()
        inbox: asyncio.Queue = asyncio.Queue()
        sub = self.session.declare_subscriber(f"{bus.ROOT}/{page.sid}/**",
                                              page.on_sample(loop, inbox))
        pump = asyncio.create_task(page.pump(inbox))
        log.info("page session %s opened (%s)", page.sid, client)
        try:
            await ws.send_json({"type": "hello", "session": page.sid, "version": schemas.VERSION,
                                "services": await asyncio.to_thread(self._services),
                                "limits": {"max_upload_bytes": self.max_upload,
                                           "max_pixels": MAX_PIXELS, "max_photos": MAX_PHOTOS,
                                           "max_measure_pixels": MAX_MEASURE_PIXELS}})
            while True:
                try:   # the whole wait: heartbeat pongs do not count as the page's activity
                    async with asyncio.timeout(self.idle_timeout):
                        m = await ws.receive()
                except TimeoutError:
                    await ws.close(code=WSCloseCode.GOING_AWAY,
                                   message=f"idle for {self.idle_timeout:g} s".encode())
                    break
                if m.type in (WSMsgType.CLOSE, WSMsgType.CLOSING, WSMsgType.CLOSED):
                    break
                try:
                    if m.type == WSMsgType.BINARY:
                        await page.upload(m.data)
                    elif m.type == WSMsgType.TEXT:
                        await page.command(m.data)
                    elif m.type == WSMsgType.ERROR:
                        log.warning("page session %s: %s", page.sid, ws.exception())
                except ConnectionError:
                    break
                except Exception as e:  # noqa: BLE001 - a bug: the page hears of it, stays open
                    await page.failed(e)
        finally:
            page.closed = True
            pump.cancel()
            await asyncio.to_thread(sub.undeclare)
            self.pages.pop(page.sid, None)
            self.handler.stats["pages_open"] = len(self.pages)
            log.info("page session %s closed (%s)", page.sid, ws.close_code)
        return ws

    def _services(self) -> list[str]:
        names = set()
        for r in self.session.liveliness().get(f"{bus.SERVICES}/**", timeout=1.0):
            if r.ok is not None:
                names.add(str(r.ok.key_expr).split("/")[-2])
        return sorted(names)


def parse_http(text: str) -> tuple[str, int]:
    """``HOST:PORT``, ``[V6]:PORT`` or ``PORT`` (host 127.0.0.1) -> (host, port)."""
    t = str(text).strip()
    host, _, port = t.rpartition(":")
    host = host.strip("[]") or "127.0.0.1"
    try:
        p = int(port)
    except ValueError:
        raise InputError(f"--http must be HOST:PORT (e.g. 127.0.0.1:8080), got {text!r}") from None
    if not 0 <= p <= 65535:
        raise InputError(f"--http port must be 0-65535, got {p}")
    return host, p


def ssl_context(cert: str | None, key: str | None) -> ssl.SSLContext | None:
    """An HTTPS context from PEM files (phones need HTTPS for the camera and motion
    sensors unless the page is on localhost)."""
    if not cert and not key:
        return None
    if not (cert and key):
        raise InputError("HTTPS needs both --tls-cert and --tls-key")
    ctx = ssl.create_default_context(ssl.Purpose.CLIENT_AUTH)
    try:
        ctx.load_cert_chain(cert, key)
    except (OSError, ssl.SSLError) as e:
        raise InputError(f"cannot load the certificate {cert} / key {key}: {e}") from None
    return ctx
