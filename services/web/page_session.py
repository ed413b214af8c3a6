"""One page's session on the gateway: its state, and its messages to and from the bus.

Each page load (one WebSocket) gets a ``PageSession`` with a session id the gateway made
(``web-<random>``). Every key is built here from that id, so a page can only act on its
own session:

    page -> session                         session -> bus
    binary upload (page_input)              findme/<s>/frame/<n>      (n = 0, 1, ... per page)
    {"type": "select", index, rank, ...}    findme/<s>/selection/<n>  (by USER)
    {"type": "measure", id, index, pixels,  query findme/<s>/measure  -> {"type": "measure", ...}
     surfaces (optional)}                   (the reply also on findme/<s>/measured/<n>, for the record)

    bus -> page: the ``FORWARDED`` kinds on findme/<s>/** (everything but frames), as JSON
    (page_output).

A measure's ``surfaces`` (null, "floor", "wall" or "top" per pixel: what the user says each tapped
point is on) become the MeasureRequest's ``said``, one per pixel, only when at least one is
said; a request that says nothing is the same as before there was a ``said``. Each point of
the reply tells the page what was said of it (``said``).

When photo n's hypotheses arrive and the page has not selected one for it yet, rank 1 is
selected (by AUTO: "the best one preselected"); the user's tap on another publishes a new
selection (by USER).

Limits per session: ``MAX_PHOTOS`` photos, ``MAX_MEASURES_IN_FLIGHT`` measure queries at
once, each answered within ``MEASURE_TIMEOUT_S``; a select or measure must name a photo of
this session, an existing hypothesis rank, and pixels inside the photo. Every refusal is an
``Error`` on the session's ``error`` key (so it is recorded like any other) which reaches
the page through its subscription; only when the bus refuses it is it sent to the page
directly.

Runs on the gateway's event loop (``on_sample``'s callback on a Zenoh thread hands each
message over to it); blocking bus calls go to worker threads.
"""

from __future__ import annotations

import asyncio
import logging
import time

import zenoh
from aiohttp import web

import schemas
from findme_core.errors import FindmeError

from ..runtime import authority, bus
from .page_command import parse_command
from .page_input import CODE, GatewayError, _bad, build_frame, parse_upload
from .page_output import to_page
from ..runtime.handler import Output
from ..runtime.service import Service

log = logging.getLogger("findme.services.gateway")

MAX_PHOTOS = 100               # per session
MAX_MEASURES_IN_FLIGHT = 4     # per session
MEASURE_TIMEOUT_S = 10.0
#: What a page sees of its session (frames are its own uploads: never sent back).
FORWARDED = ("hypotheses", "selection", "scene", "motion", "pose", "trajectory", "error", "plan")


class PageSession:
    """Per-connection state and its handling; touched only on the gateway's event loop."""

    def __init__(self, sid: str, ws: web.WebSocketResponse, zs: zenoh.Session,
                 service: Service, stats: dict, max_upload: int, decode: asyncio.Semaphore):
        self.sid, self.ws = sid, ws
        self.zs = zs                    # the gateway's Zenoh session
        self.service = service          # the gateway's Service: publishes, reports errors
        self.stats = stats              # the gateway handler's counters (shared)
        self.max_upload = max_upload
        self.decode = decode            # decoding photos costs CPU: shared by all pages
        self.next_index = 0
        self.sizes: dict = {}           # n -> (width, height)
        self.n_hyps: dict = {}          # n -> number of hypotheses
        self.selected: set = set()      # n with a selection published
        self.in_flight = 0
        self.closed = False

    # -------------------------------------------------------------- bus -> page
    def on_sample(self, loop, inbox):
        """The Zenoh callback of the session's subscription: forwarded kinds into ``inbox``
        on ``loop``."""
        def cb(sample: zenoh.Sample) -> None:  # a Zenoh thread
            if sample.kind != zenoh.SampleKind.PUT:
                return
            try:
                k = bus.parse_key(str(sample.key_expr))
                if k.kind not in FORWARDED:
                    return
                msg = schemas.decode_any(sample.payload.to_bytes())
                authority.check(str(sample.key_expr), msg)
            except FindmeError:
                return  # not a Find Me message of this key: nothing a page can show
            try:
                loop.call_soon_threadsafe(inbox.put_nowait, msg)
            except RuntimeError:
                pass  # the loop is closed: the server is stopping
        return cb

    async def pump(self, inbox: asyncio.Queue) -> None:
        """Send what arrives in ``inbox`` to the page; preselect rank 1 of new hypotheses."""
        while True:
            msg = await inbox.get()
            if isinstance(msg, schemas.HypothesisSet):
                self.n_hyps[msg.index] = len(msg.hypotheses)
            out = to_page(self.sid, msg)
            if out is not None and not self.ws.closed:
                try:
                    await self.ws.send_json(out)
                except ConnectionError:
                    return
            if (isinstance(msg, schemas.HypothesisSet) and msg.hypotheses
                    and msg.index not in self.selected):
                # the best one preselected; the user may pick another
                await self._select(msg.index, 1, schemas.SELECTED_BY_AUTO, None)

    # -------------------------------------------------------------- page -> bus
    async def _refuse(self, key: str, exc: BaseException) -> None:
        """Publish an Error about ``key`` on the session's error key; the page gets it
        through its subscription (and a recorder records it)."""
        self.stats["refused"] += 1
        code = exc.code if isinstance(exc, GatewayError) else None
        if code is None:
            _, err = await asyncio.to_thread(self.service.report, key, exc)
            return
        self.service.counters.errors += 1
        err = schemas.Error(session=self.sid, key=key, code=code, message=str(exc)[:500],
                            time_ns=time.time_ns(), service=self.service.ident)
        log.warning("%s: %s: %s", self.service.ident, key, err.message)
        try:
            await asyncio.to_thread(bus.put, self.zs, bus.key(self.sid, "error"),
                                    schemas.encode(err))
        except (FindmeError, zenoh.ZError) as e:   # no bus: tell the page directly
            log.error("cannot publish the error: %s", e)
            await self.ws.send_json(to_page(self.sid, err))

    async def failed(self, exc: BaseException) -> None:
        """A bug while handling the page's message: an INTERNAL Error (traceback in the
        log) reaches the page; its socket stays open."""
        log.error("%s: page session %s: internal error", self.service.ident, self.sid,
                  exc_info=exc)
        await self._refuse(bus.key(self.sid, "gateway"), GatewayError(
            CODE.ERROR_CODE_INTERNAL, f"internal error: {type(exc).__name__}: {exc}"))

    async def _publish(self, key: str, msg, counter: str) -> None:
        """Publish ``msg`` on ``key`` and count it in ``stats[counter]``; refuse on failure."""
        try:
            await asyncio.to_thread(self.service.publish, Output(key, msg))
            self.stats[counter] += 1
        except FindmeError as e:
            await self._refuse(key, e)

    async def upload(self, data: bytes) -> None:
        """A binary message: the page's next photo as a frame on the bus."""
        n = self.next_index
        key = bus.key(self.sid, "frame", n)
        ref = None
        try:
            header, image = parse_upload(data, self.max_upload)
            ref = header.get("id")
            if n >= MAX_PHOTOS:
                raise _bad(f"this session already has {MAX_PHOTOS} photos; reload the page to "
                           "start a new session", CODE.ERROR_CODE_TOO_LARGE)
            async with self.decode:
                frame, info = await asyncio.to_thread(build_frame, self.sid, n, header, image)
        except FindmeError as e:
            await self.ws.send_json({"type": "refused", "id": ref, "key": f"frame/{n}"})
            await self._refuse(key, e)
            return
        self.next_index = n + 1
        self.sizes[n] = (info["width"], info["height"])
        await self.ws.send_json({"type": "frame", "id": ref, **info})
        await self._publish(key, frame, "frames")

    async def command(self, text: str) -> None:
        """A text message: select, measure or ping."""
        try:
            cmd = parse_command(text)
        except GatewayError as e:
            await self._refuse(bus.key(self.sid, "gateway"), e)
            return
        if cmd["type"] == "ping":
            await self.ws.send_json({"type": "pong"})
            return
        n = cmd["index"]
        if cmd["type"] == "select":
            key = bus.key(self.sid, "selection", n)
            count = self.n_hyps.get(n)
            if n not in self.sizes:
                await self._refuse(key, _bad(f"there is no photo {n + 1} in this session",
                                             CODE.ERROR_CODE_NO_SUCH_FRAME))
            elif count is None:
                await self._refuse(key, _bad(f"photo {n + 1} has no hypotheses yet",
                                             CODE.ERROR_CODE_NO_SUCH_HYPOTHESIS))
            elif not 1 <= cmd["rank"] <= count:
                await self._refuse(key, _bad(
                    f"hypothesis {cmd['rank']} does not exist: photo {n + 1} has {count}",
                    CODE.ERROR_CODE_NO_SUCH_HYPOTHESIS))
            else:
                await self._select(n, cmd["rank"], schemas.SELECTED_BY_USER,
                                   cmd["camera_height_m"])
            return
        await self._measure(cmd)

    async def _select(self, n: int, rank: int, by, height) -> None:
        sel = schemas.Selection(session=self.sid, index=n, rank=rank, by=by,
                                time_ns=time.time_ns())
        if height is not None:
            sel.camera_height_m = height
        self.selected.add(n)
        key = bus.key(self.sid, "selection", n)
        await self._publish(key, sel, "selections")

    async def _measure(self, cmd: dict) -> None:
        key, n, ref = bus.key(self.sid, "measure"), cmd["index"], cmd.get("id")
        done = {"type": "measure", "id": ref, "index": n, "points": [], "distances": []}
        problem = None
        if n not in self.sizes:
            problem = _bad(f"there is no photo {n + 1} in this session", CODE.ERROR_CODE_NO_SUCH_FRAME)
        elif self.in_flight >= MAX_MEASURES_IN_FLIGHT:
            problem = _bad("too many measurements at once; wait for the answers",
                           CODE.ERROR_CODE_OVERLOADED)
        else:
            W, H = self.sizes[n]
            for u, v in cmd["pixels"]:
                if not (-0.5 <= u <= W - 0.5 and -0.5 <= v <= H - 0.5):
                    problem = _bad(f"pixel ({u:g}, {v:g}) is outside the {W}x{H} photo")
                    break
        if problem:
            await self._refuse(key, problem)
            await self.ws.send_json({**done, "error": str(problem)})
            return
        req = schemas.MeasureRequest(session=self.sid, index=n)
        req.pixels.extend(schemas.pixels_to_msg(cmd["pixels"]))
        req.said.extend(schemas.surfaces_to_msg(cmd.get("surfaces")))   # nothing said: none
        self.in_flight += 1
        try:
            reply, err = await asyncio.to_thread(self._query, key, schemas.encode(req), n)
        finally:
            self.in_flight -= 1
        self.stats["measures"] += 1
        if reply is not None:
            await self.ws.send_json({**to_page(self.sid, reply), "id": ref})
            try:  # for the record, as ``findme run`` does
                await asyncio.to_thread(bus.put, self.zs, bus.key(self.sid, "measured", n),
                                        schemas.encode(reply))
            except (FindmeError, zenoh.ZError) as e:
                log.warning("cannot publish the measurement for the record: %s", e)
            return
        if err is None:   # nobody answered: say so on the bus
            err = _bad(f"no measurement service answered within {MEASURE_TIMEOUT_S:.0f} s",
                       CODE.ERROR_CODE_OVERLOADED)
            await self._refuse(key, err)
            err = str(err)
        # else: the measurement service published its Error itself; the page shows that one
        await self.ws.send_json({**done, "error": err})

    def _query(self, key: str, payload: bytes, n: int):
        """(MeasureReply, None) or (None, error text) or (None, None) when nobody answered."""
        for r in self.zs.get(key, payload=payload, timeout=MEASURE_TIMEOUT_S):
            if r.ok is not None:
                try:   # a reply about another session or photo is no answer
                    reply = schemas.decode(schemas.MeasureReply, r.ok.payload.to_bytes())
                    authority.check(bus.key(self.sid, "measured", n), reply)
                except FindmeError as e:
                    return None, str(e)
                return reply, None
            try:
                return None, schemas.decode(schemas.Error, r.err.payload.to_bytes()).message
            except FindmeError:
                return None, "the measurement service failed"
        return None, None
