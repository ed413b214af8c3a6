"""The selection service: picks one hypothesis of each photo.

    findme/<session>/hypotheses/<n>  ->  findme/<session>/selection/<n>

``AutoChooser`` takes rank 1 (``findme serve selection --auto``); ``TerminalChooser`` shows
the numbered selection image (written to a file) and asks in the terminal. A phone client
publishes its own selections on the same key instead.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import cv2

import schemas
from findme_core.errors import HypothesisError
from findme_io.overlay import draw_hypotheses

from ..runtime import bus
from findme_io.convert import msg_hypotheses
from ..runtime.handler import Handler, Input, Output


class AutoChooser:
    by = schemas.SELECTED_BY_AUTO

    def __call__(self, hset, frame=None) -> int:
        return 1


class TerminalChooser:
    """Writes ``<out>/<session>_<n>_selection.png`` and reads a rank from ``stdin``."""

    by = schemas.SELECTED_BY_USER

    def __init__(self, out_dir: str = ".", stdin=None, stdout=None):
        self.out = Path(out_dir)
        self.stdin, self.stdout = stdin or sys.stdin, stdout or sys.stdout

    def __call__(self, hset, frame=None) -> int:
        n = len(hset.hypotheses)
        if frame is not None:
            from findme_io.frame_photo import frame_inputs
            image, _ = frame_inputs(frame)
            path = self.out / f"{hset.session}_{hset.index}_selection.png"
            cv2.imwrite(str(path), draw_hypotheses(image, [h.polyline for h in msg_hypotheses(hset)]))
            print(f"photo {hset.index} of {hset.session}: selection image {path}", file=self.stdout)
        for h in hset.hypotheses:
            print(f"  {h.rank:2d}. score {h.score:.3f}", file=self.stdout)
        while True:
            print(f"pick 1-{n} [1]: ", end="", file=self.stdout, flush=True)
            line = self.stdin.readline()
            if not line or not line.strip():
                return 1
            if line.strip().isdigit() and 1 <= int(line) <= n:
                return int(line)
            print(f"  {line.strip()!r} is not a number from 1 to {n}", file=self.stdout)


class SelectionHandler(Handler):
    name = "selection"
    cache_keys = ("findme/*/selection/*",)

    def __init__(self, chooser=None):
        self.chooser = chooser or AutoChooser()
        self.inputs = (Input("findme/*/hypotheses/*", schemas.HypothesisSet,
                             answers=("findme/{session}/selection/{n}",), once=True),)
        self.chosen = 0

    def on_message(self, key, hset):
        k = bus.parse_key(key)   # the key names session and n, never the payload
        n = k.index()
        if not hset.hypotheses:
            raise HypothesisError(f"photo {n} has no hypothesis to select: {hset.reason}")
        frame = None
        if isinstance(self.chooser, TerminalChooser):
            frame = self.need(bus.key(k.session, "frame", n), schemas.Frame)
        rank = self.chooser(hset, frame)
        self.chosen += 1
        sel = schemas.Selection(session=k.session, index=n, rank=rank,
                                by=self.chooser.by, time_ns=time.time_ns())
        return [Output(bus.key(k.session, "selection", n), sel)]

    def counters(self):
        return {"selections": self.chosen}
