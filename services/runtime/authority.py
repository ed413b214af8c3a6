"""The key is the only authority on a message's session and photo numbers.

The router's access control checks the KEY a device publishes on (a device may use only
``findme/<its user>-*/**``), never the payload. So a payload that names another session or
another photo than its key is refused, in every service, on every input, query and fetched
message (DESIGN.md, "Delivery and trust"): otherwise a device could file a Frame under
someone else's session by writing that session into the payload of a put on its own key.

``KEY_RULES`` says, per message type, which key kind it travels on and which payload fields
are the key's parts after the kind (``motion/<a>/<b>`` = ``Motion.index_a/index_b``); the
recorder uses the same table to give a recorded message its key back. ``check`` compares a
decoded message with its key and raises ``KeyAuthorityError`` (``ERROR_CODE_FORBIDDEN``)
naming both the key and the key the payload claims.
"""

from __future__ import annotations

from findme_core.errors import BusError, FindmeError

from . import bus

#: message type -> (key kind, payload fields giving the key parts after the kind)
KEY_RULES: dict[str, tuple[str, tuple[str, ...]]] = {
    "findme.v1.Frame": ("frame", ("index",)),
    "findme.v1.HypothesisSet": ("hypotheses", ("index",)),
    "findme.v1.Selection": ("selection", ("index",)),
    "findme.v1.Scene": ("scene", ("index",)),
    "findme.v1.Motion": ("motion", ("index_a", "index_b")),
    "findme.v1.Pose": ("pose", ("index",)),
    "findme.v1.Trajectory": ("trajectory", ()),
    "findme.v1.Plan": ("plan", ()),
    "findme.v1.Error": ("error", ()),
    # a MeasureReply published for the record by whoever asked (findme run does)
    "findme.v1.MeasureReply": ("measured", ("index",)),
}
#: queries: the request names its session (the photo number is the request's own field)
QUERY_RULES: dict[str, tuple[str, tuple[str, ...]]] = {
    "findme.v1.MeasureRequest": ("measure", ()),
}
_RULES = {**KEY_RULES, **QUERY_RULES}


class KeyAuthorityError(FindmeError):
    """A payload disagrees with the key it arrived on (its session, kind or photo numbers):
    the sender may not speak for that session or photo on this key."""


def claimed_key(msg) -> str | None:
    """The key ``msg``'s own fields say it belongs on, or None for a type with no rule
    (raw bytes, ServiceStatus)."""
    rule = _RULES.get(getattr(getattr(msg, "DESCRIPTOR", None), "full_name", None))
    if rule is None:
        return None
    kind, fields = rule
    return "/".join([bus.ROOT, msg.session, kind, *(str(getattr(msg, f)) for f in fields)])


def check(key: str, msg) -> None:
    """Refuse ``msg`` unless its session, kind and photo numbers are exactly its key's.

    Raw payloads (bytes), types without a session (ServiceStatus) and keys outside the
    ``findme/`` root (no session to speak for: test and tool keys) pass unchecked.

    Raises:
        KeyAuthorityError: the payload claims another key than ``key`` (the message names
            both), or ``key`` is not a session key at all.
    """
    claimed = claimed_key(msg)
    if claimed is None or claimed == str(key) or not str(key).startswith(bus.ROOT + "/"):
        return
    name = msg.DESCRIPTOR.name
    try:
        bus.parse_key(key)
    except BusError as e:
        raise KeyAuthorityError(f"refused: a {name} on {key}, which is not a session key "
                                f"({e})") from None
    raise KeyAuthorityError(f"refused: the {name} on key {key} says it belongs on "
                            f"{claimed[:300]}; the key is the only authority on the session "
                            "and photo numbers")
