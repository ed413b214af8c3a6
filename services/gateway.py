"""The gateway: serves the phone client (a web page) and bridges each page to the bus.

    GET /            the page (findme/web/index.html), /app.js, /style.css; nothing else
    GET /ws          a WebSocket: ONE new session per connection (= per page load)

The browser never names a key. The gateway makes the session id (``web-<random>``) and
builds every key itself, so a page can only act on its own session:

    page -> gateway                         gateway -> bus
    binary  [u32 len][JSON header][image]   findme/<s>/frame/<n>      (n = 0, 1, ... per page)
    {"type": "select", index, rank, ...}    findme/<s>/selection/<n>  (by USER)
    {"type": "measure", id, index, pixels}  query findme/<s>/measure  -> {"type": "measure", ...}
                                            (the reply also on findme/<s>/measured/<n>, for the record)

    bus -> page: everything on findme/<s>/** except frames, as JSON: hypotheses, selection,
    scene, motion, pose, trajectory and error (``Error.message`` verbatim).

When photo n's hypotheses arrive the gateway selects rank 1 for it (by AUTO: "the best one
preselected"); the user's tap on another publishes a new selection (by USER). So do not run
a ``selection --auto`` service beside a gateway (two selectors would race).

Limits, enforced here whatever the page does: upload bytes (``MAX_UPLOAD_BYTES``, also the
WebSocket's frame limit: above it the socket is closed with 1009), decoded pixels
(``MAX_PIXELS``), photos per session, pixels per measure query, text message size, open
sessions, measure queries in flight; images must decode (JPEG, PNG or WebP) and lens,
gravity and height values must be valid. Every refusal is an ``Error`` on the session's
``error`` key (so it is recorded like any other) which reaches the page through its
subscription. Cross-origin WebSocket upgrades are refused (403).

A JPEG with an EXIF rotation is decoded upright and re-encoded (quality 95) so that the
frame's pixels are the ones the browser shows and taps refer to.

The pure parts (``parse_upload``, ``build_frame``, ``parse_command``, ``to_page``) need no
bus and no server; ``Gateway`` runs them with aiohttp on a thread of its own.
"""

from __future__ import annotations

import asyncio
import json
import logging
import math
import ssl
import struct
import threading
import time
import uuid
from dataclasses import dataclass, field
from importlib import resources

import zenoh
from aiohttp import WSCloseCode, WSMsgType, web

import schemas
from findme.imageio import MAX_PIXELS, _declared_size, decode_image, encode_jpeg
from findme_core.errors import BusError, CameraError, FindmeError, ImageError, InputError

from . import bus
from .convert import frame_camera, image_format, make_frame
from .runtime import Handler, Output, Service

log = logging.getLogger("findme.services.gateway")

#: Largest photo a page may upload (bytes). Below the bus's 16 MB message limit, with room
#: for the rest of the Frame.
MAX_UPLOAD_BYTES = 15 * 1024 * 1024
MAX_HEADER_BYTES = 16 * 1024
MAX_TEXT_BYTES = 64 * 1024
MAX_PHOTOS = 100               # per session
MAX_MEASURE_PIXELS = 64        # per measure query
MAX_MEASURES_IN_FLIGHT = 4     # per session
MAX_SESSIONS = 100             # open pages at once
MEASURE_TIMEOUT_S = 10.0
#: 35 mm film diagonal (mm): a "35 mm-equivalent focal length" is relative to it.
FILM_DIAGONAL_MM = math.hypot(36.0, 24.0)
#: What a page sees of its session (frames are its own uploads: never sent back).
FORWARDED = ("hypotheses", "selection", "scene", "motion", "pose", "trajectory", "error")
WEB_FILES = {"/": ("index.html", "text/html"), "/app.js": ("app.js", "text/javascript"),
             "/style.css": ("style.css", "text/css")}
CODE = schemas.ErrorCode


class GatewayError(FindmeError):
    """Refused page input, with the Error code the page gets."""

    def __init__(self, code: int, message: str):
        super().__init__(message)
        self.code = code


def _bad(message: str, code: int = CODE.ERROR_CODE_MALFORMED) -> GatewayError:
    return GatewayError(code, message)


# ------------------------------------------------------------------------ pure: page input
def parse_upload(data: bytes, max_bytes: int = MAX_UPLOAD_BYTES) -> tuple[dict, bytes]:
    """Split a binary upload ``[u32 big-endian n][n bytes UTF-8 JSON header][image]``."""
    if len(data) < 4:
        raise _bad("upload is too short to carry a header and a photo")
    n = struct.unpack(">I", data[:4])[0]
    if n > MAX_HEADER_BYTES or 4 + n > len(data):
        raise _bad(f"upload header length {n} is not valid")
    try:
        header = json.loads(data[4:4 + n].decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError):
        raise _bad("upload header is not valid JSON") from None
    if not isinstance(header, dict):
        raise _bad("upload header must be a JSON object")
    image = data[4 + n:]
    if not image:
        raise _bad("the upload carries no photo (empty file)", CODE.ERROR_CODE_BAD_IMAGE)
    if len(image) > max_bytes:
        raise _bad(f"photo is {len(image) / 1e6:.1f} MB, over the {max_bytes / 1e6:.0f} MB limit",
                   CODE.ERROR_CODE_TOO_LARGE)
    return header, image


def _number(h: dict, name: str, lo: float, hi: float, what: str) -> float | None:
    v = h.get(name)
    if v is None or v == "":
        return None
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise _bad(f"{what} must be a number, got {v!r}", CODE.ERROR_CODE_BAD_CAMERA)
    if not lo < v <= hi:
        raise _bad(f"{what} must be in ({lo:g}, {hi:g}], got {v:g}", CODE.ERROR_CODE_BAD_CAMERA)
    return float(v)


def _vector(v, n: int, what: str) -> tuple[float, ...]:
    if (not isinstance(v, list) or len(v) != n or
            not all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
                    for x in v)):
        raise _bad(f"{what} must be {n} finite numbers, got {v!r}", CODE.ERROR_CODE_BAD_CAMERA)
    return tuple(float(x) for x in v)


def _exif_rotated(data: bytes) -> bool:
    """True when a JPEG's EXIF orientation is not 'upright' (1 or missing)."""
    if not data.startswith(b"\xff\xd8"):
        return False
    i = 2
    while i + 4 <= len(data) and data[i] == 0xFF:
        marker, seg = data[i + 1], int.from_bytes(data[i + 2:i + 4], "big")
        if marker == 0xE1 and data[i + 4:i + 10] == b"Exif\x00\x00":
            t = data[i + 10:i + 2 + seg]
            if len(t) < 8 or t[:2] not in (b"II", b"MM"):
                return False
            end = "little" if t[:2] == b"II" else "big"
            ifd = int.from_bytes(t[4:8], end)
            if ifd + 2 > len(t):
                return False
            for k in range(int.from_bytes(t[ifd:ifd + 2], end)):
                e = ifd + 2 + 12 * k
                if e + 12 > len(t):
                    return False
                if int.from_bytes(t[e:e + 2], end) == 0x0112:
                    return int.from_bytes(t[e + 8:e + 10], end) not in (0, 1)
            return False
        if marker == 0xDA:   # start of scan: no more headers
            return False
        i += 2 + seg
    return False


def checked_image(image: bytes, max_pixels: int = MAX_PIXELS) -> tuple[bytes, int, int, bool]:
    """(bytes to publish, width, height, re-encoded?) of an uploaded photo.

    Refuses other formats than JPEG/PNG/WebP, more than ``max_pixels`` (from the header,
    before decoding), and undecodable data. An EXIF-rotated JPEG comes back upright.
    """
    try:
        image_format(image)
    except ImageError:
        raise _bad("the file is not an image the server reads (JPEG, PNG or WebP)",
                   CODE.ERROR_CODE_BAD_IMAGE) from None
    w, h = _declared_size(image)
    if w * h > max_pixels:
        raise _bad(f"photo is {w}x{h} = {w * h / 1e6:.0f} MP, over the {max_pixels / 1e6:.0f} MP "
                   "limit", CODE.ERROR_CODE_TOO_LARGE)
    try:
        img = decode_image(image, "photo", max_bytes=len(image) + 1, max_pixels=max_pixels)
    except ImageError as e:
        code = CODE.ERROR_CODE_TOO_LARGE if "limit" in str(e) else CODE.ERROR_CODE_BAD_IMAGE
        raise _bad(str(e), code) from None
    H, W = img.shape[:2]
    if _exif_rotated(image) or (w and h and (w, h) != (W, H)):
        return encode_jpeg(img, 95), W, H, True
    return image, W, H, False


def build_frame(session: str, index: int, header: dict, image: bytes,
                now_ns: int | None = None):
    """(Frame, info for the page) from a parsed upload; GatewayError if anything is off."""
    data, W, H, reencoded = checked_image(image)
    lens = header.get("lens") or {}
    if not isinstance(lens, dict):
        raise _bad(f"lens must be an object, got {lens!r}", CODE.ERROR_CODE_BAD_CAMERA)
    kind = lens.get("kind", "default")
    intrinsics = hfov = None
    if kind == "intrinsics":
        fx, fy, cx, cy = (_number(lens, k, 0 if k[0] == "f" else -1e6, 1e6, k) for k in
                          ("fx", "fy", "cx", "cy"))
        if None in (fx, fy, cx, cy):
            raise _bad("intrinsics need fx, fy, cx and cy (pixels)", CODE.ERROR_CODE_BAD_CAMERA)
        seen = (lens.get("width"), lens.get("height"))
        if None not in seen and tuple(seen) != (W, H):
            raise _bad(f"intrinsics were given for a {seen[0]}x{seen[1]} photo but the photo is "
                       f"{W}x{H}", CODE.ERROR_CODE_BAD_CAMERA)
        intrinsics = (fx, fy, cx, cy, W, H)
    elif kind == "hfov":
        hfov = _number(lens, "hfov_deg", 0, 179.9, "field of view (degrees)")
    elif kind == "focal35":
        f35 = _number(lens, "focal35_mm", 1, 2000, "35 mm-equivalent focal length (mm)")
        if f35 is not None:
            f_px = f35 * math.hypot(W, H) / FILM_DIAGONAL_MM
            hfov = math.degrees(2 * math.atan(W / (2 * f_px)))
    elif kind != "default":
        raise _bad(f"lens kind {kind!r} is not one of default, hfov, focal35, intrinsics",
                   CODE.ERROR_CODE_BAD_CAMERA)
    gravity = header.get("gravity")
    if gravity is not None:
        gravity = _vector(gravity, 3, "gravity")
        if math.hypot(*gravity) < 1e-3:
            raise _bad("gravity must not be the zero vector", CODE.ERROR_CODE_BAD_CAMERA)
    height = _number(header, "camera_height_m", 0, 100, "camera height (m)")
    device = header.get("device") or ""
    device = "web" + (": " + "".join(c for c in str(device) if c.isprintable())[:80]
                      if device else "")
    now = time.time_ns() if now_ns is None else now_ns
    t = header.get("capture_time_ms")
    t_ns = int(t * 1e6) if isinstance(t, (int, float)) and not isinstance(t, bool) \
        and math.isfinite(t) and abs(t * 1e6 - now) < 86400e9 else now
    frame = make_frame(session, index, data, intrinsics=intrinsics, hfov_deg=hfov,
                       gravity=gravity, camera_height_m=height, device=device, time_ns=t_ns)
    try:
        cam = frame_camera(frame, W, H)
    except (CameraError, InputError) as e:
        raise _bad(str(e), CODE.ERROR_CODE_BAD_CAMERA) from None
    info = {"index": index, "width": W, "height": H, "bytes": len(data), "reencoded": reencoded,
            "fx": cam.fx, "fy": cam.fy, "cx": cam.cx, "cy": cam.cy,
            "gravity": [float(x) for x in cam.gravity], "camera_height_m": height}
    return frame, info


def parse_command(text: str) -> dict:
    """A page's text message as a checked dict (``select`` or ``measure``)."""
    if len(text) > MAX_TEXT_BYTES:
        raise _bad(f"message of {len(text)} characters is over the {MAX_TEXT_BYTES} limit",
                   CODE.ERROR_CODE_TOO_LARGE)
    try:
        cmd = json.loads(text)
    except json.JSONDecodeError:
        raise _bad("message is not valid JSON") from None
    if not isinstance(cmd, dict) or cmd.get("type") not in ("select", "measure", "ping"):
        raise _bad("message must be a JSON object with type select, measure or ping")
    if cmd["type"] == "ping":
        return cmd
    idx = cmd.get("index")
    if not isinstance(idx, int) or isinstance(idx, bool) or idx < 0:
        raise _bad(f"index must be a photo number (0, 1, ...), got {idx!r}",
                   CODE.ERROR_CODE_NO_SUCH_FRAME)
    if cmd["type"] == "select":
        r = cmd.get("rank")
        if not isinstance(r, int) or isinstance(r, bool) or r < 1:
            raise _bad(f"rank must be 1, 2, ..., got {r!r}", CODE.ERROR_CODE_NO_SUCH_HYPOTHESIS)
        cmd["camera_height_m"] = _number(cmd, "camera_height_m", 0, 100, "camera height (m)")
        return cmd
    px = cmd.get("pixels")
    if not isinstance(px, list) or not px:
        raise _bad("measure needs pixels: [[u, v], ...]")
    if len(px) > MAX_MEASURE_PIXELS:
        raise _bad(f"{len(px)} points in one request, over the limit of {MAX_MEASURE_PIXELS}",
                   CODE.ERROR_CODE_TOO_LARGE)
    cmd["pixels"] = [_vector(p, 2, "a pixel") for p in px]
    return cmd


# ------------------------------------------------------------------------ pure: bus -> page
def _opt(m, name):
    return getattr(m, name) if m.HasField(name) else None


def _kind_name(k: int) -> str:
    return schemas.SegKind.Name(k).removeprefix("SEG_KIND_").lower()


def _pose(p) -> dict:
    return {"index": p.index, "x_m": p.x_m, "z_m": p.z_m, "yaw_rad": p.yaw_rad,
            "sigma_x_m": _opt(p, "sigma_x_m"), "sigma_z_m": _opt(p, "sigma_z_m"),
            "sigma_yaw_rad": _opt(p, "sigma_yaw_rad")}


def to_page(session: str, msg) -> dict | None:
    """A bus message of ``session`` as the JSON the page reads (None: not for the page)."""
    name = type(msg).__name__
    if name == "HypothesisSet":
        return {"type": "hypotheses", "index": msg.index, "width": msg.width,
                "height": msg.height, "reason": msg.reason, "method": msg.method,
                "timing_ms": dict(msg.timing_ms),
                "hypotheses": [{"rank": h.rank, "score": h.score, "support": h.support,
                                "points": [[p.u, p.v] for p in h.polyline.points],
                                "kinds": [_kind_name(k) for k in h.polyline.kinds]}
                               for h in msg.hypotheses]}
    if name == "Selection":
        return {"type": "selection", "index": msg.index, "rank": msg.rank,
                "by": "user" if msg.by == schemas.SELECTED_BY_USER else "auto",
                "camera_height_m": _opt(msg, "camera_height_m")}
    if name == "Scene":
        return {"type": "scene", "index": msg.index, "rank": msg.rank, "metric": msg.metric,
                "camera_height_m": msg.camera_height_m,
                "gravity": [msg.camera.gravity.x, msg.camera.gravity.y, msg.camera.gravity.z]}
    if name == "Motion":
        d = {"type": "motion", "a": msg.index_a, "b": msg.index_b, "error": msg.error,
             "inliers": msg.inliers, "matches": msg.matches, "method": msg.method}
        for k in ("x_m", "z_m", "yaw_rad", "sigma_x_m", "sigma_z_m", "sigma_yaw_rad"):
            d[k] = _opt(msg, k)
        return d
    if name == "Pose":
        return {"type": "pose", **_pose(msg)}
    if name == "Trajectory":
        return {"type": "trajectory", "poses": [_pose(p) for p in msg.poses]}
    if name == "Error":
        prefix = f"{bus.ROOT}/{session}/"
        return {"type": "error", "code": CODE.Name(msg.code).removeprefix("ERROR_CODE_"),
                "message": msg.message, "key": msg.key.removeprefix(prefix),
                "service": msg.service}
    if name == "MeasureReply":
        return {"type": "measure", "index": msg.index, "rank": msg.rank, "metric": msg.metric,
                "error": msg.error,
                "points": [{"pixel": [p.pixel.u, p.pixel.v],
                            "surface": schemas.Surface.Name(p.surface).removeprefix("SURFACE_").lower(),
                            "xyz": [p.xyz.x, p.xyz.y, p.xyz.z] if p.HasField("xyz") else None,
                            "sigma_m": _opt(p, "sigma_m"), "error": p.error} for p in msg.points],
                "distances": [{"a": d.a, "b": d.b, "distance_m": _opt(d, "distance_m"),
                               "sigma_m": _opt(d, "sigma_m"), "error": d.error}
                              for d in msg.distances]}
    return None


# ------------------------------------------------------------------------ the service
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


@dataclass
class _Page:
    """Per-connection state; touched only on the gateway's event loop."""

    sid: str
    ws: web.WebSocketResponse
    next_index: int = 0
    sizes: dict = field(default_factory=dict)       # n -> (width, height)
    n_hyps: dict = field(default_factory=dict)      # n -> number of hypotheses
    selected: set = field(default_factory=set)      # n with a selection published
    in_flight: int = 0
    closed: bool = False


class Gateway:
    """The page server and bridge on a Zenoh session (see the module docstring)."""

    def __init__(self, session: zenoh.Session, host: str = "127.0.0.1", port: int = 8080,
                 ssl_context: ssl.SSLContext | None = None, instance: str | None = None,
                 max_upload_bytes: int = MAX_UPLOAD_BYTES):
        self.session, self.host, self.port, self.ssl = session, host, port, ssl_context
        self.handler = GatewayHandler()
        self.service = Service(self.handler, session, instance=instance)
        self.max_upload = max_upload_bytes
        self.pages: dict[str, _Page] = {}
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
        self._runner = web.AppRunner(app, access_log=None, handle_signals=False)
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
        if origin is not None and origin.split("://", 1)[-1] != request.host:
            raise web.HTTPForbidden(text="cross-origin WebSocket refused")
        ws = web.WebSocketResponse(max_msg_size=self.max_upload + MAX_HEADER_BYTES + 4,
                                   heartbeat=30.0)
        await ws.prepare(request)
        if len(self.pages) >= MAX_SESSIONS:
            await ws.send_json({"type": "error", "code": "OVERLOADED", "key": "",
                                "message": f"the server has {MAX_SESSIONS} open sessions; "
                                           "try again later"})
            await ws.close(code=WSCloseCode.TRY_AGAIN_LATER)
            return ws
        page = _Page(f"web-{uuid.uuid4().hex[:12]}", ws)
        self.pages[page.sid] = page
        self.handler.stats["pages"] += 1
        self.handler.stats["pages_open"] = len(self.pages)
        loop = asyncio.get_running_loop()
        inbox: asyncio.Queue = asyncio.Queue()
        sub = self.session.declare_subscriber(f"{bus.ROOT}/{page.sid}/**",
                                              self._on_sample(page, loop, inbox))
        pump = asyncio.create_task(self._pump(page, inbox))
        log.info("page session %s opened (%s)", page.sid, request.remote)
        try:
            await ws.send_json({"type": "hello", "session": page.sid, "version": schemas.VERSION,
                                "services": await asyncio.to_thread(self._services),
                                "limits": {"max_upload_bytes": self.max_upload,
                                           "max_pixels": MAX_PIXELS, "max_photos": MAX_PHOTOS,
                                           "max_measure_pixels": MAX_MEASURE_PIXELS}})
            async for m in ws:
                if m.type == WSMsgType.BINARY:
                    await self._upload(page, m.data)
                elif m.type == WSMsgType.TEXT:
                    await self._command(page, m.data)
                elif m.type == WSMsgType.ERROR:
                    log.warning("page session %s: %s", page.sid, ws.exception())
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

    # -------------------------------------------------------------- bus -> page
    def _on_sample(self, page: _Page, loop, inbox):
        def cb(sample: zenoh.Sample) -> None:  # a Zenoh thread
            if sample.kind != zenoh.SampleKind.PUT:
                return
            try:
                k = bus.parse_key(str(sample.key_expr))
                if k.kind not in FORWARDED:
                    return
                msg = schemas.decode_any(sample.payload.to_bytes())
            except FindmeError:
                return  # not a Find Me message: nothing a page can show
            try:
                loop.call_soon_threadsafe(inbox.put_nowait, msg)
            except RuntimeError:
                pass  # the loop is closed: the server is stopping
        return cb

    async def _pump(self, page: _Page, inbox: asyncio.Queue) -> None:
        while True:
            msg = await inbox.get()
            if isinstance(msg, schemas.HypothesisSet):
                page.n_hyps[msg.index] = len(msg.hypotheses)
            out = to_page(page.sid, msg)
            if out is not None and not page.ws.closed:
                try:
                    await page.ws.send_json(out)
                except ConnectionError:
                    return
            if (isinstance(msg, schemas.HypothesisSet) and msg.hypotheses
                    and msg.index not in page.selected):
                # the best one preselected; the user may pick another
                await self._select(page, msg.index, 1, schemas.SELECTED_BY_AUTO, None)

    # -------------------------------------------------------------- page -> bus
    async def _refuse(self, page: _Page, key: str, exc: BaseException) -> None:
        """Publish an Error about ``key`` on the session's error key; the page gets it
        through its subscription (and a recorder records it)."""
        self.handler.stats["refused"] += 1
        code = exc.code if isinstance(exc, GatewayError) else None
        if code is None:
            _, err = await asyncio.to_thread(self.service.report, key, exc)
            return
        self.service.counters.errors += 1
        err = schemas.Error(session=page.sid, key=key, code=code, message=str(exc)[:500],
                            time_ns=time.time_ns(), service=self.service.ident)
        log.warning("%s: %s: %s", self.service.ident, key, err.message)
        try:
            await asyncio.to_thread(bus.put, self.session, bus.key(page.sid, "error"),
                                    schemas.encode(err))
        except (FindmeError, zenoh.ZError) as e:   # no bus: tell the page directly
            log.error("cannot publish the error: %s", e)
            await page.ws.send_json(to_page(page.sid, err))

    async def _upload(self, page: _Page, data: bytes) -> None:
        n = page.next_index
        key = bus.key(page.sid, "frame", n)
        ref = None
        try:
            header, image = parse_upload(data, self.max_upload)
            ref = header.get("id")
            if n >= MAX_PHOTOS:
                raise _bad(f"this session already has {MAX_PHOTOS} photos; reload the page to "
                           "start a new session", CODE.ERROR_CODE_TOO_LARGE)
            async with self._decode:
                frame, info = await asyncio.to_thread(build_frame, page.sid, n, header, image)
        except FindmeError as e:
            await page.ws.send_json({"type": "refused", "id": ref, "key": f"frame/{n}"})
            await self._refuse(page, key, e)
            return
        page.next_index = n + 1
        page.sizes[n] = (info["width"], info["height"])
        await page.ws.send_json({"type": "frame", "id": ref, **info})
        try:
            await asyncio.to_thread(self.service.publish, Output(key, frame))
            self.handler.stats["frames"] += 1
        except FindmeError as e:
            await self._refuse(page, key, e)

    async def _command(self, page: _Page, text: str) -> None:
        try:
            cmd = parse_command(text)
        except GatewayError as e:
            await self._refuse(page, bus.key(page.sid, "gateway"), e)
            return
        if cmd["type"] == "ping":
            await page.ws.send_json({"type": "pong"})
            return
        n = cmd["index"]
        if cmd["type"] == "select":
            key = bus.key(page.sid, "selection", n)
            count = page.n_hyps.get(n)
            if n not in page.sizes:
                await self._refuse(page, key, _bad(f"there is no photo {n + 1} in this session",
                                                   CODE.ERROR_CODE_NO_SUCH_FRAME))
            elif count is None:
                await self._refuse(page, key, _bad(f"photo {n + 1} has no hypotheses yet",
                                                   CODE.ERROR_CODE_NO_SUCH_HYPOTHESIS))
            elif not 1 <= cmd["rank"] <= count:
                await self._refuse(page, key, _bad(
                    f"hypothesis {cmd['rank']} does not exist: photo {n + 1} has {count}",
                    CODE.ERROR_CODE_NO_SUCH_HYPOTHESIS))
            else:
                await self._select(page, n, cmd["rank"], schemas.SELECTED_BY_USER,
                                   cmd["camera_height_m"])
            return
        await self._measure(page, cmd)

    async def _select(self, page: _Page, n: int, rank: int, by, height) -> None:
        sel = schemas.Selection(session=page.sid, index=n, rank=rank, by=by,
                                time_ns=time.time_ns())
        if height is not None:
            sel.camera_height_m = height
        page.selected.add(n)
        key = bus.key(page.sid, "selection", n)
        try:
            await asyncio.to_thread(self.service.publish, Output(key, sel))
            self.handler.stats["selections"] += 1
        except FindmeError as e:
            await self._refuse(page, key, e)

    async def _measure(self, page: _Page, cmd: dict) -> None:
        key, n, ref = bus.key(page.sid, "measure"), cmd["index"], cmd.get("id")
        done = {"type": "measure", "id": ref, "index": n, "points": [], "distances": []}
        problem = None
        if n not in page.sizes:
            problem = _bad(f"there is no photo {n + 1} in this session", CODE.ERROR_CODE_NO_SUCH_FRAME)
        elif page.in_flight >= MAX_MEASURES_IN_FLIGHT:
            problem = _bad("too many measurements at once; wait for the answers",
                           CODE.ERROR_CODE_OVERLOADED)
        else:
            W, H = page.sizes[n]
            for u, v in cmd["pixels"]:
                if not (-0.5 <= u <= W - 0.5 and -0.5 <= v <= H - 0.5):
                    problem = _bad(f"pixel ({u:g}, {v:g}) is outside the {W}x{H} photo")
                    break
        if problem:
            await self._refuse(page, key, problem)
            await page.ws.send_json({**done, "error": str(problem)})
            return
        req = schemas.MeasureRequest(session=page.sid, index=n)
        req.pixels.extend(schemas.pixels_to_msg(cmd["pixels"]))
        page.in_flight += 1
        try:
            reply, err = await asyncio.to_thread(self._query, key, schemas.encode(req))
        finally:
            page.in_flight -= 1
        self.handler.stats["measures"] += 1
        if reply is not None:
            await page.ws.send_json({**to_page(page.sid, reply), "id": ref})
            try:  # for the record, as ``findme run`` does
                await asyncio.to_thread(bus.put, self.session, bus.key(page.sid, "measured", n),
                                        schemas.encode(reply))
            except (FindmeError, zenoh.ZError) as e:
                log.warning("cannot publish the measurement for the record: %s", e)
            return
        if err is None:   # nobody answered: say so on the bus
            err = _bad(f"no measurement service answered within {MEASURE_TIMEOUT_S:.0f} s",
                       CODE.ERROR_CODE_OVERLOADED)
            await self._refuse(page, key, err)
            err = str(err)
        # else: the measurement service published its Error itself; the page shows that one
        await page.ws.send_json({**done, "error": err})

    def _query(self, key: str, payload: bytes):
        """(MeasureReply, None) or (None, error text) or (None, None) when nobody answered."""
        for r in self.session.get(key, payload=payload, timeout=MEASURE_TIMEOUT_S):
            if r.ok is not None:
                return schemas.decode(schemas.MeasureReply, r.ok.payload.to_bytes()), None
            try:
                return None, schemas.decode(schemas.Error, r.err.payload.to_bytes()).message
            except FindmeError:
                return None, "the measurement service failed"
        return None, None


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
