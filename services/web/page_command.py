"""A page's text commands, parsed and checked: ``select`` (another hypothesis), ``measure``
(3D of tapped pixels, with the surface each was said to be on) and ``ping``; the wire format
and limits are ``page_input``'s (its module docstring). Pure functions; ``parse_command``
returns a new dict built from its own parse of the text.
"""

from __future__ import annotations

import json

from .page_input import (CODE, MAX_MEASURE_PIXELS, MAX_TEXT_BYTES, SURFACES, _bad, _number,
                         _vector, loads_bounded)


def parse_command(text: str) -> dict:
    """A page's text message as a checked dict (``select``, ``measure`` or ``ping``)."""
    if len(text) > MAX_TEXT_BYTES:
        raise _bad(f"message of {len(text)} characters is over the {MAX_TEXT_BYTES} limit",
                   CODE.ERROR_CODE_TOO_LARGE)
    cmd = loads_bounded(text)
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
    cmd["surfaces"] = _surfaces(cmd["surfaces"], len(px)) if "surfaces" in cmd else None
    return cmd


def _shown(v) -> str:
    """A page's value as the JSON it sent (shortened)."""
    text = json.dumps(v)
    return text if len(text) <= 40 else text[:37] + "..."


def _surfaces(sf, n: int) -> list:
    """A measure's ``surfaces``: a list of n entries, each None, "floor", "wall" or "top"."""
    if not isinstance(sf, list):
        raise _bad(f'surfaces must be a list of null, "floor", "wall" or "top", one per pixel; '
                   f"got {_shown(sf)}")
    if len(sf) != n:
        raise _bad(f"surfaces gives {len(sf)} for {n} pixels: give one per pixel "
                   "(null: as the boundary says)")
    for i, s in enumerate(sf):
        if not (s is None or isinstance(s, str) and s in SURFACES):
            raise _bad(f'surfaces[{i}] must be null, "floor", "wall" or "top", got {_shown(s)}')
    return list(sf)
